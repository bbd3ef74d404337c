"""An LSTM fed its own outputs, rolled out as one autograd node with a hand-written backward.

The decoder's twelve steps were about 70 % of a training step, spent less in arithmetic than in
the calls around it and in passes over memory: per step an embedding, two gate products, five
activations and the output layer, each an autograd node, and twice as many again backwards. Here
one product per step makes the gates from ``[h, x, 1]`` (the embedding and both biases folded
in: the input is 2-d, so ``W_ih (W_e x + b_e)`` is ``(W_ih W_e) x`` plus a constant), and on the
CPU in float32 everything else of a step is one compiled pass (:mod:`~c2inet.kernels.steps`,
``model.kernels = compiled``; tensor operations with ``tensor``). The backward walks the steps
in reverse with one product and one compiled pass each, writing each step's gate gradients over
its activations, and only over the rows some loss reached: the variety loss takes one sample of
K per scene, so the other K - 1 are left out of the walk (their gradient is exactly zero). The
weights' gradients are two products over all steps at once; the buffers are reused, since fresh
ones fault in page by page. Training reaches the same function of the same parameters as
:class:`torch.nn.LSTMCell`, summed in another order (rounding): ``tests/c2inet/test_rollout.py``
holds it to the cell in float64, and the compiled steps to the tensor steps in float32. Measured
in ``docs/learner.md``; tried and left: ``torch.compile`` of the decoder (1.12x at fixed shapes,
15 to 21 s to compile) and bf16 products on this CPU's AMX
(``torch.set_float32_matmul_precision("medium")``: no faster, the conversions eat it).
"""

from __future__ import annotations

import math

import torch
from torch.autograd.function import once_differentiable

from c2inet.kernels import check_compiled
from c2inet.kernels import steps as kernels


def rollout_weights(embed: torch.nn.Linear, cell: torch.nn.LSTMCell) -> torch.Tensor:
    """The gates' weight ``[W_hh | W_ih W_e | b]`` (4H, H + in + 1), blocks in PyTorch's order
    (i, f, g, o), as differentiable products of the modules' own parameters (their state dicts
    unchanged)."""
    bias = cell.bias_ih + cell.bias_hh + cell.weight_ih @ embed.bias
    return torch.cat([cell.weight_hh, cell.weight_ih @ embed.weight, bias[:, None]], 1)


def _cell_backward(dh, dc, acts, tanhs, c_prev, d_gates) -> None:
    """One step back through the cell in tensor operations: the gates' gradient (R, 4H) into
    ``d_gates`` (which may be ``acts`` itself) and the cell state's, carried one step back,
    into ``dc``, from the hidden state's ``dh``."""
    i, f, g, o = acts.split(dh.shape[1], 1)
    dc.addcmul_(dh * o, 1 - tanhs * tanhs)
    gates = [dc * g * i * (1 - i), dc * c_prev * f * (1 - f), dc * i * (1 - g * g)]
    gates.append(dh * tanhs * o * (1 - o))
    dc.mul_(f)
    d_gates.copy_(torch.cat(gates, 1))  # last: d_gates may be acts itself


def _forward_step(hx, cs, acts, tanhs, out, w_out_t, b_out, now, then, residual) -> None:
    """One step forward in tensor operations from the gates' pre-activations ``acts`` (R, 4H),
    as :func:`~c2inet.kernels.steps.forward_step` does compiled."""
    hidden = cs.shape[2]
    i, f, g, o = acts.split(hidden, 1)
    torch.sigmoid_(acts[:, : 2 * hidden])
    g.tanh_()
    o.sigmoid_()
    c = torch.mul(f, cs[now], out=cs[then]).addcmul_(i, g)
    h_new = torch.mul(o, torch.tanh(c, out=tanhs), out=hx[then, :, :hidden])
    x_new = torch.addmm(b_out, h_new, w_out_t, out=out)
    if residual:
        x_new += hx[now, :, hidden:-1]
    hx[then, :, hidden:-1] = x_new


