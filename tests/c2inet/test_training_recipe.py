"""The training recipe: the learning-rate schedule within a task and validation selection."""

import numpy as np
import pytest
import torch

from c2inet import trainer as trainer_module
from c2inet.errors import InputError
from c2inet.methods.base import get_method
from c2inet.model_config import ModelConfig
from c2inet.schedule import learning_rate
from c2inet.selection import BestEpoch
from c2inet.trainer import ContinualTrainer, TrainConfig

from toys import turning_tasks


def test_the_schedule_warms_up_then_decays_to_its_final_share():
    def rate(schedule, t, warmup=0.0):
        return learning_rate(1.0, schedule, t, 10, warmup, 0.01)

    assert [rate("constant", t) for t in (0, 5, 9.9)] == [1.0, 1.0, 1.0]
    assert rate("cosine", 0) == pytest.approx(1.0)
    assert rate("cosine", 5) == pytest.approx(0.505)  # half way: the mean of 1 and 0.01
    assert rate("cosine", 10) == pytest.approx(0.01)
    assert rate("linear", 2.5) == pytest.approx(1 - 0.99 * 0.25)
    assert rate("cosine", 0.5, warmup=2) == pytest.approx(0.25, abs=1e-3)  # rising linearly
    assert rate("cosine", 2, warmup=2) == pytest.approx(1.0)  # the decay starts after it
    assert 0 < rate("cosine", 0, warmup=2) < 1e-3  # the very first step still moves


def test_the_schedule_changes_the_rate_the_optimiser_steps_with():
    """A trained task's epochs record the rate of their last step: constant stays at lr,
    cosine falls towards lr * lr_final, and the optimiser holds the scheduled rate."""
    rates = {}
    for schedule in ("constant", "cosine"):
        config = TrainConfig(epochs=4, k=2, lr=2e-3, schedule=schedule, lr_final=0.1)
        trainer = ContinualTrainer(get_method("finetune")(ModelConfig()), turning_tasks(), config)
        result = trainer.run()
        rates[schedule] = [r["lr"] for r in result.history if r["task"] == 1]
    assert rates["constant"] == [2e-3] * 4
    falling = rates["cosine"]
    assert all(a > b for a, b in zip(falling, falling[1:], strict=False))
    # 8 scenes make one step an epoch: the last one starts 3 epochs into the 4
    assert falling[-1] == pytest.approx(learning_rate(2e-3, "cosine", 3, 4, 0, 0.1))
    with pytest.raises(InputError, match="schedule"):
        TrainConfig(schedule="exponential")
    with pytest.raises(InputError, match="select"):
        TrainConfig(select="test")


def test_best_epoch_keeps_the_state_of_the_lowest_score():
    model = torch.nn.Linear(2, 1)
    method = get_method("finetune")(ModelConfig())
    best = BestEpoch()
    weights = {}
    for epoch, score in enumerate([0.5, 0.2, float("nan"), 0.4]):  # a planted curve
        with torch.no_grad():
            model.weight.fill_(epoch)
        weights[epoch] = model.weight.clone()
        best.offer(score, epoch, model, None, method)
    assert best.epoch == 1 and best.score == 0.2
    best.restore(model, None, method)
    assert torch.equal(model.weight, weights[1])


def test_a_task_keeps_its_validation_best_epoch(monkeypatch):
    """With ``select = val`` the trainer scores each epoch on the current task's validation
    split alone (a planted curve here, best ADE at epoch 1 of 3, best FDE at epoch 2) and ends
    the task with the epoch its ``select_metric`` ranks first: with ADE its test errors are
    those of a run of 2 epochs, not of 3; with FDE, those of the 3-epoch run."""
    planted = {"ade": [0.5, 0.2, 0.4], "fde": [0.9, 0.8, 0.5]}
    scored = []
    real_evaluate = trainer_module.evaluate

    def fake_evaluate(model, windows, k, *args, **kwargs):
        if k == 7:  # the selection's score (select_k = 7 marks it)
            epoch = len(scored) % 3
            scored.append(windows)
            return {key: curve[epoch] for key, curve in planted.items()}
        return real_evaluate(model, windows, k, *args, **kwargs)

    monkeypatch.setattr(trainer_module, "evaluate", fake_evaluate)
    tasks = turning_tasks()

    def run(epochs, select, metric="ade"):
        config = TrainConfig(
            epochs=epochs, k=2, select=select, select_k=7, select_metric=metric, val_every=0
        )
        return ContinualTrainer(get_method("finetune")(ModelConfig()), tasks, config).run()

    def selected_epochs(result):
        return [r["selected_epoch"] for r in result.history if "selected_epoch" in r]

    selected = run(3, "val")
    assert selected_epochs(selected) == [1, 1]
    assert [r["select_fde"] for r in selected.history] == planted["fde"] * 2
    assert [id(w) for w in scored] == [id(tasks[0].val)] * 3 + [id(tasks[1].val)] * 3
    by_fde = run(3, "val", "fde")
    assert selected_epochs(by_fde) == [2, 2]
    assert selected_epochs(run(3, "val", "ade+fde")) == [2, 2]  # 0.9 against 1.0 and 1.4
    last = run(3, "last")
    np.testing.assert_array_equal(by_fde.matrices["ade"], last.matrices["ade"])
    assert not np.array_equal(selected.matrices["ade"], last.matrices["ade"])  # live
    # the selected run holds epoch 1's weights: task 0's row equals a 2-epoch run's
    monkeypatch.setattr(trainer_module, "evaluate", real_evaluate)
    two = run(2, "last")
    np.testing.assert_array_equal(selected.matrices["ade"][0], two.matrices["ade"][0])


