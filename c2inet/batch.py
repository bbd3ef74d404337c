"""Tensor batches of scenes: flattened agents for the LSTMs, padded scenes for graph attention."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import torch

from c2inet.data import Windows

MIN_SCALE = 0.05  # m per frame


@dataclass(frozen=True)
class Batch:
    """Scenes as tensors. Model inputs are built from ``obs`` alone (no future leaks in).

    Frozen, so what is derived from its tensors (displacements, scales) is computed once and
    kept: a training step asks for them a dozen times.
    """

    obs: torch.Tensor  # (8, N, 2) observed positions, metres
    fut: torch.Tensor  # (12, N, 2) future positions (targets only)
    scene_start: torch.Tensor  # (B + 1,) agent offsets of the scenes
    scene_of: torch.Tensor  # (N,) scene index of every agent
    slot_of: torch.Tensor  # (N,) position of every agent inside its scene
    max_agents: int
    bounds: tuple[int, ...]  # scene_start on the host: read without a sync from an accelerator

    @property
    def num_scenes(self) -> int:
        return len(self.scene_start) - 1

    @cached_property
    def obs_rel(self) -> torch.Tensor:
        """Observed displacements by backward differences; the first step is zero."""
        return torch.cat([torch.zeros_like(self.obs[:1]), self.obs[1:] - self.obs[:-1]])

    @cached_property
    def scale(self) -> torch.Tensor:
        """(N, 1) motion scale of each agent's scene: its mean observed step length, metres.

        Observed frames only (no leak); floored at MIN_SCALE for scenes standing still.
        """
        step = self.obs_rel[1:].norm(dim=-1).mean(0)  # (N,)
        return self.per_scene_mean(step).clamp_min(MIN_SCALE)[self.scene_of, None]

    @cached_property
    def last_rel(self) -> torch.Tensor:
        """(N, 2) each agent's last observed displacement over its scale: where decoding starts."""
        return self.obs_rel[-1] / self.scale

    @cached_property
    def agent_counts(self) -> torch.Tensor:
        return self.scene_start[1:] - self.scene_start[:-1]

    def per_scene_mean(self, per_agent: torch.Tensor) -> torch.Tensor:
        """(..., N) per agent -> (..., B) mean over the agents of each scene."""
        sums = per_agent.new_zeros((*per_agent.shape[:-1], self.num_scenes))
        sums = sums.index_add(-1, self.scene_of, per_agent)
        return sums / self.agent_counts.to(per_agent.dtype)

    def pool(self, features: torch.Tensor) -> torch.Tensor:
        """(N, F) per agent -> (B, F) mean over the agents of each scene."""
        sums = features.new_zeros((self.num_scenes, features.shape[-1]))
        return sums.index_add(0, self.scene_of, features) / self.agent_counts[:, None]

    @cached_property
    def fut_rel(self) -> torch.Tensor:
        """Future displacements, starting from the last observed position."""
        previous = torch.cat([self.obs[-1:], self.fut[:-1]])
        return self.fut - previous

    def pad(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(..., N, F) per agent -> (..., B, A, F) per scene slot, and the (B, A) presence mask."""
        shape = (*x.shape[:-2], self.num_scenes, self.max_agents, x.shape[-1])
        padded = x.new_zeros(shape)
        padded[..., self.scene_of, self.slot_of, :] = x
        mask = torch.zeros(self.num_scenes, self.max_agents, dtype=torch.bool, device=x.device)
        mask[self.scene_of, self.slot_of] = True
        return padded, mask

    def unpad(self, padded: torch.Tensor) -> torch.Tensor:
        return padded[..., self.scene_of, self.slot_of, :]

    @staticmethod
    def concat(parts: list[Batch]) -> Batch:
        """One batch of the scenes of ``parts``, in order: one forward pass where a method adds
        scenes of its own (DER++'s replay). Scenes stay apart: agents meet only their own."""
        offsets = np.cumsum([0] + [p.obs.shape[1] for p in parts[:-1]])
        counts = np.cumsum([0] + [p.num_scenes for p in parts[:-1]])
        starts = [parts[0].scene_start[:1]]
        starts += [p.scene_start[1:] + int(o) for p, o in zip(parts, offsets, strict=True)]
        return Batch(
            obs=torch.cat([p.obs for p in parts], dim=1),
            fut=torch.cat([p.fut for p in parts], dim=1),
            scene_start=torch.cat(starts),
            scene_of=torch.cat([p.scene_of + int(c) for p, c in zip(parts, counts, strict=True)]),
            slot_of=torch.cat([p.slot_of for p in parts]),
            max_agents=max(p.max_agents for p in parts),
            bounds=(
                0,
                *(b + int(o) for p, o in zip(parts, offsets, strict=True) for b in p.bounds[1:]),
            ),
        )


def make_batch(
    windows: Windows, scenes: np.ndarray | None = None, device: torch.device | str = "cpu"
) -> Batch:
    """The batch of the given scenes of ``windows`` (all scenes when None), on ``device``."""
    part = windows if scenes is None else windows.subset(scenes)
    positions = np.ascontiguousarray(part.positions.transpose(1, 0, 2))
    return tensor_batch(torch.as_tensor(positions, device=device), part.scene_start, part.obs_len)


def tensor_batch(positions: torch.Tensor, scene_start: np.ndarray, obs_len: int) -> Batch:
    """The batch of ``positions`` (frames, N, 2), already on their device, whose scenes start at
    the host's ``scene_start``: the index tensors are made on the host and copied over, so a
    batch of stored scenes (DER++'s replay) never reads its positions back."""
    scene_start = np.asarray(scene_start, dtype=np.int64)
    counts = np.diff(scene_start)
    scene_of = np.repeat(np.arange(len(counts)), counts)
    slot_of = np.arange(len(scene_of)) - np.repeat(scene_start[:-1], counts)
    device = positions.device
    starts, scene_of, slot_of = (
        torch.as_tensor(a, device=device) for a in (scene_start, scene_of, slot_of)
    )
    return Batch(
        obs=positions[:obs_len],
        fut=positions[obs_len:],
        scene_start=starts,
        scene_of=scene_of,
        slot_of=slot_of,
        max_agents=int(counts.max()),
        bounds=tuple(int(b) for b in scene_start),
    )


def batches(
    windows: Windows,
    batch_scenes: int,
    rng: np.random.Generator | None = None,
    device: torch.device | str = "cpu",
) -> Iterator[Batch]:
    """Batches of ``batch_scenes`` scenes on ``device``, shuffled when ``rng`` is given."""
    order = rng.permutation(len(windows)) if rng is not None else np.arange(len(windows))
    for first in range(0, len(order), batch_scenes):
        yield make_batch(windows, order[first : first + batch_scenes], device)


def scene_mean(per_agent: torch.Tensor, batch: Batch) -> torch.Tensor:
    """Mean over scenes of the per-scene mean over agents (GCRL's erm_loss, scaled by 1/B)."""
    return batch.per_scene_mean(per_agent).mean()


def variety_loss(per_agent: torch.Tensor, batch: Batch) -> torch.Tensor:
    """The variety loss (GCRL's ``best_k``): per scene, the best of S samples; (S, N) -> ().

    The sample whose mean over the scene's agents is smallest counts, the same one for every
    agent of the scene (the joint minimum of the metrics). With S = 1 it is :func:`scene_mean`.
    """
    return batch.per_scene_mean(per_agent).min(0).values.mean()
