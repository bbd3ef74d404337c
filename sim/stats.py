"""Realised statistics of a domain, computed from its recorded positions alone."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sim.data import Scene

MIN_STEP = 0.02  # m per frame below which an agent counts as standing (no heading)


def motion_stats(scenes: list[Scene], dt: float) -> dict[str, float]:
    """Mean speed (m/s) and mean absolute heading change per frame (rad) over all agents."""
    speeds, turns = [], []
    for scene in scenes:
        step = np.diff(scene.positions, axis=0)  # (frames-1, agents, 2), NaN where absent
        length = np.linalg.norm(step, axis=-1)
        speeds.append(length[np.isfinite(length)] / dt)
        heading = np.arctan2(step[..., 1], step[..., 0])
        moving = length > MIN_STEP
        turn = np.abs(np.angle(np.exp(1j * np.diff(heading, axis=0))))
        valid = moving[1:] & moving[:-1]
        turns.append(turn[valid])
    speeds, turns = np.concatenate(speeds), np.concatenate(turns)
    return {
        "mean_speed": float(speeds.mean()) if speeds.size else 0.0,
        "heading_change": float(turns.mean()) if turns.size else 0.0,
    }


def proximity_stats(scenes: list[Scene], contact: float | None = None) -> dict[str, float]:
    """Minimum inter-agent distance (m) and, given a ``contact`` distance (the sum of the two
    radii), the number of overlapping agent pairs, counted once per recorded frame."""
    smallest, overlaps = np.inf, 0
    for scene in scenes:
        for frame in scene.positions:
            points = frame[np.isfinite(frame[:, 0])]
            if len(points) < 2:
                continue
            tree = cKDTree(points)
            distance, _ = tree.query(points, k=2)
            smallest = min(smallest, float(distance[:, 1].min()))
            if contact is not None:
                overlaps += len(tree.query_pairs(contact, output_type="ndarray"))
    out = {"min_separation": float(smallest) if np.isfinite(smallest) else 0.0}
    return out if contact is None else {**out, "overlaps": overlaps}
