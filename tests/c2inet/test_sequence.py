"""The encoder's LSTMs through compiled steps: PyTorch's LSTM within float32 rounding, forwards
and back; off float32 refused, and never used by the reference backbone."""

import pytest
import torch
from torch import nn

from c2inet.backbones import BACKBONES
from c2inet.kernels import sequence
from c2inet.kernels import steps as kernels
from c2inet.kernels.sequence import run_lstm


def lstm_and_input(dtype=torch.float32):
    torch.manual_seed(0)
    lstm = nn.LSTM(5, 32).to(dtype)
    x = torch.randn(8, 40, 5, dtype=dtype, requires_grad=True)
    return lstm, x


def outputs_and_gradients(lstm, x, run):
    out = run(lstm, x)
    weights = torch.linspace(-1, 1, out.numel(), dtype=x.dtype).view(out.shape)
    return out, torch.autograd.grad((out * weights).sum(), [x, *lstm.parameters()])


def test_the_compiled_lstm_is_pytorchs_within_float32_rounding(monkeypatch):
    lstm, x = lstm_and_input()
    steps = []
    original = kernels.sequence_step
    monkeypatch.setattr(kernels, "sequence_step", lambda *a: steps.append(a[-1]) or original(*a))
    out, grads = outputs_and_gradients(lstm, x, run_lstm)
    assert steps == list(range(8))  # the compiled path ran, a call a step
    ref, ref_grads = outputs_and_gradients(lstm, x, lambda m, v: m(v)[0])
    torch.testing.assert_close(out, ref, rtol=1e-5, atol=1e-6)
    for grad, expected in zip(grads, ref_grads, strict=True):
        assert (grad - expected).abs().max() <= 1e-5 * expected.abs().max()
    with torch.no_grad():
        torch.testing.assert_close(run_lstm(lstm, x), ref, rtol=1e-5, atol=1e-6)


def test_float64_is_refused_and_the_reference_backbone_runs_the_module_itself(monkeypatch):
    monkeypatch.setattr(sequence, "_Sequence", None)  # any use of the compiled path fails
    lstm, x = lstm_and_input(torch.float64)
    with pytest.raises(ValueError, match="float32 CPU tensors, not torch.float64"):
        run_lstm(lstm, x)
    reference = BACKBONES["stgat-cell"](cond_dim=8).encoder  # tensor operations throughout
    assert reference._lstm(lstm.float(), x.float().detach()).shape == (8, 40, 32)
    assert BACKBONES["stgat"](cond_dim=8).encoder.compiled and not reference.compiled


def test_a_second_backward_is_refused():
    lstm, x = lstm_and_input()
    out = run_lstm(lstm, x).sum()
    out.backward(retain_graph=True)
    with pytest.raises(RuntimeError, match="backward once"):
        out.backward()
