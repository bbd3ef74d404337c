"""The fast kernels of STGAT, in a room of their own: the decoder's twelve LSTM steps as one
autograd node (``rollout``), the encoder's LSTMs likewise (``sequence``), graph attention over
each scene's agents without padding (``attention``), and the numba steps they run on the CPU in
float32 (``steps``). They register nothing and import nothing of the learner above them: the
network is :class:`c2inet.backbones.stgat.STGAT`, in plain modules, and says which of these it
uses through one option, ``model.kernels`` (:data:`MODES`), resolved once (:func:`resolve`)
and written to every run card:

- ``cell``: none of them; the decoder stepped through :class:`torch.nn.LSTMCell`, PyTorch's
  LSTMs, padded attention (the reference; start a change to the network here);
- ``tensor``: the rollout as one autograd node in tensor operations (any device);
- ``compiled``: the rollout, the encoder's LSTMs and the attention through the numba steps
  (the CPU in float32);
- ``auto``: ``compiled`` on the CPU, ``tensor`` elsewhere, and ``tensor`` where numba cannot
  be imported (said once).
"""

from __future__ import annotations

import torch

from c2inet import jit

MODES = ("auto", "compiled", "tensor", "cell")


def resolve(setting: str, device: torch.device | str) -> str:
    """The kernels a network built on ``device`` runs for ``setting`` (one of :data:`MODES`):
    ``auto`` is ``compiled`` on the CPU and ``tensor`` on another device; ``compiled`` off the
    CPU is an error naming the device."""
    if setting not in MODES:
        raise ValueError(f"model.kernels {setting!r}: expected one of {', '.join(MODES)}")
    kind = torch.device(device).type
    if setting == "auto":
        if kind == "cpu" and jit.MISSING is not None:
            jit.note(f"numba cannot be imported ({jit.MISSING}): STGAT runs its tensor kernels")
        return "compiled" if kind == "cpu" and jit.MISSING is None else "tensor"
    if setting == "compiled" and kind != "cpu":
        raise ValueError(f"model.kernels 'compiled' runs on the CPU, not on {kind} (use tensor)")
    if setting == "compiled" and jit.MISSING is not None:
        raise ValueError(f"model.kernels 'compiled' needs numba ({jit.MISSING}); use tensor")
    return setting


def check_compiled(tensor: torch.Tensor) -> None:
    """The compiled steps read float32 CPU memory: anything else is an error (a network built
    with ``compiled`` kernels, then moved or cast)."""
    if tensor.device.type != "cpu" or tensor.dtype != torch.float32:
        raise ValueError(
            f"the compiled kernels run on float32 CPU tensors, not {tensor.dtype} on "
            f"{tensor.device.type}: build the network with model.kernels = tensor or cell"
        )
