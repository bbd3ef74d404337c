"""Each baseline's own mechanism is live: it changes what the model does, the way its paper says.

(Methods with an ``inert`` switch, EWC, LwF, SI, DER++ and Invariant, are also checked by the
checker: switching them off changes the numbers.)
"""

import copy
import dataclasses

import numpy as np
import pytest
import torch

from c2inet.batch import make_batch
from c2inet.methods.base import TaskContext, get_method
from c2inet.model_config import ModelConfig
from c2inet.trainer import ContinualTrainer, TrainConfig

from toys import turners, turning_tasks

CONFIG = TrainConfig(epochs=2, k=3, k_train=2, diagnostics=False)


def trained(name, options=None, tasks=None, observers=None):
    """The method and its model after a run through ``tasks`` (two tasks of arcs)."""
    method = get_method(name)(ModelConfig(), options)
    models = []
    trainer = ContinualTrainer(
        method,
        tasks or turning_tasks(),
        CONFIG,
        observers=[lambda e, d: models.append(d["model"]) if e == "task_end" else None]
        + (observers or []),
    )
    return method, trainer.run(), models[-1]


def test_agem_projects_steps_that_would_raise_the_memory_loss():
    """Tasks turning opposite ways conflict: some steps are projected, and each projected step
    no longer points against the memory's gradient."""
    method, result, _ = trained("agem", tasks=turning_tasks(turns=(0.3, -0.3)))
    assert result.summaries[0]["projected_steps"] == 0  # no memory during the first task
    assert result.summaries[1]["projected_steps"] > 0
    assert sum(len(w) for w in method.buffer) == 16  # 8 scenes of each task


def test_agem_projection_removes_only_a_conflicting_component():
    from c2inet.methods.agem import project

    reference = torch.tensor([1.0, 0.0, 0.0])
    step, projected = project(torch.tensor([-2.0, 1.0, 3.0]), reference)
    assert projected and step @ reference == 0
    torch.testing.assert_close(step, torch.tensor([0.0, 1.0, 3.0]))
    agreeing = torch.tensor([2.0, 1.0, 3.0])
    assert project(agreeing, reference) == (agreeing, False)


def test_mog_freezes_each_tasks_components_and_keeps_them():
    snapshots = []

    def keep(event, data):
        if event == "task_end":
            snapshots.append(data["model"].queue.mixture.detached())

    _, _, model = trained("mog", {"per_task": 3}, turning_tasks(turns=(0.1, 0.2, 0.3)), [keep])
    assert [len(s) for s in snapshots] == [6, 9, 12]  # frozen + the 3 still learnt
    assert model.queue.owners == [0] * 3 + [1] * 3 + [2] * 3 + [3] * 3
    torch.testing.assert_close(snapshots[2].means[:6], snapshots[1].means[:6])  # frozen stay
    assert not torch.allclose(snapshots[1].means[6:9], snapshots[0].means[3:6])  # learnt moved
    torch.testing.assert_close(snapshots[2].weights, torch.full((12,), 1 / 12))


def test_gcrl_learns_its_prior():
    method = get_method("gcrl")(ModelConfig())
    torch.manual_seed(0)
    before = method.build_model().queue.mixture.detached()
    _, _, model = trained("gcrl")
    after = model.queue.mixture.detached()
    assert not torch.allclose(after.means, before.means)
    assert not torch.allclose(after.weights, before.weights)  # the weights are learnt too
    assert model.config.c_source == "posterior" and model.config.decoder_input == "latents"


def test_counterfactual_subtracts_the_blank_past():
    model = get_method("counterfactual")(ModelConfig()).build_model()
    windows = turners(0.2, 4, 0)
    still = windows.positions.copy()
    still[:, :8] = still[:, 7:8]  # every agent standing at its last observed position
    from c2inet.data import Windows

    assert torch.count_nonzero(model.context(make_batch(Windows(still, windows.scene_start)))) == 0
    assert model.context(make_batch(windows)).abs().sum() > 0


def test_adaptive_freezes_all_but_the_style_after_the_first_task():
    snapshots = []

    def keep(event, data):
        if event == "task_end":
            snapshots.append({k: v.clone() for k, v in data["model"].state_dict().items()})

    trained("adaptive", observers=[keep])
    first, second = snapshots
    changed = {k for k in first if not torch.equal(first[k], second[k])}
    assert changed and all(k.startswith("style.") for k in changed)


