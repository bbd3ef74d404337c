"""Toy curricula made of arrays alone: the learner's tests need no simulator."""

import numpy as np

from c2inet.checker import turners, turning_tasks
from c2inet.data import Windows

__all__ = ["toy_windows", "walkers", "turners", "turning_tasks"]


def toy_windows(scenes=12, seed=0) -> Windows:
    """Scenes of 1 to 4 agents moving at constant velocity."""
    rng = np.random.default_rng(seed)
    counts = rng.integers(1, 5, scenes)
    start = rng.normal(size=(counts.sum(), 1, 2))
    velocity = rng.normal(0, 0.4, size=(counts.sum(), 1, 2))
    positions = start + velocity * np.arange(20)[None, :, None]
    return Windows(positions.astype(np.float32), np.concatenate([[0], np.cumsum(counts)]))


def walkers(heading: float, scenes: int, seed: int) -> Windows:
    """2-agent scenes walking at 0.4 m per frame, about ``heading`` (rad, spread 0.3)."""
    rng = np.random.default_rng(seed)
    agents = 2 * scenes
    angle = rng.normal(heading, 0.3, (agents, 1))
    steps = 0.4 * np.stack([np.cos(angle), np.sin(angle)], -1).repeat(20, axis=1)
    steps += rng.normal(0, 0.15, steps.shape)
    start = rng.uniform(-20, 20, (agents, 1, 2))
    positions = start + np.cumsum(steps, axis=1)
    return Windows(positions.astype(np.float32), np.arange(0, agents + 1, 2))
