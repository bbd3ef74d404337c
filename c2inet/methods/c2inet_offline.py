"""C2INet-offline (Li et al. 2024, Algorithm 1, offline mode; method notes 3.3): a task's prior
components come from clustering its data instead of boosting.

At the first epoch of a task the posterior means of Q(C|X) over S of its agents are clustered by
k-means (``clusters``, 5 by default, GCRL's number of environments); each cluster joins the
queue as N(centre, within-cluster variance + mean posterior variance), weighted by its size
within the task's share 1/t (earlier tasks keep (t-1)/t; uniform with ``weight_opt=false``).
Every ``interval`` epochs the task's components are refined, as the offline mode "optimises the
existing components": one k-means pass started from the current centres on the current
encoder's posteriors re-estimates them in place. Pruning, anchors and the loss are C2INet-online's.
Hooks: ``before_task``, ``after_epoch``, ``after_task``. Example: ``--methods c2inet-offline``
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from sklearn.cluster import KMeans

from c2inet.methods.base import TaskContext
from c2inet.methods.c2inet_online import C2INetOnline, C2INetOptions
from c2inet.options import require
from c2inet.prior import GaussianMixture


@dataclass(frozen=True)
class C2INetOfflineOptions(C2INetOptions):
    clusters: int = 5  # k of the k-means over a task's posterior means

    def __post_init__(self):
        super().__post_init__()
        require(self, 1, "clusters", high=100)


class C2INetOffline(C2INetOnline):
    """C2INet with a task's prior components found by k-means over its posteriors."""

    name = "c2inet-offline"
    Options = C2INetOfflineOptions

    def _cluster(self, ctx: TaskContext, centres: np.ndarray | None) -> None:
        """Set the task's components from k-means of its current posteriors (from ``centres``,
        or from k-means++ seeded by the task's generator)."""
        mean, logvar = self._current_posterior(ctx)
        points = mean.numpy().astype(np.float64)
        k = min(self.options.clusters, len(np.unique(points, axis=0)))
        if centres is not None and len(centres) == k:
            kmeans = KMeans(k, init=centres, n_init=1).fit(points)
        else:
            kmeans = KMeans(k, n_init=1, random_state=int(ctx.rng.integers(2**31))).fit(points)
        labels = torch.from_numpy(kmeans.labels_)
        means, logvars, sizes = [], [], []
        for j in range(k):
            member = labels == j
            centre = mean[member].mean(0)
            spread = ((mean[member] - centre) ** 2).mean(0) + logvar[member].exp().mean(0)
            means.append(centre)
            logvars.append(spread.clamp_min(1e-6).log())
            sizes.append(float(member.sum()))
        self._enqueue(ctx, torch.stack(means), torch.stack(logvars), torch.tensor(sizes))

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
        self._cluster(ctx, None)

    def after_epoch(self, ctx: TaskContext, epoch: int) -> None:
        if (epoch + 1) % self.options.interval == 0:
            queue = ctx.model.queue
            mine = [i for i, owner in enumerate(queue.owners) if owner == ctx.index]
            self._cluster(ctx, queue.mixture.means[mine].numpy().astype(np.float64))
