"""Every registered backbone against one contract: shapes, padded scenes kept apart, no future
frame in the inputs, determinism, a constant-velocity start, and learning."""

import numpy as np
import pytest
import torch

from c2inet.backbones import BACKBONES
from c2inet.batch import make_batch
from c2inet.data import Windows
from c2inet.methods.base import discover
from c2inet.model import C2INetModel, ModelConfig, Predictor

from toys import toy_windows, turners

NAMES = sorted(BACKBONES)


@pytest.mark.parametrize("name", NAMES)
def test_shapes(name):
    batch = make_batch(toy_windows())
    backbone = BACKBONES[name](cond_dim=10)
    context = backbone.encode(batch.obs_rel, batch)
    assert context.shape == (len(batch.scene_of), backbone.context_dim)
    cond = torch.randn(3, len(batch.scene_of), 10)
    assert backbone.decode(cond, batch.obs_rel[-1]).shape == (12, 3, len(batch.scene_of), 2)


@pytest.mark.parametrize("name", NAMES)
def test_scenes_padded_into_one_batch_stay_apart(name):
    windows = toy_windows(5)
    backbone = BACKBONES[name](cond_dim=10)
    before = backbone.encode(make_batch(windows).obs_rel, make_batch(windows))
    moved = Windows(windows.positions.copy(), windows.scene_start)
    last = slice(windows.scene_start[-2], windows.scene_start[-1])
    moved.positions[last] += np.random.default_rng(0).normal(size=moved.positions[last].shape)
    batch = make_batch(moved)
    after = backbone.encode(batch.obs_rel, batch)
    others = slice(0, windows.scene_start[-2])
    torch.testing.assert_close(before[others], after[others])
    assert not torch.allclose(before[last], after[last])


@pytest.mark.parametrize("name", NAMES)
def test_no_future_frame_reaches_the_encoder_or_the_prediction(name):
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
def test_same_seed_same_backbone_and_output(name):
    batch = make_batch(toy_windows())
    outputs = []
    for _ in range(2):
        torch.manual_seed(3)
        backbone = BACKBONES[name](cond_dim=10)
        cond = torch.randn(2, len(batch.scene_of), 10)
        outputs.append(backbone.decode(cond, batch.obs_rel[-1]))
    torch.testing.assert_close(outputs[0], outputs[1], rtol=0, atol=0)


@pytest.mark.parametrize("name", NAMES)
def test_an_untrained_residual_decoder_starts_at_constant_velocity(name):
    batch = make_batch(toy_windows())
    backbone = BACKBONES[name](cond_dim=10, residual=True)
    out = backbone.decode(torch.randn(2, len(batch.scene_of), 10), batch.obs_rel[-1])
    torch.testing.assert_close(out, batch.obs_rel[-1].expand(12, 2, -1, 2))


@pytest.mark.parametrize("name", NAMES)
def test_every_method_trains_on_every_backbone(name):
    batch = make_batch(turners(0.2, 6, 0))
    for method in discover().values():
        model = method(ModelConfig(backbone=name)).build_model()
        if method.trains:
            model.loss(batch, 2).loss.backward()
        assert model.predict(batch, 2).shape == (2, 12, len(batch.scene_of), 2)


@pytest.mark.parametrize("name", NAMES)
def test_the_backbone_learns(name):
    torch.manual_seed(0)
    model = Predictor(ModelConfig(backbone=name))
    optimiser = torch.optim.Adam(model.parameters(), lr=3e-3)
    batch = make_batch(turners(0.2, 16, 0))
    first = model.loss(batch).loss.item()
    for _ in range(60):
        optimiser.zero_grad()
        model.loss(batch).loss.backward()
        optimiser.step()
    assert model.loss(batch).loss.item() < 0.5 * first