def test_adaptive_style_modulates_the_prediction():
    _, _, model = trained("adaptive")
    batch = make_batch(turners(0.2, 4, 0))
    with torch.no_grad():
        styled = model.point(batch)
        for p in model.style.parameters():
            p.zero_()
        plain = model.point(batch)
    assert not torch.allclose(styled, plain)


def test_pecnet_endpoints_spread_with_sigma_and_paths_follow_them():
    _, _, model = trained("pecnet")
    batch = make_batch(turners(0.2, 4, 0))
    torch.manual_seed(0)
    spread = model.predict(batch, 20)[:, -1].std(0).mean()
    model.options = type(model.options)(sigma=0.0)
    torch.manual_seed(0)
    assert model.predict(batch, 20)[:, -1].std(0).mean() < 1e-6 < spread
    context = model.context(batch)
    z = torch.zeros(1, len(context), model.options.latent)
    moved = model.future(context, z + 3.0)
    assert not torch.allclose(moved.sum(0), model.future(context, z).sum(0))


@pytest.mark.parametrize("risk", ["irm", "vrex"])
def test_invariant_penalty_is_zero_only_when_environments_agree(risk):
    method = get_method("invariant")(ModelConfig(), {"risk": risk})
    model = method.build_model()
    windows = turners(0.2, 8, 0)
    ctx = TaskContext(0, "t", windows, model, None, np.random.default_rng(0))
    method.before_task(ctx)
    ctx.batch = make_batch(windows)
    ctx.loss, ctx.parts, ctx.output = model.loss(ctx.batch, 2)
    method.before_backward(ctx)
    assert ctx.parts["penalty"] > 0
    assert len(method.risks(ctx, torch.ones(()))) == 2  # the two halves by motion scale
    with pytest.raises(ValueError, match="risk"):
        get_method("invariant")(ModelConfig(), {"risk": "dro"})


def test_derpp_reservoir_keeps_its_size_and_outputs_as_stored():
    method, result, model = trained("derpp", {"buffer": 10})
    assert len(method.scenes) == 10 and method.seen == 2 * 2 * 8  # epochs x tasks x scenes
    assert all(
        o.shape == (12, len(s), 2) for s, o in zip(method.scenes, method.outputs, strict=True)
    )
    assert result.summaries[-1]["buffer_scenes"] == 10


def test_derpp_computes_outputs_only_at_steps_that_keep_a_scene(monkeypatch):
    """Once the reservoir is full most steps keep no scene and so compute no outputs (every
    ``point`` call without gradients is an offer's; the replay's outputs come from the step's
    one pass, ``samples_and_point``)."""
    from c2inet.model import Predictor

    offers, point = [], Predictor.point

    def counted(self, batch):
        if not torch.is_grad_enabled():
            offers.append(len(batch.scene_start) - 1)
        return point(self, batch)

    monkeypatch.setattr(Predictor, "point", counted)
    method = get_method("derpp")(ModelConfig(), {"buffer": 2})
    config = dataclasses.replace(CONFIG, batch_scenes=1)  # a step per scene: 32 offers
    ContinualTrainer(method, turning_tasks(), config).run()
    assert method.seen == 32 and len(method.scenes) == 2 and offers[:2] == [1, 1]
    assert len(offers) <= 12  # 2 filling, then about 2/n of the n-th scene's offers kept


def test_one_pass_gives_the_samples_and_the_point_of_separate_passes():
    """``samples_and_point`` (DER++'s step) with the noise ``loss`` draws gives ``loss``'s
    samples and the chosen agents' ``point``, gradients included, from one encoder call and one
    decoder call."""
    from c2inet.model import Predictor

    torch.manual_seed(0)
    model, batch = Predictor(ModelConfig()), make_batch(turners(0.3, 4, 0))
    agents = batch.obs.shape[1]
    torch.manual_seed(1)
    samples, point = model.samples_and_point(batch, model.noise(3, batch), slice(2, None))
    assert samples.shape == (12, 3, agents, 2) and point.shape == (12, agents - 2, 2)
    fused = torch.autograd.grad(samples.sum() + point.square().sum(), model.parameters())
    torch.manual_seed(1)
    apart = model.loss(batch, 3).output
    torch.testing.assert_close(samples, apart, rtol=1e-5, atol=1e-6)
    alone = model.point(batch)[:, 2:]
    torch.testing.assert_close(point, alone, rtol=1e-5, atol=1e-6)
    grads = torch.autograd.grad(apart.sum() + alone.square().sum(), model.parameters())
    for a, b in zip(fused, grads, strict=True):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("replay_loss", ["variety", "point"])
