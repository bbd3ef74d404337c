"""The one trajectory data model every source produces, and its cutting into learner windows."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from c2inet.data import OBS_LEN, PRED_LEN, Windows

SPLITS = ("train", "val", "test")


@dataclass
class Scene:
    """One recording: positions of its agents over its frames, NaN where an agent is absent."""

    positions: np.ndarray  # (frames, agents, 2) float64, metres
    agent_ids: np.ndarray  # (agents,) int64, unique within the scene

    def __post_init__(self):
        if self.positions.ndim != 3 or self.positions.shape[2] != 2:
            raise ValueError(
                f"scene positions must be (frames, agents, 2), got {self.positions.shape}"
            )
        if len(self.agent_ids) != self.positions.shape[1]:
            raise ValueError("one agent id per agent column")

    @property
    def num_frames(self) -> int:
        return self.positions.shape[0]


@dataclass
class Domain:
    """One task: scenes per split, the knobs that made them and the statistics they realise."""

    name: str
    family: str
    generator: str
    knobs: dict[str, Any]
    dt: float
    scenes: dict[str, list[Scene]]
    stats: dict[str, float] = field(default_factory=dict)
    hash: str = ""

    def windows(
        self, split: str, stride: int = 1, share: float = 1.0, min_agents: int = 1
    ) -> Windows | None:
        """Learner windows of one split (None when the split has none), every ``stride`` frames;
        with ``share`` < 1 only the first share of them in the recording's order (rounded up)."""
        parts = [cut_windows(s, stride, min_agents) for s in self.scenes[split]]
        parts = [p for p in parts if p is not None]
        if not parts:
            return None
        windows = Windows.concat(parts)
        if share < 1:
            windows = windows.subset(np.arange(math.ceil(share * len(windows))))
        return windows

    def summary(self) -> dict[str, Any]:
        """What a run and ``summary.json`` say about the domain: knobs, split sizes, statistics
        and content hash."""
        return {
            "name": self.name,
            "family": self.family,
            "generator": self.generator,
            "knobs": self.knobs,
            "splits": {split: len(self.scenes[split]) for split in SPLITS},
            "stats": self.stats,
            "hash": self.hash,
        }


def window_members(
    scene: Scene, length: int, stride: int = 1, min_agents: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Start frames of the kept windows, and which agents each keeps, (W,) and (W, agents).

    A window keeps the agents present in all its frames, and is kept if it has at least
    ``min_agents`` of them.
    """
    present = ~np.isnan(scene.positions[..., 0])  # (frames, agents)
    # agents present in every frame of [t, t + length): a sliding-window count over frames
    counts = np.cumsum(np.vstack([np.zeros((1, present.shape[1]), int), present]), axis=0)
    starts = np.arange(0, max(scene.num_frames - length + 1, 0), stride)
    full = (counts[starts + length] - counts[starts]) == length  # (windows, agents)
    keep = full.sum(1) >= min_agents
    return starts[keep], full[keep]


def cut_windows(
    scene: Scene,
    stride: int = 1,
    min_agents: int = 1,
    obs_len: int = OBS_LEN,
    pred_len: int = PRED_LEN,
) -> Windows | None:
    """Windows of ``obs_len + pred_len`` frames every ``stride`` frames (see window_members)."""
    length = obs_len + pred_len
    starts, full = window_members(scene, length, stride, min_agents)
    if len(starts) == 0:
        return None
    window_idx, agent_idx = np.nonzero(full)
    frames = starts[window_idx, None] + np.arange(length)
    positions = scene.positions[frames, agent_idx[:, None]].astype(np.float32)
    scene_start = np.concatenate([[0], np.cumsum(full.sum(1))]).astype(np.int64)
    return Windows(positions, scene_start, obs_len)
