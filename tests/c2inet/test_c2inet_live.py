"""Is every part of C2INet live? Each test fails if its mechanism were inert."""

import math

import numpy as np
import pytest
import torch

from c2inet.batch import make_batch, variety_loss
from c2inet.data import Windows
from c2inet.diagnostics import diagnose, mutual_information, probe_accuracy
from c2inet.methods.base import TaskContext, get_method
from c2inet.methods.c2inet_online import C2INetOptions
from c2inet.model import ModelConfig, make_anchors
from c2inet.prior import GaussianMixture
from c2inet.trainer import ContinualTrainer, Task, TrainConfig

from toys import walkers


def toy_tasks(scenes=48) -> list[Task]:
    """Two domains told apart by the observed frames: crowds walking east, then north."""
    return [
        Task(name, *(walkers(heading, n, seed + i) for i, n in enumerate((scenes, 8, 40))), heading)
        for name, heading, seed in (("east", 0.0, 0), ("north", np.pi / 2, 10))
    ]


@pytest.fixture(scope="module")
def trained():
    """C2INet-online trained through the toy curriculum: its model and its result."""
    models = []
    method = get_method("c2inet-online")(ModelConfig(), {"interval": 2})
    config = TrainConfig(epochs=6, k=5, k_train=3)
    observer = [lambda event, data: models.append(data["model"]) if event == "task_end" else None]
    result = ContinualTrainer(method, toy_tasks(), config, observers=observer).run()
    return models[-1], result


def test_confounder_becomes_informative_and_the_decoder_uses_it(trained):
    _, result = trained
    last = result.diagnostics[-1]
    assert last["probe_observed"] > 0.9  # the toy's domains are visible in X
    assert last["probe_c"] > 0.8  # and C's posterior mean tells them apart (chance 0.5)
    assert last["c_effect"] > 0.05  # replacing C by a prior sample moves the prediction (m)
    assert last["knob_r2"] > 0.5  # the heading of each domain is read back from C


def test_test_time_c_comes_from_the_queue(trained):
    model, _ = trained
    batch = make_batch(toy_tasks()[1].test)
    torch.manual_seed(3)
    before = model.predict(batch, 4)
    saved = model.queue.mixture
    model.queue.mixture = GaussianMixture(saved.means + 3.0, saved.logvars, saved.weights)
    torch.manual_seed(3)
    moved = model.predict(batch, 4)
    torch.manual_seed(3)
    posterior = model.predict(batch, 4, c_source="posterior")
    model.queue.mixture = saved
    torch.manual_seed(3)
    posterior_again = model.predict(batch, 4, c_source="posterior")
    assert (before - moved).abs().max() > 0.05  # the default draws C from the queue
    torch.testing.assert_close(posterior, posterior_again)  # the posterior option ignores it


def test_pruning_fires_at_the_defaults_of_a_six_task_curriculum():
    options, epochs = C2INetOptions(), TrainConfig().epochs
    per_task = 1 + epochs // options.interval
    assert 6 * per_task > options.capacity  # so the defaults exercise pruning
    method = get_method("c2inet-online")(ModelConfig(), {"capacity": 5, "interval": 1})
    tasks = toy_tasks(12)
    result = ContinualTrainer(method, tasks, TrainConfig(epochs=3, k=2, k_train=1)).run()
    assert sum(s["pruned"] for s in result.summaries) > 0
    assert all(s["queue_size"] <= 5 for s in result.summaries)


def drift_of_old_predictions(distill: bool) -> float:
    """How far the decoder's output at task-1 anchors moves while task 2 trains."""
    torch.manual_seed(0)
    options = {"distill_decoder": distill, "distill_encoder": distill, "interval": 100}
    method = get_method("c2inet-online")(ModelConfig(), options)
    tasks = toy_tasks(24)
    model = method.build_model()
    optimiser = torch.optim.Adam(model.parameters(), lr=3e-3)
    rng = np.random.default_rng(0)
    trainer = ContinualTrainer(method, tasks, TrainConfig(epochs=3, k_train=1, val_every=0))
    ctx = TaskContext(0, "a", tasks[0].train, model, optimiser, rng)
    trainer._train_task(ctx)
    probe = make_anchors(model, model.queue.task_mixture(0), 64)
    ctx = TaskContext(1, "b", tasks[1].train, model, optimiser, rng)
    trainer._train_task(ctx)
    with torch.no_grad():
        after = model.backbone.decode(probe.cond[None], probe.last_rel)[:, 0]
    return float((after - probe.future).norm(dim=-1).mean())


def test_the_regulariser_reduces_the_drift_of_old_components_predictions():
    assert drift_of_old_predictions(True) < 0.7 * drift_of_old_predictions(False)


def test_the_queue_free_control_differs_from_c2inet_only_by_the_queue():
    config = ModelConfig()
    torch.manual_seed(0)
    full = get_method("c2inet-online")(config).build_model()
    torch.manual_seed(0)
    control = get_method("c2inet-noqueue")(config).build_model()
    for (name, a), (_, b) in zip(
        full.state_dict().items(), control.state_dict().items(), strict=True
    ):
        torch.testing.assert_close(a, b, msg=name)
    batch = make_batch(toy_tasks(8)[0].train)
    torch.manual_seed(1)
    loss_full = full.loss(batch, 2).loss
    torch.manual_seed(1)
    loss_control = control.loss(batch, 2).loss
    torch.testing.assert_close(loss_full, loss_control)  # same queue (N(0, I)), same loss
    result = ContinualTrainer(
        get_method("c2inet-noqueue")(config), toy_tasks(8), TrainConfig(epochs=2, k=2)
    ).run()
    assert result.diagnostics[-1]["queue"]["owners"] == [-1]  # the queue never grew


