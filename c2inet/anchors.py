"""What the network did at samples of old prior components, kept to hold it there (BooVAE's
distillations, C2INet-online's ``distill_decoder`` and ``distill_encoder``): the anchors, and
the two ways to make them (pseudo-inputs decoded from the components, or stored windows)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Protocol

import numpy as np
import torch

from c2inet.batch import Batch, make_batch
from c2inet.data import Windows
from c2inet.gaussians import GaussianMixture, gaussian_sample, responsibilities


class AnchorSource(Protocol):
    """What making anchors asks of a network (C2INet's model has it): its sizes, the past it
    decodes from latents, its posteriors, the decoder's condition and the backbone."""

    config: Any
    backbone: Any

    def reconstruct_past(self, z: torch.Tensor, c: torch.Tensor) -> torch.Tensor: ...

    def posteriors(self, batch: Batch) -> Any: ...

    def conditions(
        self, batch: Batch, post: Any, z: torch.Tensor, c: torch.Tensor
    ) -> torch.Tensor: ...


@dataclass
class Anchors:
    """What the network did at samples of old prior components, to hold it there (BooVAE).

    Latents with z ~ N(0, I) and c from a task's components, the pseudo-input the past decoder
    made of them (single-agent scenes), the decoder's full condition there and what it gave, and
    Q(C|X) at the pseudo-inputs.
    """

    cond: torch.Tensor  # (A, D) the decoder's condition ([context,] z, c)
    last_rel: torch.Tensor  # (A, 2) the pseudo-input's last displacement (normalised)
    future: torch.Tensor  # (12, A, 2) the decoder's output when stored
    inputs: Windows  # the pseudo-inputs (observed frames; the future is unused)
    c_mean: torch.Tensor  # (A, dc) Q(C|X) at the pseudo-inputs when stored
    c_logvar: torch.Tensor

    def __len__(self) -> int:
        return len(self.cond)

    def select(self, index: torch.Tensor) -> Anchors:
        """The anchors at the host's ``index`` (copied to their device, never read back)."""
        rows = index.to(self.cond.device)
        return Anchors(
            self.cond[rows],
            self.last_rel[rows],
            self.future[:, rows],
            self.inputs.subset(index.numpy()),
            self.c_mean[rows],
            self.c_logvar[rows],
        )

    def state_dict(self) -> dict[str, Any]:
        """Tensors and plain values only, for checkpoints (resume)."""
        state = {f.name: getattr(self, f.name) for f in fields(self)}
        return {**state, "inputs": self.inputs.state_dict()}

    @staticmethod
    def from_state(state: dict[str, Any]) -> Anchors:
        return Anchors(**{**state, "inputs": Windows.from_state(state["inputs"])})

    @staticmethod
    def concat(parts: list[Anchors]) -> Anchors:
        return Anchors(
            torch.cat([p.cond for p in parts]),
            torch.cat([p.last_rel for p in parts]),
            torch.cat([p.future for p in parts], dim=1),
            Windows.concat([p.inputs for p in parts]),
            torch.cat([p.c_mean for p in parts]),
            torch.cat([p.c_logvar for p in parts]),
        )


@torch.no_grad()
def make_anchors(model: AnchorSource, components: GaussianMixture, count: int) -> Anchors:
    """Anchors of one task: latents from its components and what the network made of them."""
    device = components.means.device
    z, c = torch.randn(1, count, model.config.z_dim, device=device), components.sample(count)[None]
    past = model.reconstruct_past(z, c)[:, 0]  # (7, A, 2)
    observed = torch.cat([past.new_zeros(1, count, 2), past.cumsum(0)])  # (8, A, 2)
    frames = torch.cat([observed, observed[-1:].expand(12, count, 2)])  # the future is unused
    inputs = Windows(frames.transpose(0, 1).cpu().numpy().copy(), np.arange(count + 1))
    batch = make_batch(inputs, device=device)
    post = model.posteriors(batch)
    cond = model.conditions(batch, post, z, c)  # single-agent scenes: per scene is per agent
    future = model.backbone.decode(cond, past[-1])[:, 0]
    return Anchors(cond[0], past[-1], future, inputs, post.c_mean, post.c_logvar)


@torch.no_grad()
def anchors_from_windows(
    model: AnchorSource, windows: Windows, components: GaussianMixture, count: int
) -> Anchors:
    """Anchors at stored training windows: ``count`` agents of ``windows`` (each its own
    one-agent pseudo-scene, its observed past in metres), C drawn from the component of
    ``components`` most responsible for its Q(C|X), Z ~ N(0, I), and what the network made of
    them. The inputs are data and the latents follow the components they stand for."""
    device = components.means.device
    pick = torch.randperm(len(windows.positions), device="cpu")[:count].sort().values.numpy()
    inputs = Windows(windows.positions[pick].copy(), np.arange(len(pick) + 1))
    batch = make_batch(inputs, device=device)
    post = model.posteriors(batch)
    k = responsibilities(components, post.c_mean, post.c_logvar).argmax(-1)
    noise = torch.randn(1, *post.c_mean.shape, device=device)
    c = gaussian_sample(components.means[k], components.logvars[k], noise)
    z = torch.randn(1, len(pick), model.config.z_dim, device=device)
    cond = model.conditions(batch, post, z, c)
    future = model.backbone.decode(cond, batch.last_rel)[:, 0]
    return Anchors(cond[0], batch.last_rel, future, inputs, post.c_mean, post.c_logvar)
