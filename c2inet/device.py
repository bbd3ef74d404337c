"""Where the learner's tensors live: ``train.device`` (``--device``) resolved to a torch device,
and a random-number fork that also covers an accelerator's generator.

The model is built on its device and every batch is moved there; every tensor the learner makes
names the device of the tensors it works with, which ``c2inet.checker.DeviceAudit`` checks.
"""

from __future__ import annotations

import contextlib
import os
import re
from collections.abc import Iterator

import torch

from c2inet.errors import InputError

DEVICE_NAMES = re.compile(r"auto|cpu|cuda(:\d{1,4})?|mps")  # no GPU index beyond 9999
WORKER_SLOT = "C2I_WORKER_SLOT"  # a local job worker's number, 0 up (sim's backends set it)


def check_device_name(name: str) -> None:
    """Raise InputError unless ``name`` is auto, cpu, cuda, cuda:N or mps."""
    if not DEVICE_NAMES.fullmatch(name):
        raise InputError(f"device {name!r} is none of auto, cpu, cuda, cuda:N, mps")


def resolve_device(name: str) -> torch.device:
    """The torch device for ``name``: ``auto`` is CUDA where there is one, then MPS, then the
    CPU; a device this machine lacks is an InputError naming it."""
    check_device_name(name)
    if name == "auto":
        if torch.cuda.is_available():
            return torch.device("cuda")
        return torch.device("mps" if torch.backends.mps.is_available() else "cpu")
    device = torch.device(name)
    if device.type == "cuda":
        if not torch.cuda.is_available():
            raise InputError(f"device {name!r}: this machine has no CUDA device (try auto or cpu)")
        if device.index is not None and device.index >= torch.cuda.device_count():
            count = torch.cuda.device_count()
            raise InputError(f"device {name!r}: this machine has {count} CUDA device(s)")
    if device.type == "mps" and not torch.backends.mps.is_available():
        raise InputError(f"device {name!r}: MPS is not available here (try auto or cpu)")
    return device


def placed(device: torch.device, count: int | None = None) -> torch.device:
    """Where a job trains: a CUDA device named without an index, on a machine with ``count``
    (default: all visible) CUDA devices, is the one of the job's worker slot modulo ``count``,
    so ``--jobs N`` spreads N jobs over N devices; any other device as named. (A Ray task sees
    only the GPUs Ray gave it, so there ``count`` is 1 and it takes its own.)"""
    if device.type != "cuda" or device.index is not None:
        return device
    count = torch.cuda.device_count() if count is None else count
    if count <= 1:
        return device
    return torch.device("cuda", int(os.environ.get(WORKER_SLOT, "0")) % count)


@contextlib.contextmanager
def seeded(seed: int, device: torch.device) -> Iterator[None]:
    """Run the block with torch's generators seeded by ``seed`` (the CPU's and ``device``'s),
    leaving the caller's random streams as they were."""
    devices = [] if device.type != "cuda" else [device.index or 0]
    with torch.random.fork_rng(devices=devices, device_type=device.type):
        torch.manual_seed(seed)
        yield


def model_device(model: torch.nn.Module) -> torch.device:
    """The device of ``model``'s parameters (the CPU for a model without any)."""
    first = next(model.parameters(), None)
    return torch.device("cpu") if first is None else first.device


def cuda_rng_state(device: torch.device) -> torch.Tensor | None:
    """The CUDA generator's state where ``device`` is a CUDA device (a checkpoint keeps it, so a
    resumed run draws as an uninterrupted one), else None."""
    return torch.cuda.get_rng_state(device) if device.type == "cuda" else None
