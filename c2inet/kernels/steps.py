"""LSTM steps compiled for the CPU in float32 (the decoder's rollout and the encoder's LSTMs):
each step's work between its products in one pass over memory, one call instead of a dozen
small tensor operations.

A training step at batch 16 calls a dozen small operations per LSTM step and as many back, each
a few microseconds of dispatch around a few of arithmetic; here the gates' activations, the cell
update, the output layer and the residual are one compiled call forwards, and the output layer's,
the cell's and the input's gradients one call backwards, leaving the gate products to torch.
Vectorising needs branch-free transcendentals, which numba's LLVM cannot take from a vector
library: :func:`tanh32` is a rational approximation (Eigen's ``generic_fast_tanh_float``, within
5 units in the last place of float32, tested), the sigmoid is ``(1 + tanh(x / 2)) / 2``.
Tensor operations (:mod:`c2inet.kernels.rollout`, ``model.kernels = tensor``) remain the
reference and the path of every other device and dtype.
"""

from __future__ import annotations

import numpy as np

from c2inet import jit
from c2inet.jit import njit

_F = np.float32
_CLAMP = _F(7.90531110763549805)  # inputs held here; beyond it tanh is within 5 ulp of tanh32(it)
# the odd numerator's and the even denominator's coefficients, highest power first
_A13, _A11, _A9, _A7 = (
    _F(-2.76076847742355e-16),
    _F(2.00018790482477e-13),
    _F(-8.60467152213735e-11),
    _F(5.12229709037114e-08),
)
_A5, _A3, _A1 = _F(1.48572235717979e-05), _F(6.37261928875436e-04), _F(4.89352455891786e-03)
_B6, _B4, _B2, _B0 = (
    _F(1.19825839466702e-06),
    _F(1.18534705686654e-04),
    _F(2.26843463243900e-03),
    _F(4.89352518554385e-03),
)
# every kernel: cached where a cache can be written (c2inet.jit), vectorised with fast math,
# run without the GIL
NUMBA_OPTIONS = jit.options(fastmath=True, nogil=True, error_model="numpy")


@njit(inline="always", **NUMBA_OPTIONS)
def tanh32(x):  # pragma: no cover (compiled)
    """tanh in float32 as an odd rational function, branch-free so that loops vectorise."""
    x = min(max(x, -_CLAMP), _CLAMP)
    x2 = x * x
    p = ((((((_A13 * x2 + _A11) * x2 + _A9) * x2 + _A7) * x2 + _A5) * x2 + _A3) * x2 + _A1) * x
    q = ((_B6 * x2 + _B4) * x2 + _B2) * x2 + _B0
    return x if abs(x) < _F(0.0004) else p / q


@njit(inline="always", **NUMBA_OPTIONS)
def _sigmoid32(x):  # pragma: no cover (compiled)
    return _F(0.5) + _F(0.5) * tanh32(_F(0.5) * x)


@njit(inline="always", **NUMBA_OPTIONS)
def _cell(a, c_prev, c, th, h):  # pragma: no cover (compiled)
    """An LSTM cell from its gates' pre-activations ``a`` (4H; i, f, g, o), activated in place:
    the cell state ``c``, its tanh ``th`` and the hidden state ``h`` (H each). Every loop
    indexes views from 0 with one store, so that it vectorises."""
    hidden = len(c)
    i, f, g, o = a[:hidden], a[hidden : 2 * hidden], a[2 * hidden : 3 * hidden], a[3 * hidden :]
    i_f = a[: 2 * hidden]
    for j in range(len(i_f)):
        i_f[j] = _sigmoid32(i_f[j])
    for j in range(hidden):
        g[j] = tanh32(g[j])
    for j in range(hidden):
        o[j] = _sigmoid32(o[j])
    for j in range(hidden):
        c[j] = f[j] * c_prev[j] + i[j] * g[j]
    for j in range(hidden):
        th[j] = tanh32(c[j])
    for j in range(hidden):
        h[j] = o[j] * th[j]


