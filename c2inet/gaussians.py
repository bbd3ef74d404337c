"""Diagonal Gaussians and their mixtures: densities, samples, KL divergences, the minibatch
estimate of a mutual information, and moment matching; what the prior queue and every latent
model are made of."""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import nn

LOG_2PI = math.log(2 * math.pi)


def gaussian_log_prob(x: torch.Tensor, mean: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """log N(x; mean, diag exp(logvar)) summed over the last axis (broadcasting)."""
    return -0.5 * (LOG_2PI + logvar + (x - mean) ** 2 / logvar.exp()).sum(-1)


def gaussian_sample(mean: torch.Tensor, logvar: torch.Tensor, noise: torch.Tensor) -> torch.Tensor:
    """The reparameterised sample mean + std * noise of a diagonal Gaussian."""
    return mean + (0.5 * logvar).exp() * noise


def kl_standard_normal(mean: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """KL(N(mean, e^logvar) || N(0, I)), summed over the last axis."""
    return 0.5 * (logvar.exp() + mean**2 - 1 - logvar).sum(-1)


def pairwise_log_prob(x: torch.Tensor, means: torch.Tensor, logvars: torch.Tensor) -> torch.Tensor:
    """log N(x; m_k, diag e^logvar_k) of every point under every Gaussian, (..., d) and (K, d)
    -> (..., K), as matrix products: -0.5 x^2 . (1/v) + x . (m/v) - 0.5 sum(m^2/v + log v +
    log 2 pi). The numbers of broadcasting ``gaussian_log_prob`` without its (..., K, d) tensors,
    about 11 times cheaper with the gradient at 160 points. The terms cancel where x is near a
    sharp component far from 0, so they are summed in float64."""
    dtype, x, means, logvars = x.dtype, x.double(), means.double(), logvars.double()
    precision = (-logvars).exp()
    scaled = means * precision
    const = -0.5 * (means * scaled + logvars + LOG_2PI).sum(-1)
    features, weights = torch.cat([x * x * -0.5, x], -1), torch.cat([precision, scaled], -1)
    return (features @ weights.mT + const[..., None, :]).to(dtype)


def minibatch_mutual_information(
    c: torch.Tensor, mean: torch.Tensor, logvar: torch.Tensor
) -> torch.Tensor:
    """MI(X; C) in nats from one draw c_i ~ Q(C|x_i) per input, (n, d) each:
    mean_i [log q(c_i|x_i) - log (1/n) sum_j q(c_i|x_j)], at most log n (differentiable)."""
    own = gaussian_log_prob(c, mean, logvar)  # (..., n)
    cross = pairwise_log_prob(c, mean, logvar)  # (..., n, n)
    aggregate = torch.logsumexp(cross, dim=-1) - math.log(mean.shape[-2])
    return (own - aggregate).mean()


def gaussian_kl(m1, lv1, m2, lv2) -> torch.Tensor:
    """KL(N(m1, e^lv1) || N(m2, e^lv2)) for diagonal Gaussians, summed over the last axis."""
    return 0.5 * (lv2 - lv1 + (lv1.exp() + (m1 - m2) ** 2) / lv2.exp() - 1).sum(-1)


def symmetric_kl(m1, lv1, m2, lv2, cap: float = 50.0) -> torch.Tensor:
    """Symmetric KL, capped so that the diversity term cannot push without bound."""
    return (0.5 * (gaussian_kl(m1, lv1, m2, lv2) + gaussian_kl(m2, lv2, m1, lv1))).clamp(max=cap)


@dataclass
class GaussianMixture:
    """A diagonal Gaussian mixture with explicit weights; the queue and the targets are these."""

    means: torch.Tensor  # (K, d)
    logvars: torch.Tensor  # (K, d)
    weights: torch.Tensor  # (K,), sums to 1

    def __len__(self) -> int:
        return len(self.weights)

    def log_prob(self, x: torch.Tensor) -> torch.Tensor:
        """log sum_k w_k N(x; m_k, s_k^2), by logsumexp; x: (..., d) -> (...)."""
        per = pairwise_log_prob(x, self.means, self.logvars)  # (..., K)
        return torch.logsumexp(per + self.weights.clamp_min(1e-30).log(), dim=-1)

    def sample(self, n: int, generator: torch.Generator | None = None) -> torch.Tensor:
        k = torch.multinomial(self.weights, n, replacement=True, generator=generator)
        noise = torch.randn(n, self.means.shape[1], generator=generator, device=self.means.device)
        return gaussian_sample(self.means[k], self.logvars[k], noise)

    def without(self, index: int) -> GaussianMixture:
        """The mixture with component ``index`` removed and the weights renormalised."""
        keep = torch.arange(len(self), device=self.weights.device) != index
        weights = self.weights[keep]
        return GaussianMixture(self.means[keep], self.logvars[keep], weights / weights.sum())

    def detached(self) -> GaussianMixture:
        return GaussianMixture(
            self.means.detach().clone(),
            self.logvars.detach().clone(),
            self.weights.detach().clone(),
        )

    def mean_pairwise_skl(self) -> torch.Tensor:
        """R_div: the mean symmetric KL over all pairs of components (0 with one component)."""
        k = len(self)
        if k < 2:
            return self.means.new_zeros(())
        skl = symmetric_kl(
            self.means[:, None], self.logvars[:, None], self.means[None], self.logvars[None]
        )
        return skl.triu(1).sum() * 2 / (k * (k - 1))


def responsibilities(
    mixture: GaussianMixture, mean: torch.Tensor, logvar: torch.Tensor
) -> torch.Tensor:
    """p(k | X) of every component for posteriors N(mean, e^logvar), (n, dc) -> (n, K).

    Exact for Gaussians: w_k * integral N(c; m_k, s_k^2) Q(c|X) dc = w_k N(mean; m_k, s_k^2 + var).
    """
    var = mixture.logvars.exp() + logvar.exp()[:, None]
    log_p = gaussian_log_prob(mean[:, None], mixture.means, var.log())
    return torch.softmax(log_p + mixture.weights.clamp_min(1e-30).log(), dim=-1)


def mix(parts: list[GaussianMixture], weights: list[float]) -> GaussianMixture:
    """The mixture sum_i weights[i] * parts[i]."""
    return GaussianMixture(
        torch.cat([p.means for p in parts]),
        torch.cat([p.logvars for p in parts]),
        torch.cat([w * p.weights for p, w in zip(parts, weights, strict=True)]),
    )


def moment_match(means: torch.Tensor, logvars: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """One Gaussian with the mean and variance of the equal mixture of the given ones."""
    m = means.mean(0)
    var = (logvars.exp() + means**2).mean(0) - m**2
    return m, var.clamp_min(1e-6).log()


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
