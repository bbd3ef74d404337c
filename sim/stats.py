"""Realised statistics of a domain, computed from its recorded positions alone."""

from __future__ import annotations

import numpy as np

from c2inet.lazy import lazy_module
from sim.data import Scene

# loaded on first use: a command that stops at bad input or answers --help does not pay for it
spatial = lazy_module("scipy.spatial")

MIN_STEP = 0.02  # m per frame below which an agent counts as standing (no heading)
DENSE_AGENTS = 64  # up to this many agents a scene's pairs are taken all at once
DENSE_PAIR_FRAMES = 1 << 21  # agents^2 x frames of one all-pairs block (bounds its memory)
PROFILES = ("closest", "speed", "heading_change", "first_speed")  # per-scene distributions


def motion_stats(scenes: list[Scene], dt: float) -> dict[str, float]:
    """Mean speed (m/s) and mean absolute heading change per frame (rad) over all agents."""
    speeds, turns = [], []
    for positions in _runs(scenes):  # (scenes, frames, agents, 2), NaN where absent
        step = np.diff(positions, axis=1)
        length = np.linalg.norm(step, axis=-1)
        speeds.append(length[np.isfinite(length)] / dt)
        heading = np.arctan2(step[..., 1], step[..., 0])
        moving = length > MIN_STEP
        turn = np.abs(np.angle(np.exp(1j * np.diff(heading, axis=1))))
        valid = moving[:, 1:] & moving[:, :-1]
        turns.append(turn[valid])
    speeds, turns = np.concatenate(speeds or [[]]), np.concatenate(turns or [[]])
    return {
        "mean_speed": float(speeds.mean()) if speeds.size else 0.0,
        "heading_change": float(turns.mean()) if turns.size else 0.0,
    }


def _runs(scenes: list[Scene]):
    """The scenes' positions stacked, one array per run of consecutive scenes of one shape, so
    that thousands of small scenes cost a few array operations (and keep their order)."""
    start = 0
    for end in range(1, len(scenes) + 1):
        if end == len(scenes) or scenes[end].positions.shape != scenes[start].positions.shape:
            yield np.stack([scene.positions for scene in scenes[start:end]])
            start = end


def proximity_stats(scenes: list[Scene], contact: float | None = None) -> dict[str, float]:
    """Minimum inter-agent distance (m) and, given a ``contact`` distance (the sum of the two
    radii), the number of overlapping agent pairs, counted once per recorded frame.

    Scenes of up to ``DENSE_AGENTS`` agents take every pair of every frame at once; larger ones
    a k-d tree per frame.
    """
    smallest, overlaps = np.inf, 0
    for positions in _runs(scenes):
        if positions.shape[2] <= DENSE_AGENTS:
            frames = positions.reshape(-1, *positions.shape[2:])
            block = max(1, DENSE_PAIR_FRAMES // positions.shape[2] ** 2)
            for first in range(0, len(frames), block):
                low, count = _dense_pairs(frames[first : first + block], contact)
                smallest, overlaps = min(smallest, low), overlaps + count
            continue
        for scene in positions:
            low, count = _tree_pairs(scene, contact)
            smallest, overlaps = min(smallest, low), overlaps + count
    out = {"min_separation": float(smallest) if np.isfinite(smallest) else 0.0}
    return out if contact is None else {**out, "overlaps": overlaps}


def _dense_pairs(positions: np.ndarray, contact: float | None) -> tuple[float, int]:
    """(smallest distance, pairs closer than ``contact``) over all frames, all pairs at once."""
    agents = positions.shape[1]
    if agents < 2:
        return np.inf, 0
    first, second = np.triu_indices(agents, k=1)
    dx = positions[:, first, 0] - positions[:, second, 0]  # (frames, pairs)
    dy = positions[:, first, 1] - positions[:, second, 1]
    distance = np.sqrt(dx * dx + dy * dy)  # as np.linalg.norm, without its overhead
    distance = distance[np.isfinite(distance)]
    if not distance.size:
        return np.inf, 0
    return float(distance.min()), int((distance <= contact).sum()) if contact is not None else 0


def _tree_pairs(positions: np.ndarray, contact: float | None) -> tuple[float, int]:
    smallest, overlaps = np.inf, 0
    for frame in positions:
        points = frame[np.isfinite(frame[:, 0])]
        if len(points) < 2:
            continue
        tree = spatial.cKDTree(points)
        distance, _ = tree.query(points, k=2)
        smallest = min(smallest, float(distance[:, 1].min()))
        if contact is not None:
            overlaps += len(tree.query_pairs(contact, output_type="ndarray"))
    return smallest, overlaps


def scene_profiles(scenes: list[Scene], dt: float) -> dict[str, np.ndarray]:
    """Per scene: its closest approach of two agents (m), mean speed (m/s), mean absolute
    heading change per frame (rad), and its agents' mean speed over their first step (m/s).

    These are the distributions a fidelity report compares between two families; a scene
    without the quantity (a single agent, say) gets NaN.
    """
    out = {name: np.full(len(scenes), np.nan) for name in PROFILES}
    for k, scene in enumerate(scenes):
        positions = scene.positions
        dense = positions.shape[1] <= DENSE_AGENTS
        closest, _ = (_dense_pairs if dense else _tree_pairs)(positions, None)
        step = np.linalg.norm(np.diff(positions, axis=0), axis=-1)  # (frames-1, agents)
        present = np.isfinite(step)
        first = present & (np.cumsum(present, axis=0) == 1)  # each agent's first step
        moves = motion_stats([scene], dt)
        out["closest"][k] = closest if np.isfinite(closest) else np.nan
        out["speed"][k] = moves["mean_speed"] if present.any() else np.nan
        out["heading_change"][k] = moves["heading_change"]
        out["first_speed"][k] = step[first].mean() / dt if first.any() else np.nan
    return out


def realised_summary(
    scenes: list[Scene], dt: float, profiles: dict[str, np.ndarray] | None = None
) -> dict[str, float]:
    """The statistics a generated family must match its reference on: minimum separation and
    median closest approach (m), mean speed (m/s), heading change per frame (rad) and speed
    over the first step (m/s). ``profiles``: the scenes' :func:`scene_profiles`, when at hand."""
    profiles = profiles if profiles is not None else scene_profiles(scenes, dt)
    moves = motion_stats(scenes, dt)
    return {
        "min_separation": float(np.nanmin(profiles["closest"])),
        "median_closest": float(np.nanmedian(profiles["closest"])),
        "mean_speed": moves["mean_speed"],
        "heading_change": moves["heading_change"],
        "first_speed": float(np.nanmean(profiles["first_speed"])),
    }


def relative_difference(value: float, reference: float) -> float:
    """(value - reference) / |reference|; 0 when both are 0."""
    if reference == 0:
        return 0.0 if value == 0 else float("inf")
    return (value - reference) / abs(reference)
