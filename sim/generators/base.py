"""Generator registry: a family names its generator by string, as Gymnasium ids name envs.

Every generator is a small class with a typed ``Knobs`` dataclass (which validates ranges) and a
``generate`` method returning a :class:`sim.data.Domain`; defining the class registers it, and
:func:`discover` imports every module of ``sim.generators``. ``sim.generators.checker`` checks
a generator against that contract (a test runs it over every registered one).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from c2inet.errors import InputError
from c2inet.registry import Registry
from sim.data import Domain


def _is_generator(entry: Any) -> str | None:
    if isinstance(entry, type) and issubclass(entry, Generator):
        return None
    return f"{entry!r} is not a subclass of sim.generators.base.Generator"


REGISTRY: Registry[type[Generator]] = Registry(
    "generator", "sim.generators", "sim.generators", _is_generator
)
GENERATORS = REGISTRY.entries  # name -> class


class Generator:
    """Base class: subclasses set ``name``, ``version``, ``Knobs`` and implement ``generate``."""

    name: ClassVar[str]
    version: ClassVar[int] = 1  # bump when output for the same knobs changes (cache key)
    Knobs: ClassVar[type]
    quick_splits: ClassVar[tuple[int, int, int]] = (12, 4, 6)  # train/val/test for smoke runs
    seeded: ClassVar[bool] = True  # False: the same domain whatever the seed (recordings)

    def __init_subclass__(cls, **kwargs):
        """A subclass defined in ``sim.generators`` registers under its own name; one defined
        elsewhere never registers itself (``Registry.enrol``): a plugin comes in through its
        entry point, and cannot replace a built-in."""
        super().__init_subclass__(**kwargs)
        REGISTRY.enrol(cls)

    @classmethod
    def resolve(cls, knobs: Any, base_dir: Path) -> dict[str, Any]:
        """Knobs as a plain dict; generators that read files resolve their paths here."""
        return dataclasses.asdict(knobs)

    @classmethod
    def content_key(cls, knobs: dict[str, Any]) -> dict[str, Any]:
        """What besides knobs, seed and sizes determines the output (e.g. input file hashes)."""
        return {}

    @classmethod
    def memory_bytes(cls, knobs: dict[str, Any], splits: Any) -> int:
        """About the peak memory of generating a domain, checked against the memory budget
        before anything runs (0: small whatever the knobs)."""
        return 0

    @classmethod
    def contact(cls, knobs: dict[str, Any]) -> float | None:
        """Two bodies' centre distance at contact in metres, where the simulator knows it (the
        collision rate at the bodies' own size is scored beside TrajNet++'s 0.2 m), else None."""
        return None

    def rollout(self, knobs: dict[str, Any], seed: np.random.SeedSequence, frames: int):
        """One longer episode of the domain (a :class:`sim.data.Scene`) for playback, or None."""
        return None

    def generate(
        self,
        name: str,
        family: str,
        knobs: dict[str, Any],
        splits: Any,
        seed: np.random.SeedSequence,
        workers: int = 1,
    ) -> Domain:
        """The domain's scenes per split, with its realised statistics; ``workers`` processes may
        share the work, and the result must not depend on how many."""
        raise NotImplementedError


def child_seed(seed: np.random.SeedSequence, *keys: int) -> np.random.SeedSequence:
    """The child of ``seed`` at ``keys`` (e.g. split, scene): stable whatever else is generated."""
    return np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, *keys))


def discover() -> dict[str, type[Generator]]:
    """Every generator: the modules of ``sim.generators`` register their classes on import, and
    so do other packages' entry points of the group ``sim.generators``."""
    return REGISTRY.discover()


def get_generator(name: str, where: str = "generator") -> type[Generator]:
    """The generator class registered under ``name``; an unknown one names ``where`` it was
    asked for (a family file)."""
    try:
        return REGISTRY.get(name)
    except InputError as error:
        raise InputError(f"{where}: {error}") from None
