"""Turning domain specs into domains: child seeds, content hashes and the Parquet cache."""

from __future__ import annotations

import hashlib
import json
import sys
import zlib
from pathlib import Path

import numpy as np

from c2inet.errors import InputError
from sim.data import Domain
from sim.families import Splits
from sim.generators import child_seed, get_generator
from sim.io import read_parquet, write_parquet
from sim.scenario import DomainSpec

CODE_VERSION = 2  # bump when the data model or the cache layout changes (2: checksums)


def domain_seed(root_seed: int, spec: DomainSpec) -> np.random.SeedSequence:
    """A child seed from the root seed, the family's offset and the domain's name.

    Keyed by name rather than curriculum position, so a domain is the same in every curriculum.
    """
    key = (spec.family.seed_offset, zlib.crc32(spec.name.encode()))
    return np.random.SeedSequence(root_seed, spawn_key=key)


def domain_hash(spec: DomainSpec, root_seed: int, splits: Splits | None = None) -> str:
    """Content hash of everything that determines a domain's data."""
    generator = get_generator(spec.family.generator)
    knobs = spec.knobs
    content = {
        "generator": generator.name,
        "generator_version": generator.version,
        "code_version": CODE_VERSION,
        "knobs": knobs,
        "inputs": generator.content_key(knobs),
        "seed": root_seed,
        "seed_key": list(domain_seed(root_seed, spec).spawn_key),
        "splits": vars(splits or spec.family.splits),
    }
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()[:16]


def cache_path(
    spec: DomainSpec, root_seed: int, cache_dir: Path, splits: Splits | None = None
) -> Path:
    """Where the cache keeps the domain of ``spec`` made from ``root_seed`` (by its content)."""
    splits = splits or spec.family.splits
    return cache_dir / f"{spec.name}-{domain_hash(spec, root_seed, splits)}.parquet"


def build_domain(
    spec: DomainSpec,
    root_seed: int,
    cache_dir: Path | None = None,
    splits: Splits | None = None,
    workers: int = 1,
    memory_budget: float | None = None,
) -> Domain:
    """Generate the domain of ``spec``, or read it from ``cache_dir`` when already made.

    ``splits`` overrides the family's scene counts (e.g. tiny sizes for smoke runs). A domain
    whose generation would need more than ``memory_budget`` GB is refused before it starts.
    """
    splits = splits or spec.family.splits
    digest = domain_hash(spec, root_seed, splits)
    cached = cache_path(spec, root_seed, cache_dir, splits) if cache_dir else None
    if cached and cached.exists():
        try:
            return read_parquet(cached)
        except InputError as error:  # damaged or truncated: never used, made again
            print(f"warning: {error}; generating it again", file=sys.stderr)
    generator = get_generator(spec.family.generator)()
    needed = generator.memory_bytes(spec.knobs, splits) / 1e9
    if memory_budget is not None and needed > memory_budget:
        raise InputError(
            f"domain {spec.name}: generating it needs about {needed:.3g} GB, more than the "
            f"memory budget of {memory_budget:g} GB (--memory-budget; fewer agents, frames or "
            "scenes)"
        )
    domain = generator.generate(
        spec.name, spec.family.name, spec.knobs, splits, domain_seed(root_seed, spec), workers
    )
    domain.hash = digest
    if cached:
        write_parquet(domain, cached)
    return domain


def rollout_scene(spec: DomainSpec, root_seed: int, frames: int):
    """A longer episode of the domain for playback (its own child seed), or None."""
    generator = get_generator(spec.family.generator)()
    return generator.rollout(spec.knobs, child_seed(domain_seed(root_seed, spec), 99), frames)
