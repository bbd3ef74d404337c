"""The prior queue: a mixture of diagonal Gaussians over the confounder C, grown and pruned online.

Equation numbers follow ``c2inet-method.md``: Eq 8 fits a new component by a boosting step
against the target density T, Eq 9 fits its weight, and pruning removes the components whose loss
costs the Eq 10 objective least. Weights are stored explicitly and always sum to one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from c2inet.eq8 import fit_closed_form
from c2inet.gaussians import (
    LOG_2PI,
    GaussianMixture,
    gaussian_log_prob,
    gaussian_sample,
    symmetric_kl,
)
from c2inet.options import choose, require

FITS = ("autograd", "closed")  # how Eq 8's component fit takes its gradient
ANCHOR_INPUTS = ("decoded", "windows")  # where the anchors' pseudo-inputs come from


@dataclass(frozen=True)
class QueueConfig:
    """Switches and sizes of the prior queue (defaults from the method notes, section 5).

    Each switch changes one thing: ``divergence`` is the paper's diversity term (Table 4) alone;
    ``task_kl``, ``distill_decoder`` and ``distill_encoder`` are BooVAE's additions, off and on
    one by one.
    """

    capacity: int = 45  # gamma
    eq17: bool = True  # the training KL of C against the queue's mixture; off: against N(0, I)
    weight_opt: bool = True  # Eq 9; off: uniform weights ("average weight parameters")
    divergence: bool = True  # Table 4's switch: the symmetric-KL diversity term of Eq 8 and pruning
    pruning: bool = True
    task_kl: bool = False  # BooVAE: a task's training KL uses that task's components, not Eq 17's
    distill_decoder: bool = True  # BooVAE: hold the decoder to its outputs at old components
    distill_encoder: bool = True  # BooVAE: hold Q(C|X) to its values at old pseudo-inputs
    mass_bounds: bool = True  # keep each task's share of the weights within [0.5/t, 2/t]
    anchors: int = 64  # anchors stored per task for the two distillations
    # where the anchors' pseudo-inputs come from: the past decoder's output at the task's
    # components ("decoded", BooVAE's way; untrained unless model.beta_x > 0), or agents of the
    # task's own training windows, stored and counted as memory, each with C drawn from the
    # component most responsible for it ("windows": data-like inputs that follow the components)
    anchor_inputs: str = "decoded"
    anchor_batch: int = 32  # anchors drawn for each training step
    distill_weight: float = 1.0
    lambda_div: float = 0.1
    fit_steps: int = 200  # Adam steps of the Eq 8 component fit
    fit_samples: int = 64
    fit_lr: float = 3e-2
    fit: str = "closed"  # Eq 8's gradient in closed form (c2inet/eq8.py), or by "autograd"
    target_samples: int = 1000

    def __post_init__(self):
        require(self, 1, "capacity", "anchors", "anchor_batch", "fit_steps", "fit_samples")
        require(self, 1, "target_samples")
        require(self, 0, "distill_weight", "lambda_div")
        require(self, 0, "fit_lr", high=10, open_low=True)
        choose(self, "fit", FITS)
        choose(self, "anchor_inputs", ANCHOR_INPUTS)


def eq8_objective(mean, logvar, noise, target, current, lambda_div: float) -> torch.Tensor:
    """Eq 8's objective J at the samples mean + e^(logvar/2) * noise (see
    :meth:`PriorQueue.fit_component`), differentiable in ``mean`` and ``logvar``."""
    c = gaussian_sample(mean, logvar, noise)
    entropy = 0.5 * (1 + LOG_2PI + logvar).sum()
    log_t, log_m = target.log_prob(c), current.log_prob(c)
    objective = (2 * log_t - torch.logaddexp(log_t, log_m)).mean() + entropy
    if lambda_div:
        skl = symmetric_kl(mean, logvar, current.means, current.logvars).mean()
        objective = objective + lambda_div * skl
    return objective


def bounded_task_mass(weights: torch.Tensor, owners: list[int], rounds: int = 50) -> torch.Tensor:
    """The weights rescaled per task so that each of the t tasks holds between 0.5/t and 2/t.

    Eq 9 fits each new component's weight against a target in which the newest task has 1/t;
    fitted one by one, the newest tasks' components came to hold 0.9 of the responsibility
    (issue 22). The bound keeps Eq 17's equal task shares within a factor of two and leaves the
    weights inside a task as Eq 9 set them. Clip, renormalise, repeat: the bounds hold at the
    fixed point, which a few rounds reach.
    """
    owner = torch.tensor(owners, device=weights.device)
    tasks = owner.unique()
    tasks = tasks[tasks >= 0]
    t = len(tasks)
    if t < 2 or (owner < 0).any():  # N(0, I) before the first task belongs to no task
        return weights
    index = torch.searchsorted(tasks, owner.clamp_min(0))
    weights = weights.clone()
    for _ in range(rounds):
        mass = weights.new_zeros(t).index_add(0, index, weights)
        bounded = mass.clamp(0.5 / t, 2 / t)
        bounded = bounded / bounded.sum()
        if torch.allclose(bounded, mass, atol=1e-6):
            break
        weights = weights * (bounded / mass.clamp_min(1e-30))[index]
    return weights / weights.sum()


class PriorQueue:
    """The memory queue of prior components, with the online C2INet update rules.

    Every component remembers the task that added it (``owners``); before any task the queue
    holds N(0, I), owned by no task (-1).
    """

    def __init__(self, dim: int, config: QueueConfig | None = None):
        self.dim = dim
        self.config = config or QueueConfig()
        self.mixture = GaussianMixture(torch.zeros(1, dim), torch.zeros(1, dim), torch.ones(1))
        self.owners = [-1]

    def __len__(self) -> int:
        return len(self.mixture)

    def log_prob(self, c: torch.Tensor) -> torch.Tensor:
        return self.mixture.log_prob(c)

    def task_mixture(self, owner: int) -> GaussianMixture:
        """The components added by task ``owner``, with their weights renormalised."""
        keep = torch.tensor([o == owner for o in self.owners], device=self.mixture.weights.device)
        if not keep.any():
            raise ValueError(f"no component of task {owner} in the queue")
        m = self.mixture
        weights = m.weights[keep]
        return GaussianMixture(m.means[keep], m.logvars[keep], weights / weights.sum())

    def training_prior(self) -> GaussianMixture:
        """The prior of the training KL: the whole mixture (Eq 17), or with ``task_kl`` the
        newest task's components (BooVAE); without ``eq17``, N(0, I): the queue then reaches
        training only through the anchors."""
        if not self.config.eq17:
            zeros = self.mixture.means.new_zeros(1, self.dim)
            return GaussianMixture(zeros, zeros, zeros.new_ones(1))
        if self.config.task_kl and self.owners[-1] >= 0:
            return self.task_mixture(self.owners[-1])
        return self.mixture

    def reset(self, mean: torch.Tensor, logvar: torch.Tensor, owner: int = 0) -> None:
        """Start the queue with one component (the first task's initial prior)."""
        self.mixture = GaussianMixture(mean[None].detach(), logvar[None].detach(), mean.new_ones(1))
        self.owners = [owner]

    def add(self, mean: torch.Tensor, logvar: torch.Tensor, new_weight: float, owner: int) -> None:
        """Append a component with weight ``new_weight``; the old ones keep 1 - new_weight
        (then each task's share is bounded, with ``mass_bounds``)."""
        m = self.mixture
        weights = torch.cat([(1 - new_weight) * m.weights, m.weights.new_full((1,), new_weight)])
        if not self.config.weight_opt:
            weights = torch.full_like(weights, 1 / len(weights))
        self.mixture = GaussianMixture(
            torch.cat([m.means, mean[None].detach()]),
            torch.cat([m.logvars, logvar[None].detach()]),
            weights,
        )
        self.owners.append(owner)
        if self.config.mass_bounds:
            self.mixture.weights = bounded_task_mass(self.mixture.weights, self.owners)

    def remove(self, index: int) -> None:
        self.mixture = self.mixture.without(index)
        del self.owners[index]

    # --- Eq 8: the new component -------------------------------------------------------------
    def fit_component(
        self,
        target: GaussianMixture,
        generator: torch.Generator | None = None,
        start: tuple[torch.Tensor, torch.Tensor] | None = None,
        current: GaussianMixture | None = None,
        steps: int | None = None,
    ):
        """Eq 8: a Gaussian P fitted where the target T is poorly covered by the queue M.

        Maximises E_P[log T + log(T / (T + M))] + H[P] (+ lambda_div * mean SKL(P, P_k)), i.e.
        minimises KL(P || T r) with r = T / (T + M) in (0, 1). BooVAE's form E_P[log T/M] + H[P]
        has the same optimum direction but is unbounded for latent-space Gaussians (T/M grows
        without limit in the tails), so P would run away; the factor r keeps the target
        normalisable while still favouring regions that M misses. ``start`` (mean, logvar)
        refines an existing component against ``current`` (the queue without it), for
        ``steps`` Adam steps (default ``fit_steps``): the offline mode's update.
        """
        cfg = self.config
        current = (self.mixture if current is None else current).detached()
        if start is None:
            start = target.sample(1, generator)[0], target.logvars.mean(0)
        steps = cfg.fit_steps if steps is None else steps
        lambda_div = cfg.lambda_div if cfg.divergence else 0.0
        if cfg.fit == "closed":
            return fit_closed_form(
                *start, target, current, lambda_div, steps, cfg.fit_samples, cfg.fit_lr, generator
            )
        mean = start[0].clone().requires_grad_(True)
        logvar = start[1].clone().requires_grad_(True)
        optimiser = torch.optim.Adam([mean, logvar], lr=cfg.fit_lr)
        for _ in range(steps):
            noise = torch.randn(cfg.fit_samples, self.dim, generator=generator, device=mean.device)
            objective = eq8_objective(mean, logvar, noise, target, current, lambda_div)
            optimiser.zero_grad()
            (-objective).backward()
            optimiser.step()
        return mean.detach(), logvar.detach()

    # --- Eq 9: the weight of the new component -----------------------------------------------
    def fit_weight(
        self,
        mean: torch.Tensor,
        logvar: torch.Tensor,
        target: GaussianMixture,
        generator=None,
        current: GaussianMixture | None = None,
    ) -> float:
        """The new component's weight 1 - alpha maximising E_T[log(alpha M + (1 - alpha) P)],
        M the queue (or ``current``).

        A concave 1-D problem, solved by golden-section search on [1e-3, 1 - 1e-3].
        """
        c = target.sample(self.config.target_samples, generator)
        log_m = (self.mixture if current is None else current).log_prob(c)
        log_p = gaussian_log_prob(c, mean, logvar)

        def score(new: float) -> float:
            return torch.logaddexp(math.log(1 - new) + log_m, math.log(new) + log_p).mean().item()

        low, high = 1e-3, 1 - 1e-3
        ratio = (math.sqrt(5) - 1) / 2
        a, b = high - ratio * (high - low), low + ratio * (high - low)
        fa, fb = score(a), score(b)
        for _ in range(40):
            if fa < fb:
                low, a, fa = a, b, fb
                b = low + ratio * (high - low)
                fb = score(b)
            else:
                high, b, fb = b, a, fa
                a = high - ratio * (high - low)
                fa = score(a)
        return (low + high) / 2

    # --- pruning by the Eq 10 criterion --------------------------------------------------------
    def prune(self, generator: torch.Generator | None = None) -> list[int]:
        """Remove components until at most ``capacity`` remain; returns the removed indices.

        Each round removes the component whose deletion (with renormalised weights) lowers
        E_{c~M}[log M(c)] - lambda_div * R_div the least.
        """
        removed = []
        cfg = self.config

        def score(mixture: GaussianMixture, c: torch.Tensor) -> float:
            value = mixture.log_prob(c).mean()
            if cfg.divergence:
                value = value + cfg.lambda_div * mixture.mean_pairwise_skl()
            return value.item()

        while cfg.pruning and len(self) > cfg.capacity:
            m = self.mixture
            c = m.sample(cfg.target_samples, generator)
            full = score(m, c)
            costs = [full - score(m.without(k), c) for k in range(len(m))]
            index = min(range(len(costs)), key=costs.__getitem__)
            self.remove(index)
            removed.append(index)
        if removed and cfg.mass_bounds:
            self.mixture.weights = bounded_task_mass(self.mixture.weights, self.owners)
        return removed

    def state_dict(self) -> dict[str, torch.Tensor]:
        m = self.mixture
        owners = torch.tensor(self.owners, device=m.weights.device)
        return {"means": m.means, "logvars": m.logvars, "weights": m.weights, "owners": owners}

    def load_state_dict(self, state: dict[str, torch.Tensor]) -> None:
        self.mixture = GaussianMixture(state["means"], state["logvars"], state["weights"])
        self.owners = state["owners"].tolist()


class LearnablePrior(torch.nn.Module):
    """A mixture prior over C trained with the model, for the MoG and GCRL baselines.

    ``components`` Gaussians are parameters, learnt by the training KL; :meth:`freeze` appends
    them, fixed, to the ``frozen`` ones (MoG keeps each finished task's). Weights are learnt
    logits (GCRL) or uniform over every component (MoG). It answers what the model and the
    diagnostics ask of a :class:`PriorQueue`: ``mixture``, ``training_prior``, ``log_prob``,
    ``owners`` and ``config`` (no queue regularisers).
    """

    def __init__(self, dim: int, components: int, learn_weights: bool):
        super().__init__()
        self.means = torch.nn.Parameter(torch.randn(components, dim))
        self.logvars = torch.nn.Parameter(torch.zeros(components, dim))
        self.logits = torch.nn.Parameter(torch.zeros(components), requires_grad=learn_weights)
        self.frozen = GaussianMixture(torch.zeros(0, dim), torch.zeros(0, dim), torch.zeros(0))
        self.frozen_owners: list[int] = []
        self.owner = 0  # the task the learnt components belong to now
        self.config = QueueConfig(divergence=False, distill_decoder=False, distill_encoder=False)

    def __len__(self) -> int:
        return len(self.frozen) + len(self.means)

    @property
    def mixture(self) -> GaussianMixture:
        logits = torch.cat([self.logits.new_zeros(len(self.frozen)), self.logits])
        return GaussianMixture(
            torch.cat([self.frozen.means, self.means]),
            torch.cat([self.frozen.logvars, self.logvars.clamp(-8, 4)]),
            torch.softmax(logits, 0),
        )

    @property
    def owners(self) -> list[int]:
        return self.frozen_owners + [self.owner] * len(self.means)

    def training_prior(self) -> GaussianMixture:
        return self.mixture

    def log_prob(self, c: torch.Tensor) -> torch.Tensor:
        return self.mixture.log_prob(c)

    def freeze(self, next_owner: int) -> None:
        """Append the learnt components, fixed, to the frozen ones; learning goes on for
        ``next_owner`` from where they are."""
        means = torch.cat([self.frozen.means, self.means.detach().clone()])
        logvars = torch.cat([self.frozen.logvars, self.logvars.detach().clamp(-8, 4)])
        self.frozen = GaussianMixture(means, logvars, means.new_full((len(means),), 1 / len(means)))
        self.frozen_owners += [self.owner] * len(self.means)
        self.owner = next_owner

    def get_extra_state(self) -> dict:
        """The frozen components travel in the model's ``state_dict`` (checkpoints, resume)."""
        f = self.frozen
        return {
            "means": f.means,
            "logvars": f.logvars,
            "weights": f.weights,
            "owners": torch.tensor(self.frozen_owners, dtype=torch.int64, device=f.weights.device),
            "owner": self.owner,
        }

    def set_extra_state(self, state: dict) -> None:
        self.frozen = GaussianMixture(state["means"], state["logvars"], state["weights"])
        self.frozen_owners, self.owner = state["owners"].tolist(), int(state["owner"])
