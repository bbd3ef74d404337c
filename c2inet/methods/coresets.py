"""Coresets: replay a fixed-size random buffer of scenes from every past task.

After each task a random subset of ``per_task`` (default 30) of its training scenes joins the
buffer; later tasks train on their own scenes plus the buffer (BooVAE's ``add_coreset``).
Hooks: ``training_windows``, ``after_task``. Example: ``--methods coresets``
"""

from dataclasses import dataclass
from typing import Any

from c2inet.data import Windows
from c2inet.methods.base import Method, TaskContext
from c2inet.options import require


@dataclass(frozen=True)
class CoresetOptions:
    per_task: int = 30  # scenes kept from every finished task

    def __post_init__(self):
        require(self, 0, "per_task")


class Coresets(Method):
    """Replay of a random buffer of scenes from every finished task."""

    name = "coresets"
    Options = CoresetOptions

    def __init__(self, model_config, options: dict[str, Any] | None = None):
        super().__init__(model_config, options)
        self.buffer: list[Windows] = []

    @classmethod
    def replay_options(cls, scenes: int, tasks: int) -> dict[str, Any]:
        """The last task replays what the ``tasks - 1`` before it kept: ``scenes`` in all."""
        return {"per_task": max(1, scenes // max(1, tasks - 1))}

    def training_windows(self, ctx: TaskContext) -> Windows:
        return Windows.concat([ctx.train, *self.buffer])

    def after_task(self, ctx: TaskContext) -> None:
        count = min(self.options.per_task, len(ctx.train))
        if count:
            kept = ctx.rng.choice(len(ctx.train), count, replace=False)
            self.buffer.append(ctx.train.subset(kept))

    def state_dict(self, model) -> dict[str, Any]:
        return {"buffer": [w.state_dict() for w in self.buffer]}

    def load_state_dict(self, state: dict[str, Any], model) -> None:
        self.buffer = [Windows.from_state(w) for w in state["buffer"]]

    def summary(self) -> dict[str, Any]:
        return {"buffer_scenes": sum(len(w) for w in self.buffer)}
