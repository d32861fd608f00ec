"""The noise models' non-negative least squares against scipy.optimize.nnls."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import nnls as scipy_nnls

from handeye_cli.numeric.nnls import nnls


@pytest.mark.parametrize("seed", range(40))
def test_equals_scipy_on_random_fits(seed: int) -> None:
    rng = np.random.default_rng(seed)
    m, n = int(rng.integers(5, 400)), int(rng.integers(1, 7))
    A = rng.normal(size=(m, n)) * 10.0 ** rng.uniform(-3, 3, n)        # columns on different scales
    b = A @ rng.normal(size=n) + 0.1 * rng.normal(size=m)               # some coefficients want to be < 0
    x, r = nnls(A, b)
    xs, rs = scipy_nnls(A, b)
    assert (x >= 0).all()
    assert r == pytest.approx(rs, rel=1e-10, abs=1e-12)
    np.testing.assert_allclose(A @ x, A @ xs, rtol=1e-9, atol=1e-9 * np.abs(b).max())
    np.testing.assert_array_equal(x > 0, xs > 0)


def test_noise_model_designs() -> None:
    """Variance fits as the noise model makes them: positive features, squared residuals, a floor."""
    rng = np.random.default_rng(3)
    dt = rng.uniform(0.05, 20.0, 2000)
    path = 0.5 * dt * rng.uniform(0.8, 1.2, 2000)                       # nearly collinear with dt
    lever = rng.uniform(0.0, 0.2, 2000)
    design = np.column_stack([np.ones_like(dt), dt, path, lever, dt * lever])
    for terms in ([1e-6, 0, 0, 1e-4, 0], [1e-6, 2e-7, 0, 0, 0], [0, 0, 3e-7, 1e-5, 1e-7]):
        r2 = (design @ np.array(terms)) * rng.chisquare(3, 2000) / 3
        scale = design.max(axis=0)
        x, r = nnls(design / scale, r2)
        xs, rs = scipy_nnls(design / scale, r2)
        assert r == pytest.approx(rs, rel=1e-9)
        np.testing.assert_allclose(x, xs, rtol=1e-6, atol=1e-12 * r2.max())


def test_bounds_and_degenerate_cases() -> None:
    A = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    x, r = nnls(A, np.array([2.0, 1.0, 1.0]))
    np.testing.assert_allclose(x, [1.5, 1.0])
    assert r == pytest.approx(np.sqrt(0.5))
    x, r = nnls(A, -np.ones(3))                                          # every coefficient at its bound
    np.testing.assert_array_equal(x, [0.0, 0.0])
    assert r == pytest.approx(np.sqrt(3.0))
    x, r = nnls(np.zeros((4, 2)), np.ones(4))                            # no column moves the residual
    np.testing.assert_array_equal(x, [0.0, 0.0])
    twin = np.column_stack([np.arange(5.0), np.arange(5.0)])             # two equal columns: the fit, not x, is unique
    x, r = nnls(twin, np.arange(5.0) * 2)
    assert (x >= 0).all() and r == pytest.approx(0.0, abs=1e-12) and x.sum() == pytest.approx(2.0)


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("units", [1e-6, 1.0, 1e6])
def test_coefficients_in_any_units_without_scipys_fallback(seed: int, units: float, monkeypatch) -> None:
    """Large design entries and small coefficients (the noise models' variance fits: entries ~1e6, x ~1e-5,
    where the gradient's tolerance is far above every x): Lawson and Hanson's steps back to the bound
    must not drop the columns that are off it. The fits must end without scipy's fallback."""
    import scipy.optimize

    monkeypatch.setattr(scipy.optimize, "nnls", lambda *a: pytest.fail("fell back to scipy"))
    rng = np.random.default_rng(100 + seed)
    m, n = 200, 5
    base = rng.uniform(0.0, 1.0, (m, 1))
    A = np.column_stack([np.ones(m), base, base * rng.uniform(0.99, 1.01, (m, 1)), rng.uniform(0, 1, (m, 2))])
    A *= 1e6 * units                                                     # nearly collinear columns 1 and 2
    truth = rng.uniform(0.0, 1.0, n) * (rng.random(n) < 0.6)
    b = A @ truth * 1e-5 / units ** 2 * rng.chisquare(3, m) / 3          # coefficients ~1e-5 / units²
    x, r = nnls(A, b)
    xs, rs = scipy_nnls(A, b)
    assert (x >= 0).all()
    assert r == pytest.approx(rs, rel=1e-9)
    np.testing.assert_allclose(A @ x, A @ xs, rtol=1e-7, atol=1e-9 * np.abs(b).max())
