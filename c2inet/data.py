"""The learner's input type: fixed-length position windows, agents flattened, grouped by scene."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import torch

OBS_LEN = 8
PRED_LEN = 12


@dataclass(frozen=True)
class Windows:
    """Windows of ``obs_len`` observed plus ``pred_len`` future positions for many scenes.

    ``positions[scene_start[s]:scene_start[s + 1]]`` are the agents of scene ``s``; every agent is
    present in every frame of its window. Units are metres.
    """

    positions: np.ndarray  # (agents_total, obs_len + pred_len, 2) float32
    scene_start: np.ndarray  # (scenes + 1,) int64, scene_start[0] == 0
    obs_len: int = OBS_LEN
    # m: two bodies' centre distance at contact, where the data knows it (a simulated crowd's
    # 2 x radius), scored as a collision rate beside TrajNet++'s fixed 0.2 m
    contact: float | None = None

    def __post_init__(self):
        if self.positions.ndim != 3 or self.positions.shape[2] != 2:
            raise ValueError(f"positions must be (agents, frames, 2), got {self.positions.shape}")
        if self.scene_start[0] != 0 or self.scene_start[-1] != len(self.positions):
            raise ValueError("scene_start must run from 0 to the number of agents")
        if np.any(np.diff(self.scene_start) < 1):
            raise ValueError("every scene needs at least one agent")

    def __len__(self) -> int:
        return len(self.scene_start) - 1

    @property
    def pred_len(self) -> int:
        return self.positions.shape[1] - self.obs_len

    @property
    def agents_per_scene(self) -> np.ndarray:
        return np.diff(self.scene_start)

    def subset(self, scenes: np.ndarray) -> Windows:
        """The windows of the given scene indices, in that order."""
        scenes = np.asarray(scenes, dtype=np.int64)
        counts = self.agents_per_scene[scenes]
        starts = self.scene_start[scenes]
        rows = np.repeat(starts - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
        return Windows(
            self.positions[rows],
            np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
            self.obs_len,
            self.contact,
        )

    @staticmethod
    def concat(parts: list[Windows]) -> Windows:
        """All scenes of ``parts`` in order; they must share the observed length (the
        contact distance kept where they share one)."""
        if not parts:
            raise ValueError("nothing to concatenate")
        offsets = np.cumsum([0] + [len(p.positions) for p in parts[:-1]])
        starts = [p.scene_start[:-1] + o for p, o in zip(parts, offsets, strict=True)]
        total = sum(len(p.positions) for p in parts)
        return Windows(
            np.concatenate([p.positions for p in parts]),
            np.concatenate([*starts, [total]]).astype(np.int64),
            parts[0].obs_len,
            parts[0].contact if len({p.contact for p in parts}) == 1 else None,
        )

    def state_dict(self) -> dict[str, torch.Tensor | int]:
        """Tensors and plain values only, for checkpoints read with ``weights_only=True``."""
        import torch  # here only: the simulators build windows without loading torch

        return {
            "positions": torch.from_numpy(self.positions.copy()),
            "scene_start": torch.from_numpy(self.scene_start.copy()),
            "obs_len": self.obs_len,
            "contact": -1.0 if self.contact is None else float(self.contact),
        }

    @staticmethod
    def from_state(state: dict[str, torch.Tensor | int]) -> Windows:
        return Windows(
            state["positions"].cpu().numpy(),
            state["scene_start"].cpu().numpy(),
            int(state["obs_len"]),
            None if float(state.get("contact", -1.0)) < 0 else float(state["contact"]),
        )
