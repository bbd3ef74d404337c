"""The generator checker (as Gymnasium's ``check_env``): generates a small domain and raises
:class:`GeneratorCheckError` naming the first broken promise.

What every generator owes the curricula: a documented, registered class with a frozen
``Knobs`` dataclass whose numeric knobs declare ranges (NaN and absurd values are refused on
construction); the same domain for the same seed and another for another seed; a memory
estimate that bounds what generation allocates; the realised statistics every report reads;
and scenes that cut into finite learner windows of the declared shape.

    from sim.generators.checker import check_generator
    check_generator(get_generator("crowd"), {"agents": 3})
"""

from __future__ import annotations

import dataclasses
import tracemalloc
from typing import Any

import numpy as np

from c2inet.data import OBS_LEN, PRED_LEN
from c2inet.errors import InputError
from sim.data import SPLITS, Domain
from sim.families import Splits
from sim.generators.base import GENERATORS, Generator

STATISTICS = ("mean_speed", "min_separation", "heading_change", "density")
SPLITS_CHECKED = Splits(train=1, val=1, test=1)  # scenes of the checker's small domains
ALLOWANCE = 64e6  # bytes of interpreter and library overhead beyond a generator's own estimate


class GeneratorCheckError(AssertionError):
    """A generator broke its contract; the message says which part and how."""


def _fail(cls: type, what: str) -> None:
    raise GeneratorCheckError(f"generator {getattr(cls, 'name', cls.__name__)!r}: {what}")


def check_contract(cls: type[Generator], registered: bool = True) -> None:
    """A documented subclass, registered under its name, with a frozen ``Knobs`` dataclass."""
    if not (isinstance(cls, type) and issubclass(cls, Generator)):
        _fail(cls, "is not a subclass of sim.generators.Generator")
    if not cls.__doc__ or not getattr(cls, "name", ""):
        _fail(cls, "needs a name and a docstring")
    if registered and GENERATORS.get(cls.name) is not cls:
        _fail(cls, "is not registered under its name")
    if cls.version < 1 or len(cls.quick_splits) != 3:
        _fail(cls, "needs version >= 1 and three quick_splits")
    knobs = getattr(cls, "Knobs", None)
    if not (dataclasses.is_dataclass(knobs) and knobs.__dataclass_params__.frozen):
        _fail(cls, "Knobs must be a frozen dataclass")


def check_ranges(cls: type[Generator], knobs: dict[str, Any]) -> None:
    """Every numeric knob refuses NaN and 1e12 on construction, with an ``InputError``."""
    cls.Knobs(**knobs)
    for field in dataclasses.fields(cls.Knobs):
        value = knobs.get(field.name, field.default)
        if isinstance(value, bool) or not isinstance(value, int | float):
            continue
        for bad in (float("nan"), 1e12):
            try:
                cls.Knobs(**{**knobs, field.name: bad})
            except InputError:
                continue
            _fail(cls, f"knob {field.name}={bad:g} is accepted: declare its range")


def _generate(cls, knobs, seed: int) -> Domain:
    """The checker's small domain from ``seed``."""
    return cls().generate("check", "check", knobs, SPLITS_CHECKED, np.random.SeedSequence(seed))


def _traced(cls, knobs, seed: int) -> tuple[Domain, int]:
    """:func:`_generate` under tracemalloc, and the bytes traced at its peak. Run after a first
    generation, so the simulator's modules are imported untraced: their memory is not the
    domain's, and importing highway-env under tracing took 8 s instead of 1."""
    tracemalloc.start()
    try:
        domain = _generate(cls, knobs, seed)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return domain, peak


def _positions(domain: Domain) -> list[np.ndarray]:
    return [scene.positions for split in SPLITS for scene in domain.scenes[split]]


def _same(a: Domain, b: Domain) -> bool:
    pa, pb = _positions(a), _positions(b)
    if len(pa) != len(pb):
        return False
    return all(np.array_equal(x, y, equal_nan=True) for x, y in zip(pa, pb, strict=True))


def check_domain(cls: type[Generator], domain: Domain) -> None:
    """Splits, statistics and windows: what curricula and reports read."""
    if not isinstance(domain, Domain) or set(domain.scenes) != set(SPLITS):
        _fail(cls, "generate must return a Domain with scenes for train, val and test")
    missing = [s for s in STATISTICS if not np.isfinite(domain.stats.get(s, np.nan))]
    if missing:
        _fail(cls, f"statistics missing or not finite: {', '.join(missing)}")
    for split in ("train", "test"):
        windows = domain.windows(split)
        if windows is None:
            _fail(cls, f"no learner windows in the {split} split")
        if windows.positions.shape[1:] != (OBS_LEN + PRED_LEN, 2):
            _fail(cls, f"windows of shape {windows.positions.shape[1:]}, expected (20, 2)")
        if not np.isfinite(windows.positions).all():
            _fail(cls, f"the {split} windows hold NaN or infinite positions")


def check_generator(
    cls: type[Generator], knobs: dict[str, Any] | None = None, registered: bool = True
) -> None:
    """Check ``cls`` on a small domain with ``knobs`` as ``generate`` takes them (a family's
    ``knobs_for``; the defaults where None); raises
    :class:`GeneratorCheckError` at the first broken promise. ``registered``: it must be
    found by name (False for a class checked before it is registered)."""
    knobs = {} if knobs is None else knobs
    check_contract(cls, registered)
    check_ranges(cls, knobs)
    first = _generate(cls, knobs, 0)
    check_domain(cls, first)
    again, peak = _traced(cls, knobs, 0)
    if not _same(first, again):
        _fail(cls, "the same seed gave another domain")
    if cls.seeded and _same(first, _generate(cls, knobs, 1)):
        _fail(cls, "another seed gave the same domain")
    estimate = cls.memory_bytes(knobs, SPLITS_CHECKED)
    if peak > estimate + ALLOWANCE:
        _fail(cls, f"allocated {peak / 1e6:.0f} MB, its memory estimate says {estimate / 1e6:.0f}")