def test_variety_loss_takes_the_best_sample_per_scene():
    batch = make_batch(toy_tasks(2)[0].train)  # 2 scenes of 2 agents
    per_agent = torch.tensor([[1.0, 1.0, 9.0, 9.0], [0.0, 4.0, 1.0, 1.0]])
    # scene 0: sample 0 mean 1, sample 1 mean 2 -> 1; scene 1: 9 vs 1 -> 1
    assert variety_loss(per_agent, batch).item() == pytest.approx(1.0)
    assert variety_loss(per_agent[:1], batch).item() == pytest.approx(5.0)


def test_c_per_scene_is_shared_by_the_agents_of_a_scene():
    model = get_method("c2inet-online")(ModelConfig(c_per="scene")).build_model()
    batch = make_batch(toy_tasks(4)[0].train)
    post = model.posteriors(batch)
    assert post.c_mean.shape == (batch.num_scenes, model.config.c_dim)
    for source in ("prior", "posterior"):
        z, c = model.latents(batch, post, 3, source)
        cond = model.conditions(batch, z, c)[..., model.config.z_dim :]
        torch.testing.assert_close(cond[:, 0], cond[:, 1])  # agents 0 and 1 share scene 0


def test_mutual_information_estimate_spans_zero_to_log_n():
    n = 64
    same = mutual_information(torch.zeros(n, 2), torch.zeros(n, 2))
    apart = mutual_information(
        torch.arange(n, dtype=torch.float32)[:, None] * 10, torch.full((n, 1), -4.0)
    )
    assert abs(same) < 0.05 and apart == pytest.approx(math.log(n), abs=0.05)


def test_probe_accuracy_separates_signal_from_noise():
    rng = np.random.default_rng(0)
    labels = np.repeat([0, 1, 2], 40)
    signal = labels[:, None] + rng.normal(0, 0.1, (120, 2))
    assert probe_accuracy(signal, labels) == 1.0
    assert probe_accuracy(rng.normal(size=(120, 2)), labels) < 0.6
    assert probe_accuracy(signal, np.zeros(120, int)) is None


def test_diagnostics_of_a_baseline_have_no_confounder_part():
    tasks = toy_tasks(8)
    model = get_method("finetune")(ModelConfig()).build_model()
    out = diagnose(model, [t.test for t in tasks], [t.value for t in tasks])
    assert set(out) == {"probe_observed", "probe_context"}


def test_decoder_sees_the_past_only_through_the_latents():
    """Two histories with the same last step and motion scale (the earlier steps reversed): with
    the same [z, c] the predictions are equal, with other latents they are not."""
    model = get_method("c2inet-online")(ModelConfig()).build_model()
    with torch.no_grad():  # the residual decoder starts at constant velocity, blind to its input
        model.backbone.decoder.out.weight.normal_(0, 0.1)
    windows = toy_tasks(4)[0].train
    steps = np.diff(windows.positions[:, :8], axis=1)  # (N, 7, 2)
    steps[:, :6] = steps[:, 5::-1]
    history = windows.positions[:, 7:8] - np.cumsum(steps[:, ::-1], axis=1)[:, ::-1]
    other = Windows(windows.positions.copy(), windows.scene_start)
    other.positions[:, :7] = history
    first, second = make_batch(windows), make_batch(other)
    torch.testing.assert_close(first.obs_rel[-1], second.obs_rel[-1])
    torch.testing.assert_close(first.scale, second.scale)
    assert not torch.allclose(model.context(first), model.context(second))
    cond = torch.randn(2, len(first.scene_of), 16)
    torch.testing.assert_close(model.decode(first, cond), model.decode(second, cond))
    assert not torch.allclose(model.decode(first, cond), model.decode(first, cond.flip(0)))


def test_past_reconstruction_trains_the_past_decoder_only_when_weighted():
    batch = make_batch(toy_tasks(4)[0].train)
    grads = {}
    for beta_x in (0.0, 1.0):
        torch.manual_seed(0)
        model = get_method("c2inet-noqueue")(ModelConfig(beta_x=beta_x)).build_model()
        model.loss(batch, 2).loss.backward()
        grads[beta_x] = sum(p.grad.abs().sum().item() for p in model.past.parameters())
    assert grads[0.0] == 0.0 and grads[1.0] > 0


def test_variety_loss_spreads_the_samples():
    """Best of k_train samples lets the latent spread futures; one sample pulls them together."""
    spread = {}
    for k_train in (1, 5):
        torch.manual_seed(0)
        result = ContinualTrainer(
            get_method("finetune")(ModelConfig()),
            toy_tasks(24)[:1],
            TrainConfig(epochs=4, k=8, k_train=k_train, diagnostics=False),
        ).run()
        spread[k_train] = result.matrices["endpoint_spread"][0, 0]
    assert spread[5] > 1.5 * spread[1]
