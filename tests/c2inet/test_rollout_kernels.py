"""The compiled steps' transcendentals: a rational tanh within a few units in the last place of
float32, and the sigmoid made from it within float32 rounding of the exact one."""

import numpy as np
import pytest

from c2inet.kernels.steps import NUMBA_OPTIONS, _sigmoid32, tanh32

njit = pytest.importorskip("numba", exc_type=ImportError).njit  # none without numba


@njit(**{**NUMBA_OPTIONS, "cache": False})  # as the kernels compile it
def _apply(x, sigmoid):  # pragma: no cover (compiled)
    out = np.empty_like(x)
    for j in range(len(x)):
        out[j] = _sigmoid32(x[j]) if sigmoid else tanh32(x[j])
    return out


def grid() -> np.ndarray:
    tiny = np.geomspace(1e-9, 1, 20_001)
    return np.concatenate([np.linspace(-30, 30, 600_001), tiny, -tiny, [0.0]]).astype(np.float32)


def test_tanh32_is_within_five_units_in_the_last_place():
    x = grid()
    exact = np.tanh(x.astype(np.float64))
    out = _apply(x, False)
    ulps = np.abs(out - exact) / np.spacing(np.abs(exact).astype(np.float32))
    assert ulps.max() <= 5
    assert np.array_equal(_apply(-x, False), -out) and np.abs(out).max() <= 1  # odd, bounded


def test_the_sigmoid_from_it_is_within_float32_rounding_of_the_exact_one():
    x = grid()
    exact = 1 / (1 + np.exp(-x.astype(np.float64)))
    assert np.abs(_apply(x, True) - exact).max() <= 2.5e-7  # 2 ulp at 1
    out = _apply(x, True)
    assert out.min() >= 0 and out.max() <= 1
    assert np.abs(out + _apply(-x, True) - 1).max() <= 2.5e-7