def test_derpp_one_pass_step_is_the_step_of_separate_passes(replay_loss):
    """DER++'s joined step gives the loss, and the gradient, of the passes it replaces: the
    step's loss, then the replayed batch's drift and task loss (its variety loss with the same
    draws, or its noise-free output's)."""
    options = {"buffer": 6, "replay_batch": 4, "replay_loss": replay_loss}
    method = get_method("derpp")(ModelConfig(), options)
    torch.manual_seed(0)
    model = method.build_model()
    old, new = turners(-0.3, 6, 1), turners(0.3, 5, 2)
    ctx = TaskContext(0, "t", old, model, None, np.random.default_rng(0))
    ctx.batch = make_batch(old)
    method._offer(ctx)  # the reservoir: the six old scenes and their outputs
    with torch.no_grad():  # the model has moved since: the stored outputs drift
        for weight in model.parameters():
            weight.add_(0.05 * torch.randn_like(weight))
    batch, k = make_batch(new), 3
    torch.manual_seed(1)
    ctx.rng = np.random.default_rng(5)
    joined = method.step_loss(ctx, batch, k)
    torch.manual_seed(1)
    ctx.rng = np.random.default_rng(5)
    step = model.loss(batch, k)
    replay, stored = method._draw(ctx)
    point = model.point(replay)
    if replay_loss == "variety":
        loss = model.loss(replay, k).loss
    else:
        loss = replay.per_scene_mean(model.nll(replay, point[:, None])).mean()
    drift = ((point - stored) ** 2).sum(dim=(0, 2))
    drift = replay.per_scene_mean(drift).mean() / (2 * ModelConfig().likelihood_std ** 2)
    apart = step.loss + method.options.alpha * drift + method.options.beta * loss
    assert joined.parts["replay_outputs"] > 1e-3 and joined.parts["replay"] > 0
    torch.testing.assert_close(joined.loss, apart, rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(joined.output, step.output, rtol=1e-5, atol=1e-6)
    grads = torch.autograd.grad(joined.loss, model.parameters())
    for a, b in zip(grads, torch.autograd.grad(apart, model.parameters()), strict=True):
        # float32 sums over differently shaped products (the rollout walks back the rows a
        # loss reached): within rounding of the gradient's scale, not of each element's
        assert (a - b).abs().max() <= 1e-4 * b.abs().max() + 1e-6


def test_derpp_replays_its_batch_through_one_encoder_call_a_step(monkeypatch):
    """Each step encodes its own scenes and the replayed ones as one batch: one encoder call
    with gradients a step, not two (the step's, the replay's) or three (one more for the
    stored outputs' term)."""
    from c2inet.model import Predictor

    encoded, context = [], Predictor.context

    def counted(self, batch):
        encoded.append(torch.is_grad_enabled())
        return context(self, batch)

    monkeypatch.setattr(Predictor, "context", counted)
    method = get_method("derpp")(ModelConfig(), {"buffer": 4})
    config = dataclasses.replace(CONFIG, batch_scenes=1)  # a step per scene
    ContinualTrainer(method, turning_tasks(), config).run()
    assert encoded.count(True) == method.seen  # one step per scene


def test_lwf_holds_the_model_to_its_previous_predictions():
    """After a second task turning the other way, the distilled model predicts the first task's
    scenes closer to how it did after the first task than undistilled fine-tuning does."""
    batch = make_batch(turners(0.3, 4, 0))
    tasks = turning_tasks(turns=(0.3, -0.3))

    def drift(options):
        points = []

        def keep(event, data):
            if event == "task_end":
                with torch.no_grad():
                    points.append(data["model"].point(batch))

        trained("lwf", options, tasks, [keep])
        return (points[1] - points[0]).abs().mean()

    assert drift({"strength": 10.0}) < drift({"strength": 0.0})


def test_si_importance_grows_where_weights_reduced_the_loss():
    method, _, _ = trained("si")
    total = sum(v.sum() for v in method.importance.values())
    assert total > 0 and all((v >= 0).all() for v in method.importance.values())


def test_c2inet_offline_enqueues_clusters_and_refines_them(monkeypatch):
    """Each task adds its k clusters; the Eq 8 / Eq 9 refinement moves them during the task and
    keeps each task's mass within [0.5/t, 2/t]."""
    from c2inet.methods.c2inet_offline import C2INetOffline

    at_start = []
    cluster = C2INetOffline._cluster

    def spy(self, ctx, centres):
        cluster(self, ctx, centres)
        if centres is None:
            at_start.append(ctx.model.queue.mixture.detached())

    monkeypatch.setattr(C2INetOffline, "_cluster", spy)
    _, _, model = trained("c2inet-offline", {"clusters": 3, "interval": 1})
    queue = model.queue
    assert queue.owners == [0, 0, 0, 1, 1, 1]
    torch.testing.assert_close(at_start[1].weights[:3].sum(), torch.tensor(0.5))  # 1/t at first
    assert 0.25 <= queue.mixture.weights[:3].sum().item() <= 1.0
    assert not torch.allclose(queue.mixture.means[3:], at_start[1].means[3:])  # refined
    torch.testing.assert_close(queue.mixture.means[:3], at_start[1].means[:3])  # kept


def test_memory_counts_what_each_method_keeps_between_tasks():
    tasks = turning_tasks(turns=(0.1, 0.2, 0.3))
    memory = {
        name: [s["memory_floats"] for s in trained(name, tasks=tasks)[1].summaries]
        for name in ("finetune", "coresets", "ewc", "joint", "mog")
    }
    assert memory["finetune"] == [0, 0, 0]
    per_task = 5 * (2 * ModelConfig().c_dim + 1)  # MoG's frozen Gaussians: means, variances, weight
    assert memory["mog"] == [per_task, 2 * per_task, 3 * per_task]
    scene = turners(0.1, 1, 0).positions.size  # the floats of one remembered scene
    assert memory["coresets"][1] > memory["coresets"][0] >= scene  # a buffer per task
    parameters = sum(p.numel() for p in get_method("ewc")(ModelConfig()).build_model().parameters())
    assert memory["ewc"][-1] >= 2 * parameters  # a Fisher and an anchor per parameter
    train = [t.train.positions.size for t in tasks]
    assert memory["joint"] == [train[0], train[0] + train[1], sum(train)]  # every task's data


def test_joint_from_scratch_restarts_every_task_from_the_initial_weights():
    method, scratch, _ = trained("joint-scratch")
    _, warm, _ = trained("joint")
    assert not np.array_equal(scratch.matrices["ade"][1], warm.matrices["ade"][1])
    model = method.build_model()
    ctx = TaskContext(
        1,
        "t",
        turning_tasks()[1].train,
        model,
        torch.optim.Adam(model.parameters()),
        np.random.default_rng(0),
    )
    for p in model.parameters():
        p.data.add_(1.0)  # as if trained
    method.before_task(ctx)
    restored = model.state_dict()
    assert all(torch.equal(restored[k], v) for k, v in method.initial.items())


def test_joint_from_scratch_final_only_trains_once_on_the_union_at_the_last_task():
    """Before the last task the model keeps its initial weights (no step taken: its rows are
    those of the untrained model); at the last it trains on every task's data."""
    weights = []
    keep = [
        lambda e, d: (
            weights.append(copy.deepcopy(d["model"].state_dict())) if e == "task_end" else None
        )
    ]
    tasks = turning_tasks(turns=(0.1, 0.2, 0.3))
    method, once, _ = trained("joint-scratch", {"final_only": True}, tasks, keep)
    first = weights[0]
    assert all(torch.equal(first[k], v) for k, v in method.initial.items())
    assert all(torch.equal(weights[1][k], v) for k, v in first.items())
    assert not all(torch.equal(weights[2][k], v) for k, v in first.items())
    untrained, last = once.matrices["ade"][0], once.matrices["ade"][-1]
    assert (last < untrained).all()  # the one fit learnt every task


def test_pecnet_is_scored_at_its_own_point_and_other_models_at_the_mean_of_draws():
    """``ade_k1`` of PECNet is the error of its z = 0 prediction; fine-tuning's that of the mean
    of its samples."""
    from c2inet.evaluation import evaluate, natural_points, sample_predictions

    windows = turning_tasks()[0].test
    truth = windows.positions[:, windows.obs_len :].transpose(1, 0, 2)
    for name, natural in (("pecnet", True), ("finetune", False)):
        _, _, model = trained(name)
        assert getattr(model, "natural_point", False) == natural
        if natural:
            point = natural_points(model, windows)
        else:
            point = sample_predictions(model, windows, 16, 0 + 7_919).mean(0)
        expected = np.linalg.norm(point - truth, axis=-1).mean()
        assert evaluate(model, windows, 3, 0)["ade_k1"] == pytest.approx(expected, rel=1e-5)
