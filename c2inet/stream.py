"""Learning from a stream without given task boundaries: chunks of windows, one after another.

A :class:`StreamLearner` trains a method on each chunk as it arrives and can be evaluated at any
moment. The method's task hooks (``before_task``, ``after_task``: where EWC, SI, LwF, the replay
memories and C2INet's queue do their work) run only at the boundaries the caller declares, for
instance those a :class:`ShiftDetector` finds in the data; between two boundaries the chunks form
one segment, which the hooks see as one task (``ctx.train`` is the chunk at hand). A method whose
``needs_boundaries`` is true gets nothing from those hooks on a stream without boundaries.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from c2inet.data import Windows
from c2inet.diagnostics import observed_features
from c2inet.evaluation import evaluate, sample_predictions
from c2inet.methods.base import Method, TaskContext
from c2inet.trainer import TrainConfig, start_training, train_epoch

# observed_features' mean speed, heading change, agent count and smallest neighbour distance
FEATURES = [2, 5, 6, 9]


class StreamLearner:
    """One method, one model, trained chunk by chunk (``config.epochs`` passes over each)."""

    def __init__(self, method: Method, config: TrainConfig):
        self.method, self.config = method, config
        self.model, self.optimiser, self.rng = start_training(method, config)
        self.ctx: TaskContext | None = None
        self.boundaries: list[int] = []  # chunk indices that opened a segment
        self.seen: list[Windows] = []  # earlier chunks, kept only for ``sees_old_tasks`` (joint)
        self.chunks = 0

    def learn(self, chunk: Windows, boundary: bool = False) -> None:
        """Train on ``chunk``. The first chunk, and any with ``boundary``, first ends the open
        segment (``after_task``) and starts a new one (``before_task``)."""
        if self.ctx is None or boundary:
            self.end_segment()
            self.ctx = TaskContext(
                len(self.boundaries), f"segment {len(self.boundaries)}", chunk, self.model,
                self.optimiser, self.rng,
            )  # fmt: skip
            self.boundaries.append(self.chunks)
            if self.method.trains:
                self.model.train()
                self.method.before_task(self.ctx)
        self.ctx.train, self.ctx.seen_train = chunk, self.seen
        self.chunks += 1
        if self.method.sees_old_tasks:
            self.seen = [*self.seen, chunk]
        if not self.method.trains:
            return
        self.model.train()
        data = self.method.training_windows(self.ctx)
        for epoch in range(self.config.epochs):
            train_epoch(self.method, self.ctx, data, self.config)
            self.method.after_epoch(self.ctx, epoch)

    def end_segment(self) -> None:
        """Run the open segment's ``after_task`` (nothing when none is open)."""
        if self.ctx is not None and self.method.trains:
            self.method.after_task(self.ctx)
        self.ctx = None

    def evaluate(self, windows: Windows, seed: int) -> dict[str, float]:
        """The model's metrics on ``windows`` now (best of ``config.k``), reproducible."""
        return evaluate(self.model, windows, self.config.k, seed, self.config.eval_batch_scenes)

    def disagreement(self, windows: Windows, seed: int) -> float:
        """How far the model's samples spread: the mean over agents of the standard deviation
        of their ``config.k`` sampled final positions (metres), a label-free uncertainty."""
        samples = sample_predictions(self.model, windows, self.config.k, seed)  # (K, T, N, 2)
        final = samples[:, -1]  # (K, N, 2)
        return float(np.sqrt(final.var(axis=0).sum(axis=-1)).mean())


@dataclass
class ShiftDetector:
    """Declares a boundary when the scenes of a chunk move differently from those of the chunk
    that opened the segment: some per-scene feature of what the model observes (``FEATURES`` of
    :func:`c2inet.diagnostics.observed_features`) whose mean changed by more than ``threshold``
    (relative) and by more than ``z`` standard errors (so that sampling noise of small chunks
    does not fire it).

    It looks at the data only: gradual drift yields a boundary each time the accumulated change
    passes the threshold, an abrupt shift one at once.
    """

    threshold: float = 0.15
    z: float = 3.0
    floor: float = 1e-3  # feature means smaller than this count as this, not as zero
    reference: np.ndarray | None = field(default=None, repr=False)

    def __call__(self, chunk: Windows) -> bool:
        features = observed_features(chunk)[:, FEATURES]
        features[features < 0] = np.nan  # -1: a lone agent has no neighbour distance
        if self.reference is None:
            self.reference = features
            return False
        for new, old in zip(features.T, self.reference.T, strict=True):
            new, old = new[np.isfinite(new)], old[np.isfinite(old)]
            if len(new) < 2 or len(old) < 2:
                continue
            change = abs(new.mean() - old.mean())
            error = np.sqrt(new.var(ddof=1) / len(new) + old.var(ddof=1) / len(old))
            if (
                change > self.threshold * max(abs(old.mean()), self.floor)
                and change > self.z * error
            ):
                self.reference = features
                return True
        return False
