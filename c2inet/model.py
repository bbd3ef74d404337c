"""Trajectory predictors: a backbone whose decoder is conditioned on a vector with a random part.

The plain predictor conditions its decoder on the encoder's context and noise drawn from
N(0, I) (the baselines). :class:`C2INetModel` conditions it on two latents alone, Z (invariant)
and the confounder C (variant), so all it knows of the past passes through them (the bottleneck
of GCRL); C is scored against the prior queue. Displacements are divided by
each scene's own motion scale (``Batch.scale``, from observed frames only) and predictions
multiplied back, so pedestrians and vehicles alike reach the network at unit size.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, NamedTuple

import numpy as np
import torch
from torch import nn

from c2inet.backbones import BACKBONES
from c2inet.batch import Batch, make_batch, variety_loss
from c2inet.data import OBS_LEN, Windows
from c2inet.options import require
from c2inet.prior import (
    GaussianMixture,
    LearnablePrior,
    PriorQueue,
    QueueConfig,
    gaussian_log_prob,
    gaussian_sample,
    kl_standard_normal,
    symmetric_kl,
)

C_SOURCES = ("prior", "posterior", "posterior_mean")


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
    beta_x: float = 1.0  # weight of the past reconstruction log p(X | z, c)
    n_mc: int = 10  # Monte Carlo samples for the KL to the mixture and the past likelihood
    c_source: str = "prior"  # test-time C: prior (the back-door average, Eq 16) | posterior
    c_per: str = "agent"  # one C per agent (GCRL, method notes 7.8) or per scene
    residual: bool = True  # decoder steps change the last displacement (constant-velocity prior)

    def __post_init__(self):
        if self.backbone not in BACKBONES:
            raise ValueError(
                f"backbone {self.backbone!r} is unknown (known: {', '.join(BACKBONES)})"
            )
        if self.c_source not in ("prior", "posterior"):
            raise ValueError(f"c_source {self.c_source!r}: expected prior or posterior")
        if self.c_per not in ("agent", "scene"):
            raise ValueError(f"c_per {self.c_per!r}: expected agent or scene")
        require(self, 1, "latent_dim", "z_dim", "c_dim", "n_mc")
        require(self, 0, "beta_c", "beta_z", "beta_x")
        require(self, 0, "likelihood_std", open_low=True)


class LossOutput(NamedTuple):
    """A training step's loss, its parts for the logs, and the model output it came from."""

    loss: torch.Tensor
    parts: dict[str, float]
    output: torch.Tensor  # predicted normalised future displacements (12, S, N, 2)


def to_positions(batch: Batch, rel: torch.Tensor) -> torch.Tensor:
    """Normalised displacements (12, S, N, 2) -> absolute positions in metres (S, 12, N, 2)."""
    return (batch.obs[-1] + (rel * batch.scale).cumsum(0)).transpose(0, 1)


class Predictor(nn.Module):
    """A backbone predicting future displacements from its context and N(0, I) noise."""

    def __init__(self, config: ModelConfig, cond_dim: int | None = None):
        super().__init__()
        self.config = config
        backbone = BACKBONES[config.backbone]
        if cond_dim is None:
            cond_dim = backbone.context_dim + config.latent_dim
        self.backbone = backbone(cond_dim, residual=config.residual)

    def context(self, batch: Batch) -> torch.Tensor:
        return self.backbone.encode(batch.obs_rel / batch.scale, batch)

    def decode(self, batch: Batch, cond: torch.Tensor) -> torch.Tensor:
        """Normalised future displacements (12, S, N, 2) from conditions (S, N, D)."""
        return self.backbone.decode(cond, batch.obs_rel[-1] / batch.scale)

    def _context_with_noise(self, context: torch.Tensor, samples: int) -> torch.Tensor:
        noise = torch.randn(samples, context.shape[0], self.config.latent_dim)
        return torch.cat([context.expand(samples, *context.shape), noise], -1)

    def nll(self, batch: Batch, pred_rel: torch.Tensor) -> torch.Tensor:
        """Gaussian negative log-likelihood of the future displacements per agent (S, N)."""
        error = pred_rel - (batch.fut_rel / batch.scale)[:, None]
        return (error**2).sum(dim=(0, 3)) / (2 * self.config.likelihood_std**2)

    def loss(self, batch: Batch, k_train: int = 1) -> LossOutput:
        """The training loss; with ``k_train`` > 1 the variety loss over that many samples."""
        cond = self._context_with_noise(self.context(batch), k_train)
        pred = self.decode(batch, cond)
        loss = variety_loss(self.nll(batch, pred), batch)
        return LossOutput(loss, {"nll": loss.item()}, pred)

    def point(self, batch: Batch) -> torch.Tensor:
        """The noise-free prediction, normalised displacements (12, N, 2), differentiable: what
        distillation methods (LwF, DER++) hold the model to."""
        context = self.context(batch)
        cond = torch.cat([context, context.new_zeros(len(context), self.config.latent_dim)], -1)
        return self.decode(batch, cond[None])[:, 0]

    @torch.no_grad()
    def predict(self, batch: Batch, samples: int) -> torch.Tensor:
        """K sampled futures as absolute positions in metres, (K, 12, N, 2)."""
        cond = self._context_with_noise(self.context(batch), samples)
        return to_positions(batch, self.decode(batch, cond))

    def evaluation_variants(self) -> dict[str, dict]:
        """Other ways to predict that the trainer also scores, by metric suffix."""
        return {}


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