class _Buffers:
    """Flat buffers handed out again once a rollout (or an encoder LSTM,
    :mod:`~c2inet.kernels.sequence`) is done with them. A training step's rollout holds about
    25 MB; fresh, every page of it faults in (glibc maps blocks that large anew each time),
    which cost about 15 % of a decoder step. Best fit first; a new buffer has
    room for a batch a quarter larger; at most ``keep`` are kept, none over ``largest`` bytes."""

    def __init__(self, keep: int = 12, largest: int = 64 << 20):
        self.free: list[torch.Tensor] = []
        self.keep, self.largest = keep, largest

    def take(self, like: torch.Tensor, *shape: int) -> torch.Tensor:
        size = math.prod(shape)
        fits = [
            k
            for k, b in enumerate(self.free)
            if b.numel() >= size and b.dtype == like.dtype and b.device == like.device
        ]
        if fits:
            buffer = self.free.pop(min(fits, key=lambda k: self.free[k].numel()))
        else:
            buffer = like.new_empty(size + size // 4)
        return buffer[:size].view(shape)

    def give(self, *views: torch.Tensor) -> None:
        for view in views:
            buffer = view if view._base is None else view._base
            if buffer.numel() * buffer.element_size() <= self.largest:
                self.free.append(buffer)
        del self.free[: -self.keep]


BUFFERS = _Buffers()  # shared with the encoder's LSTMs (sequence.py)


def _run(h, x, weight, w_out, b_out, steps: int, residual: bool, keep: bool, fused: bool):
    """The forward loop: outputs (steps, R, out) and, with ``keep``, what the backward needs:
    every step's gate inputs ``[h, x, 1]`` (steps + 1, R, H + out + 1), activations (steps, R,
    4H), cell states (steps + 1, R, H) and their tanh (steps, R, H). Without ``keep`` two of
    each are reused (evaluation at thousands of rows). ``fused``: each step's cell through the
    compiled kernel (float32 on the CPU), else tensor operations."""
    rows, hidden = h.shape
    width = x.shape[1]
    kept = steps + 1 if keep else 2
    hx = BUFFERS.take(h, kept, rows, hidden + width + 1)
    hx[..., -1] = 1
    cs = BUFFERS.take(h, kept, rows, hidden)
    cs[0] = 0
    acts = BUFFERS.take(h, steps if keep else 1, rows, 4 * hidden)
    tanhs = BUFFERS.take(h, steps if keep else 1, rows, hidden)
    outs = h.new_empty(steps, rows, width)
    hx[0, :, :hidden], hx[0, :, hidden:-1] = h, x
    weight_t, w_out_t = weight.t(), w_out.t()
    if fused:
        check_compiled(h)
        arrays = [b.numpy() for b in (hx, cs, acts, tanhs, outs)]
        w_out_np, b_out_np = w_out.detach().numpy(), b_out.detach().numpy()
    for t in range(steps):
        now, then = (t, t + 1) if keep else (t % 2, (t + 1) % 2)
        at = t if keep else 0
        torch.mm(hx[now], weight_t, out=acts[at])
        if fused:
            kernels.forward_step(*arrays, w_out_np, b_out_np, now, then, at, t, residual)
        else:
            _forward_step(hx, cs, acts[at], tanhs[at], outs[t], w_out_t, b_out, now, then, residual)
    return outs, (hx, cs, acts, tanhs)


def walks_reached_rows(d_outs: torch.Tensor) -> bool:
    """Whether the backward walks only the rows a loss reached (the variety loss reaches one
    sample of every K): on the CPU; an accelerator walks every row, which costs less than
    reading back which rows were reached."""
    return d_outs.device.type == "cpu"


class _Rollout(torch.autograd.Function):
    @staticmethod
    def forward(ctx, h, x, weight, w_out, b_out, steps, residual, fused):
        outs, kept = _run(h, x, weight, w_out, b_out, steps, residual, keep=True, fused=fused)
        ctx.save_for_backward(weight, w_out, *kept)
        ctx.residual, ctx.fused, ctx.spent = residual, fused, False
        return outs

    @staticmethod
    @once_differentiable
    def backward(ctx, d_outs):
        weight, w_out, *kept = ctx.saved_tensors
        if ctx.spent:
            raise RuntimeError("the decoder's rollout runs backward once (its buffers are reused)")
        ctx.spent = True
        live = (d_outs != 0).any(2).any(0) if walks_reached_rows(d_outs) else None
        if live is None or bool(live.all()):
            grads = _backward(weight, w_out, d_outs, *kept, ctx.residual, ctx.fused)
        else:
            index = live.nonzero()[:, 0]
            rows = [BUFFERS.take(b, len(b), len(index), b.shape[2]) for b in kept]
            for buffer, taken in zip(kept, rows, strict=True):
                torch.index_select(buffer, 1, index, out=taken)
            d_rows = d_outs.index_select(1, index)
            dh, carry, *weights = _backward(weight, w_out, d_rows, *rows, ctx.residual, ctx.fused)
            grads = (_scatter(dh, index, len(live)), _scatter(carry, index, len(live)), *weights)
            BUFFERS.give(*rows)
        BUFFERS.give(*kept)
        return *grads, None, None, None


def _scatter(rows: torch.Tensor, index: torch.Tensor, total: int) -> torch.Tensor:
    """The walked rows' gradients (n, F) back at their places ``index`` of ``total`` rows, the
    rest zero (no loss reached them)."""
    return rows.new_zeros(total, rows.shape[1]).index_copy_(0, index, rows)


def _backward(weight, w_out, d_outs, hx, cs, acts, tanhs, residual: bool, fused: bool):
    """The rollout's gradients from its outputs' ``d_outs`` (steps, R, out), walking its kept
    buffers back (``acts`` becomes the gates' gradient): the initial hidden state's and input's,
    then the gate weights', the output weight's and bias'."""
    steps, rows, width = d_outs.shape
    hidden = cs.shape[-1]
    d_gates = acts  # each step's gradient over its activations, read just before
    d_xs = BUFFERS.take(d_outs, *d_outs.shape)  # the gradient at every output, all paths
    dh = hx.new_zeros(rows, hidden)
    dc = hx.new_zeros(rows, hidden)
    carry = hx.new_zeros(rows, width)  # the gradient reaching x_t through the later steps
    to_h = weight[:, :hidden].contiguous()  # the gates' weights on h_{t-1} and on x_{t-1}
    to_x = weight[:, hidden:-1].contiguous()
    if fused:
        arrays = [a.numpy() for a in (d_outs.contiguous(), d_xs, carry, dh, dc, acts, tanhs, cs)]
        w_out_np, to_x_np = w_out.detach().numpy(), to_x.t().contiguous().numpy()
        for t in reversed(range(steps)):
            kernels.backward_step(*arrays, w_out_np, to_x_np, t, residual)
            torch.mm(d_gates[t], to_h, out=dh)
    else:
        for t in reversed(range(steps)):
            dx = torch.add(d_outs[t], carry, out=d_xs[t])
            dh.addmm_(dx, w_out)
            _cell_backward(dh, dc, acts[t], tanhs[t], cs[t], d_gates[t])
            dh = d_gates[t] @ to_h
            carry = torch.addmm(dx, d_gates[t], to_x) if residual else d_gates[t] @ to_x
    d_weight = (hx[:steps].flatten(0, 1).t() @ d_gates.flatten(0, 1)).t()
    d_out = (hx[1:].flatten(0, 1).t() @ d_xs.flatten(0, 1)).t()  # (out, H + out + 1)
    BUFFERS.give(d_xs)
    return dh, carry, d_weight, d_out[:, :hidden], d_out[:, -1]


def lstm_rollout(
    h: torch.Tensor,
    x: torch.Tensor,
    weight: torch.Tensor,
    w_out: torch.Tensor,
    b_out: torch.Tensor,
    steps: int,
    residual: bool,
    fused: bool,
) -> torch.Tensor:
    """``steps`` outputs (steps, R, out) of an LSTM started at hidden state ``h`` (R, H) and
    cell state zero, each step's input its last output (``x``, (R, out), the first): the output
    is ``W_out h + b_out``, added to the last one with ``residual``. ``weight`` makes the gates
    from ``[h, x, 1]`` (:func:`rollout_weights`). ``fused``: each step through the compiled
    kernel (``model.kernels = compiled``), else tensor operations."""
    args = (h, x, weight, w_out, b_out)
    if torch.is_grad_enabled() and any(a.requires_grad for a in args):
        return _Rollout.apply(*args, steps, residual, fused)
    outs, kept = _run(*args, steps, residual, keep=False, fused=fused)
    BUFFERS.give(*kept)
    return outs
