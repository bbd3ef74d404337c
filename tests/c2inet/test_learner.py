"""The learner: batching without leakage, method hooks, checkpoints, and learning itself."""

from dataclasses import FrozenInstanceError, replace

import numpy as np
import pytest
import torch

from c2inet.batch import Batch, make_batch
from c2inet.data import Windows
from c2inet.errors import InputError
from c2inet.methods.base import TaskContext, discover, get_method
from c2inet.model import C2INetModel, Predictor
from c2inet.model_config import ModelConfig
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


def test_a_batch_is_frozen_and_derives_its_displacements_and_scales_once():
    """A training step asks for them a dozen times; computed once, they cannot go stale."""
    batch = make_batch(toy_windows())
    with pytest.raises(FrozenInstanceError):
        batch.obs = batch.obs + 1
    for name in ("obs_rel", "scale", "last_rel", "fut_rel", "agent_counts"):
        assert getattr(batch, name) is getattr(batch, name), name  # kept, not made again
    fresh = make_batch(toy_windows())
    torch.testing.assert_close(batch.scale, fresh.scale, rtol=0, atol=0)


def test_scene_noise_moves_a_scenes_agents_together_and_agent_noise_each_alone():
    """``noise_per = scene`` (STGAT's global noise) gives a scene's agents one draw a sample,
    so a sample moves the scene as a whole; the default draws each agent's own, as before."""
    batch = make_batch(toy_windows())
    for per in ("agent", "scene"):
        model = Predictor(ModelConfig(noise_per=per))
        torch.manual_seed(0)
        noise = model.noise(3, batch)
        assert noise.shape == (3, len(batch.scene_of), 16)
        first, second = batch.scene_start[1:3]  # scene 1's agents (it has several)
        assert second - first > 1
        same = torch.equal(noise[:, first], noise[:, second - 1])
        assert same == (per == "scene")
        if per == "agent":  # the default's draws are the ones it always drew
            torch.manual_seed(0)
            assert torch.equal(noise, torch.randn(3, len(batch.scene_of), 16))
    with pytest.raises(ValueError, match="noise_per"):
        ModelConfig(noise_per="world")


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


def test_a_run_stops_after_the_first_task_its_objective_so_far_is_above_its_bound(tmp_path):
    """``stop_above`` (tuning's pruning): the run stops after task t when its average point
    error over tasks 0..t is above the bound; None (no bound) never stops it, and a run
    resumed from its checkpoints stops where the uninterrupted one did."""
    from c2inet.metrics import average_seen

    tasks = turning_tasks((0.1, 0.2, 0.3))
    full = ContinualTrainer(get_method("finetune")(ModelConfig()), tasks, TrainConfig(epochs=1))
    curve = average_seen(full.run().matrices["ade_k1"])
    bounds = (None, curve[1] * 0.999)  # through the first task, stop after the second
    config = TrainConfig(epochs=1, stop_above=bounds)
    stopped = ContinualTrainer(get_method("finetune")(ModelConfig()), tasks, config, tmp_path)
    result = stopped.run()
    assert len(result.summaries) == 2 and np.isnan(result.matrices["ade_k1"][2]).all()
    np.testing.assert_array_equal(average_seen(result.matrices["ade_k1"][:2]), curve[:2])
    assert {epoch["task"] for epoch in result.history} == {0, 1}
    again = ContinualTrainer(get_method("finetune")(ModelConfig()), tasks, config, tmp_path)
    assert len(again.run(resume=True).summaries) == 2  # resumed after task 1: stops at once
    loose = TrainConfig(epochs=1, stop_above=(curve[0], curve[1] * 1.001))
    through = ContinualTrainer(get_method("finetune")(ModelConfig()), tasks, loose).run()
    assert len(through.summaries) == 3
    for bad in (-1.0, float("nan")):
        with pytest.raises(InputError, match="stop_above"):
            TrainConfig(stop_above=(bad,))


@pytest.mark.parametrize("name", sorted(n for n, cls in discover().items() if cls.trains))
def test_trained_methods_beat_constant_velocity_on_the_newest_task(name):
    tasks = turning_tasks(train=40)
    config = TrainConfig(epochs=6, k=20)
    learned = ContinualTrainer(get_method(name)(ModelConfig()), tasks, config).run()
    floor = ContinualTrainer(get_method("cv")(ModelConfig()), tasks, config).run()
    assert learned.matrices["ade"][-1, -1] < floor.matrices["ade"][-1, -1]


def test_without_unseen_tasks_only_the_seen_cells_are_scored_and_they_are_the_same():
    tasks = turning_tasks(turns=(0.1, 0.2, 0.3))
    config = TrainConfig(epochs=1, k=2, k_train=1, diagnostics=False, val_every=0)
    every = ContinualTrainer(get_method("finetune")(ModelConfig()), tasks, config).run()
    lean = replace(config, eval_unseen=False)
    seen = ContinualTrainer(get_method("finetune")(ModelConfig()), tasks, lean).run()
    upper = np.triu(np.ones((3, 3), bool), 1)
    for metric, matrix in seen.matrices.items():
        assert np.isnan(matrix[upper]).all() and np.isfinite(matrix[~upper]).all()
        np.testing.assert_array_equal(matrix[~upper], every.matrices[metric][~upper])
