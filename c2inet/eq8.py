"""Eq 8's component fit with its gradient in closed form (the default), beside the autograd fit
of ``PriorQueue.fit_component`` (``QueueConfig.fit``: "closed" or "autograd").

The fit maximises J(P) = E_P[2 log T - log(T + M)] + H[P] (+ lambda_div * mean SKL(P, P_k)) over
a diagonal Gaussian P = N(mean, e^logvar), by Adam on reparameterised samples c = mean + s * noise.
In closed form it needs no graph: for a mixture X, grad_c log X(c) = sum_k r_k(c) (m_k - c) / v_k
with r its responsibilities, and the Gaussian densities of all samples are matrix products. Both
fits draw the same noise step for step, so they differ by float rounding only
(``tests/c2inet/test_eq8.py``); ``benchmarks/eq8_fit.py`` times them: one fit 5 to 7 times
cheaper, a C2INet-online job 1.15 to 1.28 times, with the same accuracy over 3 seeds on
crowd_radius and crowd_noise. Runs before this option (December 2026) used autograd; the
commit in a run's card reproduces it bit for bit (the mixture densities have since become matrix
products, the same to float rounding).
"""

from __future__ import annotations

import math

import torch

LOG_2PI = math.log(2 * math.pi)
SKL_CAP = 50.0  # symmetric_kl's cap: past it the diversity term pushes no more
ADAM = (0.9, 0.999, 1e-8)  # torch.optim.Adam's defaults


class _Density:
    """A fixed diagonal mixture's log density and its gradient at many points, as matrix
    products: log N(c; m, v) = -0.5 c^2 . (1/v) + c . (m/v) - 0.5 sum(m^2/v + log v + log 2 pi).
    One product gives the (S, K) log densities from [c^2, c], one exponential their
    responsibilities, and one product the gradient's two sums over the components."""

    def __init__(self, mixture):
        precision = (-mixture.logvars).exp()  # (K, d)
        scaled = mixture.means * precision
        self.dim = precision.shape[1]
        self.quadratic = torch.cat([-0.5 * precision, scaled], 1).T.contiguous()  # (2d, K)
        self.moments = torch.cat([scaled, precision], 1)  # (K, 2d)
        self.const = mixture.weights.clamp_min(1e-30).log() - 0.5 * (
            mixture.means * scaled + mixture.logvars + LOG_2PI
        ).sum(-1)

    def log_prob_and_grad(self, c: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """log X(c) (S,) and its gradient in c (S, d): sum_k r_k (m_k - c) / v_k."""
        per = torch.addmm(self.const, torch.cat([c * c, c], 1), self.quadratic)  # (S, K)
        peak = per.amax(1, keepdim=True)
        weights = per.sub_(peak).exp_()  # responsibilities up to their sum
        total = weights.sum(1, keepdim=True)
        sums = (weights @ self.moments).div_(total)  # (S, 2d): sum_k r_k m_k/v_k, r_k / v_k
        log_x = (total.log_() + peak)[:, 0]
        return log_x, sums[:, : self.dim] - c * sums[:, self.dim :]


def _skl_gradient(mean, logvar, current) -> tuple[torch.Tensor, torch.Tensor]:
    """Gradient of mean_k SKL(P, P_k) (each capped at SKL_CAP) in mean and logvar."""
    var, var_k = logvar.exp(), current.logvars.exp()  # (d,), (K, d)
    diff = mean - current.means  # (K, d)
    square = diff * diff
    skl = 0.25 * ((var + square) / var_k + (var_k + square) / var - 2).sum(-1)  # (K,)
    live = (skl <= SKL_CAP).to(mean.dtype)[:, None] / len(skl)  # clamp: no gradient past the cap
    grad_mean = (0.5 * diff * (1 / var_k + 1 / var) * live).sum(0)
    grad_logvar = (0.25 * (var / var_k - (var_k + square) / var) * live).sum(0)
    return grad_mean, grad_logvar


class ClosedForm:
    """J's gradient for one target T and queue M, their densities prepared once per fit."""

    def __init__(self, target, current, lambda_div: float):
        self.target, self.current = _Density(target), _Density(current)
        self.queue = current  # the diversity term's components
        self.lambda_div = lambda_div

    def gradient(self, mean, logvar, noise) -> tuple[torch.Tensor, torch.Tensor]:
        """dJ/dmean and dJ/dlogvar at the samples mean + e^(logvar/2) * noise, (S, d) noise."""
        std = (0.5 * logvar).exp()
        c = mean + std * noise
        log_t, grad_t = self.target.log_prob_and_grad(c)
        log_m, grad_m = self.current.log_prob_and_grad(c)
        share = torch.sigmoid(log_t - log_m)[:, None]  # T / (T + M)
        grad_c = (2 - share) * grad_t - (1 - share) * grad_m  # (S, d)
        grad_mean = grad_c.mean(0)
        grad_logvar = (grad_c * noise).mean(0) * 0.5 * std + 0.5  # + the entropy's
        if self.lambda_div:
            skl_mean, skl_logvar = _skl_gradient(mean, logvar, self.queue)
            grad_mean = grad_mean + self.lambda_div * skl_mean
            grad_logvar = grad_logvar + self.lambda_div * skl_logvar
        return grad_mean, grad_logvar


def fit_closed_form(
    mean, logvar, target, current, lambda_div, steps, samples, lr, generator=None
) -> tuple[torch.Tensor, torch.Tensor]:
    """Adam (torch's update, step for step) on -J with J's gradient in closed form."""
    beta1, beta2, eps = ADAM
    closed = ClosedForm(target, current, lambda_div)
    dim = len(mean)
    params = torch.cat([mean, logvar])
    first, second = torch.zeros_like(params), torch.zeros_like(params)
    for step in range(1, steps + 1):
        noise = torch.randn(samples, dim, generator=generator, device=params.device)
        grad = -torch.cat(closed.gradient(params[:dim], params[dim:], noise))  # minimise -J
        first.mul_(beta1).add_(grad, alpha=1 - beta1)
        second.mul_(beta2).addcmul_(grad, grad, value=1 - beta2)
        denominator = (second.sqrt() / math.sqrt(1 - beta2**step)).add_(eps)
        params = params.addcdiv(first, denominator, value=-lr / (1 - beta1**step))
    return params[:dim].clone(), params[dim:].clone()
