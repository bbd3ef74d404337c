"""Every registered backbone passes the backbone checker (shapes, padded scenes kept apart, no
future frame in the inputs, determinism, a constant-velocity start, learning), the checker
catches backbones broken on purpose, and every model and method runs on every backbone."""

import pytest
import torch

from c2inet.backbones import BACKBONES
from c2inet.backbones.checker import BackboneCheckError, check_backbone
from c2inet.backbones.stgat import STGAT
from c2inet.batch import make_batch
from c2inet.data import Windows
from c2inet.methods.base import discover
from c2inet.model import C2INetModel, Predictor
from c2inet.model_config import ModelConfig

from toys import toy_windows, turners

NAMES = sorted(BACKBONES)


@pytest.mark.parametrize("name", NAMES)
def test_every_registered_backbone_passes_the_checker(name):
    assert set(NAMES) >= {"stgat", "stgcnn"} and BACKBONES[name].name == name
    check_backbone(BACKBONES[name])


class Peeking(STGAT):
    """Reads the future frames."""

    def encode(self, obs_rel, batch):
        return super().encode(obs_rel, batch) + batch.fut.mean()


class Mixing(STGAT):
    """Pools over the whole batch, across scenes."""

    def encode(self, obs_rel, batch):
        context = super().encode(obs_rel, batch)
        return context + context.mean(0, keepdim=True)


class TimeLast(STGAT):
    """Decodes with the samples first."""

    def decode(self, cond, last_rel):
        return super().decode(cond, last_rel).transpose(0, 1)


class Frozen(STGAT):
    """Its output does not depend on what it learns."""

    def decode(self, cond, last_rel):
        return super().decode(cond, last_rel).detach()


class Restless(STGAT):
    """Draws noise of its own, outside torch's seed."""

    def decode(self, cond, last_rel):
        noise = torch.from_numpy(__import__("numpy").random.default_rng().normal(size=1))
        return super().decode(cond, last_rel) + noise.float()


@pytest.mark.parametrize(
    "broken,message",
    [
        (Peeking, "a future frame reaches the encoder"),
        (Mixing, "another scene of the batch changed"),
        (TimeLast, "decode gave"),
        (Frozen, "does not depend on its parameters"),
        (Restless, "the same seed gave another"),
    ],
)
def test_the_checker_catches_a_broken_backbone(broken, message):
    with pytest.raises(BackboneCheckError, match=message):
        check_backbone(broken)


@pytest.mark.parametrize("name", NAMES)
def test_no_future_frame_reaches_the_models_context_or_prediction(name):
    windows = toy_windows()
    altered = Windows(windows.positions.copy(), windows.scene_start)
    altered.positions[:, 8:] += 100.0
    a, b = make_batch(windows), make_batch(altered)
    config = ModelConfig(backbone=name)
    for model in (Predictor(config), C2INetModel(config)):
        torch.testing.assert_close(model.context(a), model.context(b))
        torch.manual_seed(0)
        first = model.predict(a, 2)
        torch.manual_seed(0)
        torch.testing.assert_close(first, model.predict(b, 2))


@pytest.mark.parametrize("name", NAMES)
def test_every_method_trains_on_every_backbone(name):
    batch = make_batch(turners(0.2, 6, 0))
    for method in discover().values():
        model = method(ModelConfig(backbone=name)).build_model()
        if method.trains:
            model.loss(batch, 2).loss.backward()
        assert model.predict(batch, 2).shape == (2, 12, len(batch.scene_of), 2)


def test_one_option_says_which_kernels_run_resolved_once_for_the_device():
    """``model.kernels``: auto is compiled on the CPU and tensor on a GPU; compiled on a GPU and
    an unknown name are refused; stgat-cell is always the cell; a compiled network moved off
    float32 refuses rather than sniffing another path."""
    from c2inet import kernels
    from c2inet.model_config import ModelConfig

    assert (
        kernels.resolve("auto", "cpu") == "compiled" and kernels.resolve("auto", "cuda") == "tensor"
    )
    assert [kernels.resolve(m, "cpu") for m in ("compiled", "tensor", "cell")] == [
        "compiled",
        "tensor",
        "cell",
    ]
    with pytest.raises(ValueError, match="runs on the CPU, not on cuda"):
        kernels.resolve("compiled", "cuda")
    with pytest.raises(ValueError, match="expected one of auto, compiled, tensor, cell"):
        ModelConfig(kernels="fast")
    assert BACKBONES["stgat-cell"].kernels_for("auto", "cpu") == "cell"
    network = BACKBONES["stgat"](cond_dim=8)
    assert network.kernels == "compiled" and network.encoder.compiled
    assert network.decoder.kernel == "compiled"
    plain = BACKBONES["stgat"](cond_dim=8, kernels="tensor")
    assert not plain.encoder.compiled and plain.decoder.kernel == "tensor"
    network.double()
    with pytest.raises(ValueError, match="float32 CPU tensors"):
        network.decode(
            torch.zeros(1, 3, 8, dtype=torch.float64), torch.zeros(3, 2, dtype=torch.float64)
        )
