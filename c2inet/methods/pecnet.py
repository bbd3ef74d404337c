"""PECNet (Mangalam et al., ECCV 2020, "It is Not the Journey but the Destination"): an endpoint-
conditioned CVAE that samples where each agent is going, then the path there.

The backbone's encoder reads the past (its graph attention stands in for PECNet's social
pooling; its decoder is unused). A CVAE over the endpoint: Q(z | past, true endpoint) in
training, z ~ N(0, sigma^2) at test (PECNet's truncation, sigma = 1.3). The endpoint decoder
maps [past, z] to an endpoint, the path MLP maps [past, encoded endpoint] to the eleven
positions before it. The loss is PECNet's: squared endpoint error plus squared path error (under
the variety loss over the training samples, as every method here) plus the KL of z. Trained in
sequence with no protection against forgetting. No hooks. Example: ``--methods pecnet``
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from c2inet.batch import Batch, variety_loss
from c2inet.data import PRED_LEN
from c2inet.gaussians import GaussianHead, gaussian_sample, kl_standard_normal
from c2inet.methods.base import Method
from c2inet.model import LossOutput, Predictor, to_positions
from c2inet.model_config import ModelConfig
from c2inet.options import Tunable, require


@dataclass(frozen=True)
class PECNetOptions:
    latent: int = 16  # size of z
    sigma: float = 1.3  # std of z at test time (PECNet's truncation trick)
    kl_weight: float = 1.0

    def __post_init__(self):
        require(self, 1, "latent")
        require(self, 0, "sigma", "kl_weight")


def mlp(inputs: int, outputs: int) -> nn.Sequential:
    return nn.Sequential(nn.Linear(inputs, 64), nn.ReLU(), nn.Linear(64, outputs))


class EndpointCVAE(Predictor):
    """PECNet's endpoint CVAE and path MLP on the backbone's encoder."""

    def __init__(self, config: ModelConfig, options: PECNetOptions):
        super().__init__(config)
        self.options = options
        width = self.backbone.context_dim
        self.encode_end = mlp(2, 16)
        self.to_z = GaussianHead(width + 16, options.latent)
        self.decode_end = mlp(width + options.latent, 2)
        self.decode_path = mlp(width + 16, 2 * (PRED_LEN - 1))

    def future(self, context: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        """Normalised future displacements (12, S, N, 2) for latents z (S, N, latent)."""
        context = context.expand(len(z), *context.shape)
        end = self.decode_end(torch.cat([context, z], -1))  # from the last observed position
        path = self.decode_path(torch.cat([context, self.encode_end(end)], -1))
        positions = torch.cat([path.unflatten(-1, (PRED_LEN - 1, 2)), end[..., None, :]], -2)
        steps = positions.diff(dim=-2, prepend=torch.zeros_like(positions[..., :1, :]))
        return steps.movedim(-2, 0)

    def loss(self, batch: Batch, k_train: int = 1) -> LossOutput:
        context = self.context(batch)
        end = (batch.fut[-1] - batch.obs[-1]) / batch.scale
        mean, logvar = self.to_z(torch.cat([context, self.encode_end(end)], -1))
        z = gaussian_sample(mean, logvar, torch.randn(k_train, *mean.shape, device=mean.device))
        pred = self.future(context, z)
        # PECNet's plain squared errors (in units of the scene's step), not a likelihood
        path_error = self.nll(batch, pred) * 2 * self.config.likelihood_std**2
        fit = variety_loss(path_error + ((pred.sum(0) - end) ** 2).sum(-1), batch)
        kl = batch.per_scene_mean(kl_standard_normal(mean, logvar)).mean()
        loss = fit + self.options.kl_weight * kl
        return LossOutput(loss, {"nll": fit.detach(), "kl_z": kl.detach()}, pred)

    @torch.no_grad()
    def predict(self, batch: Batch, samples: int) -> torch.Tensor:
        context = self.context(batch)
        noise = torch.randn(samples, len(context), self.options.latent, device=context.device)
        z = self.options.sigma * noise
        return to_positions(batch, self.future(context, z))

    natural_point = True  # scored at z = 0, PECNet's own point, not the mean of its draws

    def point(self, batch: Batch) -> torch.Tensor:
        context = self.context(batch)
        return self.future(context, context.new_zeros(1, len(context), self.options.latent))[:, 0]


class PECNet(Method):
    """The endpoint-conditioned CVAE, trained in sequence."""

    name = "pecnet"
    search_space = {"kl_weight": Tunable(0.01, 10.0, log=True), "sigma": Tunable(0.5, 2.0)}
    Options = PECNetOptions

    def build_model(self) -> torch.nn.Module:
        return EndpointCVAE(self.model_config, self.options)
