"""The staged tuning design: plain numbers (no learner), so a preset can name its own.

Every setting is scored on the same few data draws (common random numbers: the draws are
paired across settings and methods), and every run counts towards one estimate, rather than
the minimum of noisy single draws being taken. Stage 1 puts every method's learning rate on the
same log grid (its other knobs at their defaults); each further stage moves one knob of the
method's own at the rates and values chosen so far, on a few points around its default. A stage
chooses the minimum of a parabola through the grid point of best mean and its two neighbours
(in log space for a log range), which lies between those neighbours; a best point at the
grid's edge adds a point beyond it, until the search space's bound, where the choice is marked.
The budget is per dimension: a 1-D method runs ``lr_points`` settings, a 7-D one about
``lr_points + 3 x 6``, each on ``draws`` draws, plus the chosen and the default settings once
more (what the artefact reports as their objectives).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from c2inet.errors import InputError
from c2inet.options import Choice, Tunable

EDGE = 0.05  # a choice within this share of its (log) range of a bound is marked
KEEP_RULES = ("mean", "every-draw")  # when the defaults are kept over the walk's choice


@dataclass(frozen=True)
class Design:
    """``lr_low``..``lr_high``: stage 1's log grid of ``lr_points`` learning rates, shifted by
    ``offset`` of a grid step (a second design); ``draws``: the data draws every setting is
    scored on; ``spread``: a further knob's neighbours lie this share of its (log) range either
    side of its default; ``extend``: the points a stage may add beyond its grid's edge;
    ``keep_defaults``: when the defaults, scored beside the walk's choice on the same draws, are
    kept instead of it: ``every-draw`` (lower on each draw: a tie within the draws' noise keeps
    the walk's choice, fitted through every run) or ``mean`` (a lower mean over the draws: every
    tuning shipped so far; evaluated on 10 seeds, the walk's choice beat its kept defaults for 8
    of the 11 methods the rules split, fine-tuning on traffic by 6.4 cm:
    ``docs/leaderboards/keep-every-draw/``)."""

    lr_low: float = 1e-4
    lr_high: float = 1e-2
    lr_points: int = 5
    draws: int = 2
    spread: float = 0.25
    offset: float = 0.0
    extend: int = 3
    keep_defaults: str = "every-draw"

    def __post_init__(self):
        if not 0 < self.lr_low < self.lr_high:
            raise InputError(f"design: learning rates {self.lr_low:g}..{self.lr_high:g}")
        if self.lr_points < 3 or self.draws < 1 or self.extend < 0:
            raise InputError("design: at least 3 learning rates, 1 draw and 0 extensions")
        if not 0 < self.spread <= 0.5 or not -1 < self.offset < 1:
            raise InputError("design: spread in (0, 0.5], offset in (-1, 1)")
        if self.keep_defaults not in KEEP_RULES:
            rules = ", ".join(KEEP_RULES)
            raise InputError(f"design: keep_defaults {self.keep_defaults!r}, not one of {rules}")

    def to_json(self) -> dict[str, Any]:
        """The design as an artefact names it; the ``mean`` rule unnamed, as every tuning made
        before the rule was an option has it (so an artefact without the word is read as
        ``mean``, and its resumed tuning is the same design)."""
        plain = asdict(self)
        if plain["keep_defaults"] == "mean":
            del plain["keep_defaults"]
        return {"kind": "staged", **plain}

    def keeps_defaults(self, defaults: list[float], chosen: list[float]) -> bool:
        """Whether the defaults' scores on the draws beat the walk's choice's under this rule;
        a NaN (a diverged run) never beats and is always beaten."""
        if not all(math.isfinite(d) for d in defaults):
            return False
        if not all(math.isfinite(c) for c in chosen):
            return True
        if self.keep_defaults == "every-draw":
            return all(d < c for d, c in zip(defaults, chosen, strict=True))
        return float(np.mean(defaults)) < float(np.mean(chosen))

    def shifted(self, offset: float = 0.5) -> Design:
        """The same design with its grids moved by ``offset`` of a step: a second design."""
        return Design(**{**asdict(self), "offset": offset})

    def keeping(self, rule: str) -> Design:
        """The same design with ``rule`` for when the defaults are kept."""
        return Design(**{**asdict(self), "keep_defaults": rule})

    def first_points(self, key: str, space: Tunable | Choice, default: Any) -> list[Any]:
        """A stage's first grid: the learning rate's log grid, or a knob's default and its two
        neighbours (every value of a choice)."""
        if isinstance(space, Choice):
            return list(space.values)
        if key == "train.lr":
            low, high = math.log10(self.lr_low), math.log10(self.lr_high)
            step = (high - low) / (self.lr_points - 1)
            xs = [low + (i + self.offset) * step for i in range(self.lr_points)]
            return _points(space, xs)
        x, width = _coordinate(space, default), self.spread * _width(space)
        centre = x + self.offset * width
        return _points(space, [centre - width, centre, centre + width])

    def grid_runs(self, space: dict[str, Tunable | Choice]) -> int:
        """The runs the grids of a method of search ``space`` ask: its learning rates, then
        each further knob's first grid less the point it shares with the settings so far, on
        every draw. An estimate's count: the defaults, a stage that extends its grid and a
        choice fitted between its points each add a run a draw."""
        points = 0
        for key, dim in space.items():
            if key == "train.lr":
                points += self.lr_points
            else:
                points += len(dim.values) - 1 if isinstance(dim, Choice) else 2
        return points * self.draws

    def beyond(self, space: Tunable | Choice, points: list[Any], low_side: bool) -> Any | None:
        """One point past the grid's ``low_side`` (or high) edge at the grid's spacing, clipped
        to the search space; None where the edge is already the space's bound."""
        if isinstance(space, Choice) or len(points) < 2:
            return None
        xs = sorted(_coordinate(space, p) for p in points)
        bound = _coordinate(space, space.low if low_side else space.high)
        edge = xs[0] if low_side else xs[-1]
        if math.isclose(edge, bound, abs_tol=1e-12):
            return None
        step = (xs[1] - xs[0]) if low_side else (xs[-1] - xs[-2])
        x = max(edge - step, bound) if low_side else min(edge + step, bound)
        new = _points(space, [x])
        return new[0] if new and new[0] not in points else None


