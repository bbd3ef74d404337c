"""Pure metric functions: displacement errors, best-of-K by scene or by agent, continual scores.

Every aggregate names how it was taken: ``joint`` takes the best sample per scene (the sum of its
agents' errors, as sgan and GCRL do), ``agent`` the best sample per agent (Social-STGCNN style).
"""

from __future__ import annotations

import numpy as np

POINT_DRAWS = 16  # the point prediction (K = 1) is the mean of at least this many sampled futures
# TrajNet++'s collision (trajnetplusplustools.metrics.collision): two people of radius 0.1 m
# collide where their paths come within two radii, 0.2 m, checked at the frames and at the
# midpoint of every step between two predicted frames (its inter_parts = 2)
COLLISION_RADIUS = 0.1
COLLISION_DISTANCE = 2 * COLLISION_RADIUS
COLLISION_PARTS = 2  # each step between frames cut in this many, its points compared in pairs


def displacement_errors(pred: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ADE and FDE of every sample and agent: pred (K, T, N, 2), truth (T, N, 2) -> (K, N) each."""
    distance = np.linalg.norm(pred - truth[None], axis=-1)  # (K, T, N)
    return distance.mean(axis=1), distance[:, -1]


def best_sample(errors: np.ndarray, scene_start: np.ndarray, mode: str) -> np.ndarray:
    """Index of the chosen sample for every agent; errors (K, N) -> (N,).

    ``joint``: one sample per scene, the one with the smallest sum over the scene's agents.
    ``agent``: each agent's own smallest error.
    """
    if mode == "agent":
        return errors.argmin(axis=0)
    if mode != "joint":
        raise ValueError(f"unknown best-of-K mode {mode!r}")
    counts = np.diff(scene_start)
    scene_of = np.repeat(np.arange(len(counts)), counts)
    totals = np.zeros((errors.shape[0], len(counts)))
    np.add.at(totals, (slice(None), scene_of), errors)
    return totals.argmin(axis=0)[scene_of]


def best_of_k(errors: np.ndarray, scene_start: np.ndarray, mode: str) -> np.ndarray:
    """Per-agent error after choosing the best of K samples (see :func:`best_sample`)."""
    chosen = best_sample(errors, scene_start, mode)
    return errors[chosen, np.arange(errors.shape[1])]


def evaluate_predictions(
    pred: np.ndarray,
    truth: np.ndarray,
    scene_start: np.ndarray,
    point: np.ndarray | None = None,
    contact: float | None = None,
) -> dict[str, float]:
    """ADE/FDE in metres: best of K, joint and per agent; ``ade_draw``, one random draw (the
    first sample); ``ade_k1``, the point prediction ``point`` (T, N, 2), when given, with its
    collision rates (TrajNet++'s, and at the bodies' own ``contact`` distance where the data
    knows it: ``col_pred_body``, ``col_truth_body``, all agents); and the spread of the K
    endpoints (mean distance of each agent's K final points to their mean)."""
    ade, fde = displacement_errors(pred, truth)
    final = pred[:, -1]  # (K, N, 2)
    spread = np.linalg.norm(final - final.mean(axis=0), axis=-1).mean()
    scores = {
        "ade": float(best_of_k(ade, scene_start, "joint").mean()),
        "fde": float(best_of_k(fde, scene_start, "joint").mean()),
        "ade_agent": float(best_of_k(ade, scene_start, "agent").mean()),
        "fde_agent": float(best_of_k(fde, scene_start, "agent").mean()),
        "ade_draw": float(ade[0].mean()),
        "fde_draw": float(fde[0].mean()),
        "endpoint_spread": float(spread),
    }
    if point is not None:
        point_ade, point_fde = displacement_errors(point[None], truth)
        scores |= {"ade_k1": float(point_ade.mean()), "fde_k1": float(point_fde.mean())}
        scores |= collisions(point, truth, scene_start)
        if contact is not None:
            body = collisions(point, truth, scene_start, contact)
            scores |= {"col_pred_body": body["col_pred"], "col_truth_body": body["col_truth"]}
    return scores


def _densified(paths: np.ndarray) -> np.ndarray:
    """(T, N, 2) paths with the points that cut each step between frames into
    :data:`COLLISION_PARTS` equal parts (the frames kept), as TrajNet++ checks them."""
    steps = np.linspace(0, 1, COLLISION_PARTS + 1)[:-1, None, None, None]
    between = paths[:-1][None] + steps * (paths[1:] - paths[:-1])[None]  # (S, T-1, N, 2)
    return np.concatenate([between.transpose(1, 0, 2, 3).reshape(-1, *paths.shape[1:]), paths[-1:]])


def collisions(
    point: np.ndarray,
    truth: np.ndarray,
    scene_start: np.ndarray,
    distance: float = COLLISION_DISTANCE,
) -> dict[str, float]:
    """TrajNet++'s collision rates of the point prediction (T, N, 2), over the scenes with two
    agents or more: Col-I, a predicted path within ``distance`` (<=; TrajNet++'s 0.2 m by
    default) of another agent's predicted path at the same moment; Col-II, of another agent's
    true path. TrajNet++ scores each scene's primary agent (its first: ``col_pred_primary``,
    ``col_truth_primary``); ``col_pred`` and ``col_truth`` take the share of all those scenes'
    agents. 0 where no scene has two agents."""
    pred, true = _densified(point), _densified(truth)
    names = ("col_pred", "col_truth")
    hits: dict[str, list] = {name: [] for name in (*names, *(f"{n}_primary" for n in names))}
    for first, end in zip(scene_start[:-1], scene_start[1:], strict=True):
        if end - first < 2:
            continue
        mine = pred[:, first:end]
        others = np.eye(end - first, dtype=bool)[None]  # an agent never collides with itself
        for name, theirs in zip(names, (mine, true[:, first:end]), strict=True):
            gaps = np.linalg.norm(mine[:, :, None] - theirs[:, None], axis=-1)  # (T', n, n)
            hit = ((gaps <= distance) & ~others).any(axis=(0, 2))
            hits[name].append(hit)
            hits[f"{name}_primary"].append(hit[:1])
    return {
        name: float(np.concatenate(found).mean()) if found else 0.0 for name, found in hits.items()
    }


def average_seen(matrix: np.ndarray) -> np.ndarray:
    """The paper's Table-2 row: after task i, the mean error over tasks 0..i."""
    return np.array([np.mean(matrix[i, : i + 1]) for i in range(len(matrix))])


def forgetting_worst(matrix: np.ndarray) -> np.ndarray:
    """Per task j but the last: worst error after leaving it minus the error right after it."""
    t = len(matrix)
    return np.array([matrix[j + 1 :, j].max() - matrix[j, j] for j in range(t - 1)])


def forgetting_final(matrix: np.ndarray) -> np.ndarray:
    """Per task j but the last: final error minus the best error before the last task.

    Chaudhry et al. 2018 (best earlier accuracy minus final), written for errors.
    """
    t = len(matrix)
    return np.array([matrix[-1, j] - matrix[j:-1, j].min() for j in range(t - 1)])


def backward_transfer(matrix: np.ndarray) -> float:
    """Mean over j < T-1 of final error minus error right after training j (> 0: worse)."""
    t = len(matrix)
    if t < 2:
        return 0.0
    return float(np.mean([matrix[-1, j] - matrix[j, j] for j in range(t - 1)]))
