"""C2INet-online (Li et al. 2024, Algorithm 1): a continually grown mixture prior over C.

At the first epoch of a task, S samples of the task build an initial prior component (their
moment-matched aggregated posterior) that joins the queue; every ``interval`` epochs a new
component is fitted by the boosting step (Eq 8) against the target
T = (t-1)/t * M_old + 1/t * Q_cur and weighted by Eq 9, each task's share of the weights kept
within [0.5/t, 2/t] (``mass_bounds``); after the task the queue is pruned to ``capacity`` (Eq 10
criterion). The training loss is Eq 10 (``C2INetModel.loss``), its KL taken against the whole
mixture (Eq 17), or against the task's own components with BooVAE's ``task_kl``.

BooVAE's additions, each its own switch: after each task, anchors are drawn from that task's
components (z ~ N(0, I), c ~ its components, and the pseudo-input the past decoder makes of
them); while later tasks train, the model's loss holds the decoder to what it predicted at the
anchors (``distill_decoder``) and Q(C|X) at the pseudo-inputs to what it was
(``distill_encoder``, symmetric KL). ``divergence=false`` switches off the paper's diversity
term alone (Table 4). Hooks: ``before_task``, ``after_epoch``, ``after_task``.
Example: ``--methods c2inet-online``
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import torch

from c2inet.anchors import Anchors, anchors_from_windows, make_anchors
from c2inet.batch import make_batch
from c2inet.gaussians import GaussianMixture, mix, moment_match
from c2inet.methods.base import Method, TaskContext
from c2inet.model import C2INetModel
from c2inet.model_config import C2INET_SPACE
from c2inet.options import require
from c2inet.prior import QueueConfig

TARGET_COMPONENTS = 256


@dataclass(frozen=True)
class C2INetOptions(QueueConfig):
    """The queue's switches and sizes, plus the schedule of Algorithm 1."""

    interval: int = 2  # |E|: epochs between new components (11 a task at 20 epochs: pruning runs)
    samples: int = 1000  # S: agents sampled for the initial prior and the targets
    # the upper bound of issue 61, not the method: no growth or pruning; after each task its
    # components are replaced by one, its trained posterior moment-matched, frozen, every task
    # weighing the same (score old tasks with the ``own`` rule: C from the true task's component)
    oracle: bool = False

    def __post_init__(self):
        super().__post_init__()
        require(self, 1, "interval", "samples")