def _coordinate(space: Tunable, value: float) -> float:
    return math.log10(value) if space.log else float(value)


def _width(space: Tunable) -> float:
    return _coordinate(space, space.high) - _coordinate(space, space.low)


def _points(space: Tunable, xs: list[float]) -> list[Any]:
    """Coordinates back to values, clipped into the range, rounded for an integer knob,
    without repeats, in order."""
    lo, hi = _coordinate(space, space.low), _coordinate(space, space.high)
    out: list[Any] = []
    for x in sorted(min(max(x, lo), hi) for x in xs):
        value = 10**x if space.log else x
        value = int(round(value)) if space.integer else float(value)
        if value not in out:
            out.append(value)
    return out


def near_bound(space: Tunable | Choice, value: Any) -> str | None:
    """``low`` or ``high`` where ``value`` lies within 5 % of its range (log range for a log
    knob) of that bound of ``space``; None inside, for a choice, and at a floor of 0 on a
    linear range (no free bits, no floor: a setting in its own right, not a range cut short)."""
    if isinstance(space, Choice) or isinstance(value, bool):
        return None
    share = (_coordinate(space, value) - _coordinate(space, space.low)) / _width(space)
    if share <= EDGE:
        return None if not space.log and space.low == 0 else "low"
    return "high" if share >= 1 - EDGE else None


def choose(space: Tunable | Choice, means: dict[Any, float]) -> tuple[Any, str]:
    """A stage's choice from the mean objective of each of its points: the minimum of the
    parabola through the best point and its two neighbours (between those neighbours, so a
    noisy grid cannot throw it far), the best point itself at an edge, where a neighbour
    diverged, or for a choice; returns the value and how it was found."""
    finite = {v: m for v, m in means.items() if math.isfinite(m)}
    if not finite:
        first = next(iter(means))
        return first, "every point diverged: the first kept"
    best = min(finite, key=lambda v: (finite[v], str(v)))
    if isinstance(space, Choice):
        return best, "the best mean"
    order = sorted(means, key=lambda v: _coordinate(space, v))
    i = order.index(best)
    if i in (0, len(order) - 1):
        return best, "the best mean, at the grid's edge"
    neighbours = order[i - 1 : i + 2]
    if not all(math.isfinite(means[v]) for v in neighbours):
        return best, "the best mean (a neighbour diverged)"
    xs = np.array([_coordinate(space, v) for v in neighbours])
    ys = np.array([means[v] for v in neighbours])
    a, b, _ = np.polyfit(xs, ys, 2)
    x = float(np.clip(-b / (2 * a), xs[0], xs[2])) if a > 0 else float(xs[1])
    value = _points(space, [x])[0]
    return value, "the parabola's minimum through the best point and its neighbours"
