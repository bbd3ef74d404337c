"""The learner: batching without leakage, method hooks, checkpoints, and learning itself."""

import numpy as np
import pytest
import torch

from c2inet.batch import Batch, make_batch
from c2inet.data import Windows
from c2inet.methods.base import TaskContext, discover, get_method
from c2inet.model import C2INetModel, ModelConfig, Predictor
from c2inet.trainer import ContinualTrainer, TrainConfig

from toys import toy_windows, turning_tasks


def test_changing_future_frames_never_changes_model_inputs():
    windows = toy_windows()
    altered = Windows(windows.positions.copy(), windows.scene_start)
    altered.positions[:, 8:] += 100.0
    a, b = make_batch(windows), make_batch(altered)
    torch.testing.assert_close(a.obs_rel, b.obs_rel)
    assert not torch.equal(a.fut_rel, b.fut_rel)
    for model in (Predictor(ModelConfig()), C2INetModel(ModelConfig())):
        torch.testing.assert_close(model.context(a), model.context(b))


def test_padding_round_trips_agents_to_scene_slots():
    batch = make_batch(toy_windows())
    x = torch.arange(len(batch.scene_of), dtype=torch.float32)[:, None]
    padded, mask = batch.pad(x)
    assert mask.sum() == len(x) and padded.shape[:2] == (batch.num_scenes, batch.max_agents)
    torch.testing.assert_close(batch.unpad(padded), x)


def test_joined_batches_are_the_batch_of_their_scenes():
    """``Batch.concat`` (DER++'s one pass over its step and its replay) equals the batch made
    from both parts' scenes at once, agent offsets, scene indices and padding included."""
    first, second = toy_windows(5, seed=1), toy_windows(7, seed=2)
    joined = Batch.concat([make_batch(first), make_batch(second)])
    whole = make_batch(Windows.concat([first, second]))
    for name in ("obs", "fut", "scene_start", "scene_of", "slot_of"):
        assert torch.equal(getattr(joined, name), getattr(whole, name)), name
    assert joined.max_agents == whole.max_agents and joined.num_scenes == 12


def test_graph_attention_stays_inside_each_scene():
    windows = toy_windows(4)
    model = Predictor(ModelConfig())
    base = model.context(make_batch(windows))
    moved = Windows(windows.positions.copy(), windows.scene_start)
    last = slice(windows.scene_start[-2], windows.scene_start[-1])
    moved.positions[last] += (
        np.random.default_rng(1).normal(size=moved.positions[last].shape).astype(np.float32)
    )
    after = model.context(make_batch(moved))
    first_scenes = slice(0, windows.scene_start[-2])
    torch.testing.assert_close(base[first_scenes], after[first_scenes])


def test_ewc_penalty_is_zero_at_the_anchor_and_positive_away():
    ewc = get_method("ewc")(ModelConfig())
    model = ewc.build_model()
    ctx = TaskContext(0, "t", toy_windows(), model, None, np.random.default_rng(0))
    ewc.after_task(ctx)
    assert ewc.penalty(model).item() == 0.0
    with torch.no_grad():
        for p in model.parameters():
            p.add_(0.5)
    assert ewc.penalty(model).item() > 0


def test_coresets_buffer_respects_its_size():
    method = get_method("coresets")(ModelConfig(), {"per_task": 5})
    rng = np.random.default_rng(0)
    for index, scenes in enumerate((12, 3, 8)):
        method.after_task(TaskContext(index, "t", toy_windows(scenes, seed=index), None, None, rng))
    assert [len(w) for w in method.buffer] == [5, 3, 5]
    current = toy_windows(7)
    assert len(method.training_windows(TaskContext(3, "t", current, None, None, rng))) == 7 + 13


def test_same_seed_same_training_on_cpu():
    runs = [
        ContinualTrainer(
            get_method("finetune")(ModelConfig()), turning_tasks(), TrainConfig(epochs=1, k=2)
        ).run()
        for _ in range(2)
    ]
    np.testing.assert_array_equal(runs[0].matrices["ade"], runs[1].matrices["ade"])


def test_fused_adam_takes_the_loops_steps_to_rounding():
    """The default optimiser is Adam in one kernel; ``fused_adam=False`` is the earlier loop
    over the weights (runs before December 2026). A training differs only by rounding."""
    from c2inet.trainer import start_training

    method = get_method("finetune")(ModelConfig())
    weights = []
    for fused in (True, False):
        model, optimiser, _ = start_training(method, TrainConfig(fused_adam=fused))
        assert optimiser.defaults["fused"] is fused
        batch = make_batch(toy_windows())
        for _ in range(5):
            optimiser.zero_grad()
            model.loss(batch, 2).loss.backward()
            optimiser.step()
        weights.append(torch.cat([p.detach().flatten() for p in model.parameters()]))
    assert not torch.equal(*weights)  # the option is live
    torch.testing.assert_close(*weights, rtol=0, atol=1e-5)


@pytest.mark.parametrize("name", sorted(n for n, cls in discover().items() if cls.trains))
def test_trained_methods_beat_constant_velocity_on_the_newest_task(name):
    tasks = turning_tasks(train=40)
    config = TrainConfig(epochs=6, k=20)
    learned = ContinualTrainer(get_method(name)(ModelConfig()), tasks, config).run()
    floor = ContinualTrainer(get_method("cv")(ModelConfig()), tasks, config).run()
    assert learned.matrices["ade"][-1, -1] < floor.matrices["ade"][-1, -1]
