"""C2INet-offline (Li et al. 2024, Algorithm 1, offline mode; method notes 3.3): a task's prior
components come from clustering its data instead of boosting.

At the first epoch of a task the posterior means of Q(C|X) over S of its agents are clustered by
k-means (``clusters``, 5 by default, GCRL's number of environments); each cluster joins the
queue as N(centre, within-cluster variance + mean posterior variance), weighted by its size
within the task's share 1/t (earlier tasks keep (t-1)/t; uniform with ``weight_opt=false``).
Every ``interval`` epochs the task's components are refined, as Algorithm 1 (line 16) "optimises
the existing components (Eq 8, 9)": each in turn is moved by the Eq 8 objective against the
target T = (t-1)/t * M_old + 1/t * Q_cur, with the rest of the queue as M and the component
itself as the start, then reweighted by Eq 9 against that rest. The task's components share
``fit_steps`` Adam steps (online's cost per update); ``refine="kmeans"`` keeps the earlier rule
(one k-means pass from the current centres). Pruning, anchors and the loss are C2INet-online's.
Hooks: ``before_task``, ``after_epoch``, ``after_task``. Example: ``--methods c2inet-offline``
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from c2inet.errors import InputError
from c2inet.gaussians import GaussianMixture
from c2inet.lazy import lazy_module
from c2inet.methods.base import TaskContext
from c2inet.methods.c2inet_online import C2INetOnline, C2INetOptions
from c2inet.options import require
from c2inet.prior import bounded_task_mass

sk_cluster = lazy_module("sklearn.cluster")  # scikit-learn loads where k-means first runs


@dataclass(frozen=True)
class C2INetOfflineOptions(C2INetOptions):
    clusters: int = 5  # k of the k-means over a task's posterior means
    refine: str = "eq8"  # how the task's components are updated: eq8 (Eq 8 and Eq 9) | kmeans

    def __post_init__(self):
        super().__post_init__()
        require(self, 1, "clusters", high=100)
        if self.refine not in ("eq8", "kmeans"):
            raise InputError(f"refine {self.refine!r}: expected eq8 or kmeans")


class C2INetOffline(C2INetOnline):
    """C2INet with a task's prior components found by k-means over its posteriors."""

    name = "c2inet-offline"
    Options = C2INetOfflineOptions

    def _cluster(self, ctx: TaskContext, centres: np.ndarray | None) -> None:
        """Set the task's components from k-means of its current posteriors (from ``centres``,
        or from k-means++ seeded by the task's generator)."""
        mean, logvar = self._current_posterior(ctx)
        points = mean.cpu().numpy().astype(np.float64)
        k = min(self.options.clusters, len(np.unique(points, axis=0)))
        if centres is not None and len(centres) == k:
            kmeans = sk_cluster.KMeans(k, init=centres, n_init=1).fit(points)
        else:
            kmeans = sk_cluster.KMeans(k, n_init=1, random_state=int(ctx.rng.integers(2**31))).fit(
                points
            )
        labels = torch.as_tensor(kmeans.labels_, device=mean.device)
        means, logvars, sizes = [], [], []
        for j in range(k):
            member = labels == j
            centre = mean[member].mean(0)
            spread = ((mean[member] - centre) ** 2).mean(0) + logvar[member].exp().mean(0)
            means.append(centre)
            logvars.append(spread.clamp_min(1e-6).log())
            sizes.append(float(member.sum()))
        self._enqueue(ctx, torch.stack(means), torch.stack(logvars), mean.new_tensor(sizes))

    def _enqueue(self, ctx, means: torch.Tensor, logvars: torch.Tensor, sizes: torch.Tensor):
        """Replace the task's components: earlier tasks keep (t-1)/t of the mass, these 1/t."""
        queue, t = ctx.model.queue, ctx.index + 1
        keep = [i for i, owner in enumerate(queue.owners) if owner not in (-1, ctx.index)]
        old = queue.mixture
        kept = old.weights[keep]
        weights = torch.cat(
            [kept / kept.sum() * (t - 1) / t if keep else kept, sizes / sizes.sum() / t]
        )
        if not self.queue_config.weight_opt:
            weights = torch.full((len(weights),), 1 / len(weights))
        queue.mixture = GaussianMixture(
            torch.cat([old.means[keep], means]), torch.cat([old.logvars[keep], logvars]), weights
        )
        queue.owners = [queue.owners[i] for i in keep] + [ctx.index] * len(means)

    def before_task(self, ctx: TaskContext) -> None:
        self._sample(ctx)
        self.old = ctx.model.queue.mixture.detached()  # M_old of the Eq 8 target
        self._cluster(ctx, None)

    def after_epoch(self, ctx: TaskContext, epoch: int) -> None:
        if (epoch + 1) % self.options.interval:
            return
        queue = ctx.model.queue
        mine = [i for i, owner in enumerate(queue.owners) if owner == ctx.index]
        if self.options.refine == "kmeans":
            self._cluster(ctx, queue.mixture.means[mine].cpu().numpy().astype(np.float64))
            return
        target = self._target(ctx, *self._current_posterior(ctx))
        steps = max(1, self.options.fit_steps // len(mine))
        for k in mine:
            m = queue.mixture
            rest = m.without(k)
            start = (m.means[k], m.logvars[k])
            mean, logvar = queue.fit_component(target, start=start, current=rest, steps=steps)
            new = m.weights[k].item()  # uniform weights stay uniform without Eq 9
            if len(m) == 1:  # a lone component keeps all the mass
                new = 1.0
            elif self.queue_config.weight_opt:
                new = queue.fit_weight(mean, logvar, target, current=rest)
            weights = torch.cat([rest.weights[:k], rest.weights.new_zeros(1), rest.weights[k:]])
            weights = weights * (1 - new)
            weights[k] = new
            means, logvars = m.means.clone(), m.logvars.clone()
            means[k], logvars[k] = mean, logvar
            queue.mixture = GaussianMixture(means, logvars, weights)
        if self.queue_config.mass_bounds:
            queue.mixture.weights = bounded_task_mass(queue.mixture.weights, queue.owners)
