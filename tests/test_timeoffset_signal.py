"""The time offset's cross-correlation and peak search against scipy.signal (which it does not import)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from handeye_cli.stages.timeoffset import _correlate, _prominent_peaks


@pytest.mark.parametrize("seed", range(10))
def test_correlation_equals_scipy(seed: int) -> None:
    rng = np.random.default_rng(seed)
    v, u = rng.normal(size=int(rng.integers(1, 3000))), rng.normal(size=int(rng.integers(1, 3000)))
    expected = signal.correlate(v, u, mode="full", method="fft")
    got = _correlate(v, u)
    assert got.shape == expected.shape
    np.testing.assert_allclose(got, expected, atol=1e-9 * np.abs(expected).max())
    np.testing.assert_array_equal(np.arange(-(len(u) - 1), len(v)), signal.correlation_lags(len(v), len(u)))


def _signals():
    rng = np.random.default_rng(7)
    t = np.linspace(0, 40, 4000)
    for k in range(12):
        x = np.sin(t * (1 + k / 3)) * np.exp(-((t - 20) / (5 + k)) ** 2) + 0.05 * rng.normal(size=len(t))
        yield np.where(rng.random(len(t)) < 0.1 * (k % 3), -1.0, x)             # masked stretches, as the search
    x = np.round(np.sin(np.linspace(0, 30, 3000)) * 8) / 8                        # plateaus everywhere
    yield x
    yield np.r_[0.0, 1.0, 1.0, 0.5, 2.0, 2.0, 2.0]                               # a plateau running to the end
    yield np.ones(5)


@pytest.mark.parametrize("x", list(_signals()))
@pytest.mark.parametrize("prominence", [0.01, 0.05, 0.3])
def test_peaks_equal_scipys_above_a_height(x: np.ndarray, prominence: float) -> None:
    height = float(np.quantile(x, 0.5))
    peaks, _ = signal.find_peaks(x, prominence=prominence)
    np.testing.assert_array_equal(_prominent_peaks(x, prominence, height), peaks[x[peaks] >= height])
