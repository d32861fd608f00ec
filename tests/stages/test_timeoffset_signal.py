"""The time offset's numpy pieces against the scipy routines they replace (and it does not import):
the FFT length and cross-correlation (scipy.fft, scipy.signal), the peak search (scipy.signal), the
smoothing, median and minimum filters (scipy.ndimage) and Brent's bounded minimiser (scipy.optimize)."""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from scipy import fft, ndimage, optimize, signal

from handeye_cli.numeric.minimize import minimize_bounded
from handeye_cli.simulation import Rig, random_transform, simulate_rig
from handeye_cli.stages import timeoffset
from handeye_cli.stages.timeoffset import _correlate, _prominent_peaks


@pytest.mark.parametrize("seed", range(10))
def test_correlation_equals_scipy(seed: int) -> None:
    rng = np.random.default_rng(seed)
    v, u = rng.normal(size=int(rng.integers(1, 3000))), rng.normal(size=int(rng.integers(1, 3000)))
    expected = signal.correlate(v, u, mode="full", method="fft")
    got = _correlate(v, u)
    assert got.shape == expected.shape
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
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


def test_fft_lengths_equal_scipys() -> None:
    sizes = [*range(1, 3000), 2**20 - 1, 2**20 + 1, 3**11 + 1, 5**8 - 1, 999_983, 12_345_678]
    assert [timeoffset._fast_len(n) for n in sizes] == [fft.next_fast_len(n, real=True) for n in sizes]


@pytest.mark.parametrize("seed", range(8))
def test_smoothing_equals_scipys(seed: int) -> None:
    """Same kernel (radius, normalisation) and edges (repeated samples), on lengths down to shorter
    than the kernel and σ from below a sample to 50 samples (a 4 Hz stream's)."""
    rng = np.random.default_rng(seed)
    for m in (1, 2, 7, int(rng.integers(3, 400)) | 1, int(rng.integers(400, 3000))):
        x = rng.normal(size=(m, 3)).cumsum(axis=0) + rng.normal(size=3) * 10
        for sigma in (0.4, 1.0, float(rng.uniform(1, 10)), 50.0):
            expected = ndimage.gaussian_filter1d(x, sigma, axis=0, mode="nearest", truncate=timeoffset._TRUNCATE)
            np.testing.assert_allclose(timeoffset._gaussian_filter(x, sigma), expected, rtol=0,
                                       atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("seed", range(8))
def test_median_filter_equals_scipys(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for m in (1, 4, 11, 12, int(rng.integers(13, 5000))):
        x = rng.exponential(size=m)
        x[rng.random(m) < 0.3] = 2.0                     # ties
        for size in (1, 3, 11):
            expected = ndimage.median_filter(x, size=size, mode="nearest")
            np.testing.assert_array_equal(timeoffset._median_filter(x, size), expected)


@pytest.mark.parametrize("seed", range(8))
def test_erosion_equals_scipys_minimum_filter(seed: int) -> None:
    """Masks with invalid stretches and lone gaps, windows wider than the mask; both modes the stage used."""
    rng = np.random.default_rng(seed)
    for m in (1, 5, int(rng.integers(6, 3000))):
        mask = rng.random(m) > rng.choice([0.0, 0.02, 0.3])
        mask[rng.integers(m):][:int(rng.integers(1, 20))] = False
        for size in (1, 3, 23, 2 * m + 1):
            for mode in ("nearest", "reflect"):
                expected = ndimage.minimum_filter1d(mask.astype(np.uint8), size, mode=mode).astype(bool)
                np.testing.assert_array_equal(timeoffset._erode(mask, size), expected)
    assert timeoffset._erode(np.ones(4, dtype=bool), 3).dtype == bool


def _scipy_minimum(f: Callable[[float], float], lo: float, hi: float, xatol: float) -> tuple[float, int]:
    """(scipy's minimum, its evaluations); where f is inf its parabola is NaN (inf − inf), as ours is."""
    with np.errstate(invalid="ignore"):
        res = optimize.minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": xatol})
    return float(res.x), int(res.nfev)


def _counted(f: Callable[[float], float], calls: list[float]) -> Callable[[float], float]:
    def counted(x: float) -> float:
        calls.append(x)
        return f(x)
    return counted


def _functions(rng: np.random.Generator) -> list[tuple[Callable[[float], float], float, float]]:
    c = float(rng.uniform(-1, 1))
    return [
        (lambda x: (x - c) ** 2, -1.0, 1.0),                                   # smooth
        (lambda x: abs(x - c) + 0.1 * (x - c) ** 2, -2.0, 2.0),                # a kink at the minimum
        (lambda x: np.sin(7 * x) + 0.3 * x * x, -3.0, 3.0),                    # several local minima
        (lambda x: x ** 3, 0.5, 2.0),                                           # the minimum at a bound
        (lambda x: np.inf if x < c - 0.5 else (x - c) ** 2, -2.0, 2.0),        # no overlap: inf, as the costs
        (lambda x: ((x - 1.2e11 - 3e6 * c) / 1e6) ** 2 + 1.0, 1.2e11 - 2.5e8, 1.2e11 + 2.5e8),   # offsets in ns
    ]


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("xatol", [1e-6, 1e-3, 1e3])
def test_the_minimiser_agrees_with_scipys(seed: int, xatol: float) -> None:
    """To the tolerance, and step for step (as many evaluations)."""
    for f, lo, hi in _functions(np.random.default_rng(seed)):
        calls: list[float] = []
        got = minimize_bounded(_counted(f, calls), lo, hi, xatol=xatol)
        expected, evaluations = _scipy_minimum(f, lo, hi, xatol)
        assert lo <= got <= hi and abs(got - expected) <= xatol and len(calls) == evaluations


def test_the_minimiser_stops_at_maxiter_and_checks_its_bounds() -> None:
    calls: list[float] = []
    minimize_bounded(_counted(lambda x: (x - 0.3) ** 2, calls), 0.0, 1.0, xatol=1e-12, maxiter=5)
    assert len(calls) == 5
    with pytest.raises(ValueError, match="bounds"):
        minimize_bounded(abs, 1.0, 0.0, xatol=1e-6)


def test_the_refinements_find_scipys_minimum_on_a_simulated_rig() -> None:
    """The ω refinement (τ in s, tolerance 1 µs) and the step refinement (ns, tolerance 1 µs) on their
    own costs: the minimum agrees with scipy's to the tolerance."""
    offset = 12_345_678_901
    a, b = simulate_rig(Rig(random_transform(np.random.default_rng(3), 0.3), offset), duration_s=12, rate_a=100,
                        rate_b=5, sigma_r=np.deg2rad(0.1), sigma_t=0.002, seed=3)
    sa, sb = timeoffset.angular_velocity(a, 200_000_000, 2e8), timeoffset.angular_velocity(b, 200_000_000, 2e8)
    ref = timeoffset._Refiner(sa, sb, offset + 3e6)
    tau0 = (offset + 3e6 - ref.base_ns) / 1e9
    got = minimize_bounded(ref.cost, tau0 - 0.05, tau0 + 0.05, xatol=1e-6)
    assert abs(got - _scipy_minimum(ref.cost, tau0 - 0.05, tau0 + 0.05, 1e-6)[0]) <= 1e-6
    steps = timeoffset._StepRefiner(a, b)
    got = minimize_bounded(steps.cost, offset - 5e7, offset + 5e7, xatol=1e3)
    assert abs(got - _scipy_minimum(steps.cost, offset - 5e7, offset + 5e7, 1e3)[0]) <= 1e3
    assert abs(got - offset) < 1e6                        # and it is the offset
