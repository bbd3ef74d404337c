"""The backbone checker (as Gymnasium's ``check_env``): runs a backbone on small scenes and raises
:class:`BackboneCheckError` naming the first broken promise.

What every backbone owes the models: the declared shapes; scenes padded into one batch that stay
apart; no future frame reaching the encoder; the same output for the same seed; a residual
decoder that starts at constant velocity; and an encoder and decoder that learn.

    from c2inet.backbones.checker import check_backbone
    check_backbone(BACKBONES["stgat"])
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from c2inet.batch import Batch, make_batch
from c2inet.checker import turners
from c2inet.data import PRED_LEN, Windows

COND_DIM = 10


class BackboneCheckError(AssertionError):
    """A backbone broke its contract; the message says which part and how."""


def _fail(cls: type, what: str) -> None:
    raise BackboneCheckError(f"backbone {getattr(cls, 'name', cls.__name__)!r}: {what}")


def check_contract(cls: type) -> None:
    """A documented ``nn.Module`` with a positive ``context_dim``, ``encode`` and ``decode``."""
    if not (isinstance(cls, type) and issubclass(cls, nn.Module)) or not cls.__doc__:
        _fail(cls, "must be a documented torch.nn.Module")
    if not isinstance(getattr(cls, "context_dim", None), int) or cls.context_dim < 1:
        _fail(cls, "needs a positive integer context_dim")
    if not (callable(getattr(cls, "encode", None)) and callable(getattr(cls, "decode", None))):
        _fail(cls, "needs encode(obs_rel, batch) and decode(cond, last_rel)")


def check_shapes(cls: type, batch: Batch) -> None:
    backbone = cls(cond_dim=COND_DIM)
    agents = len(batch.scene_of)
    context = backbone.encode(batch.obs_rel, batch)
    if tuple(context.shape) != (agents, cls.context_dim):
        _fail(cls, f"encode gave {tuple(context.shape)}, expected ({agents}, {cls.context_dim})")
    out = backbone.decode(torch.randn(3, agents, COND_DIM), batch.obs_rel[-1])
    if tuple(out.shape) != (PRED_LEN, 3, agents, 2):
        _fail(cls, f"decode gave {tuple(out.shape)}, expected ({PRED_LEN}, 3, {agents}, 2)")


def check_scenes_apart(cls: type, windows: Windows) -> None:
    """Moving the last scene's agents changes their context and nobody else's."""
    backbone = cls(cond_dim=COND_DIM)
    before = backbone.encode(make_batch(windows).obs_rel, make_batch(windows))
    moved = Windows(windows.positions.copy(), windows.scene_start)
    last = slice(windows.scene_start[-2], windows.scene_start[-1])
    moved.positions[last] += np.random.default_rng(0).normal(size=moved.positions[last].shape)
    batch = make_batch(moved)
    after = backbone.encode(batch.obs_rel, batch)
    others = slice(0, windows.scene_start[-2])
    if not torch.allclose(before[others], after[others]):
        _fail(cls, "another scene of the batch changed an agent's context")
    if torch.allclose(before[last], after[last]):
        _fail(cls, "an agent's context ignores its own scene")


def check_no_future(cls: type, windows: Windows) -> None:
    """Changing only the future frames changes no context."""
    altered = Windows(windows.positions.copy(), windows.scene_start)
    altered.positions[:, -PRED_LEN:] += 100.0
    backbone = cls(cond_dim=COND_DIM)
    a, b = make_batch(windows), make_batch(altered)
    if not torch.allclose(backbone.encode(a.obs_rel, a), backbone.encode(b.obs_rel, b)):
        _fail(cls, "a future frame reaches the encoder")


def check_determinism(cls: type, batch: Batch) -> None:
    outputs = []
    for _ in range(2):
        torch.manual_seed(3)
        backbone = cls(cond_dim=COND_DIM)
        cond = torch.randn(2, len(batch.scene_of), COND_DIM)
        context = backbone.encode(batch.obs_rel, batch)
        outputs.append((context, backbone.decode(cond, batch.obs_rel[-1])))
    if not all(torch.equal(x, y) for x, y in zip(*outputs, strict=True)):
        _fail(cls, "the same seed gave another backbone or output")


def check_residual_start(cls: type, batch: Batch) -> None:
    backbone = cls(cond_dim=COND_DIM, residual=True)
    out = backbone.decode(torch.randn(2, len(batch.scene_of), COND_DIM), batch.obs_rel[-1])
    if not torch.allclose(out, batch.obs_rel[-1].expand(PRED_LEN, 2, -1, 2)):
        _fail(cls, "an untrained residual decoder does not start at constant velocity")


def check_learns(cls: type, batch: Batch, steps: int = 60) -> None:
    """Encoder and decoder together fit the future displacements of turning agents."""
    torch.manual_seed(0)
    backbone = cls(cond_dim=cls.context_dim)
    parameters = list(backbone.parameters())
    if not parameters:
        _fail(cls, "has no parameters to learn")
    optimiser = torch.optim.Adam(parameters, lr=3e-3)
    target = torch.diff(torch.cat([batch.obs[-1:], batch.fut]), dim=0)

    def loss() -> torch.Tensor:
        context = backbone.encode(batch.obs_rel, batch)
        return ((backbone.decode(context[None], batch.obs_rel[-1])[:, 0] - target) ** 2).mean()

    first = loss().item()
    for _ in range(steps):
        optimiser.zero_grad()
        value = loss()
        if not value.requires_grad:
            _fail(cls, "its output does not depend on its parameters")
        value.backward()
        optimiser.step()
    if not loss().item() < 0.5 * first:
        _fail(cls, f"did not learn: loss {first:.4f} -> {loss().item():.4f} in {steps} steps")


def check_backbone(cls: type) -> None:
    """Check ``cls``; raises :class:`BackboneCheckError` at the first broken promise."""
    check_contract(cls)
    windows = turners(0.2, 6, 0)
    batch = make_batch(windows)
    check_shapes(cls, batch)
    check_no_future(cls, windows)
    check_scenes_apart(cls, windows)
    check_determinism(cls, batch)
    check_residual_start(cls, batch)
    check_learns(cls, make_batch(turners(0.2, 16, 0)))
