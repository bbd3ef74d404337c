"""Checkpoint selection within a task: the epoch whose validation error is lowest is kept.

Early stopping as the field practises it, on the current task's validation split only (never a
test split, never an earlier task's data): after every epoch the trainer offers the score, and
at the task's end the best epoch's model, optimiser and method state are put back, as if
training had stopped there.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import torch

SELECTIONS = ("last", "val")  # the epoch a task keeps: its last, or its validation-best
# what "best" means: the lowest best-of-K ADE, FDE, or their sum (both, in metres)
SELECTION_METRICS = ("ade", "fde", "ade+fde")


def selection_score(scores: dict[str, float], metric: str) -> float:
    """The number an epoch is selected by, from its validation ``scores`` (``ade``, ``fde``)."""
    if metric == "ade+fde":
        return scores["ade"] + scores["fde"]
    return scores[metric]


class BestEpoch:
    """The lowest validation score offered so far and the state it was reached in."""

    def __init__(self) -> None:
        self.score = math.inf
        self.epoch: int | None = None
        self._state: dict[str, Any] | None = None

    def offer(self, score: float, epoch: int, model: torch.nn.Module, optimiser, method) -> bool:
        """Keep a copy of the state if ``score`` beats every earlier one (a NaN never does);
        returns whether it did."""
        if not score < self.score:
            return False
        self.score, self.epoch = score, epoch
        self._state = copy.deepcopy(
            {
                "model": model.state_dict(),
                "optimiser": None if optimiser is None else optimiser.state_dict(),
                "method": method.state_dict(model),
            }
        )
        return True

    def restore(self, model: torch.nn.Module, optimiser, method) -> None:
        """Put the best epoch's state back (nothing when none was offered)."""
        if self._state is None:
            return
        model.load_state_dict(self._state["model"])
        if optimiser is not None:
            optimiser.load_state_dict(self._state["optimiser"])
        method.load_state_dict(self._state["method"], model)
