"""STGAT's graph attention: the compiled pass over each scene's agents is the padded tensor form
within float32 rounding, forwards and back; the reference backbone never takes it."""

import numpy as np
import torch

from c2inet.backbones import BACKBONES
from c2inet.batch import Batch, make_batch
from c2inet.data import Windows
from c2inet.kernels import attention

from toys import toy_windows


def mixed_batch() -> Batch:
    """Scenes of 1 to 4 agents, some alone (the toy windows), then five one-agent scenes."""
    windows = toy_windows(12, seed=3)
    alone = Windows(windows.positions[:5].copy(), np.arange(6))
    return make_batch(Windows.concat([windows, alone]))


def social_and_gradients(encoder, traj, batch):
    out = encoder._social(traj, batch)
    weights = torch.linspace(-1, 1, out.numel(), dtype=out.dtype).view(out.shape)
    gat = [p for name, p in encoder.named_parameters() if name.startswith("gat")]
    return out, torch.autograd.grad((out * weights).sum(), [traj, *gat])


def test_the_compiled_attention_is_the_padded_form_within_float32_rounding(monkeypatch):
    """Held to the padded form in float64: the compiled pass errs no more than the padded form
    in float32 does (the second layer's score gradients are sums that nearly cancel, so
    rounding is the measure, not a fixed tolerance)."""
    torch.manual_seed(0)
    batch = mixed_batch()
    encoder = BACKBONES["stgat"](cond_dim=8).encoder
    traj = torch.randn(8, len(batch.scene_of), 32, requires_grad=True)
    calls = []
    original = attention.attend_forward
    monkeypatch.setattr(attention, "attend_forward", lambda *a: calls.append(1) or original(*a))
    out, grads = social_and_gradients(encoder, traj, batch)
    assert len(calls) == 2  # both layers ran compiled
    encoder.compiled = False
    padded, padded_grads = social_and_gradients(encoder, traj, batch)
    assert not torch.equal(out, padded)  # another path, rounded differently
    exact, exact_grads = social_and_gradients(encoder.double(), traj.double(), batch)
    paths = zip((out, *grads), (padded, *padded_grads), (exact, *exact_grads), strict=True)
    for ours, theirs, truth in paths:
        error, float32_error = (ours - truth).abs().max(), (theirs - truth).abs().max()
        assert error <= 4 * float32_error + 1e-7 * truth.abs().max(), (error, float32_error)


def test_the_reference_backbone_pads_and_never_compiles(monkeypatch):
    monkeypatch.setattr(attention, "attend", None)  # any use of the compiled path fails
    batch = mixed_batch()
    reference = BACKBONES["stgat-cell"](cond_dim=8).encoder
    traj = torch.randn(8, len(batch.scene_of), 32)
    padded, mask = batch.pad(traj)
    layers = reference.gat2(torch.nn.functional.elu(reference.gat1(padded, mask)), mask)
    assert torch.equal(reference._social(traj, batch), batch.unpad(layers))