def test_an_unknown_selection_metric_is_refused():
    with pytest.raises(ValueError, match="select_metric"):
        TrainConfig(select_metric="mse")


def test_selection_needs_a_validation_split():
    tasks = turning_tasks()
    tasks[0].val = None
    config = TrainConfig(epochs=1, k=2, select="val")
    with pytest.raises(InputError, match="no validation split"):
        ContinualTrainer(get_method("finetune")(ModelConfig()), tasks, config).run()


def test_the_likelihood_in_metres_is_the_squared_error_in_metres():
    """``loss_units = "metres"``: the error the variety loss minimises is each displacement's
    error in metres (as STGAT trains); the default divides it by the scene's motion scale."""
    from c2inet.batch import make_batch
    from c2inet.model import Predictor

    from toys import toy_windows

    batch = make_batch(toy_windows())
    torch.manual_seed(0)
    pred = torch.randn(12, 3, batch.obs.shape[1], 2)
    scaled = Predictor(ModelConfig()).nll(batch, pred)
    metres = Predictor(ModelConfig(loss_units="metres")).nll(batch, pred)
    truth = ((pred * batch.scale - batch.fut_rel[:, None]) ** 2).sum(dim=(0, 3)) / (2 * 0.1**2)
    torch.testing.assert_close(metres, truth)
    assert not torch.allclose(scaled, metres)
    with pytest.raises(InputError, match="loss_units"):
        ModelConfig(loss_units="feet")


@pytest.mark.parametrize("kind", ["rotate", "axes"])
def test_augmentation_turns_each_scene_whole_and_changes_training(kind):
    """Every distance within a scene is kept (agents turn together), the headings change, and
    ``axes`` draws only the square's symmetries; a run with it trains otherwise than without."""
    from c2inet.augment import augment_scenes

    from toys import toy_windows

    windows = toy_windows(scenes=40)
    turned = augment_scenes(windows, np.random.default_rng(0), kind)
    for scene in range(len(windows)):
        rows = slice(windows.scene_start[scene], windows.scene_start[scene + 1])
        a, b = windows.positions[rows], turned.positions[rows]
        gaps = np.linalg.norm(a[:, None] - a[None], axis=-1)
        np.testing.assert_allclose(np.linalg.norm(b[:, None] - b[None], axis=-1), gaps, atol=1e-4)
    steps = np.diff(windows.positions, axis=1).reshape(-1, 2)
    after = np.diff(turned.positions, axis=1).reshape(-1, 2)
    assert not np.allclose(steps, after, atol=1e-3)
    if kind == "axes":  # a quarter turn or a mirror: |x| and |y| swap or stay, never mix
        swapped = np.isclose(np.abs(after), np.abs(steps)[:, ::-1], atol=1e-4).all(1)
        stayed = np.isclose(np.abs(after), np.abs(steps), atol=1e-4).all(1)
        assert (swapped | stayed).all()
    plain = TrainConfig(epochs=1, k=2)
    runs = [
        ContinualTrainer(get_method("finetune")(ModelConfig()), turning_tasks(), config).run()
        for config in (plain, TrainConfig(epochs=1, k=2, augment=kind))
    ]
    assert not np.array_equal(runs[0].matrices["ade"], runs[1].matrices["ade"])


@pytest.mark.parametrize("name", ["finetune", "c2inet-online", "derpp", "pecnet", "ewc"])
def test_a_training_step_reads_no_number_back_for_its_logs(monkeypatch, name):
    """Issue 65: a step on an accelerator never waits for a number from it. Run as on one (the
    tensor path, the rollout walking every row back), every call that reads a tensor back to
    the host is counted during the steps (C2INet-online's second task, anchors and queue
    acting, and DER++'s replay included): ``item``, ``float``, ``bool``, ``int``, ``tolist``,
    ``nonzero``, ``cpu``. (``numpy`` raises on a device tensor rather than waiting; the index
    arrays a batch is cut with are made on the host.) The epoch reads each loss part once."""
    from c2inet import trainer
    from c2inet.kernels import rollout

    monkeypatch.setattr(rollout, "walks_reached_rows", lambda d_outs: False)
    reads = []
    for attribute in ("item", "__float__", "__bool__", "__int__", "tolist", "nonzero", "cpu"):
        real = getattr(torch.Tensor, attribute)

        def counted(self, *args, _real=real, _name=attribute, **kwargs):
            reads.append(_name)
            return _real(self, *args, **kwargs)

        monkeypatch.setattr(torch.Tensor, attribute, counted)
    real_step = trainer.train_step
    per_step = []

    def step(*args, **kwargs):
        before = len(reads)
        parts = real_step(*args, **kwargs)
        per_step.append(len(reads) - before)
        return parts

    monkeypatch.setattr(trainer, "train_step", step)
    config = TrainConfig(epochs=2, k=2, diagnostics=False, val_every=0)
    model = ModelConfig(kernels="tensor")  # an accelerator's kernels
    result = ContinualTrainer(get_method(name)(model), turning_tasks(), config).run()
    assert per_step and set(per_step) == {0}, (per_step, reads[:10])
    assert all(type(v) in (int, float) for r in result.history for v in r.values())  # no tensor
