"""Where the learner's tensors live: ``--device`` names, what this machine lacks refused, every
tensor of a run and of the diagnostics made on the model's device, and the method checker on CUDA
where there is one."""

from pathlib import Path

import pytest
import torch

import c2inet
from c2inet.checker import DeviceAudit, check_method, turning_tasks
from c2inet.device import resolve_device
from c2inet.diagnostics import diagnose
from c2inet.errors import InputError
from c2inet.methods.base import get_method
from c2inet.model_config import ModelConfig
from c2inet.trainer import ContinualTrainer, TrainConfig

LEARNER = Path(c2inet.__file__).parent


def test_device_names_resolve_or_fail_in_one_line(monkeypatch):
    assert resolve_device("cpu") == torch.device("cpu")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    assert resolve_device("auto") == torch.device("cuda")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    monkeypatch.setattr(torch.backends.mps, "is_available", lambda: False)
    assert resolve_device("auto") == torch.device("cpu")
    with pytest.raises(InputError, match="'cuda:1': this machine has no CUDA device"):
        resolve_device("cuda:1")
    with pytest.raises(InputError, match="'gpu' is none of auto, cpu, cuda"):
        TrainConfig(device="gpu")
    with pytest.raises(InputError, match="is none of"):  # an index torch cannot hold
        TrainConfig(device="cuda:99999999999999999999")


def test_the_audit_names_each_tensor_made_without_a_device():
    with DeviceAudit([Path(__file__).parent]) as audit:
        torch.zeros(3, device="cpu")  # named: not noted
        torch.ones(2, 2, device="cpu").new_zeros(3)  # follows its tensor: not noted
        line = _line_of_a_bare_factory()
    assert audit.found == {f"{__file__}:{line}"}


def _line_of_a_bare_factory() -> int:
    import inspect

    torch.randn(2)
    return inspect.currentframe().f_lineno - 1


def test_the_diagnostics_make_their_tensors_on_the_models_device():
    """Training and evaluation are audited by the method checker; here the C2INet diagnostics
    (posteriors, MI, probes, the queue's responsibilities) after two tasks."""
    tasks = turning_tasks()
    config = TrainConfig(epochs=1, k=2, k_train=2, diagnostics=False)
    trainer = ContinualTrainer(get_method("c2inet-online")(ModelConfig()), tasks, config)
    trainer.run()
    with DeviceAudit([LEARNER]) as audit:
        out = diagnose(trainer.model, [t.test for t in tasks], [t.value for t in tasks], 0)
    assert audit.found == set() and out["mi_xc"] is not None and "nmi" in out


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device here")
@pytest.mark.parametrize("name", ["finetune", "c2inet-online", "derpp", "gcrl", "ewc", "agem"])
def test_the_method_checker_passes_on_cuda(name):
    """Where CUDA's kernels are deterministic for these small models; a method whose numbers
    vary run to run on a GPU fails here by name."""
    check_method(get_method(name), device="cuda")
