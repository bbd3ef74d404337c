"""Evaluation of a trained model on windows: K sampled futures, the point prediction, and the
metrics of both, reproducible for a seed and leaving training's random streams untouched."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from c2inet.batch import batches
from c2inet.data import Windows
from c2inet.device import model_device, seeded
from c2inet.metrics import POINT_DRAWS, evaluate_predictions
from c2inet.model import to_positions

VARIANT_METRICS = ("ade", "fde", "ade_k1", "fde_k1", "ade_draw", "fde_draw")
POINT_SEED = 7_919  # offsets the seed of the point prediction's own draws from the K samples'


def sample_predictions(
    model: torch.nn.Module,
    windows: Windows,
    k: int,
    seed: int,
    batch_scenes: int = 256,
    **options: Any,
) -> np.ndarray:
    """``k`` sampled futures of every agent of ``windows``, (K, T, N, 2) in metres.

    Reproducible for a seed, and the global RNG stream of training is left untouched.
    ``options`` go to ``model.predict`` (e.g. C2INet's ``c_source``).
    """
    was_training = getattr(model, "training", False)
    model.eval()
    device = model_device(model)
    with seeded(seed, device):
        preds = [
            model.predict(batch, k, **options).cpu().numpy()
            for batch in batches(windows, batch_scenes, device=device)
        ]
    model.train(was_training)
    return np.concatenate(preds, axis=2)


@torch.no_grad()
def natural_points(model: torch.nn.Module, windows: Windows, batch_scenes: int = 256) -> np.ndarray:
    """The model's own point prediction (``model.point``) of every agent, (T, N, 2) in metres."""
    was_training = getattr(model, "training", False)
    model.eval()
    device = model_device(model)
    points = [
        to_positions(batch, model.point(batch)[:, None])[0].cpu().numpy()
        for batch in batches(windows, batch_scenes, device=device)
    ]
    model.train(was_training)
    return np.concatenate(points, axis=1)


def evaluate(
    model: torch.nn.Module,
    windows: Windows,
    k: int,
    seed: int,
    batch_scenes: int = 256,
    point_draws: int = POINT_DRAWS,
    **options: Any,
) -> dict[str, float]:
    """Metrics of ``model`` on ``windows`` with ``k`` samples, reproducible for a seed.

    The point prediction (``ade_k1``) is the model's own where it declares one
    (``natural_point``: PECNet's z = 0), else the mean of the K samples when there are at least
    ``point_draws``, else of ``point_draws`` samples drawn apart (a deterministic model's mean
    is its prediction); ``point_draws=0`` skips it, for validation curves that read ``ade`` only.
    """
    pred = sample_predictions(model, windows, k, seed, batch_scenes, **options)
    truth = windows.positions[:, windows.obs_len :].transpose(1, 0, 2)
    point = None
    if point_draws and getattr(model, "natural_point", False) and not options:
        point = natural_points(model, windows, batch_scenes)
    elif point_draws:
        draws = pred
        if k < point_draws:
            draws = sample_predictions(
                model, windows, point_draws, seed + POINT_SEED, batch_scenes, **options
            )
        point = draws.mean(axis=0)
    return evaluate_predictions(pred, truth, windows.scene_start, point, windows.contact)


def evaluate_all(
    model: torch.nn.Module,
    windows: Windows,
    k: int,
    seed: int,
    batch_scenes: int = 256,
    variants: bool = True,
    task: int | None = None,
) -> dict[str, float]:
    """:func:`evaluate` for the model's default, and (with ``variants``) for each of its
    evaluation variants with the variant's name appended to the metric names
    (``ade_c_posterior``); ``task``: the index of the task ``windows`` belong to, for the
    variants that need it (C2INet's ``own`` rule)."""
    scores = evaluate(model, windows, k, seed, batch_scenes)
    for suffix, options in model.evaluation_variants(task).items() if variants else ():
        other = evaluate(model, windows, k, seed, batch_scenes, **options)
        scores.update({f"{m}_{suffix}": v for m, v in other.items() if m in VARIANT_METRICS})
    return scores
