"""STGAT's graph attention: the compiled pass over each scene's agents is the padded tensor form
within float32 rounding, forwards and back; agents alone in their scene skip the padding
exactly; the reference backbone never takes the compiled path."""

import numpy as np
import torch

from c2inet.backbones import BACKBONES, attention
from c2inet.batch import Batch, make_batch
from c2inet.data import Windows
from c2inet.model import C2INetModel
from c2inet.model_config import ModelConfig

from toys import toy_windows, walkers


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


def test_agents_alone_skip_the_padding_exactly(monkeypatch):
    """An agent alone attends to itself with weight 1: the shortcut's output is the padded
    attention's to the bit, in a batch of mixed scenes and in one of lone agents only. The
    reference backbone never takes the compiled path."""
    monkeypatch.setattr(attention, "attend", None)  # any use of the compiled path fails
    torch.manual_seed(1)
    reference = BACKBONES["stgat-cell"](cond_dim=8).encoder
    for batch in (mixed_batch(), make_batch(Windows(toy_windows().positions[:4], np.arange(5)))):
        company = batch.company
        assert company.alone is not None
        traj = torch.randn(8, len(batch.scene_of), 32)
        padded, mask = batch.pad(traj)
        layers = reference.gat2(torch.nn.functional.elu(reference.gat1(padded, mask)), mask)
        assert torch.equal(reference._social(traj, batch), batch.unpad(layers))


def test_the_company_layout_pads_only_the_scenes_of_several_agents():
    batch = mixed_batch()
    company = batch.company
    counts = batch.agent_counts[batch.scene_of]
    together = torch.arange(len(counts))[company.together]
    assert torch.equal(together, (counts > 1).nonzero()[:, 0])
    assert company.mask.shape == (int((batch.agent_counts > 1).sum()), 4)
    assert int(company.mask.sum()) == len(together)
    rows = torch.arange(len(counts), dtype=torch.float32)[:, None]
    assert torch.equal(company.unpad(company.pad(rows[company.together])), rows[company.together])
    # a batch whose lone agents come last (a training batch, then the anchors) needs no reorder
    joined = Batch.concat([make_batch(walkers(0.0, 4, seed=5)), make_batch(alone_windows())])
    assert joined.company.order is None and isinstance(joined.company.together, slice)


def alone_windows(count: int = 6) -> Windows:
    return Windows(toy_windows(8, seed=6).positions[:count].copy(), np.arange(count + 1))


def test_the_anchors_ride_in_the_batchs_encoder_call():
    """``posteriors_beside``: one encoder call over a batch and the anchors' one-agent scenes
    gives each what its own call gives, within float32 rounding."""
    torch.manual_seed(2)
    model = C2INetModel(ModelConfig())
    batch, anchors = make_batch(walkers(0.5, 6, seed=4)), make_batch(alone_windows())
    joint, beside = model.posteriors_beside(batch, anchors)
    for together, alone in ((joint, model.posteriors(batch)), (beside, model.posteriors(anchors))):
        for name in ("context", "c_mean", "c_logvar"):
            torch.testing.assert_close(getattr(together, name), getattr(alone, name))
