"""DER++ (Buzzega et al., NeurIPS 2020, "Dark Experience for General Continual Learning"):
replay old scenes with both their true futures and the model's own past outputs for them.

A reservoir of ``buffer`` scenes (each scene seen has the same chance to be in it, across task
boundaries: no task labels needed) keeps every scene's noise-free prediction (``point``, the
regressor's "logits") from when it was stored. Each step adds ``alpha`` times the squared drift
from those stored outputs and ``beta`` times the task loss on a batch of ``replay_batch``
reservoir scenes (one batch for both terms, where Mammoth draws two), scored in the same forward
pass as the step's own scenes (``step_loss``: one joined batch), then offers the step's scenes
to the reservoir (``before_backward``). Example: ``--methods derpp``
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from c2inet.batch import Batch, tensor_batch, variety_loss
from c2inet.methods.base import Method, TaskContext
from c2inet.model import LossOutput
from c2inet.options import Tunable, choose, require


@dataclass(frozen=True)
class DERPPOptions:
    buffer: int = 200  # scenes in the reservoir
    alpha: float = 0.3  # weight of the stored outputs' term
    beta: float = 0.5  # weight of the replayed scenes' task loss
    replay_batch: int = 16
    # the replayed scenes' task loss: the step's variety loss over k_train samples, or the
    # noise-free output's (the one the alpha term holds: DER++'s two terms on one output)
    replay_loss: str = "variety"

    def __post_init__(self):
        require(self, 1, "buffer", "replay_batch")
        require(self, 0, "alpha", "beta")
        choose(self, "replay_loss", ("variety", "point"))


class DERPP(Method):
    """Dark experience replay with labels: a reservoir of scenes and their past outputs."""

    name = "derpp"
    # down to 0.001: tuned at batch 64 alpha chose 0.025, near the old floor of 0.01
    search_space = {"alpha": Tunable(1e-3, 10.0, log=True), "beta": Tunable(1e-3, 10.0, log=True)}
    Options = DERPPOptions
    inert = {"alpha": 0.0, "beta": 0.0}

    @classmethod
    def replay_options(cls, scenes: int, tasks: int) -> dict[str, Any]:
        return {"buffer": scenes}  # one reservoir over the whole stream

    def __init__(self, model_config, options: dict[str, Any] | None = None):
        super().__init__(model_config, options)
        self.scenes: list[torch.Tensor] = []  # (agents, 20, 2) positions of each stored scene
        self.outputs: list[torch.Tensor] = []  # (12, agents, 2) its output when stored
        self.seen = 0  # scenes offered to the reservoir so far

    def _draw(self, ctx: TaskContext) -> tuple[Batch, torch.Tensor]:
        """A batch of ``replay_batch`` reservoir scenes and their stored outputs (12, N, 2)."""
        count = min(self.options.replay_batch, len(self.scenes))
        chosen = ctx.rng.choice(len(self.scenes), count, replace=False)
        parts = [self.scenes[i] for i in chosen]
        starts = np.cumsum([0] + [len(p) for p in parts])
        positions = torch.cat(parts).transpose(0, 1).to(ctx.device)  # (frames, N, 2)
        stored = torch.cat([self.outputs[i] for i in chosen], dim=1)
        return tensor_batch(positions, starts, ctx.train.obs_len), stored

    def step_loss(self, ctx: TaskContext, batch: Batch, k_train: int) -> LossOutput:
        """The step's scenes and a replayed batch in one forward pass (:class:`Batch.concat`):
        the step's variety loss, ``alpha`` times the replayed scenes' drift from their stored
        outputs and ``beta`` times their task loss (``replay_loss``). The noise is drawn part
        by part, in the order separate passes would draw it."""
        if not self.scenes:
            return super().step_loss(ctx, batch, k_train)
        model, own = ctx.model, batch.obs.shape[1]
        noise = model.noise(k_train, batch)
        replay, stored = self._draw(ctx)
        variety = self.options.replay_loss == "variety"
        if variety:
            noise = torch.cat([noise, model.noise(k_train, replay)], dim=1)
        joined = Batch.concat([batch, replay])
        samples, point = model.samples_and_point(joined, noise, slice(own, None))
        replayed = samples[:, :, own:] if variety else point[:, None]
        drift = ((point - stored) ** 2).sum(dim=(0, 2))
        drift = replay.per_scene_mean(drift).mean() / (2 * self.model_config.likelihood_std**2)
        terms = {
            "nll": variety_loss(model.nll(batch, samples[:, :, :own]), batch),
            "replay_outputs": self.options.alpha * drift,
            "replay": self.options.beta * variety_loss(model.nll(replay, replayed), replay),
        }
        parts = {name: value.detach() for name, value in terms.items()}
        return LossOutput(sum(terms.values()), parts, samples[:, :, :own])

    def _offer(self, ctx: TaskContext) -> None:
        """Reservoir sampling of the step's scenes with their current outputs. The places are
        drawn first and the outputs computed only when a scene is kept: once the reservoir is
        full, most steps keep none (``point`` draws no random numbers, so the run is the same)."""
        batch = ctx.batch
        bounds = batch.bounds
        kept = []  # (first agent, last agent, reservoir slot) of each scene kept, in order
        filled = len(self.scenes)
        for first, last in zip(bounds[:-1], bounds[1:], strict=True):
            self.seen += 1
            if filled < self.options.buffer:
                kept.append((first, last, filled))
                filled += 1
                continue
            slot = int(ctx.rng.integers(self.seen))
            if slot < self.options.buffer:
                kept.append((first, last, slot))
        if not kept:
            return
        with torch.no_grad():
            outputs = ctx.model.point(batch)
        positions = torch.cat([batch.obs, batch.fut]).transpose(0, 1)
        for first, last, slot in kept:
            scene, output = positions[first:last].clone(), outputs[:, first:last].clone()
            if slot == len(self.scenes):
                self.scenes.append(scene)
                self.outputs.append(output)
            else:
                self.scenes[slot], self.outputs[slot] = scene, output

    def before_backward(self, ctx: TaskContext) -> None:
        self._offer(ctx)

    def state_dict(self, model: torch.nn.Module) -> dict[str, Any]:
        return {"scenes": list(self.scenes), "outputs": list(self.outputs), "seen": self.seen}

    def load_state_dict(self, state: dict[str, Any], model: torch.nn.Module) -> None:
        self.scenes, self.outputs = list(state["scenes"]), list(state["outputs"])
        self.seen = int(state["seen"])

    def summary(self) -> dict[str, Any]:
        return {"buffer_scenes": len(self.scenes)}