@dataclass
class Posteriors:
    """Q(Z|X) per agent (N, dz) and Q(C|X) per agent (N, dc) or per scene (B, dc)."""

    z_mean: torch.Tensor
    z_logvar: torch.Tensor
    c_mean: torch.Tensor
    c_logvar: torch.Tensor


@dataclass
class Anchors:
    """What the network did at samples of old prior components, to hold it there (BooVAE).

    Latents [z, c] with z ~ N(0, I) and c from a task's components, the pseudo-input the past
    decoder made of them (single-agent scenes), and what the decoder and Q(C|X) gave then.
    """

    cond: torch.Tensor  # (A, dz + dc)
    last_rel: torch.Tensor  # (A, 2) the pseudo-input's last displacement (normalised)
    future: torch.Tensor  # (12, A, 2) the decoder's output when stored
    inputs: Windows  # the pseudo-inputs (observed frames; the future is unused)
    c_mean: torch.Tensor  # (A, dc) Q(C|X) at the pseudo-inputs when stored
    c_logvar: torch.Tensor

    def __len__(self) -> int:
        return len(self.cond)

    def select(self, index: torch.Tensor) -> Anchors:
        return Anchors(
            self.cond[index],
            self.last_rel[index],
            self.future[:, index],
            self.inputs.subset(index.numpy()),
            self.c_mean[index],
            self.c_logvar[index],
        )

    def state_dict(self) -> dict[str, Any]:
        """Tensors and plain values only, for checkpoints (resume)."""
        state = {f.name: getattr(self, f.name) for f in fields(self)}
        return {**state, "inputs": self.inputs.state_dict()}

    @staticmethod
    def from_state(state: dict[str, Any]) -> Anchors:
        return Anchors(**{**state, "inputs": Windows.from_state(state["inputs"])})

    @staticmethod
    def concat(parts: list[Anchors]) -> Anchors:
        return Anchors(
            torch.cat([p.cond for p in parts]),
            torch.cat([p.last_rel for p in parts]),
            torch.cat([p.future for p in parts], dim=1),
            Windows.concat([p.inputs for p in parts]),
            torch.cat([p.c_mean for p in parts]),
            torch.cat([p.c_logvar for p in parts]),
        )


