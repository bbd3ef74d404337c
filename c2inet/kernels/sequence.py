"""An LSTM over a given sequence (the encoder's), one autograd node with compiled steps.

STGAT's encoder runs two one-layer LSTMs over the eight observed steps of a batch's agents, a
few hundred rows. At that size PyTorch's oneDNN LSTM spends most of its time around the
arithmetic (0.25 to 0.6 ms forwards, 0.4 to 1.3 ms back, per call, measured). Here the input's
part of every step's gates is one product, each step adds the hidden state's product and runs
the cell in one compiled pass (:mod:`~c2inet.kernels.steps`), and the backward walks
the steps with one compiled pass and one product each, the weights' gradients as products over
all steps. The module's own parameters are used (its state dict unchanged); off the CPU or in
another dtype the module runs as it is.
"""

from __future__ import annotations

import torch
from torch import nn
from torch.autograd.function import once_differentiable

from c2inet.kernels import check_compiled
from c2inet.kernels import steps as kernels
from c2inet.kernels.rollout import BUFFERS


def lstm_weights(lstm: nn.LSTM) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``W_ih`` (4H, I), ``W_hh`` (4H, H) and the summed biases (4H) of a one-layer LSTM."""
    return lstm.weight_ih_l0, lstm.weight_hh_l0, lstm.bias_ih_l0 + lstm.bias_hh_l0


def _forward(x, w_ih, w_hh, bias):
    """The forward loop: every step's hidden state (T + 1, R, H), the first zero, and what the
    backward needs: cell states (T + 1, R, H), activations (T, R, 4H) and the cells' tanh (T, R,
    H), the last three from the reused buffers (fresh ones fault in page by page)."""
    steps, rows, _ = x.shape
    hidden = w_hh.shape[1]
    acts = BUFFERS.take(x, steps, rows, 4 * hidden)
    torch.addmm(bias, x.flatten(0, 1), w_ih.t(), out=acts.view(steps * rows, 4 * hidden))
    hs = x.new_empty(steps + 1, rows, hidden)
    cs = BUFFERS.take(x, steps + 1, rows, hidden)
    hs[0], cs[0] = 0, 0
    tanhs = BUFFERS.take(x, steps, rows, hidden)
    arrays = [a.numpy() for a in (hs, cs, acts, tanhs)]
    act_steps, h_steps, w_hh_t = acts.unbind(), hs.unbind(), w_hh.t()
    for t in range(steps):
        if t:  # h_0 is zero
            act_steps[t].addmm_(h_steps[t], w_hh_t)
        kernels.sequence_step(*arrays, t)
    return hs, (cs, acts, tanhs)


class _Sequence(torch.autograd.Function):
    @staticmethod
    def forward(ctx, x, w_ih, w_hh, bias):
        hs, kept = _forward(x, w_ih, w_hh, bias)
        ctx.save_for_backward(x, w_ih, w_hh, hs, *kept)
        ctx.spent = False
        return hs[1:]

    @staticmethod
    @once_differentiable
    def backward(ctx, d_hs):
        x, w_ih, w_hh, hs, cs, acts, tanhs = ctx.saved_tensors
        if ctx.spent:
            raise RuntimeError("an encoder LSTM runs backward once (its buffers are reused)")
        ctx.spent = True
        steps, rows, hidden = d_hs.shape
        dh = hs.new_zeros(rows, hidden)
        dc = hs.new_zeros(rows, hidden)
        arrays = [a.numpy() for a in (d_hs.contiguous(), dh, dc, acts, tanhs, cs)]
        act_steps = acts.unbind()
        for t in reversed(range(steps)):
            kernels.sequence_back(*arrays, t)  # acts[t] becomes the gates' gradient
            if t:
                torch.mm(act_steps[t], w_hh, out=dh)
        d_gates = acts.flatten(0, 1)
        d_x = (d_gates @ w_ih).view_as(x) if ctx.needs_input_grad[0] else None
        d_w_ih = d_gates.t() @ x.flatten(0, 1)
        d_w_hh = d_gates[rows:].t() @ hs[1:steps].flatten(0, 1)
        d_bias = d_gates.sum(0)
        BUFFERS.give(cs, acts, tanhs)
        return d_x, d_w_ih, d_w_hh, d_bias


def run_lstm(lstm: nn.LSTM, x: torch.Tensor) -> torch.Tensor:
    """The output sequence (T, R, H) of a one-layer, one-way LSTM over ``x`` (T, R, I) from zero
    states, through the compiled steps (float32 on the CPU; :func:`~c2inet.kernels.check_compiled`):
    the same function as the module's own ``lstm(x)[0]``."""
    check_compiled(x)
    weights = lstm_weights(lstm)
    if torch.is_grad_enabled() and (x.requires_grad or lstm.weight_hh_l0.requires_grad):
        return _Sequence.apply(x, *weights)
    hs, kept = _forward(x, *weights)
    BUFFERS.give(*kept)
    return hs[1:]
