"""Trajectory predictors: a backbone whose decoder is conditioned on a vector with a random part.

The plain predictor conditions its decoder on the encoder's context and noise drawn from
N(0, I) (the baselines). :class:`C2INetModel` follows the paper's Eq 16,
P(Y|do(X)) = sum_{Z,C} P(Y|X,Z,C) P(Z|X,C) P(C): its decoder sees the context beside the two
latents, Z (invariant) is inferred given the confounder C, and C is scored against the prior
queue. The earlier bottleneck (the decoder sees [z, c] alone, as GCRL) stays an option
(``decoder_input="latents"``). Displacements are divided by each scene's own motion scale
(``Batch.scale``, from observed frames only) and predictions multiplied back, so pedestrians
and vehicles alike reach the network at unit size.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import torch
from torch import nn

from c2inet.anchors import Anchors
from c2inet.backbones import BACKBONES
from c2inet.batch import Batch, make_batch, variety_loss
from c2inet.data import OBS_LEN
from c2inet.device import model_device
from c2inet.gaussians import (
    GaussianHead,
    gaussian_log_prob,
    gaussian_sample,
    kl_standard_normal,
    minibatch_mutual_information,
    responsibilities,
    symmetric_kl,
)
from c2inet.model_config import C_SOURCES, ModelConfig
from c2inet.prior import LearnablePrior, PriorQueue, QueueConfig


class LossOutput(NamedTuple):
    """A training step's loss, its parts for the logs (detached scalars), and its model output."""

    loss: torch.Tensor
    parts: dict[str, torch.Tensor | float]
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
        self.backbone = backbone(cond_dim, residual=config.residual, kernels=config.kernels)

    def context(self, batch: Batch) -> torch.Tensor:
        return self.backbone.encode(batch.obs_rel / batch.scale, batch)

    def decode(self, batch: Batch, cond: torch.Tensor) -> torch.Tensor:
        """Normalised future displacements (12, S, N, 2) from conditions (S, N, D)."""
        return self.backbone.decode(cond, batch.last_rel)

    def noise(self, samples: int, batch: Batch) -> torch.Tensor:
        """The N(0, I) part of ``samples`` conditions of the batch's agents, (S, N, latent): a
        draw per agent, or per scene (``noise_per``) shared by the scene's agents."""
        device, size = model_device(self), self.config.latent_dim
        if self.config.noise_per == "scene":
            return torch.randn(samples, batch.num_scenes, size, device=device)[:, batch.scene_of]
        return torch.randn(samples, batch.obs.shape[1], size, device=device)

    def _context_with_noise(
        self, context: torch.Tensor, samples: int, batch: Batch
    ) -> torch.Tensor:
        noise = self.noise(samples, batch)
        return torch.cat([context.expand(samples, *context.shape), noise], -1)

    def nll(self, batch: Batch, pred_rel: torch.Tensor) -> torch.Tensor:
        """Gaussian negative log-likelihood of the future displacements per agent (S, N), in
        units of the scene's motion scale or in metres (``loss_units``)."""
        error = pred_rel - (batch.fut_rel / batch.scale)[:, None]
        if self.config.loss_units == "metres":
            error = error * batch.scale  # (N, 1) against (12, S, N, 2): each agent's own
        return (error**2).sum(dim=(0, 3)) / (2 * self.config.likelihood_std**2)

    def loss(self, batch: Batch, k_train: int = 1) -> LossOutput:
        """The training loss; with ``k_train`` > 1 the variety loss over that many samples."""
        cond = self._context_with_noise(self.context(batch), k_train, batch)
        pred = self.decode(batch, cond)
        loss = variety_loss(self.nll(batch, pred), batch)
        return LossOutput(loss, {"nll": loss.detach()}, pred)

    def point(self, batch: Batch) -> torch.Tensor:
        """The noise-free prediction, normalised displacements (12, N, 2), differentiable: what
        distillation methods (LwF, DER++) hold the model to."""
        return self.decode(batch, self._noise_free(self.context(batch))[None])[:, 0]

    def _noise_free(self, context: torch.Tensor) -> torch.Tensor:
        return torch.cat([context, context.new_zeros(len(context), self.config.latent_dim)], -1)

    def samples_and_point(
        self, batch: Batch, noise: torch.Tensor, point_of: slice
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Samples (12, S, n, 2) of the batch's first n agents from ``noise`` (S, n, latent), as
        :meth:`loss` draws them, and the noise-free prediction (12, m, 2) of the agents
        ``point_of``, as :meth:`point` gives it, from one encoder call and one decoder call:
        both ride as rows of one call (the decoder reads rows independently). DER++ scores its
        step's scenes and its replayed ones in this one pass."""
        context = self.context(batch)
        samples, agents = noise.shape[:2]
        noisy = torch.cat([context[:agents].expand(samples, agents, -1), noise], -1)
        rows = torch.cat([noisy.flatten(0, 1), self._noise_free(context[point_of])])
        last_rel = batch.last_rel
        last = torch.cat([last_rel[:agents].repeat(samples, 1), last_rel[point_of]])
        out = self.backbone.decode(rows[None], last)[:, 0]
        sampled = samples * agents
        return out[:, :sampled].unflatten(1, (samples, agents)), out[:, sampled:]

    @torch.no_grad()
    def predict(self, batch: Batch, samples: int) -> torch.Tensor:
        """K sampled futures as absolute positions in metres, (K, 12, N, 2)."""
        cond = self._context_with_noise(self.context(batch), samples, batch)
        return to_positions(batch, self.decode(batch, cond))

    def evaluation_variants(self, task: int | None = None) -> dict[str, dict]:
        """Other ways to predict that the trainer also scores, by metric suffix (``task``: the
        scored task's index, for a rule that needs it)."""
        return {}


@dataclass
class Posteriors:
    """The backbone's context per agent (N, H) and Q(C|X) per agent (N, dc) or per scene (B, dc).

    Q(Z|X,C) depends on the drawn C, so it is asked for with :meth:`C2INetModel.z_posterior`.
    """

    context: torch.Tensor
    c_mean: torch.Tensor
    c_logvar: torch.Tensor


class C2INetModel(Predictor):
    """C2INet: latents Z and C; the decoder sees the context and [z, c] (Eq 16's P(Y|X,Z,C)).

    Separate trunks read the backbone's context: Q(C|X) from each agent's, or from the scene's
    mean context with ``c_per="scene"`` (one confounder shared by a scene's agents), and
    Q(Z|X,C) from the agent's context and its drawn C (``z_given_c``). A past decoder
    reconstructs the observed displacements from z (``past_from="z"``) or [z, c] (GCRL's E1).
    C is scored against the prior queue's training prior (its KL, Eq 10/17), or against a
    learnt ``prior`` (the MoG and GCRL baselines). ``decoder_input="latents"`` is the old
    bottleneck: the decoder then knows the past only through [z, c].
    """

    def __init__(
        self,
        config: ModelConfig,
        queue: QueueConfig | None = None,
        prior: LearnablePrior | None = None,
    ):
        width = BACKBONES[config.backbone].context_dim
        latents = config.z_dim + config.c_dim
        super().__init__(config, cond_dim=latents + (width if self.sees_context(config) else 0))
        self.to_z = GaussianHead(width + (config.c_dim if config.z_given_c else 0), config.z_dim)
        self.to_c = GaussianHead(width, config.c_dim)
        past_dim = config.z_dim + (config.c_dim if config.past_from == "zc" else 0)
        self.past = nn.Sequential(
            nn.Linear(past_dim, 64), nn.Tanh(), nn.Linear(64, 2 * (OBS_LEN - 1))
        )
        self.queue = PriorQueue(config.c_dim, queue) if prior is None else prior
        self.anchors: Anchors | None = None  # stored after each task by the method

    @staticmethod
    def sees_context(config: ModelConfig) -> bool:
        return config.decoder_input == "context"

    @property
    def c_per_scene(self) -> bool:
        return self.config.c_per == "scene"

    def posteriors(self, batch: Batch) -> Posteriors:
        """Q(C|X) and the context; with ``c_detached`` C's terms (KL, MI floor) cannot reshape
        the backbone the decoder reads."""
        context = self.context(batch)
        c_input = context.detach() if self.config.c_detached else context
        c_input = batch.pool(c_input) if self.c_per_scene else c_input
        return Posteriors(context, *self.to_c(c_input))

    def per_agent(self, c: torch.Tensor, batch: Batch) -> torch.Tensor:
        """C (S, N or B, dc) as one row per agent (S, N, dc)."""
        return c[:, batch.scene_of] if self.c_per_scene else c

    def z_posterior(
        self, batch: Batch, post: Posteriors, c: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Q(Z|X,C) at each drawn C: mean and log-variance (S, N, dz) (Q(Z|X) broadcast when
        ``z_given_c`` is off)."""
        context = post.context.expand(len(c), *post.context.shape)
        if self.config.z_given_c:
            context = torch.cat([context, self.per_agent(c, batch)], -1)
        return self.to_z(context)

    def sample_c(
        self, batch: Batch, post: Posteriors, samples: int, c_source: str, task: int | None = None
    ):
        """``samples`` draws of C (S, N or B, dc) by a test-time rule, or at the posterior mean
        (``posterior_mean``); ``own``: from the queue components task ``task`` added; one C per
        agent, or per scene with ``c_per="scene"``, as trained."""
        mc, lc = post.c_mean, post.c_logvar
        mixture = self.queue.mixture
        if c_source == "own" and task in getattr(self.queue, "owners", ()):  # issue 61
            own = self.queue.task_mixture(task)  # the components the scored task added
            return own.sample(samples * len(mc)).view(samples, len(mc), -1)
        if c_source in ("posterior", "own"):  # own, for a task that left none: the posterior
            return gaussian_sample(mc, lc, torch.randn(samples, *mc.shape, device=mc.device))
        if c_source == "posterior_mean":
            return mc.expand(samples, *mc.shape)
        if c_source == "prior":  # the back-door average over P(C), Eq 16
            return mixture.sample(samples * len(mc)).view(samples, len(mc), -1)
        if c_source == "responsible":  # k ~ p(k | X), then c from component k
            weights = responsibilities(mixture, mc, lc)  # (n, K)
            k = torch.multinomial(weights, samples, replacement=True).T  # (S, n)
            noise = torch.randn(samples, *mc.shape, device=mc.device)
            return gaussian_sample(mixture.means[k], mixture.logvars[k], noise)
        raise ValueError(f"c_source {c_source!r}: expected one of {', '.join(C_SOURCES)}")

    def latents(
        self,
        batch: Batch,
        post: Posteriors,
        samples: int,
        c_source: str,
        z_mean: bool = False,
        task: int | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """C (S, N or B, dc) by ``c_source``, then Z (S, N, dz) from Q(Z|X,C) (at its mean with
        ``z_mean``), with Q(Z|X,C)'s mean and log-variance."""
        c = self.sample_c(batch, post, samples, c_source, task)
        mz, lz = self.z_posterior(batch, post, c)
        z = mz if z_mean else gaussian_sample(mz, lz, torch.randn_like(mz))
        return z, c, mz, lz

    def conditions(
        self, batch: Batch, post: Posteriors, z: torch.Tensor, c: torch.Tensor
    ) -> torch.Tensor:
        """The decoder's condition per agent (S, N, D): [context, z, c], or [z, c]."""
        parts = [z, self.per_agent(c, batch)]
        if self.sees_context(self.config):
            parts.insert(0, post.context.expand(len(z), *post.context.shape))
        return torch.cat(parts, -1)

    def drop_context(self, cond: torch.Tensor) -> torch.Tensor:
        """The training condition with the context zeroed for a random ``context_dropout`` share
        of agents (the same agents in every sample); the identity when the option is off."""
        share = self.config.context_dropout
        if not share or not self.sees_context(self.config):
            return cond
        width = self.backbone.context_dim
        keep = (torch.rand(cond.shape[1], 1, device=cond.device) >= share).to(cond.dtype)
        return torch.cat([cond[..., :width] * keep, cond[..., width:]], -1)

    def per_scene(self, per_c: torch.Tensor, batch: Batch) -> torch.Tensor:
        """A figure per C (..., N or B) as a per-scene figure (..., B)."""
        return per_c if self.c_per_scene else batch.per_scene_mean(per_c)

    def reconstruct_past(self, z: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        """Normalised observed displacements (T_obs - 1, S, N, 2) decoded from z (or [z, c]),
        both per agent."""
        source = torch.cat([z, c], -1) if self.config.past_from == "zc" else z
        return self.past(source).unflatten(-1, (OBS_LEN - 1, 2)).movedim(-2, 0)

    def _protection(self) -> tuple[Anchors | None, bool, bool]:
        """A random batch of the stored anchors, and which regularisers are on."""
        q = self.queue.config
        if self.anchors is None or not (q.distill_decoder or q.distill_encoder):
            return None, False, False
        chosen = torch.randperm(len(self.anchors), device="cpu")  # the host indexes the windows
        anchors = self.anchors.select(chosen[: q.anchor_batch])
        return anchors, q.distill_decoder, q.distill_encoder

    def _decode(
        self, batch: Batch, cond: torch.Tensor, anchors: Anchors | None
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Future displacements of the batch (12, S, N, 2) and, given anchors, of their latents
        (12, A, 2): the anchors ride in the batch's own decoder call as extra rows."""
        last_rel = batch.last_rel
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
            post = self.posteriors(make_batch(anchors.inputs, device=anchors.cond.device))
            skl = symmetric_kl(post.c_mean, post.c_logvar, anchors.c_mean, anchors.c_logvar)
            held["distill_encoder"] = skl.mean()
        return held

    def loss(self, batch: Batch, k_train: int = 1) -> LossOutput:
        """Eq 10 with the variety loss over ``k_train`` samples, plus the queue's penalties.

        KL_C is taken against the queue's training prior (the whole mixture, Eq 17, unless
        ``task_kl``), with ``free_bits_c`` nats per C free; KL_Z is Q(Z|X,C)'s against N(0, I).
        With ``mi_floor_c`` a batch whose MI(X; C) falls below it pays ``mi_weight`` per missing
        nat: with the context beside it the decoder needs nothing from C, so C stays live only
        when asked to; with ``c_detached`` that costs no plasticity (docs/c2inet-study.md).
        """
        cfg = self.config
        anchors, hold_decoder, hold_encoder = self._protection()
        post = self.posteriors(batch)
        z, c, mz, lz = self.latents(batch, post, max(k_train, cfg.n_mc), "posterior")
        cond = self.drop_context(self.conditions(batch, post, z, c))
        pred, anchor_future = self._decode(batch, cond[:k_train], anchors if hold_decoder else None)
        future = variety_loss(self.nll(batch, pred), batch)
        mc = cfg.n_mc
        log_q = gaussian_log_prob(c[:mc], post.c_mean, post.c_logvar)
        kl_c = (log_q - self.queue.training_prior().log_prob(c[:mc])).mean(0)
        kl_c = self.per_scene(kl_c, batch)  # (B,)
        kl_z = kl_standard_normal(mz[:mc], lz[:mc]).mean(0)
        per_agent = cfg.beta_z * kl_z
        kl_c_cost = kl_c.clamp_min(cfg.free_bits_c) if cfg.free_bits_c else kl_c
        parts = {
            "nll": future.detach(),
            "kl_c": kl_c.mean().detach(),
            # the share of scenes whose KL_C, above the free bits, has a gradient: where the
            # queue's prior (Eq 17) shapes training
            "kl_c_binding": (kl_c > cfg.free_bits_c).float().mean().detach()
            if cfg.free_bits_c
            else 1.0,
            "kl_z": batch.per_scene_mean(kl_z).mean().detach(),
        }
        if cfg.beta_x:  # the past reconstruction, only where it is weighted
            past = self.reconstruct_past(z[:mc], self.per_agent(c[:mc], batch))
            past_error = past - (batch.obs_rel[1:] / batch.scale)[:, None]
            nll_x = (past_error**2).sum(dim=(0, 3)).mean(0) / (2 * cfg.likelihood_std**2)
            per_agent = per_agent + cfg.beta_x * nll_x
            parts["nll_past"] = batch.per_scene_mean(nll_x).mean().detach()
        loss = future + batch.per_scene_mean(per_agent).mean() + cfg.beta_c * kl_c_cost.mean()
        if cfg.mi_floor_c and cfg.mi_weight:  # an n x n estimate: only where it is asked for
            mi = minibatch_mutual_information(c[:mc], post.c_mean, post.c_logvar)
            loss = loss + cfg.mi_weight * (cfg.mi_floor_c - mi).clamp_min(0)
            parts["mi_c"] = mi.detach()
        if anchors is not None:
            for name, held in self._held(anchors, anchor_future, hold_encoder).items():
                loss = loss + self.queue.config.distill_weight * held
                parts[name] = held.detach()
        return LossOutput(loss, parts, pred)

    def point(self, batch: Batch) -> torch.Tensor:
        """The prediction at the posterior means of C and then Z, (12, N, 2), differentiable."""
        post = self.posteriors(batch)
        z, c, _, _ = self.latents(batch, post, 1, "posterior_mean", z_mean=True)
        return self.decode(batch, self.conditions(batch, post, z, c))[:, 0]

    @torch.no_grad()
    def predict(
        self,
        batch: Batch,
        samples: int,
        c_source: str | None = None,
        z_mean: bool = False,
        post: Posteriors | None = None,
        task: int | None = None,
    ) -> torch.Tensor:
        """K sampled futures in metres (K, 12, N, 2): C by ``c_source`` (default: config), then
        Z from Q(Z|X,C). ``post``: the batch's posteriors, when the caller has them already;
        ``task``: the scored task's index, for the ``own`` rule."""
        post = self.posteriors(batch) if post is None else post
        source = c_source or self.config.c_source
        z, c, _, _ = self.latents(batch, post, samples, source, z_mean, task)
        return to_positions(batch, self.decode(batch, self.conditions(batch, post, z, c)))

    def evaluation_variants(self, task: int | None = None) -> dict[str, dict]:
        """Every test-time rule but the default, scored beside it (``ade_c_prior`` ...); with a
        queue and a task ``task``, also C from the components that task added alone
        (``ade_c_own``: can an old task be served by what it left? a task that left none, not
        yet learnt or pruned away, is scored with the posterior)."""
        rules = {f"c_{s}": {"c_source": s} for s in C_SOURCES if s != self.config.c_source}
        if task is not None and hasattr(self.queue, "task_mixture"):  # C2INet's queue alone
            rules["c_own"] = {"c_source": "own", "task": task}
        return rules