class C2INetModel(Predictor):
    """C2INet: latents Z and C, the decoder conditioned on [z, c] alone.

    Separate trunks read the backbone's context: Q(Z|X) from each agent's, Q(C|X) from each
    agent's too, or from the scene's mean context with ``c_per="scene"`` (one confounder shared
    by a scene's agents). A past decoder reconstructs the observed displacements from [z, c]
    (GCRL's E1), and C is scored against the prior queue's training prior (its KL, Eq 10), or
    against a learnt ``prior`` (the MoG and GCRL baselines).
    """

    def __init__(
        self,
        config: ModelConfig,
        queue: QueueConfig | None = None,
        prior: LearnablePrior | None = None,
    ):
        super().__init__(config, cond_dim=config.z_dim + config.c_dim)
        width = self.backbone.context_dim
        self.to_z = GaussianHead(width, config.z_dim)
        self.to_c = GaussianHead(width, config.c_dim)
        self.past = nn.Sequential(
            nn.Linear(config.z_dim + config.c_dim, 64), nn.Tanh(), nn.Linear(64, 2 * (OBS_LEN - 1))
        )
        self.queue = PriorQueue(config.c_dim, queue) if prior is None else prior
        self.anchors: Anchors | None = None  # stored after each task by the method

    @property
    def c_per_scene(self) -> bool:
        return self.config.c_per == "scene"

    def posteriors(self, batch: Batch) -> Posteriors:
        context = self.context(batch)
        c_input = batch.pool(context) if self.c_per_scene else context
        return Posteriors(*self.to_z(context), *self.to_c(c_input))

    def latents(
        self, batch: Batch, post: Posteriors, samples: int, c_source: str, z_mean: bool = False
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Samples of Z (S, N, dz) and C (S, N or B, dc).

        C from the queue's mixture (``prior``), the posterior, or the posterior's mean; Z from
        its posterior, or at its mean with ``z_mean``.
        """
        mz, lz, mc, lc = post.z_mean, post.z_logvar, post.c_mean, post.c_logvar
        scenes, scene_of = batch.num_scenes, batch.scene_of
        if z_mean:
            z = mz.expand(samples, *mz.shape)
        else:
            z = gaussian_sample(mz, lz, torch.randn(samples, *mz.shape))
        if c_source == "prior":  # the back-door average over P(C), Eq 16: one C per scene
            c = self.queue.mixture.sample(samples * scenes).view(samples, scenes, -1)
            if not self.c_per_scene:
                c = c[:, scene_of]
        elif c_source == "posterior":
            c = gaussian_sample(mc, lc, torch.randn(samples, *mc.shape))
        elif c_source == "posterior_mean":
            c = mc.expand(samples, *mc.shape)
        else:
            raise ValueError(f"c_source {c_source!r}: expected one of {', '.join(C_SOURCES)}")
        return z, c

    def conditions(self, batch: Batch, z: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        """[z, c] per agent (S, N, dz + dc); with C per scene each agent gets its scene's."""
        return torch.cat([z, c[:, batch.scene_of] if self.c_per_scene else c], -1)

    def per_scene(self, per_c: torch.Tensor, batch: Batch) -> torch.Tensor:
        """A figure per C (..., N or B) as a per-scene figure (..., B)."""
        return per_c if self.c_per_scene else batch.per_scene_mean(per_c)

    def reconstruct_past(self, cond: torch.Tensor) -> torch.Tensor:
        """Normalised observed displacements (T_obs - 1, S, N, 2) decoded from [z, c]."""
        return self.past(cond).unflatten(-1, (OBS_LEN - 1, 2)).movedim(-2, 0)

    def _protection(self) -> tuple[Anchors | None, bool, bool]:
        """A random batch of the stored anchors, and which regularisers are on."""
        q = self.queue.config
        if self.anchors is None or not q.divergence:
            return None, False, False
        anchors = self.anchors.select(torch.randperm(len(self.anchors))[: q.anchor_batch])
        return anchors, q.distill_decoder, q.distill_encoder

    def _decode(
        self, batch: Batch, cond: torch.Tensor, anchors: Anchors | None
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Future displacements of the batch (12, S, N, 2) and, given anchors, of their latents
        (12, A, 2): the anchors ride in the batch's own decoder call as extra rows."""
        last_rel = batch.obs_rel[-1] / batch.scale
        if anchors is None:
            return self.backbone.decode(cond, last_rel), None
        samples, agents = cond.shape[:2]
        rows = torch.cat([cond.flatten(0, 1), anchors.cond])
        last = torch.cat([last_rel.repeat(samples, 1), anchors.last_rel])
        out = self.backbone.decode(rows[None], last)[:, 0]
        pred = out[:, : samples * agents].unflatten(1, (samples, agents))
        return pred, out[:, samples * agents :]

    def _held(
        self, anchors: Anchors, future: torch.Tensor | None, encoder: bool
    ) -> dict[str, torch.Tensor]:
        """The BooVAE penalties: the decoder's drift at the anchors (as a negative
        log-likelihood) and Q(C|X)'s at their pseudo-inputs (symmetric KL)."""
        held = {}
        if future is not None:
            error = ((future - anchors.future) ** 2).sum(dim=(0, 2)).mean()
            held["distill_decoder"] = error / (2 * self.config.likelihood_std**2)
        if encoder:  # its own encoder call: padded into the batch, each would take A slots
            post = self.posteriors(make_batch(anchors.inputs))
            skl = symmetric_kl(post.c_mean, post.c_logvar, anchors.c_mean, anchors.c_logvar)
            held["distill_encoder"] = skl.mean()
        return held

    def loss(self, batch: Batch, k_train: int = 1) -> LossOutput:
        """Eq 10 with the variety loss over ``k_train`` samples, plus the queue's penalties."""
        cfg = self.config
        anchors, hold_decoder, hold_encoder = self._protection()
        post = self.posteriors(batch)
        z, c = self.latents(batch, post, max(k_train, cfg.n_mc), "posterior")
        cond = self.conditions(batch, z, c)
        pred, anchor_future = self._decode(batch, cond[:k_train], anchors if hold_decoder else None)
        future = variety_loss(self.nll(batch, pred), batch)
        past_error = (
            self.reconstruct_past(cond[: cfg.n_mc]) - (batch.obs_rel[1:] / batch.scale)[:, None]
        )
        nll_x = (past_error**2).sum(dim=(0, 3)).mean(0) / (2 * cfg.likelihood_std**2)
        log_q = gaussian_log_prob(c[: cfg.n_mc], post.c_mean, post.c_logvar)
        kl_c = (log_q - self.queue.training_prior().log_prob(c[: cfg.n_mc])).mean(0)
        kl_c = self.per_scene(kl_c, batch)  # (B,)
        kl_z = kl_standard_normal(post.z_mean, post.z_logvar)
        per_agent = batch.per_scene_mean(cfg.beta_x * nll_x + cfg.beta_z * kl_z)
        loss = future + per_agent.mean() + cfg.beta_c * kl_c.mean()
        parts = {
            "nll": future.item(),
            "nll_past": batch.per_scene_mean(nll_x).mean().item(),
            "kl_c": kl_c.mean().item(),
            "kl_z": batch.per_scene_mean(kl_z).mean().item(),
        }
        if anchors is not None:
            for name, held in self._held(anchors, anchor_future, hold_encoder).items():
                loss = loss + self.queue.config.distill_weight * held
                parts[name] = held.item()
        return LossOutput(loss, parts, pred)

    def point(self, batch: Batch) -> torch.Tensor:
        """The prediction at the posterior means of Z and C, (12, N, 2), differentiable."""
        z, c = self.latents(batch, self.posteriors(batch), 1, "posterior_mean", z_mean=True)
        return self.decode(batch, self.conditions(batch, z, c))[:, 0]

    @torch.no_grad()
    def predict(
        self,
        batch: Batch,
        samples: int,
        c_source: str | None = None,
        z_mean: bool = False,
        post: Posteriors | None = None,
    ) -> torch.Tensor:
        """K sampled futures in metres (K, 12, N, 2); C from ``c_source`` (default: config).

        ``post``: the batch's posteriors, when the caller has them already.
        """
        post = self.posteriors(batch) if post is None else post
        z, c = self.latents(batch, post, samples, c_source or self.config.c_source, z_mean)
        return to_positions(batch, self.decode(batch, self.conditions(batch, z, c)))

    def evaluation_variants(self) -> dict[str, dict]:
        other = "posterior" if self.config.c_source == "prior" else "prior"
        return {f"c_{other}": {"c_source": other}}


@torch.no_grad()
def make_anchors(model: C2INetModel, components: GaussianMixture, count: int) -> Anchors:
    """Anchors of one task: latents from its components and what the network made of them."""
    cond = torch.cat([torch.randn(count, model.config.z_dim), components.sample(count)], -1)
    past = model.reconstruct_past(cond[None])[:, 0]  # (7, A, 2)
    observed = torch.cat([torch.zeros(1, count, 2), past.cumsum(0)])  # (8, A, 2)
    frames = torch.cat([observed, observed[-1:].expand(12, count, 2)])  # the future is unused
    inputs = Windows(frames.transpose(0, 1).numpy().copy(), np.arange(count + 1))
    future = model.backbone.decode(cond[None], past[-1])[:, 0]
    post = model.posteriors(make_batch(inputs))
    return Anchors(cond, past[-1], future, inputs, post.c_mean, post.c_logvar)


class ConstantVelocity(nn.Module):
    """Repeats the last observed displacement: no training, the floor every learner must beat."""

    @torch.no_grad()
    def predict(self, batch: Batch, samples: int) -> torch.Tensor:
        steps = torch.arange(1, batch.fut.shape[0] + 1, dtype=batch.obs.dtype)[:, None, None]
        future = batch.obs[-1] + steps * batch.obs_rel[-1]
        return future.expand(samples, *future.shape)

    def evaluation_variants(self) -> dict[str, dict]:
        return {}
