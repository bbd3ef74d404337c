"""The prior queue: densities, weights, Eq 8 / Eq 9 fits, pruning, the symmetric KL."""

import math

import pytest
import torch

from c2inet.gaussians import (
    GaussianMixture,
    gaussian_log_prob,
    mix,
    moment_match,
    pairwise_log_prob,
    responsibilities,
    symmetric_kl,
)
from c2inet.prior import PriorQueue, QueueConfig, bounded_task_mass


def random_mixture(k=4, d=3, seed=0) -> GaussianMixture:
    g = torch.Generator().manual_seed(seed)
    w = torch.rand(k, generator=g) + 0.1
    return GaussianMixture(
        torch.randn(k, d, generator=g) * 2, torch.randn(k, d, generator=g) * 0.3, w / w.sum()
    )


def test_log_density_matches_a_brute_force_sum():
    m = random_mixture()
    x = torch.randn(7, 3)
    brute = torch.zeros(7)
    for k in range(len(m)):
        var = m.logvars[k].exp()
        density = torch.exp(-0.5 * ((x - m.means[k]) ** 2 / var).sum(-1)) / torch.sqrt(
            (2 * math.pi * var).prod()
        )
        brute += m.weights[k] * density
    torch.testing.assert_close(m.log_prob(x), brute.log(), rtol=1e-5, atol=1e-5)


def test_log_density_is_finite_far_from_every_component():
    m = random_mixture()
    assert torch.isfinite(m.log_prob(torch.full((2, 3), 1e3))).all()


@pytest.mark.parametrize("spread", [1.0, 300.0])
def test_pairwise_log_density_is_the_broadcast_one_with_its_gradient(spread):
    """The matrix-product form gives every point's log density under every Gaussian as the
    broadcast one does in float64, gradient included, also for sharp components far from 0
    (spread 300, std 0.02), where float32 sums of its terms would cancel to within a nat."""
    g = torch.Generator().manual_seed(1)
    means = (torch.randn(40, 4, generator=g) * spread).requires_grad_()
    logvars = torch.full((40, 4), -8.0).requires_grad_()
    x = (means.detach()[None] + 0.02 * torch.randn(3, 40, 4, generator=g)).requires_grad_()
    weight = torch.randn(3, 40, 40, generator=g, dtype=torch.float64)
    fast = pairwise_log_prob(x, means, logvars)
    exact = [t.detach().double().requires_grad_() for t in (x, means, logvars)]
    slow = gaussian_log_prob(exact[0].unsqueeze(-2), *exact[1:])
    assert fast.dtype == torch.float32 and fast.shape == slow.shape == (3, 40, 40)
    torch.testing.assert_close(fast.double(), slow, rtol=1e-6, atol=1e-4)
    gradients = torch.autograd.grad((fast * weight).sum(), [x, means, logvars])
    for a, b in zip(gradients, torch.autograd.grad((slow * weight).sum(), exact), strict=True):
        torch.testing.assert_close(a.double(), b, rtol=1e-5, atol=1e-3)


def test_weights_sum_to_one_after_adds_and_removes():
    q = PriorQueue(3)
    q.reset(torch.zeros(3), torch.zeros(3))
    for k in range(5):
        q.add(torch.full((3,), float(k)), torch.zeros(3), new_weight=0.2 + 0.1 * k, owner=k)
        assert q.mixture.weights.sum().item() == pytest.approx(1.0)
    q.remove(2)
    assert len(q) == 5 and q.mixture.weights.sum().item() == pytest.approx(1.0)
    assert q.owners == [0, 0, 2, 3, 4]
    uniform = PriorQueue(3, QueueConfig(weight_opt=False))
    uniform.reset(torch.zeros(3), torch.zeros(3))
    uniform.add(torch.ones(3), torch.zeros(3), new_weight=0.9, owner=1)
    assert uniform.mixture.weights.tolist() == [0.5, 0.5]


def test_pruning_keeps_at_most_capacity_and_drops_the_redundant_component():
    q = PriorQueue(2, QueueConfig(capacity=3))
    q.reset(torch.tensor([0.0, 0.0]), torch.zeros(2))
    q.add(torch.tensor([10.0, 0.0]), torch.zeros(2), 0.4, owner=1)
    q.add(torch.tensor([0.0, 10.0]), torch.zeros(2), 0.3, owner=2)
    q.add(torch.tensor([0.01, 0.0]), torch.zeros(2), 0.2, owner=3)  # a near copy of the first
    removed = q.prune(torch.Generator().manual_seed(0))
    assert len(q) == 3 and len(removed) == 1 and removed[0] in (0, 3)
    assert len(q.owners) == 3 and q.owners[1:] in ([1, 2], [2, 3])
    off = PriorQueue(2, QueueConfig(capacity=1, pruning=False))
    off.reset(torch.zeros(2), torch.zeros(2))
    off.add(torch.ones(2), torch.zeros(2), 0.5, owner=1)
    assert off.prune() == [] and len(off) == 2