@njit(inline="always", **NUMBA_OPTIONS)
def _cell_back(a, dh, dc, th, c_prev):  # pragma: no cover (compiled)
    """Back through a cell from the hidden state's gradient ``dh``: the gates' gradient over
    their activations ``a`` (4H), and the cell state's ``dc`` carried one step back."""
    one = _F(1.0)
    hidden = len(dh)
    i, f, g, o = a[:hidden], a[hidden : 2 * hidden], a[2 * hidden : 3 * hidden], a[3 * hidden :]
    for j in range(hidden):
        tj, d_h, fj, ij, gj, oj = th[j], dh[j], f[j], i[j], g[j], o[j]
        d_c = dc[j] + d_h * oj * (one - tj * tj)
        i[j] = d_c * gj * ij * (one - ij)
        f[j] = d_c * c_prev[j] * fj * (one - fj)
        o[j] = d_h * tj * oj * (one - oj)
        g[j] = d_c * ij * (one - gj * gj)
        dc[j] = d_c * fj


@njit(**NUMBA_OPTIONS)
def forward_step(
    hx, cs, acts, tanhs, outs, w_out, b_out, now, then, at, t, residual
):  # pragma: no cover
    """The decoder's step from the gates' pre-activations ``acts[at]`` (R, 4H): the cell
    (:func:`_cell`) into ``cs[then]``, ``tanhs[at]`` and ``hx[then]``'s hidden part, then the
    output ``W_out h + b_out`` (plus the last output with ``residual``) into ``outs[t]`` and
    ``hx[then]``'s input part."""
    hidden = cs.shape[2]
    for r in range(hx.shape[1]):
        h = hx[then, r]
        _cell(acts[at, r], cs[now, r], cs[then, r], tanhs[at, r], h[:hidden])
        for k in range(outs.shape[2]):
            s = b_out[k]
            for j in range(hidden):
                s += h[j] * w_out[k, j]
            if residual:
                s += hx[now, r, hidden + k]
            outs[t, r, k] = s
            h[hidden + k] = s


@njit(**NUMBA_OPTIONS)
def backward_step(
    d_outs, d_xs, carry, dh, dc, acts, tanhs, cs, w_out, to_x, t, residual
):  # pragma: no cover
    """The decoder's step ``t`` back: the output's gradient ``d_xs[t]`` (its own plus
    ``carry``, what reached it through the later steps), the hidden state's ``dh`` (R, H)
    gaining the output layer's part, the cell (:func:`_cell_back`, over ``acts[t]``), and
    ``carry`` for the step before: the gates' gradient through their weights on the input
    ``to_x`` (out, 4H), plus the output's own with ``residual``. The gates' gradient through
    their weights on h is the caller's product."""
    hidden = dh.shape[1]
    width = d_xs.shape[2]
    for r in range(dh.shape[0]):
        a, dx, dhr = acts[t, r], d_xs[t, r], dh[r]
        for k in range(width):
            dx[k] = d_outs[t, r, k] + carry[r, k]
            for j in range(hidden):
                dhr[j] += dx[k] * w_out[k, j]
        _cell_back(a, dhr, dc[r], tanhs[t, r], cs[t, r])
        for k in range(width):
            s = dx[k] if residual else _F(0.0)
            for j in range(4 * hidden):
                s += a[j] * to_x[k, j]
            carry[r, k] = s


@njit(**NUMBA_OPTIONS)
def sequence_step(hs, cs, acts, tanhs, t):  # pragma: no cover (compiled)
    """An encoder LSTM's step ``t`` from the gates' pre-activations ``acts[t]`` (R, 4H): the
    cell into ``cs[t + 1]``, ``tanhs[t]`` and the hidden state ``hs[t + 1]``."""
    for r in range(hs.shape[1]):
        _cell(acts[t, r], cs[t, r], cs[t + 1, r], tanhs[t, r], hs[t + 1, r])


@njit(**NUMBA_OPTIONS)
def sequence_back(d_hs, dh, dc, acts, tanhs, cs, t):  # pragma: no cover (compiled)
    """An encoder LSTM's step ``t`` back: ``dh`` gains the output's gradient ``d_hs[t]``, then
    the cell, over ``acts[t]``; ``dh``'s path through the weights on h is the caller's."""
    for r in range(dh.shape[0]):
        dhr = dh[r]
        for j in range(dh.shape[1]):
            dhr[j] += d_hs[t, r, j]
        _cell_back(acts[t, r], dhr, dc[r], tanhs[t, r], cs[t, r])
