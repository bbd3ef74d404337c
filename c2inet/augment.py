"""Training-time augmentation: each scene of an epoch turned by its own random angle.

A model of displacements learns the same motion in every heading: what it learns from scenes
walked left to right then holds where people walk up and down (ETH-UCY's HOTEL, where a model
trained on the other four scenes otherwise trails constant velocity). Rotation changes no
distance, so no error; the evaluation never rotates.
"""

from __future__ import annotations

import numpy as np

from c2inet.data import Windows

AUGMENTATIONS = ("none", "rotate")


def rotate_scenes(windows: Windows, rng: np.random.Generator) -> Windows:
    """``windows`` with every scene rotated about the origin by an angle drawn from ``rng``,
    uniform in [0, 2 pi): all agents of a scene turn together, so their interactions are kept."""
    angles = np.repeat(rng.uniform(0, 2 * np.pi, len(windows)), windows.agents_per_scene)
    cos, sin = np.cos(angles)[:, None], np.sin(angles)[:, None]
    x, y = windows.positions[..., 0], windows.positions[..., 1]
    turned = np.stack([cos * x - sin * y, sin * x + cos * y], axis=-1)
    return Windows(turned.astype(windows.positions.dtype), windows.scene_start, windows.obs_len)
