"""Every registered method against one contract (as Gymnasium's env checker), resume included."""

import dataclasses
import sys

import numpy as np
import pytest

from c2inet.methods.base import Method, discover
from c2inet.model import ModelConfig
from c2inet.trainer import ContinualTrainer, TrainConfig, load_checkpoint

from toys import turning_tasks

METHODS = discover()


@pytest.mark.parametrize("name", sorted(METHODS))
def test_method_contract(name):
    cls = METHODS[name]
    assert issubclass(cls, Method) and cls.name == name and cls.__doc__
    assert "Example" in sys.modules[cls.__module__].__doc__  # Mammoth-style: name, doc, example
    assert dataclasses.is_dataclass(cls.Options)
    model = cls(ModelConfig()).build_model()
    assert callable(model.predict) and (not cls.trains or callable(model.loss))


def recorded_run(name, tasks, folder, resume=False):
    """A run of method ``name`` and the (event, task or epoch) its observers received."""
    events = []

    def observe(event, data):
        key = data["task"] if event == "task_end" else (data["task"], data["epoch"])
        events.append((event, key, data.get("row") or data.get("nll")))

    trainer = ContinualTrainer(
        METHODS[name](ModelConfig()),
        tasks,
        TrainConfig(epochs=2, k=3, k_train=2),
        checkpoint_dir=folder,
        observers=[observe],
    )
    return trainer.run(resume=resume), events


@pytest.mark.parametrize("name", sorted(METHODS))
def test_a_resumed_run_equals_an_uninterrupted_one(tmp_path, name):
    """Checkpoints carry all a method keeps: resuming after any task gives the same numbers,
    and the observers see the same events (the finished tasks' are replayed)."""
    tasks = turning_tasks(turns=(0.1, 0.2, 0.3))
    whole, whole_events = recorded_run(name, tasks, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["task_00.pt", "task_01.pt", "task_02.pt"]
    for finished in (1, 2):
        for later in range(finished, 3):
            (tmp_path / f"task_{later:02d}.pt").unlink(missing_ok=True)
        resumed, events = recorded_run(name, tasks, tmp_path, resume=True)
        for metric, matrix in whole.matrices.items():
            np.testing.assert_array_equal(resumed.matrices[metric], matrix, err_msg=metric)
        assert resumed.history == whole.history and resumed.summaries == whole.summaries
        assert resumed.diagnostics == whole.diagnostics and events == whole_events
    state = load_checkpoint(tmp_path / "task_02.pt")
    assert state["task"] == 2 and len(state["history"]) == len(whole.history)
