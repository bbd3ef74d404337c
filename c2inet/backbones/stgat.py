"""STGAT (Huang et al., ICCV 2019): trajectory LSTM, per-step graph attention, graph LSTM, decoder.

The whole network is here, in plain modules: a change to it starts in this file, with
``model.kernels = cell`` (PyTorch's own LSTMs and cell, padded attention: one attention call
covers every scene of a batch at every observed step). The fast kernels of
:mod:`c2inet.kernels` compute the same function of the same parameters (checkpoints load either
way) and are chosen by that one option, resolved once when the network is built: a change that
keeps their shapes (sizes, activations, the residual) needs nothing there; a new gate or layer
inside the LSTMs or the attention needs its port, or runs with ``tensor`` or ``cell`` until then
(docs/learner.md, "Changing the network").
"""

from __future__ import annotations

import torch
from torch import nn

from c2inet import kernels as _kernels
from c2inet.backbones.base import register
from c2inet.batch import Batch
from c2inet.kernels import attention
from c2inet.kernels.rollout import lstm_rollout, rollout_weights
from c2inet.kernels.sequence import run_lstm


class GraphAttention(nn.Module):
    """Multi-head graph attention over the agents of each scene (padded, masked)."""

    def __init__(self, in_dim: int, out_dim: int, heads: int, concat: bool):
        super().__init__()
        self.heads, self.out_dim, self.concat = heads, out_dim, concat
        self.linear = nn.Linear(in_dim, heads * out_dim, bias=False)
        self.att_src = nn.Parameter(torch.randn(heads, out_dim) * 0.1)
        self.att_dst = nn.Parameter(torch.randn(heads, out_dim) * 0.1)
        self.bias = nn.Parameter(torch.zeros(heads * out_dim if concat else out_dim))

    def forward(self, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        # x: (T, B, A, F); mask: (B, A)
        h = self.linear(x).unflatten(-1, (self.heads, self.out_dim))  # (T, B, A, H, D)
        src = (h * self.att_src).sum(-1)  # (T, B, A, H)
        dst = (h * self.att_dst).sum(-1)
        scores = nn.functional.leaky_relu(src.unsqueeze(3) + dst.unsqueeze(2), 0.2)  # (T,B,A,A,H)
        scores = scores.masked_fill(~mask[None, :, None, :, None], float("-inf"))
        weights = torch.softmax(scores, dim=3)
        weights = torch.nan_to_num(weights)  # rows of padding slots
        return self._combine(torch.einsum("tbijh,tbjhd->tbihd", weights, h))

    def over_scenes(self, x: torch.Tensor, batch: Batch) -> torch.Tensor:
        """:meth:`forward` on per-agent rows x (T, N, F), through the compiled kernels
        (:func:`~c2inet.kernels.attention.attend`): no padding."""
        h = self.linear(x).unflatten(-1, (self.heads, self.out_dim))
        out = attention.attend(h, self.att_src, self.att_dst, batch.scene_start, batch.max_agents)
        return self._combine(out)

    def _combine(self, out: torch.Tensor) -> torch.Tensor:
        """The heads' outputs (..., H, D) concatenated or averaged, plus the bias."""
        return (out.flatten(-2) if self.concat else out.mean(-2)) + self.bias


class STGATEncoder(nn.Module):
    """Encodes observed displacements into a 64-d vector per agent (32 trajectory + 32 graph).

    ``compiled``: its LSTMs run through :func:`~c2inet.kernels.sequence.run_lstm` (compiled
    steps on the CPU in float32) and its attention through
    :func:`~c2inet.kernels.attention.attend`, else as the modules themselves (oneDNN, padded
    attention); the same function.
    """

    def __init__(
        self, traj_hidden=32, graph_hidden=32, gat_hidden=16, gat_out=32, heads=4, compiled=False
    ):
        super().__init__()
        self.compiled = compiled
        self.traj_lstm = nn.LSTM(2, traj_hidden)
        self.gat1 = GraphAttention(traj_hidden, gat_hidden, heads, concat=True)
        self.gat2 = GraphAttention(gat_hidden * heads, gat_out, 1, concat=False)
        self.graph_lstm = nn.LSTM(gat_out, graph_hidden)
        self.out_dim = traj_hidden + graph_hidden

    def forward(self, obs_rel: torch.Tensor, batch: Batch) -> torch.Tensor:
        traj = self._lstm(self.traj_lstm, obs_rel)  # (T, N, 32)
        graph = self._lstm(self.graph_lstm, self._social(traj, batch))
        return torch.cat([traj[-1], graph[-1]], dim=-1)

    def _social(self, traj: torch.Tensor, batch: Batch) -> torch.Tensor:
        """The two graph attention layers' output per agent (T, N, 32): compiled over each
        scene's agents, else padded to the batch's widest scene (tensor operations)."""
        elu = nn.functional.elu
        if self.compiled:
            return self.gat2.over_scenes(elu(self.gat1.over_scenes(traj, batch)), batch)
        padded, mask = batch.pad(traj)
        return batch.unpad(self.gat2(elu(self.gat1(padded, mask)), mask))

    def _lstm(self, lstm: nn.LSTM, x: torch.Tensor) -> torch.Tensor:
        return run_lstm(lstm, x) if self.compiled else lstm(x)[0]


class Decoder(nn.Module):
    """Autoregressive LSTM decoder of future displacements from a conditioning vector.

    Everything the decoder knows of the past comes through ``cond`` (its initial state) and the
    last observed displacement (its first input). With ``residual`` each step outputs the change
    of displacement, so an untrained decoder already extrapolates at constant velocity.
    ``kernel`` (``model.kernels`` resolved): ``"cell"`` steps through
    :class:`torch.nn.LSTMCell`; ``"tensor"`` and ``"compiled"`` run the twelve steps as one
    autograd node (:func:`~c2inet.kernels.rollout.lstm_rollout`), its cell in tensor operations
    or compiled; the same parameters and function, rounded differently.
    """

    def __init__(
        self, cond_dim: int, hidden=64, embed=16, pred_len=12, residual=False, kernel="cell"
    ):
        super().__init__()
        if kernel not in ("compiled", "tensor", "cell"):
            raise ValueError(f"decoder kernel {kernel!r}: expected compiled, tensor or cell")
        self.pred_len, self.residual, self.kernel = pred_len, residual, kernel
        self.init = nn.Sequential(nn.Linear(cond_dim, hidden), nn.Tanh())
        self.embed = nn.Linear(2, embed)
        self.cell = nn.LSTMCell(embed, hidden)
        self.out = nn.Linear(hidden, 2)
        if residual:  # start exactly at constant velocity
            nn.init.zeros_(self.out.weight)
            nn.init.zeros_(self.out.bias)

    def forward(self, cond: torch.Tensor, last_rel: torch.Tensor) -> torch.Tensor:
        # cond: (S, N, D); last_rel: (N, 2) or (S, N, 2) -> (12, S, N, 2)
        samples, agents = cond.shape[:2]
        h = self.init(cond).flatten(0, 1)
        step = last_rel.expand(samples, agents, 2).flatten(0, 1)
        if self.kernel != "cell":
            weight, out = rollout_weights(self.embed, self.cell), self.out
            fused = self.kernel == "compiled"
            outputs = lstm_rollout(
                h, step, weight, out.weight, out.bias, self.pred_len, self.residual, fused
            )
            return outputs.unflatten(1, (samples, agents))
        c = torch.zeros_like(h)
        outputs = []
        for _ in range(self.pred_len):
            h, c = self.cell(self.embed(step), (h, c))
            step = step + self.out(h) if self.residual else self.out(h)
            outputs.append(step)
        return torch.stack(outputs).unflatten(1, (samples, agents))


@register("stgat")
class STGAT(nn.Module):
    """The backbone as one module: ``encode`` observed displacements, ``decode`` from a vector.

    ``cond_dim`` is the size of what the decoder is conditioned on: the caller decides whether
    that is the encoder's context with noise (the baselines) or latents alone (C2INet).
    ``kernels`` (``model.kernels``, :data:`c2inet.kernels.MODES`) is resolved for the device the
    network is built on and kept as :attr:`kernels`.
    """

    context_dim = 64  # the encoder's output: 32 trajectory + 32 graph

    def __init__(
        self, cond_dim: int, pred_len: int = 12, residual: bool = False, kernels: str = "auto"
    ):
        super().__init__()
        self.kernels = self.kernels_for(kernels, torch.get_default_device())
        self.encoder = STGATEncoder(compiled=self.kernels == "compiled")
        self.decoder = Decoder(cond_dim, pred_len=pred_len, residual=residual, kernel=self.kernels)
        assert self.encoder.out_dim == self.context_dim

    @classmethod
    def kernels_for(cls, setting: str, device: torch.device | str) -> str:
        """The kernels a network of this class built on ``device`` runs for ``setting``."""
        return _kernels.resolve(setting, device)

    def encode(self, obs_rel: torch.Tensor, batch: Batch) -> torch.Tensor:
        return self.encoder(obs_rel, batch)

    def decode(self, cond: torch.Tensor, last_rel: torch.Tensor) -> torch.Tensor:
        return self.decoder(cond, last_rel)


@register("stgat-cell")
class STGATCell(STGAT):
    """``stgat`` with ``model.kernels = cell`` whatever the setting (the name earlier boards and
    studies ran under): the reference the kernels are tested and timed against."""

    @classmethod
    def kernels_for(cls, setting: str, device: torch.device | str) -> str:
        _kernels.resolve(setting, device)  # a bad setting is still one
        return "cell"
