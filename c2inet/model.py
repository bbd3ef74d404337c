"""Trajectory predictors: a backbone whose decoder is conditioned on a latent sample.

The plain predictor draws that latent from N(0, I) (the baselines); :class:`C2INetModel` infers a
trajectory latent Z and a confounder C with Gaussian heads and scores C against the prior queue.
Displacements are divided by each scene's own motion scale (``Batch.scale``, from observed frames
only) and predictions multiplied back, so pedestrians and vehicles alike reach the network at
unit size, in one curriculum too.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from c2inet.backbones import BACKBONES
from c2inet.batch import Batch, scene_mean
from c2inet.prior import PriorQueue, QueueConfig, gaussian_log_prob, gaussian_sample


@dataclass
class ModelConfig:
    """Sizes and loss weights shared by every learner (defaults: method notes, sections 4-5)."""

    backbone: str = "stgat"
    latent_dim: int = 16  # noise size of the baselines; C2INet uses z_dim + c_dim
    z_dim: int = 8
    c_dim: int = 8
    likelihood_std: float = 0.1  # std of the Gaussian likelihood, in units of the scene scale
    beta_c: float = 1.0
    beta_z: float = 1.0
    n_mc: int = 10  # Monte Carlo samples of C for the KL to the mixture
    c_source: str = "posterior"  # where test-time C comes from: posterior | prior
    residual: bool = True  # decoder steps change the last displacement (constant-velocity prior)

    def __post_init__(self):
        if self.backbone not in BACKBONES:
            raise ValueError(
                f"backbone {self.backbone!r} is unknown (known: {', '.join(BACKBONES)})"
            )
        if self.c_source not in ("posterior", "prior"):
            raise ValueError(f"c_source {self.c_source!r}: expected posterior or prior")


class Predictor(nn.Module):
    """A backbone predicting future displacements from a latent drawn from N(0, I)."""

    def __init__(self, config: ModelConfig, latent_dim: int | None = None):
        super().__init__()
        self.config = config
        self.latent_dim = latent_dim or config.latent_dim
        self.backbone = BACKBONES[config.backbone](self.latent_dim, residual=config.residual)

    def context(self, batch: Batch) -> torch.Tensor:
        return self.backbone.encode(batch.obs_rel / batch.scale, batch)

    def latents(self, context: torch.Tensor, samples: int) -> torch.Tensor:
        return torch.randn(samples, context.shape[0], self.latent_dim)

    def decode(self, batch: Batch, context: torch.Tensor, latent: torch.Tensor) -> torch.Tensor:
        """Normalised future displacements (12, S, N, 2)."""
        ctx = context.expand(latent.shape[0], *context.shape)
        return self.backbone.decode(ctx, latent, batch.obs_rel[-1] / batch.scale)

    def nll(self, batch: Batch, pred_rel: torch.Tensor) -> torch.Tensor:
        """Gaussian negative log-likelihood of the future displacements per agent (S, N)."""
        error = pred_rel - (batch.fut_rel / batch.scale)[:, None]
        return (error**2).sum(dim=(0, 3)) / (2 * self.config.likelihood_std**2)

    def loss(self, batch: Batch) -> tuple[torch.Tensor, dict[str, float]]:
        context = self.context(batch)
        nll = self.nll(batch, self.decode(batch, context, self.latents(context, 1)))[0]
        loss = scene_mean(nll, batch)
        return loss, {"nll": loss.item()}

    @torch.no_grad()
    def predict(self, batch: Batch, samples: int) -> torch.Tensor:
        """K sampled futures as absolute positions in metres, (K, 12, N, 2)."""
        context = self.context(batch)
        rel = self.decode(batch, context, self.latents(context, samples)) * batch.scale
        return (batch.obs[-1] + rel.cumsum(0)).transpose(0, 1)


class GaussianHead(nn.Module):
    """MLP (32, 32, LeakyReLU) then mean and log-variance of a diagonal Gaussian (GCRL Mapping)."""

    def __init__(self, in_dim: int, out_dim: int):
        super().__init__()
        self.body = nn.Sequential(
            nn.Linear(in_dim, 32), nn.LeakyReLU(), nn.Linear(32, 32), nn.LeakyReLU()
        )
        self.mean = nn.Linear(32, out_dim)
        self.logvar = nn.Linear(32, out_dim)

    def forward(self, h: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        h = self.body(h)
        return self.mean(h), self.logvar(h).clamp(-8, 4)


class C2INetModel(Predictor):
    """C2INet: posteriors Q(Z|X) and Q(C|X) on the backbone, C scored against the prior queue."""

    def __init__(self, config: ModelConfig, queue: QueueConfig | None = None):
        super().__init__(config, latent_dim=config.z_dim + config.c_dim)
        self.to_z = GaussianHead(self.backbone.out_dim, config.z_dim)
        self.to_c = GaussianHead(self.backbone.out_dim, config.c_dim)
        self.queue = PriorQueue(config.c_dim, queue)

    def posterior_c(self, batch: Batch) -> tuple[torch.Tensor, torch.Tensor]:
        return self.to_c(self.context(batch))

    def latents(self, context: torch.Tensor, samples: int) -> torch.Tensor:
        mz, lz = self.to_z(context)
        z = gaussian_sample(mz, lz, torch.randn(samples, *mz.shape))
        if self.config.c_source == "prior":  # the literal back-door average over P(C)
            c = self.queue.mixture.sample(samples * len(mz)).view(samples, len(mz), -1)
        else:
            mc, lc = self.to_c(context)
            c = gaussian_sample(mc, lc, torch.randn(samples, *mc.shape))
        return torch.cat([z, c], dim=-1)

    def loss(self, batch: Batch) -> tuple[torch.Tensor, dict[str, float]]:
        cfg = self.config
        context = self.context(batch)
        mz, lz = self.to_z(context)
        mc, lc = self.to_c(context)
        c = gaussian_sample(mc, lc, torch.randn(cfg.n_mc, *mc.shape))  # (S, N, dc)
        z = gaussian_sample(mz, lz, torch.randn(*mz.shape))
        nll = self.nll(batch, self.decode(batch, context, torch.cat([z, c[0]], -1)[None]))[0]
        kl_c = (gaussian_log_prob(c, mc, lc) - self.queue.log_prob(c)).mean(0)
        kl_z = 0.5 * (lz.exp() + mz**2 - 1 - lz).sum(-1)
        per_agent = nll + cfg.beta_c * kl_c + cfg.beta_z * kl_z
        parts = {
            name: scene_mean(v, batch).item()
            for name, v in (("nll", nll), ("kl_c", kl_c), ("kl_z", kl_z))
        }
        return scene_mean(per_agent, batch), parts


class ConstantVelocity(nn.Module):
    """Repeats the last observed displacement: no training, the floor every learner must beat."""

    @torch.no_grad()
    def predict(self, batch: Batch, samples: int) -> torch.Tensor:
        steps = torch.arange(1, batch.fut.shape[0] + 1, dtype=batch.obs.dtype)[:, None, None]
        future = batch.obs[-1] + steps * batch.obs_rel[-1]
        return future.expand(samples, *future.shape)
