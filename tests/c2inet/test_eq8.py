"""Eq 8's fit in closed form: its gradient is autograd's, and its fit follows the autograd one."""

import pytest
import torch

from c2inet.eq8 import ClosedForm
from c2inet.errors import InputError
from c2inet.gaussians import GaussianMixture
from c2inet.prior import PriorQueue, QueueConfig, eq8_objective


def mixture(k: int, seed: int, spread: float = 1.0) -> GaussianMixture:
    g = torch.Generator().manual_seed(seed)
    weights = torch.rand(k, generator=g) + 0.1
    return GaussianMixture(
        spread * torch.randn(k, 8, generator=g),
        0.5 * torch.randn(k, 8, generator=g) - 1,
        weights / weights.sum(),
    )


@pytest.mark.parametrize("lambda_div", [0.0, 0.1])
def test_the_closed_form_gradient_is_autograds(lambda_div):
    target, current = mixture(40, 0), mixture(6, 1)
    current.means[0] += 40.0  # a component so far that its SKL is capped: no gradient from it
    g = torch.Generator().manual_seed(2)
    mean = torch.randn(8, generator=g).requires_grad_(True)
    logvar = (0.3 * torch.randn(8, generator=g) - 1).requires_grad_(True)
    noise = torch.randn(64, 8, generator=g)
    eq8_objective(mean, logvar, noise, target, current, lambda_div).backward()
    closed = ClosedForm(target, current, lambda_div).gradient(mean.detach(), logvar.detach(), noise)
    torch.testing.assert_close(closed[0], mean.grad, rtol=1e-4, atol=1e-5)
    torch.testing.assert_close(closed[1], logvar.grad, rtol=1e-4, atol=1e-5)


def fit(kind: str, seed: int, steps: int | None = None) -> tuple[PriorQueue, tuple]:
    """A queue of 5 components and its Eq 8 fit of a new one, (mean, logvar)."""
    queue = PriorQueue(8, QueueConfig(fit=kind))
    for k, (m, lv) in enumerate(zip(mixture(5, 4).means, mixture(5, 5).logvars, strict=True)):
        queue.add(m, lv, 0.2, owner=k)
    return queue, queue.fit_component(
        mixture(64, 3), torch.Generator().manual_seed(seed), steps=steps
    )


def test_the_closed_form_fit_follows_the_autograd_fit_to_rounding():
    """Step for step to rounding (1e-5 after 100 steps). Past that the stochastic fit amplifies
    any rounding (doubling every 10 steps, as another BLAS would), so the full fits are compared
    by their objective: within 0.01 for each seed, where seeds differ by up to 0.5."""
    _, autograd = fit("autograd", 6, steps=100)
    _, closed = fit("closed", 6, steps=100)
    assert not torch.equal(autograd[0], closed[0])  # the option is live
    for a, b in zip(autograd, closed, strict=True):
        torch.testing.assert_close(b, a, rtol=0, atol=1e-4)
    noise = torch.randn(4096, 8, generator=torch.Generator().manual_seed(7))
    for seed in (2, 6):
        values = []
        for kind in ("autograd", "closed"):
            queue, pair = fit(kind, seed)
            values.append(eq8_objective(*pair, noise, mixture(64, 3), queue.mixture, 0.1).item())
        assert abs(values[0] - values[1]) < 0.01, (seed, values)


def test_an_unknown_fit_is_refused():
    with pytest.raises(InputError, match="fit 'newton': expected one of autograd, closed"):
        QueueConfig(fit="newton")
