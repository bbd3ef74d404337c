"""The decoder's rollout (one autograd node, a hand-written backward) is the LSTM cell it
replaces: the same outputs and gradients in float64, within float32 rounding through the compiled
steps, with or without gradients, walking back only the rows a loss reached, and its reused
buffers never shared by two live rollouts."""

import pytest
import torch

from c2inet.backbones import BACKBONES
from c2inet.backbones.stgat import Decoder
from c2inet.kernels import rollout
from c2inet.kernels.rollout import BUFFERS


def decoders(residual: bool, dtype=torch.float64) -> tuple[Decoder, torch.Tensor, torch.Tensor]:
    torch.manual_seed(0)
    decoder = Decoder(10, residual=residual).to(dtype)
    torch.nn.init.normal_(decoder.out.weight, 0, 0.3)  # a residual decoder starts at zero
    cond = torch.randn(3, 7, 10, dtype=dtype, requires_grad=True)
    last_rel = torch.randn(7, 2, dtype=dtype, requires_grad=True)
    return decoder, cond, last_rel


def outputs_and_gradients(decoder, kernel, cond, last_rel, calls=1):
    decoder.kernel = kernel
    outs = [decoder(cond, last_rel) for _ in range(calls)]  # all alive before the backward
    weights = torch.linspace(-1, 1, outs[0].numel(), dtype=cond.dtype).view(outs[0].shape)
    loss = sum(((k + 1) * out * weights).sum() for k, out in enumerate(outs))
    return outs[0], torch.autograd.grad(loss, [cond, last_rel, *decoder.parameters()])


@pytest.mark.parametrize("residual", [True, False])
def test_the_rollout_is_the_lstm_cell_with_the_same_gradients(residual):
    decoder, cond, last_rel = decoders(residual)
    out, grads = outputs_and_gradients(decoder, "tensor", cond, last_rel)
    ref, ref_grads = outputs_and_gradients(decoder, "cell", cond, last_rel)
    torch.testing.assert_close(out, ref, rtol=1e-12, atol=1e-12)
    assert len(grads) == 2 + len(list(decoder.parameters()))
    for grad, expected in zip(grads, ref_grads, strict=True):
        assert expected.abs().max() > 0  # every parameter takes part
        torch.testing.assert_close(grad, expected, rtol=1e-10, atol=1e-12)
    with torch.no_grad():  # the lean loop: two steps kept, the same outputs
        torch.testing.assert_close(decoder.train()(cond, last_rel), ref, rtol=0, atol=1e-12)


def test_in_float32_the_compiled_backward_stays_within_rounding_of_the_cell():
    decoder, cond, last_rel = decoders(True, torch.float32)
    out, grads = outputs_and_gradients(decoder, "compiled", cond, last_rel)
    ref, ref_grads = outputs_and_gradients(decoder, "cell", cond, last_rel)
    torch.testing.assert_close(out, ref, rtol=1e-5, atol=1e-5)
    for grad, expected in zip(grads, ref_grads, strict=True):
        assert (grad - expected).abs().max() <= 1e-5 * expected.abs().max()


def test_rollouts_alive_at_once_keep_their_own_buffers_and_a_finished_one_is_reused():
    decoder, cond, last_rel = decoders(True, torch.float32)
    # three forward passes before one backward (a method decoding twice in a step)
    _, grads = outputs_and_gradients(decoder, "compiled", cond, last_rel, calls=3)
    _, ref_grads = outputs_and_gradients(decoder, "cell", cond, last_rel, calls=3)
    for grad, expected in zip(grads, ref_grads, strict=True):
        assert (grad - expected).abs().max() <= 1e-5 * expected.abs().max()
    kept = {b.data_ptr() for b in BUFFERS.free}
    decoder.kernel = "compiled"
    decoder(cond, last_rel).sum().backward()  # a step: takes buffers and gives them back
    assert kept and {b.data_ptr() for b in BUFFERS.free} <= kept


def test_stgat_decodes_through_the_rollout_and_stgat_cell_through_the_cell():
    cond, last_rel = torch.randn(2, 5, 8, requires_grad=True), torch.randn(5, 2)
    nodes = {}
    for name, kernels in (("stgat", "auto"), ("stgat", "tensor"), ("stgat", "cell")):
        backbone = BACKBONES[name](cond_dim=8, kernels=kernels)
        out = backbone.decode(cond, last_rel)
        nodes[kernels] = type(out.grad_fn.next_functions[0][0]).__name__  # under the unflatten
    assert nodes == {
        "auto": "_RolloutBackward",
        "tensor": "_RolloutBackward",
        "cell": "StackBackward0",
    }
    assert BACKBONES["stgat"](cond_dim=8).kernels == "compiled"  # auto, on the CPU
    assert BACKBONES["stgat-cell"](cond_dim=8, kernels="compiled").kernels == "cell"


def test_a_second_backward_through_one_rollout_is_refused():
    """Its activations become their gradients in the backward (and its buffers go back to be
    reused), so a retained graph cannot be walked twice: that is an error, not wrong numbers."""
    decoder, cond, last_rel = decoders(True, torch.float32)
    decoder.kernel = "compiled"
    out = decoder(cond, last_rel).sum()
    out.backward(retain_graph=True)
    with pytest.raises(RuntimeError, match="backward once"):
        out.backward()


def test_the_variety_losss_unreached_samples_are_not_walked_back(monkeypatch):
    """Best of K reaches one sample a scene: the backward walks only the rows a loss reached
    (fewer rows, checked), and the gradients are still the cell's."""
    decoder, cond, last_rel = decoders(True)
    walked = []
    original = rollout._backward
    monkeypatch.setattr(
        rollout, "_backward", lambda *a: walked.append(a[2].shape[1]) or original(*a)
    )

    def best_of_k(kernel):
        decoder.kernel = kernel
        out = decoder(cond, last_rel)  # (12, S=3, N=7, 2)
        per_sample = (out**2).sum(dim=(0, 3))  # (S, N)
        loss = per_sample.min(0).values.sum()  # one sample per agent
        return torch.autograd.grad(loss, [cond, last_rel, *decoder.parameters()])

    grads, ref_grads = best_of_k("tensor"), best_of_k("cell")
    assert walked == [7]  # of 21 rows
    for grad, expected in zip(grads, ref_grads, strict=True):
        torch.testing.assert_close(grad, expected, rtol=1e-10, atol=1e-12)
    assert (grads[0].abs().sum(-1) == 0).sum() == 14  # the samples not chosen: exactly zero


@pytest.mark.parametrize("residual", [True, False])
def test_the_compiled_steps_are_the_tensor_steps_within_float32_rounding(residual, monkeypatch):
    decoder, cond, last_rel = decoders(residual, torch.float32)
    out, grads = outputs_and_gradients(decoder, "compiled", cond, last_rel)
    with torch.no_grad():  # the lean loop, compiled too
        lean = decoder(cond, last_rel)
    ref, ref_grads = outputs_and_gradients(decoder, "tensor", cond, last_rel)
    assert not torch.equal(out, ref)  # the two paths really differ (rounding)
    torch.testing.assert_close(out, ref, rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(lean, out, rtol=0, atol=0)
    for grad, expected in zip(grads, ref_grads, strict=True):
        assert (grad - expected).abs().max() <= 1e-5 * expected.abs().max()