def test_eq9_weight_scores_at_least_as_well_as_one_half():
    q = PriorQueue(2)
    q.reset(torch.tensor([-2.0, 0.0]), torch.zeros(2))
    new_mean, new_logvar = torch.tensor([2.0, 0.0]), torch.zeros(2)
    target = GaussianMixture(
        torch.tensor([[-2.0, 0.0], [2.0, 0.0]]), torch.zeros(2, 2), torch.tensor([0.2, 0.8])
    )
    g = torch.Generator().manual_seed(1)
    weight = q.fit_weight(new_mean, new_logvar, target, g)
    samples = target.sample(4000, torch.Generator().manual_seed(2))

    def objective(w):
        return torch.logaddexp(
            math.log(1 - w) + q.log_prob(samples),
            math.log(w) + gaussian_log_prob(samples, new_mean, new_logvar),
        ).mean()

    assert objective(weight) >= objective(0.5)
    assert weight == pytest.approx(0.8, abs=0.05)


def test_eq8_component_goes_where_the_target_is_poorly_covered():
    q = PriorQueue(2, QueueConfig(fit_steps=300))
    q.reset(torch.tensor([0.0, 0.0]), torch.zeros(2))
    target = mix(
        [q.mixture, GaussianMixture(torch.tensor([[4.0, 4.0]]), torch.zeros(1, 2), torch.ones(1))],
        [0.5, 0.5],
    )
    torch.manual_seed(0)
    mean, _ = q.fit_component(target, torch.Generator().manual_seed(0))
    assert torch.linalg.norm(mean - torch.tensor([4.0, 4.0])) < 1.0


def test_symmetric_kl_is_symmetric_non_negative_and_zero_on_equals():
    a, b = random_mixture(2, 4, seed=3), random_mixture(2, 4, seed=4)
    ab = symmetric_kl(a.means[0], a.logvars[0], b.means[1], b.logvars[1])
    ba = symmetric_kl(b.means[1], b.logvars[1], a.means[0], a.logvars[0])
    assert ab.item() == pytest.approx(ba.item()) and ab.item() > 0
    assert symmetric_kl(a.means[0], a.logvars[0], a.means[0], a.logvars[0]).item() == pytest.approx(
        0.0, abs=1e-6
    )
    assert random_mixture().mean_pairwise_skl().item() >= 0


def test_training_prior_is_the_whole_mixture_unless_task_kl():
    q = PriorQueue(1, QueueConfig(mass_bounds=False))
    assert q.training_prior() is q.mixture  # N(0, I) before any task
    q.reset(torch.zeros(1), torch.zeros(1), owner=0)
    q.add(torch.full((1,), 5.0), torch.zeros(1), 0.5, owner=1)
    q.add(torch.full((1,), 7.0), torch.zeros(1), 0.2, owner=1)
    assert len(q.training_prior()) == 3  # Eq 17: the whole mixture
    per_task = PriorQueue(1, QueueConfig(task_kl=True))
    per_task.mixture, per_task.owners = q.mixture, q.owners
    newest = per_task.training_prior()
    assert newest.means.flatten().tolist() == [5.0, 7.0]
    assert newest.weights.sum().item() == pytest.approx(1.0)
    state = q.state_dict()
    again = PriorQueue(1)
    again.load_state_dict(state)
    assert again.owners == [0, 1, 1]


def test_task_mass_is_bounded_and_inner_weights_kept():
    weights = torch.tensor([0.02, 0.03, 0.05, 0.6, 0.3])  # task 0 holds 0.1 of 3 tasks
    owners = [0, 0, 1, 2, 2]
    bounded = bounded_task_mass(weights, owners)
    mass = [bounded[[i for i, o in enumerate(owners) if o == t]].sum().item() for t in range(3)]
    assert sum(mass) == pytest.approx(1.0)
    assert all(0.5 / 3 - 1e-4 <= m <= 2 / 3 + 1e-4 for m in mass)
    assert mass[0] > 0.1  # the starved task got mass back
    assert (bounded[0] / bounded[1]).item() == pytest.approx(2 / 3)  # inside a task: as fitted
    fine = torch.tensor([0.3, 0.3, 0.4])
    torch.testing.assert_close(bounded_task_mass(fine, [0, 1, 2]), fine)  # in bounds: untouched


def test_queue_add_keeps_every_task_within_its_bounds():
    q = PriorQueue(1)
    q.reset(torch.zeros(1), torch.zeros(1), owner=0)
    for task in (1, 2, 3):
        for _ in range(3):  # each new component takes 0.9: the newest task would hold 0.999
            q.add(torch.full((1,), float(task)), torch.zeros(1), 0.9, owner=task)
    owners = torch.tensor(q.owners)
    for task in range(4):
        mass = q.mixture.weights[owners == task].sum().item()
        assert 0.5 / 4 - 1e-4 <= mass <= 2 / 4 + 1e-4


def test_responsibilities_are_the_exact_posterior_over_components():
    mixture = random_mixture()
    mean, logvar = torch.randn(5, 3), torch.randn(5, 3) * 0.3 - 1
    exact = responsibilities(mixture, mean, logvar)
    torch.manual_seed(0)  # Monte Carlo: E_{c ~ Q}[w_k N(c; m_k, s_k)], normalised
    c = mean + (0.5 * logvar).exp() * torch.randn(200_000, 5, 3)
    per = gaussian_log_prob(c[..., None, :], mixture.means, mixture.logvars).exp()
    mc = (per * mixture.weights).mean(0)
    torch.testing.assert_close(exact, mc / mc.sum(-1, keepdim=True), atol=0.01, rtol=0.05)


def test_moment_match_of_two_gaussians():
    mean, logvar = moment_match(torch.tensor([[-1.0], [1.0]]), torch.zeros(2, 1))
    assert mean.item() == pytest.approx(0.0) and logvar.exp().item() == pytest.approx(2.0)
