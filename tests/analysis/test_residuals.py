"""Per-pair residuals of A_i X = X B_i (handeye_cli.analysis.residuals) against closed-form truth."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from handeye_cli.analysis import extrinsic_error, pair_residuals, summarize
from handeye_cli.analysis.residuals import Residuals
from handeye_cli.errors import HandEyeError
from handeye_cli.geometry import se3
from handeye_cli.simulation import motion_pairs, random_transform


def _rot(rotvec):
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    return T


def test_noise_free_residuals_vanish():
    rng = np.random.default_rng(0)
    X = random_transform(rng)
    A, B = motion_pairs(200, X, rng, "random")
    r = pair_residuals(A, B, X)
    assert r.rotation_deg.shape == (200,) and r.translation_m.shape == (200,)
    assert r.rotation_deg.max() < 1e-9 and r.translation_m.max() < 1e-12


def test_rotation_residual_exact_for_half_turn():
    """A: 180° about z. X' = Rot(x, 1°) X gives R_A R' vs R' R_B differing by exactly 2° (sign flip of q)."""
    rng = np.random.default_rng(1)
    X = random_transform(rng)
    A = _rot([0.0, 0.0, np.pi])[None].repeat(3, axis=0)
    A[:, :3, 3] = rng.normal(size=(3, 3))
    B = se3.inverse(X) @ A @ X
    r = pair_residuals(A, B, _rot(np.deg2rad([1.0, 0.0, 0.0])) @ X)
    np.testing.assert_allclose(r.rotation_deg, 2.0, rtol=1e-9)


def test_translation_residual_exact_for_offset():
    """Shifting t_X by δ (frame a) under a 90° turn of a gives |(R_A - I) δ| = √2 |δ|, no rotation residual."""
    rng = np.random.default_rng(2)
    X = random_transform(rng)
    A = _rot([0.0, 0.0, np.pi / 2])[None].repeat(4, axis=0)
    A[:, :3, 3] = rng.normal(size=(4, 3))
    B = se3.inverse(X) @ A @ X
    Xs = X.copy()
    Xs[:3, 3] += [0.01, 0.0, 0.0]
    r = pair_residuals(A, B, Xs)
    np.testing.assert_allclose(r.translation_m, np.sqrt(2) * 0.01, rtol=1e-9)
    assert r.rotation_deg.max() < 1e-9


def test_matches_matrix_computation_on_noisy_data():
    rng = np.random.default_rng(3)
    X = random_transform(rng)
    A, B = motion_pairs(50, X, rng, "random", np.deg2rad(2.0), 0.05)
    r = pair_residuals(A, B, X)
    L, R = A @ X, X @ B
    np.testing.assert_allclose(r.rotation_deg, np.rad2deg(se3.rotation_angle(se3.inverse(L) @ R)), atol=1e-9)
    np.testing.assert_allclose(r.translation_m, np.linalg.norm(L[:, :3, 3] - R[:, :3, 3], axis=1), atol=1e-12)


def test_summary_and_mask():
    r = Residuals(np.arange(1.0, 101.0), np.arange(1.0, 101.0) / 100)
    s = summarize(r)
    assert s.rotation_median_deg == pytest.approx(50.5) and s.rotation_max_deg == 100.0
    assert s.rotation_p95_deg == pytest.approx(95.05) and s.translation_p95_m == pytest.approx(0.9505)
    m = r.summary(mask=np.arange(100) < 10)
    assert m.rotation_max_deg == 10.0 and set(m.as_dict()) >= {"rotation_median_deg", "translation_p95_m"}


def test_extrinsic_error():
    rng = np.random.default_rng(4)
    X = random_transform(rng)
    Y = X.copy()
    Y[:3, :3] = Rotation.from_rotvec(np.deg2rad([0.0, 3.0, 4.0])).as_matrix() @ X[:3, :3]
    Y[:3, 3] += [0.3, 0.4, 0.0]
    rot, trans = extrinsic_error(Y, X)
    assert rot == pytest.approx(5.0) and trans == pytest.approx(0.5)


def test_bad_shape_is_a_handeye_error():
    with pytest.raises(HandEyeError):
        pair_residuals(np.eye(4)[None].repeat(3, 0), np.eye(4)[None].repeat(2, 0), np.eye(4))
