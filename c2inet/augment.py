"""Training-time augmentation: each scene of an epoch turned by its own random angle.

A model of displacements learns the same motion in every heading: what it learns from scenes
walked left to right then holds where people walk up and down (ETH-UCY's HOTEL, where a model
trained on the other four scenes otherwise trails constant velocity). Rotation changes no
distance, so no error; the evaluation never rotates.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from c2inet.data import Windows

AUGMENTATIONS = ("none", "rotate", "axes")


def augment_scenes(windows: Windows, rng: np.random.Generator, kind: str) -> Windows:
    """``windows`` with every scene turned about the origin, all its agents together (so their
    interactions are kept), by ``rng``'s draw: ``rotate``, an angle uniform in [0, 2 pi);
    ``axes``, a quarter turn (0 to 3) then a mirror image or not, one of the square's eight
    symmetries, which keep walking along the image's axes along them."""
    scenes = len(windows)
    if kind == "rotate":
        angles, mirror = rng.uniform(0, 2 * np.pi, scenes), np.ones(scenes)
    else:
        angles = rng.integers(0, 4, scenes) * (np.pi / 2)
        mirror = np.where(rng.integers(0, 2, scenes) == 1, -1.0, 1.0)
    angles = np.repeat(angles, windows.agents_per_scene)[:, None]
    x = windows.positions[..., 0] * np.repeat(mirror, windows.agents_per_scene)[:, None]
    y = windows.positions[..., 1]
    cos, sin = np.round(np.cos(angles), 12), np.round(np.sin(angles), 12)
    turned = np.stack([cos * x - sin * y, sin * x + cos * y], axis=-1)
    return replace(windows, positions=turned.astype(windows.positions.dtype))
