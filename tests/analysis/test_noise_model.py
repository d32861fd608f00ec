"""The noise model (handeye_cli.analysis.noise_model): known variance terms recovered, outliers
trimmed, drifting and absolute recordings told apart, residuals in the cost's units."""
from __future__ import annotations

import numpy as np
import pytest

from handeye_cli.analysis.noise_model import PairFeatures, cost_residuals, fit_noise_model
from handeye_cli.analysis.residuals import pair_residuals
from handeye_cli.analysis.selection import select_pairs
from handeye_cli.simulation import motion_pairs, random_transform
from handeye_cli.simulation.recordings import scenario
from handeye_cli.stages.gates import pose_jump_gate
from handeye_cli.stages.sync import associate


def _draw(rng: np.random.Generator, variance: np.ndarray) -> np.ndarray:
    """Residual norms of 3-vectors with isotropic Gaussian components of total variance ``variance``."""
    return np.sqrt(variance * rng.chisquare(3, len(variance)) / 3)


def test_known_terms_are_recovered_and_outliers_trimmed() -> None:
    rng = np.random.default_rng(0)
    n = 6000
    f = PairFeatures(rng.uniform(0.05, 10.0, n), rng.uniform(0.0, 3.0, n), rng.uniform(0.0, 4.0, n))
    rot_terms = np.array([1e-6, 4e-6, 0.0])                     # floor (0.06°)² + 4e-6 rad²/s
    dual_terms = np.array([4e-6, 2e-5, 0.0, 3e-6, 0.0])          # floor (2 mm)², drift, lever
    r_rot, r_dual = _draw(rng, f.rot_design() @ rot_terms), _draw(rng, f.dual_design() @ dual_terms)
    bad = rng.choice(n, 120, replace=False)
    r_rot[bad] *= 40.0
    r_dual[bad] *= 40.0
    model = fit_noise_model(r_rot, r_dual, f)
    good = np.setdiff1d(np.arange(n), bad)
    sub = PairFeatures(f.dt_s[good], f.path_m[good], f.lever2_m2[good])
    np.testing.assert_allclose(model.rot_variance(sub), sub.rot_design() @ rot_terms, rtol=0.15)
    np.testing.assert_allclose(model.dual_variance(sub), sub.dual_design() @ dual_terms, rtol=0.2)
    assert model.outliers >= len(bad)
    assert model.kind == "drifting"


def test_constant_noise_is_absolute() -> None:
    rng = np.random.default_rng(1)
    n = 3000
    f = PairFeatures(rng.uniform(0.05, 30.0, n), rng.uniform(0.0, 10.0, n), rng.uniform(0.0, 4.0, n))
    model = fit_noise_model(_draw(rng, np.full(n, 1e-5)), _draw(rng, np.full(n, 4e-6)), f)
    assert model.kind == "absolute"
    d = model.as_dict()
    assert d["kind"] == "absolute"
    assert d["rotation"]["floor_deg"] == pytest.approx(np.rad2deg(np.sqrt(1e-5)), rel=0.1)
    assert d["translation"]["floor_m"] == pytest.approx(2e-3, rel=0.1)


def test_cost_residuals_read_as_radians_and_metres_for_small_errors() -> None:
    rng = np.random.default_rng(2)
    X = random_transform(rng, 0.3)
    A, B = motion_pairs(200, X, rng, "random", np.deg2rad(0.05), 0.0)
    r_rot, _ = cost_residuals(A, B, X)
    np.testing.assert_allclose(np.rad2deg(r_rot), pair_residuals(A, B, X).rotation_deg, rtol=1e-3)
    A, B = motion_pairs(200, X, rng, "random", 0.0, 0.001)
    _, r_dual = cost_residuals(A, B, X)
    np.testing.assert_allclose(r_dual, pair_residuals(A, B, X).translation_m, rtol=1e-3)


@pytest.mark.parametrize("name, kind", [("vio-vio", "drifting"), ("mocap-mocap", "absolute"), ("arm", "absolute")])
def test_recording_kinds_are_told_apart(name: str, kind: str) -> None:
    rec = scenario(name, seed=5, duration_s=30)
    synced, _ = pose_jump_gate(associate(rec.a, rec.b, time_offset_ns=rec.rig.time_offset_ns)[0])
    model = select_pairs(synced).model
    assert model is not None and model.kind == kind