class C2INetOnline(Method):
    """C2INet with the online prior queue (Algorithm 1)."""

    name = "c2inet-online"
    search_space = C2INET_SPACE
    Options = C2INetOptions
    # its two ways into training, each required to act: the KL of C against the queue's mixture
    # (Eq 17), and the anchors that hold the decoder and Q(C|X) to the past components
    inert = [{"eq17": False}, {"distill_decoder": False, "distill_encoder": False}]

    def __init__(self, model_config, options: dict[str, Any] | None = None):
        super().__init__(model_config, options)
        queue_fields = QueueConfig.__dataclass_fields__
        self.queue_config = QueueConfig(
            **{k: v for k, v in asdict(self.options).items() if k in queue_fields}
        )
        self.old: GaussianMixture | None = None
        self.sample_scenes = None
        self.queue_sizes: list[int] = []
        self.pruned: list[int] = []  # components removed after each task

    def build_model(self) -> torch.nn.Module:
        return C2INetModel(self.model_config, self.queue_config)

    def _current_posterior(self, ctx: TaskContext) -> tuple[torch.Tensor, torch.Tensor]:
        """Q(C|X) of the sampled scenes under the current encoder, one row per agent.

        A C per scene is repeated per agent: scenes weigh by their agents, as S counts agents.
        """
        batch = make_batch(ctx.train, self.sample_scenes, ctx.device)
        with torch.no_grad():
            post = ctx.model.posteriors(batch)
        mean, logvar = post.c_mean, post.c_logvar
        if ctx.model.c_per_scene:
            mean, logvar = mean[batch.scene_of], logvar[batch.scene_of]
        return mean[: self.options.samples], logvar[: self.options.samples]

    def _target(
        self, ctx: TaskContext, mean: torch.Tensor, logvar: torch.Tensor
    ) -> GaussianMixture:
        """T = (t-1)/t * M_old + 1/t * Q_cur, with Q_cur from the first TARGET_COMPONENTS
        posteriors (the same density at a fraction of the cost)."""
        mean, logvar = mean[:TARGET_COMPONENTS], logvar[:TARGET_COMPONENTS]
        current = GaussianMixture(mean, logvar, mean.new_full((len(mean),), 1 / len(mean)))
        t = ctx.index + 1
        return current if t == 1 else mix([self.old, current], [(t - 1) / t, 1 / t])

    def _sample(self, ctx: TaskContext) -> None:
        """Draw the scenes holding the task's S sampled agents."""
        agents_per_scene = max(1.0, ctx.train.agents_per_scene.mean())
        scenes = min(len(ctx.train), int(self.options.samples / agents_per_scene) + 1)
        self.sample_scenes = ctx.rng.choice(len(ctx.train), scenes, replace=False)

    def before_task(self, ctx: TaskContext) -> None:
        self._sample(ctx)
        queue = ctx.model.queue
        self.old = queue.mixture.detached()
        posteriors = self._current_posterior(ctx)
        mean, logvar = moment_match(*posteriors)
        t = ctx.index + 1
        if t == 1:
            queue.reset(mean, logvar, owner=ctx.index)
            return
        weight = 1 / t
        if self.queue_config.weight_opt:
            weight = queue.fit_weight(mean, logvar, self._target(ctx, *posteriors))
        queue.add(mean, logvar, weight, owner=ctx.index)

    def after_epoch(self, ctx: TaskContext, epoch: int) -> None:
        if self.options.oracle or (epoch + 1) % self.options.interval:
            return
        queue = ctx.model.queue
        target = self._target(ctx, *self._current_posterior(ctx))
        mean, logvar = queue.fit_component(target)
        queue.add(mean, logvar, queue.fit_weight(mean, logvar, target), owner=ctx.index)

    def after_task(self, ctx: TaskContext) -> None:
        model = ctx.model
        queue = model.queue
        self.pruned.append(0 if self.options.oracle else len(queue.prune()))
        if self.options.oracle:
            self._freeze_oracle(ctx)
        self.queue_sizes.append(len(queue))
        hold = self.queue_config.distill_decoder or self.queue_config.distill_encoder
        if hold and ctx.index in queue.owners:  # pruning may remove all of a task's components
            components, count = queue.task_mixture(ctx.index), self.options.anchors
            if self.queue_config.anchor_inputs == "windows":
                new = anchors_from_windows(model, ctx.train, components, count)
            else:
                new = make_anchors(model, components, count)
            model.anchors = new if model.anchors is None else Anchors.concat([model.anchors, new])

    def _freeze_oracle(self, ctx: TaskContext) -> None:
        """The oracle's queue after task t: its components one per task, this task's the
        moment-matched posterior of its sampled agents under the trained encoder, the others
        as their tasks left them, every task weighing 1/t."""
        queue = ctx.model.queue
        for index in reversed([i for i, o in enumerate(queue.owners) if o == ctx.index]):
            if len(queue.owners) > 1:
                queue.remove(index)
        mean, logvar = moment_match(*self._current_posterior(ctx))
        if queue.owners == [ctx.index]:  # the first task: its start component replaced
            queue.reset(mean, logvar, owner=ctx.index)
        else:
            queue.add(mean, logvar, 0.5, owner=ctx.index)
        weights = queue.mixture.weights
        queue.mixture.weights = torch.full_like(weights, 1 / len(weights))

    def state_dict(self, model: torch.nn.Module) -> dict[str, Any]:
        return {
            "queue": model.queue.state_dict(),
            "queue_sizes": list(self.queue_sizes),
            "pruned": list(self.pruned),
            "anchors": None if model.anchors is None else model.anchors.state_dict(),
        }

    def load_state_dict(self, state: dict[str, Any], model: torch.nn.Module) -> None:
        model.queue.load_state_dict(state["queue"])
        self.queue_sizes, self.pruned = list(state["queue_sizes"]), list(state["pruned"])
        anchors = state["anchors"]
        model.anchors = None if anchors is None else Anchors.from_state(anchors)

    def summary(self) -> dict[str, Any]:
        return {
            "queue_size": self.queue_sizes[-1] if self.queue_sizes else 0,
            "pruned": self.pruned[-1] if self.pruned else 0,
        }
