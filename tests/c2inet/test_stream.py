"""Stream learning: task hooks only at declared boundaries, a data-only shift detector."""

import numpy as np
import pytest
import torch

from c2inet.checker import CHECK_CONFIG
from c2inet.data import Windows
from c2inet.methods.base import get_method
from c2inet.model_config import ModelConfig
from c2inet.stream import ShiftDetector, StreamLearner
from c2inet.trainer import ContinualTrainer

from toys import turners, turning_tasks


def learner(name: str) -> StreamLearner:
    return StreamLearner(get_method(name)(ModelConfig()), CHECK_CONFIG)


def same_weights(a: torch.nn.Module, b: torch.nn.Module) -> bool:
    pairs = zip(a.state_dict().values(), b.state_dict().values(), strict=True)
    return all(torch.equal(x, y) for x, y in pairs)


@pytest.mark.parametrize("name", ["finetune", "ewc", "coresets"])
def test_a_boundary_at_every_chunk_is_the_continual_trainer(name):
    tasks = turning_tasks((0.05, 0.2, 0.35))
    stream = learner(name)
    for i, task in enumerate(tasks):
        stream.learn(task.train, boundary=i > 0)
    stream.end_segment()
    trainer = ContinualTrainer(get_method(name)(ModelConfig()), tasks, CHECK_CONFIG)
    trainer.run()
    assert same_weights(stream.model, trainer.model)
    assert stream.boundaries == [0, 1, 2]


def test_without_boundaries_a_boundary_method_is_idle_and_marked():
    assert get_method("ewc").needs_boundaries() and get_method("si").needs_boundaries()
    assert not get_method("finetune").needs_boundaries()
    assert not get_method("derpp").needs_boundaries()  # replay on every step
    chunks = [t.train for t in turning_tasks((0.05, 0.3))]
    ewc = get_method("ewc")
    runs = {}
    for options, boundary in ((ewc.inert, False), (None, False), (None, True)):
        stream = StreamLearner(ewc(ModelConfig(), options), CHECK_CONFIG)
        for i, chunk in enumerate(chunks):
            stream.learn(chunk, boundary=boundary and i > 0)
        runs[options is None, boundary] = stream.model
    assert same_weights(runs[True, False], runs[False, False])  # no task end: no penalty
    assert not same_weights(runs[True, True], runs[False, False])


def test_joint_sees_every_earlier_chunk():
    stream = learner("joint")
    chunks = [turners(0.1, 4, seed) for seed in range(3)]
    for chunk in chunks:
        stream.learn(chunk)
    assert len(stream.seen) == 3
    assert len(stream.method.training_windows(stream.ctx)) == 12


def test_the_detector_fires_on_a_shift_and_not_on_more_of_the_same():
    detector = ShiftDetector(threshold=0.15)
    calm = [detector(turners(0.1, 30, seed)) for seed in range(5)]
    assert calm == [False] * 5
    assert detector(turners(0.3, 30, 9))  # three times the turn rate
    assert not detector(turners(0.3, 30, 10))  # the new regime is now the reference
    fast = turners(0.3, 30, 11)
    assert detector(Windows(fast.positions * 1.5, fast.scene_start))  # half as fast again


def test_disagreement_is_zero_for_a_deterministic_predictor():
    windows = turners(0.2, 6, 1)
    trained = learner("finetune")
    trained.learn(windows)
    assert trained.disagreement(windows, seed=0) > 0.0
    assert learner("cv").disagreement(windows, seed=0) == pytest.approx(0.0, abs=1e-5)
    assert np.isfinite(trained.evaluate(windows, seed=0)["ade"])
