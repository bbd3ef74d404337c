"""Graph attention over the agents of each scene, compiled for the CPU in float32: no padding,
one call forwards and one back for a layer's scores, softmax and weighted sums.

STGAT's two attention layers in tensor operations pad every scene to the batch's widest, then
run about thirty small operations forwards and back (scores, mask, softmax, a batched product of
2 x 2 matrices on 2-agent scenes): 1.36 of the encoder's 2.43 ms forwards and back on a 2-agent
batch that holds almost no arithmetic (0.60 ms here; docs/learner.md). Here a layer is its
linear projection in torch, then one compiled pass over each scene's agents (``scene_start``
offsets, so a scene of one agent attends to itself alone); the backward is one pass that returns
the projection's, and both attention vectors', gradients. The same function as
:class:`~c2inet.backbones.stgat.GraphAttention`'s padded form (tested within float32 rounding),
which remains the path of every other device and dtype.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch.autograd.function import once_differentiable

from c2inet.jit import njit
from c2inet.kernels import check_compiled
from c2inet.kernels.steps import NUMBA_OPTIONS

SLOPE = np.float32(0.2)  # the scores' leaky ReLU, as STGAT's


@njit(**NUMBA_OPTIONS)
def _scores(h, a_src, a_dst, src, dst):  # pragma: no cover (compiled)
    """Each agent's source and destination score per head: h . a over the head's features."""
    steps, agents, heads, dim = h.shape
    for t in range(steps):
        for i in range(agents):
            for k in range(heads):
                s = np.float32(0)
                d = np.float32(0)
                for f in range(dim):
                    s += h[t, i, k, f] * a_src[k, f]
                    d += h[t, i, k, f] * a_dst[k, f]
                src[t, i, k] = s
                dst[t, i, k] = d


@njit(**NUMBA_OPTIONS)
def attend_forward(h, a_src, a_dst, starts, src, dst, weights, out):  # pragma: no cover
    """out[t, i, k] = sum_j softmax_j(leaky(src_i + dst_j)) h[t, j, k] over the agents j of i's
    scene; ``weights`` (T, N, A, K) keeps the softmax, j counted from the scene's first agent."""
    _scores(h, a_src, a_dst, src, dst)
    steps, _, heads, dim = h.shape
    for t in range(steps):
        for b in range(len(starts) - 1):
            first, end = starts[b], starts[b + 1]
            for i in range(first, end):
                for k in range(heads):
                    peak = np.float32(-np.inf)
                    for j in range(first, end):
                        e = src[t, i, k] + dst[t, j, k]
                        e = e if e > 0 else SLOPE * e
                        weights[t, i, j - first, k] = e
                        peak = max(peak, e)
                    total = np.float32(0)
                    for j in range(end - first):
                        w = np.float32(math.exp(weights[t, i, j, k] - peak))
                        weights[t, i, j, k] = w
                        total += w
                    for j in range(end - first):
                        weights[t, i, j, k] /= total
                    for f in range(dim):
                        out[t, i, k, f] = 0
                    for j in range(first, end):
                        w = weights[t, i, j - first, k]
                        for f in range(dim):
                            out[t, i, k, f] += w * h[t, j, k, f]


@njit(**NUMBA_OPTIONS)
def attend_backward(
    d_out, h, a_src, a_dst, starts, src, dst, weights, d_h, d_a_src, d_a_dst
):  # pragma: no cover
    """The gradients of :func:`attend_forward`'s output ``d_out`` reaching h (``d_h``, zeroed
    here) and both attention vectors (``d_a_src``, ``d_a_dst``, zeroed here)."""
    steps, agents, heads, dim = h.shape
    d_src = np.zeros((agents, heads), dtype=h.dtype)
    d_dst = np.zeros((agents, heads), dtype=h.dtype)
    d_w = np.empty(weights.shape[2], dtype=h.dtype)
    d_h[:] = 0
    d_a_src[:] = 0
    d_a_dst[:] = 0
    for t in range(steps):
        d_src[:] = 0
        d_dst[:] = 0
        for b in range(len(starts) - 1):
            first, end = starts[b], starts[b + 1]
            for i in range(first, end):
                for k in range(heads):
                    dot = np.float32(0)
                    for j in range(first, end):
                        w = weights[t, i, j - first, k]
                        g = np.float32(0)
                        for f in range(dim):
                            g += d_out[t, i, k, f] * h[t, j, k, f]
                            d_h[t, j, k, f] += w * d_out[t, i, k, f]
                        d_w[j - first] = g
                        dot += w * g
                    for j in range(first, end):
                        d_e = weights[t, i, j - first, k] * (d_w[j - first] - dot)
                        d_e = d_e if src[t, i, k] + dst[t, j, k] > 0 else SLOPE * d_e
                        d_src[i, k] += d_e
                        d_dst[j, k] += d_e
        for i in range(agents):
            for k in range(heads):
                for f in range(dim):
                    d_h[t, i, k, f] += d_src[i, k] * a_src[k, f] + d_dst[i, k] * a_dst[k, f]
                    d_a_src[k, f] += d_src[i, k] * h[t, i, k, f]
                    d_a_dst[k, f] += d_dst[i, k] * h[t, i, k, f]


def _forward(h, a_src, a_dst, starts, widest):
    steps, agents, heads, _ = h.shape
    src, dst = h.new_empty(steps, agents, heads), h.new_empty(steps, agents, heads)
    weights, out = h.new_empty(steps, agents, widest, heads), torch.empty_like(h)
    arrays = (h, a_src, a_dst, starts, src, dst, weights, out)
    attend_forward(*(a.detach().numpy() for a in arrays))
    return out, (src, dst, weights)


class _Attend(torch.autograd.Function):
    @staticmethod
    def forward(ctx, h, a_src, a_dst, starts, widest):
        out, kept = _forward(h, a_src, a_dst, starts, widest)
        ctx.save_for_backward(h, a_src, a_dst, starts, *kept)
        return out

    @staticmethod
    @once_differentiable
    def backward(ctx, d_out):
        h, a_src, a_dst, starts, src, dst, weights = ctx.saved_tensors
        d_h, d_a_src, d_a_dst = (
            torch.empty_like(h),
            torch.empty_like(a_src),
            torch.empty_like(a_dst),
        )
        arrays = (d_out.contiguous(), h, a_src, a_dst, starts, src, dst, weights)
        grads = (d_h, d_a_src, d_a_dst)
        attend_backward(*(a.detach().numpy() for a in arrays + grads))
        return d_h, d_a_src, d_a_dst, None, None


def attend(h, a_src, a_dst, starts: torch.Tensor, widest: int) -> torch.Tensor:
    """Each agent's attention-weighted sum of its scene's projected features, per head:
    ``h`` (T, N, K, F) per agent, the attention vectors (K, F), the scenes' agent offsets
    ``starts`` (B + 1,) and the most agents of a scene -> (T, N, K, F). Float32 on the CPU."""
    check_compiled(h)
    h = h.contiguous()
    if torch.is_grad_enabled() and (h.requires_grad or a_src.requires_grad):
        return _Attend.apply(h, a_src, a_dst, starts, widest)
    return _forward(h, a_src, a_dst, starts, widest)[0]
