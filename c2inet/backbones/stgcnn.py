"""Social-STGCNN (Mohamed et al., CVPR 2020): a spatio-temporal graph CNN over the observed frames
and a time-extrapolator CNN (TXP-CNN) for the future.

Encoder: at every observed step a graph of each scene's agents with the kernel
a_ij = 1 / ||v_i - v_j|| on their (normalised) displacements (0 where they coincide), normalised
as D^-1/2 (A + I) D^-1/2; one ST-GCN layer (graph convolution, then a temporal convolution of
kernel 3, PReLU, a residual path), its feature map pooled over time into the context. Decoder:
the condition (context and noise, or C2INet's [z, c]) mapped to a feature map with the observed
steps as channels, five TXP-CNN layers turning 8 step-channels into 12 (PReLU, residual after the
first), then each step's 2-D displacement (the method notes' recommended output, so every method
keeps its Gaussian likelihood; the original predicts a bivariate Gaussian per step).
"""

from __future__ import annotations

import torch
from torch import nn

from c2inet.backbones.base import register
from c2inet.batch import Batch
from c2inet.data import OBS_LEN


def graph_kernel(displacements: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """(T, B, A, 2) padded displacements -> (T, B, A, A) normalised adjacency per step."""
    distance = torch.cdist(displacements, displacements)
    kernel = torch.where(distance > 0, 1 / distance.clamp_min(1e-6), torch.zeros_like(distance))
    pair = (mask[:, :, None] & mask[:, None, :])[None]
    eye = torch.eye(mask.shape[1], dtype=torch.bool)
    adjacency = (kernel * pair) + (eye & pair).to(kernel.dtype)  # A + I on present agents
    degree = adjacency.sum(-1).clamp_min(1e-6).rsqrt()
    return degree[..., :, None] * adjacency * degree[..., None, :]


class STGCNNEncoder(nn.Module):
    """One ST-GCN layer over the observed steps, pooled over time into a 64-d context."""

    def __init__(self, features: int = 32, out_dim: int = 64):
        super().__init__()
        self.spatial = nn.Linear(2, features)
        self.temporal = nn.Conv1d(features, features, kernel_size=3, padding=1)
        self.residual = nn.Linear(2, features)
        self.act = nn.PReLU()
        self.pool = nn.Linear(OBS_LEN * features, out_dim)

    def forward(self, obs_rel: torch.Tensor, batch: Batch) -> torch.Tensor:
        padded, mask = batch.pad(obs_rel)  # (T, B, A, 2)
        graph = torch.einsum("tbij,tbjf->tbif", graph_kernel(padded, mask), self.spatial(padded))
        per_agent = batch.unpad(graph)  # (T, N, F)
        temporal = self.temporal(per_agent.permute(1, 2, 0)).permute(2, 0, 1)
        features = self.act(temporal + self.residual(obs_rel))  # (T, N, F)
        return torch.tanh(self.pool(features.permute(1, 0, 2).flatten(1)))


class TXPDecoder(nn.Module):
    """TXP-CNN: the condition as a (steps x features) map, convolved from 8 step-channels to 12."""

    def __init__(self, cond_dim: int, pred_len: int = 12, features: int = 32, residual=False):
        super().__init__()
        self.features, self.residual = features, residual
        self.lift = nn.Linear(cond_dim, OBS_LEN * features)
        self.first = nn.Conv1d(OBS_LEN, pred_len, kernel_size=3, padding=1)
        self.layers = nn.ModuleList(
            nn.Conv1d(pred_len, pred_len, kernel_size=3, padding=1) for _ in range(4)
        )
        self.act = nn.PReLU()
        self.out = nn.Linear(features, 2)
        if residual:  # start exactly at constant velocity
            nn.init.zeros_(self.out.weight)
            nn.init.zeros_(self.out.bias)

    def forward(self, cond: torch.Tensor, last_rel: torch.Tensor) -> torch.Tensor:
        # cond: (S, N, D); last_rel: (N, 2) or (S, N, 2) -> (12, S, N, 2)
        samples, agents = cond.shape[:2]
        x = self.lift(cond).flatten(0, 1).unflatten(-1, (OBS_LEN, self.features))
        x = self.act(self.first(x))
        for layer in self.layers:
            x = x + self.act(layer(x))
        steps = self.out(x).unflatten(0, (samples, agents)).permute(2, 0, 1, 3)
        return last_rel.expand(samples, agents, 2) + steps if self.residual else steps


@register("stgcnn")
class STGCNN(nn.Module):
    """The backbone as one module: ``encode`` observed displacements, ``decode`` a condition."""

    context_dim = 64

    def __init__(
        self, cond_dim: int, pred_len: int = 12, residual: bool = False, kernels: str = "auto"
    ):
        super().__init__()
        self.kernels = self.kernels_for(kernels, "cpu")
        self.encoder = STGCNNEncoder(out_dim=self.context_dim)
        self.decoder = TXPDecoder(cond_dim, pred_len, residual=residual)

    @classmethod
    def kernels_for(cls, setting: str, device) -> str:
        """No kernels of its own: every setting runs its tensor operations."""
        return "tensor"

    def encode(self, obs_rel: torch.Tensor, batch: Batch) -> torch.Tensor:
        return self.encoder(obs_rel, batch)

    def decode(self, cond: torch.Tensor, last_rel: torch.Tensor) -> torch.Tensor:
        return self.decoder(cond, last_rel)
