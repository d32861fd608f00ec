"""solvers.refine: the maximum-likelihood refinement of X (and b's scale) under the motions' noise."""
from __future__ import annotations

import importlib.util
import sys

import numpy as np
import pytest
from _util import ROOT
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from handeye_cli.errors import ConfigError, DataError, HandEyeError, UnderdeterminedError
from handeye_cli.geometry import se3
from handeye_cli.simulation import perturb
from handeye_cli.simulation.arm import look_at_stations
from handeye_cli.solvers import solve
from handeye_cli.solvers.refine import (
    Chain,
    _model,
    band_factor,
    gaussian_terms,
    motion_covariances,
    refine,
    refine_poses,
    residual_covariances,
)

CHI2_6_95 = 12.591587243743977          # χ²₆ quantile of 0.95
ROBOT, CAMERA = (1e-4, 1e-4), (5e-3, 2e-4)   # perturb's σ_r [rad] (angle), σ_t [m]: rotation-dominated camera


def _capture(seed: int, stations: int = 20, pairs: str = "consecutive", noise: bool = True
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Motions A, B, their covariances and the truth X of look-at stations with perturb's noise."""
    rng = np.random.default_rng(seed)
    Ta, Tb, X = look_at_stations(stations, rng)
    if noise:
        Ta, Tb = perturb(Ta, rng, *ROBOT), perturb(Tb, rng, *CAMERA)
    if pairs == "all":
        i, j = np.triu_indices(stations, 1)
    elif pairs == "disjoint":               # independent pairs: (0, 1), (2, 3), …
        i, j = np.arange(0, stations - 1, 2), np.arange(1, stations, 2)
    else:
        i, j = np.arange(stations - 1), np.arange(1, stations)
    cov_a = motion_covariances(Ta[i], Ta[j], ROBOT[0] / np.sqrt(3), ROBOT[1])
    cov_b = motion_covariances(Tb[i], Tb[j], CAMERA[0] / np.sqrt(3), CAMERA[1])
    return se3.relative(Ta[i], Ta[j]), se3.relative(Tb[i], Tb[j]), cov_a, cov_b, X


def _scaled(B: np.ndarray, s: float) -> np.ndarray:
    out = B.copy()
    out[:, :3, 3] /= s
    return out


def test_noise_free_motions_give_x_and_the_scale_exactly() -> None:
    A, B, ca, cb, X = _capture(0, noise=False)
    X0 = perturb(X, np.random.default_rng(1), 0.05, 0.02)
    r = refine(A, B, X0, ca, cb)
    assert r.converged and r.scale is None and r.covariance.shape == (6, 6)
    assert np.abs(r.matrix - X).max() < 1e-9 and r.cost < 1e-12 < r.cost_start
    s = refine(A, _scaled(B, 1.7), X0, ca, cb, scale=1.0)
    assert s.converged and s.covariance.shape == (7, 7)
    assert np.abs(s.matrix - X).max() < 1e-9 and abs(s.scale - 1.7) < 1e-9


@pytest.mark.parametrize("scale", [None, 1.3])
def test_scipy_least_squares_on_the_whitened_residuals_agrees(scale: float | None) -> None:
    """Σ frozen at refine's answer, an absolute parametrisation (rotation vector of R, t, s) and scipy's
    rotations for the residual: the same X to 1e-8."""
    A, B, ca, cb, _ = _capture(3)
    if scale is not None:
        B = _scaled(B, scale)
    X0 = solve(A, _scaled(B, 1 / scale) if scale else B).matrix
    r = refine(A, B, X0, ca, cb, scale=None if scale is None else 1.0)
    assert r.converged
    sigma = residual_covariances(A, B, r.matrix, ca, cb, r.scale)
    W = np.linalg.inv(np.linalg.cholesky(sigma))

    def whitened(p: np.ndarray) -> np.ndarray:
        R = Rotation.from_rotvec(p[:3]).as_matrix()
        s = p[6] if scale is not None else 1.0
        rot = Rotation.from_matrix(R.T @ A[:, :3, :3] @ R @ B[:, :3, :3].transpose(0, 2, 1)).as_rotvec()
        tra = A[:, :3, :3] @ p[3:6] + A[:, :3, 3] - s * B[:, :3, 3] @ R.T - p[3:6]
        return np.einsum("nij,nj->ni", W, np.c_[rot, tra]).ravel()

    p0 = np.r_[Rotation.from_matrix(X0[:3, :3]).as_rotvec(), X0[:3, 3], [] if scale is None else [1.0]]
    fit = least_squares(whitened, p0, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    assert np.abs(Rotation.from_rotvec(fit.x[:3]).as_matrix() - r.matrix[:3, :3]).max() < 1e-8
    assert np.abs(fit.x[3:6] - r.matrix[:3, 3]).max() < 1e-8
    assert fit.cost * 2 == pytest.approx(r.cost, rel=1e-9)
    if scale is not None:
        assert abs(fit.x[6] - r.scale) < 1e-8 and abs(r.scale - scale) < 0.05


def test_analytic_jacobians_match_finite_differences() -> None:
    """``∂r/∂(ω, v, log s)`` and ``∂r/∂(noise of A, B)`` (the motion's ``(R Exp(ε_rot), t + ε_tra)``)."""
    A, B, _, _, X = _capture(5, stations=6)
    X = perturb(X, np.random.default_rng(2), 0.02, 0.01)           # residuals far from zero
    s, h = 1.2, 1e-6
    r0, J, Ja, Jb = _model(A, B, X, s)

    def moved(T: np.ndarray, d: np.ndarray) -> np.ndarray:
        out = T.copy()
        out[..., :3, :3] = T[..., :3, :3] @ Rotation.from_rotvec(d[:3]).as_matrix()
        out[..., :3, 3] = T[..., :3, 3] + d[3:]
        return out

    for k in range(7):
        d = np.zeros(7)
        d[k] = h
        Xp, Xm = X.copy(), X.copy()
        Xp[:3, :3], Xm[:3, :3] = moved(X, d[:6])[:3, :3], moved(X, -d[:6])[:3, :3]
        Xp[:3, 3], Xm[:3, 3] = X[:3, 3] + X[:3, :3] @ d[3:6], X[:3, 3] - X[:3, :3] @ d[3:6]
        fd = (_model(A, B, Xp, s * np.exp(h * (k == 6)))[0] - _model(A, B, Xm, s * np.exp(-h * (k == 6)))[0]) / (2 * h)
        assert np.abs(fd - J[:, :, k]).max() < 1e-7
    for k in range(6):
        d = np.zeros(6)
        d[k] = h
        fd_a = (_model(moved(A, d), B, X, s)[0] - _model(moved(A, -d), B, X, s)[0]) / (2 * h)
        fd_b = (_model(A, moved(B, d), X, s)[0] - _model(A, moved(B, -d), X, s)[0]) / (2 * h)
        assert np.abs(fd_a - Ja[:, :, k]).max() < 1e-7 and np.abs(fd_b - Jb[:, :, k]).max() < 1e-7


def test_motion_covariances_match_sampled_perturb_noise() -> None:
    rng = np.random.default_rng(7)
    Ta, _, _ = look_at_stations(3, rng)
    sr, st, draws = 5e-3, 2e-4, 40_000
    C = motion_covariances(Ta[[0, 1]], Ta[[1, 2]], sr / np.sqrt(3), st)
    for k, (i, j) in enumerate(((0, 1), (1, 2))):
        M = se3.relative(Ta[i], Ta[j])
        Mn = se3.relative(perturb(np.repeat(Ta[i:i + 1], draws, 0), rng, sr, st),
                          perturb(np.repeat(Ta[j:j + 1], draws, 0), rng, sr, st))
        e = np.c_[Rotation.from_matrix(M[:3, :3].T @ Mn[:, :3, :3]).as_rotvec(), Mn[:, :3, 3] - M[:3, 3]]
        S = np.cov(e.T)
        scale = np.sqrt(np.outer(np.diag(C[k]), np.diag(C[k])))
        assert np.abs((S - C[k]) / scale).max() < 0.04
        assert np.abs(C[k][:3, 3:]).max() > 0.1 * np.sqrt(C[k][0, 0] * C[k][3, 3])   # the lever's correlation
    extra = motion_covariances(Ta[[0]], Ta[[1]], 0.0, 0.0, np.array([[1e-6, 4e-8]]))
    assert np.allclose(extra[0], np.diag([1e-6] * 3 + [4e-8] * 3), atol=1e-20)


@pytest.mark.statistical
def test_the_covariance_covers_the_truth() -> None:
    """The 95 % ellipsoid of ``X̂ Exp(δ)`` (δ in frame b) holds the truth 88–99 % of 60 independent-pair captures."""
    inside = []
    for seed in range(60):
        A, B, ca, cb, X = _capture(seed, stations=40, pairs="disjoint")
        r = refine(A, B, solve(A, B).matrix, ca, cb)
        E = se3.inverse(r.matrix) @ X
        d = np.r_[Rotation.from_matrix(E[:3, :3]).as_rotvec(), E[:3, 3]]
        inside.append(d @ np.linalg.solve(r.covariance, d) <= CHI2_6_95)
    assert 0.88 <= np.mean(inside) <= 0.99


@pytest.mark.statistical
def test_refine_wins_where_rotation_noise_dominates(capsys: pytest.CaptureFixture[str]) -> None:
    """A camera with 5 mrad of rotation noise and 0.2 mm of translation noise 0.1–0.3 m from its target:
    over 30 captures of 20 stations (consecutive pairs) refine's median rotation error is below dqopt's
    (α = 1 and the noise model's α) and Park + LM's, its translation error within 5 % of the best."""
    spec = importlib.util.spec_from_file_location("efficiency", ROOT / "benchmarks" / "efficiency.py")
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    sys.modules["efficiency"] = bench
    spec.loader.exec_module(bench)
    medians, times = bench.table(30, bench.REGIMES["rotation-dominated"], 20, "consecutive")
    with capsys.disabled():
        bench.show("rotation-dominated, 30 seeds, 20 stations, consecutive pairs", medians, times)
    rot, tra = {m: v[0] for m, v in medians.items()}, {m: v[1] for m, v in medians.items()}
    assert rot["refine"] <= min(rot["park+LM"], rot["dqopt a=1"], rot["dqopt auto"])
    assert tra["refine"] <= 1.05 * min(tra["dqopt a=1"], tra["dqopt auto"], tra["park+LM"])


def test_bad_input_fails_loudly() -> None:
    A, B, ca, cb, X = _capture(1, stations=5, noise=False)
    nan = A.copy()
    nan[0, 0, 3] = np.nan
    cases = [((nan, B, X, ca, cb), {}, DataError), ((A[:, :3], B, X, ca, cb), {}, DataError),
             ((A, B, X[:3], ca, cb), {}, DataError), ((A, B, X, ca[:2], cb), {}, DataError),
             ((A, B, X, ca * np.nan, cb), {}, DataError), ((A, B, X, 0 * ca, 0 * cb), {}, DataError),
             ((A, B, X, ca, cb), {"scale": -1.0}, ConfigError),
             ((A, B, X, ca, cb), {"max_iterations": -1}, ConfigError)]
    for args, kwargs, kind in cases:
        with pytest.raises(kind):
            refine(*args, **kwargs)
    with pytest.raises(HandEyeError):
        motion_covariances(np.eye(4), np.eye(4), 1e-3, 1e-3)
    with pytest.raises(ConfigError):
        motion_covariances(A, B, -1.0, 1e-3)
    with pytest.raises(DataError):
        motion_covariances(A, B, 1e-3, 1e-3, extra=np.ones(len(A)))
    same_axis = np.tile(np.eye(4), (4, 1, 1))
    same_axis[:, :3, :3] = Rotation.from_rotvec(np.outer([0.1, 0.2, 0.3, 0.4], [0, 0, 1])).as_matrix()
    with pytest.raises(UnderdeterminedError):
        refine(same_axis, same_axis, np.eye(4), np.eye(6) * 1e-6, np.eye(6) * 1e-6)


# --- refine_poses: the samples' consecutive motions, their neighbours' correlation in a band ---------------------
def _poses(seed: int, stations: int = 20, noise: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Look-at stations (T_base_flange, T_target_camera) with perturb's noise, and the truth X."""
    rng = np.random.default_rng(seed)
    Ta, Tb, X = look_at_stations(stations, rng)
    return (perturb(Ta, rng, *ROBOT), perturb(Tb, rng, *CAMERA), X) if noise else (Ta, Tb, X)


def _pose_noise(sigma: tuple[float, float]) -> np.ndarray:
    """The (6, 6) covariance of perturb's noise σ (angle, per-axis translation) per axis."""
    return np.diag([sigma[0] ** 2 / 3] * 3 + [sigma[1] ** 2] * 3)


def _dense_sigma(Ta: np.ndarray, Tb: np.ndarray, X: np.ndarray) -> np.ndarray:
    """The residuals' joint covariance (6P, 6P) of the consecutive motions, built densely by finite differences of
    the residuals by every pose's noise: independent of refine_poses' maps and band."""
    h, P = 1e-7, len(Ta) - 1
    cov = {id(Ta): _pose_noise(ROBOT), id(Tb): _pose_noise(CAMERA)}
    total = np.zeros((6 * P, 6 * P))
    for T in (Ta, Tb):
        G = np.zeros((6 * P, 6 * len(T)))
        for k in range(len(T)):
            for d in range(6):
                cols = []
                for sign in (1, -1):
                    moved = T.copy()
                    step = np.zeros(6)
                    step[d] = sign * h
                    moved[k, :3, :3] = T[k, :3, :3] @ Rotation.from_rotvec(step[:3]).as_matrix()
                    moved[k, :3, 3] = T[k, :3, 3] + T[k, :3, :3] @ step[3:]      # perturb's T ∘ [Exp φ | δ]
                    a, b = (moved, Tb) if T is Ta else (Ta, moved)
                    cols.append(_model(se3.relative(a[:-1], a[1:]), se3.relative(b[:-1], b[1:]), X, 1.0)[0].ravel())
                G[:, 6 * k + d] = (cols[0] - cols[1]) / (2 * h)
        total += G @ np.kron(np.eye(len(T)), cov[id(T)]) @ G.T
    return total


def test_refine_poses_is_exact_on_noise_free_poses_and_refines_the_scale() -> None:
    Ta, Tb, X = _poses(0, noise=False)
    X0 = perturb(X, np.random.default_rng(1), 0.05, 0.02)
    r = refine_poses(Chain.of(Ta, Tb), X0, _pose_noise(ROBOT), _pose_noise(CAMERA))
    assert r.converged and np.abs(r.matrix - X).max() < 1e-9 and r.cost < 1e-12 < r.cost_start
    scaled = Tb.copy()
    scaled[:, :3, 3] /= 1.7
    s = refine_poses(Chain.of(Ta, scaled), X0, _pose_noise(ROBOT), _pose_noise(CAMERA), scale=1.0)
    assert s.converged and np.abs(s.matrix - X).max() < 1e-9 and abs(s.scale - 1.7) < 1e-9


def test_refine_poses_band_is_the_dense_covariance_and_scipy_agrees() -> None:
    """The cost refine_poses reaches equals rᵀ Σ⁻¹ r with Σ built densely by finite differences of the residuals
    by each pose's noise (so the neighbours' correlation and the band are right), and scipy's least_squares on the
    residuals whitened by that dense Σ (frozen) reaches the same X."""
    Ta, Tb, _ = _poses(4, stations=8)
    A, B = se3.relative(Ta[:-1], Ta[1:]), se3.relative(Tb[:-1], Tb[1:])
    r = refine_poses(Chain.of(Ta, Tb), solve(A, B).matrix, _pose_noise(ROBOT), _pose_noise(CAMERA))
    assert r.converged
    sigma = _dense_sigma(Ta, Tb, r.matrix)
    res = _model(A, B, r.matrix, 1.0)[0].ravel()
    assert res @ np.linalg.solve(sigma, res) == pytest.approx(r.cost, rel=1e-6)
    W = np.linalg.inv(np.linalg.cholesky(sigma))

    def whitened(p: np.ndarray) -> np.ndarray:
        R = Rotation.from_rotvec(p[:3]).as_matrix()
        rot = Rotation.from_matrix(R.T @ A[:, :3, :3] @ R @ B[:, :3, :3].transpose(0, 2, 1)).as_rotvec()
        tra = A[:, :3, :3] @ p[3:] + A[:, :3, 3] - B[:, :3, 3] @ R.T - p[3:]
        return W @ np.c_[rot, tra].ravel()

    fit = least_squares(whitened, np.r_[Rotation.from_matrix(r.matrix[:3, :3]).as_rotvec() + 1e-3, r.matrix[:3, 3]],
                        method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    assert np.abs(Rotation.from_rotvec(fit.x[:3]).as_matrix() - r.matrix[:3, :3]).max() < 1e-7
    assert np.abs(fit.x[3:] - r.matrix[:3, 3]).max() < 1e-7


def test_refine_poses_drift_weighs_the_motions() -> None:
    """A drift of its own per consecutive motion: the same as those variances added to the motions' covariances —
    with no neighbour correlation (zero pose noise but a floor) refine_poses is refine on those motions."""
    Ta, Tb, _ = _poses(6, stations=10)
    A, B = se3.relative(Ta[:-1], Ta[1:]), se3.relative(Tb[:-1], Tb[1:])
    drift = np.tile([1e-6, 1e-8], (len(A), 1))
    X0 = solve(A, B).matrix
    floor = np.eye(6) * 1e-30
    chained = refine_poses(Chain.of(Ta, Tb), X0, floor, floor, drift_a=drift, drift_b=drift)
    alone = refine(A, B, X0, motion_covariances(Ta[:-1], Ta[1:], 0.0, 0.0, extra=drift),
                   motion_covariances(Tb[:-1], Tb[1:], 0.0, 0.0, extra=drift))
    assert np.abs(chained.matrix - alone.matrix).max() < 1e-12
    assert chained.cost == pytest.approx(alone.cost, rel=1e-9)


@pytest.mark.statistical
def test_refine_poses_covers_and_wins_on_all_pairs_of_look_at_stations() -> None:
    """Over 40 captures of 20 stations: its 95 % ellipsoid covers the truth 88–99 % of the time (refine on
    all-with-all pairs: 7 %), and its median errors are below dqopt's and Park + LM's on all-with-all pairs, and
    below refine's on them in translation."""
    errors: dict[str, list[tuple[float, float]]] = {k: [] for k in ("poses", "dqopt", "park+LM", "refine all")}
    inside = []
    spec = importlib.util.spec_from_file_location("efficiency", ROOT / "benchmarks" / "efficiency.py")
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    sys.modules["efficiency"] = bench
    spec.loader.exec_module(bench)
    for seed in range(40):
        Ta, Tb, X = _poses(100 + seed)
        i, j = np.triu_indices(len(Ta), 1)
        A, B = se3.relative(Ta[i], Ta[j]), se3.relative(Tb[i], Tb[j])
        X0 = solve(A, B).matrix
        r = refine_poses(Chain.of(Ta, Tb), X0, _pose_noise(ROBOT), _pose_noise(CAMERA))
        ca = motion_covariances(Ta[i], Ta[j], ROBOT[0] / np.sqrt(3), ROBOT[1])
        cb = motion_covariances(Tb[i], Tb[j], CAMERA[0] / np.sqrt(3), CAMERA[1])
        for name, T in (("poses", r.matrix), ("dqopt", X0), ("park+LM", bench.park_lm(A, B)),
                        ("refine all", refine(A, B, X0, ca, cb).matrix)):
            E = se3.inverse(X) @ T
            errors[name].append((float(se3.rotation_angle(E)), float(np.linalg.norm(E[:3, 3]))))
        E = se3.inverse(r.matrix) @ X
        d = np.r_[Rotation.from_matrix(E[:3, :3]).as_rotvec(), E[:3, 3]]
        inside.append(d @ np.linalg.solve(r.covariance, d) <= CHI2_6_95)
    median = {k: np.median(v, axis=0) for k, v in errors.items()}
    assert 0.88 <= np.mean(inside) <= 0.99, np.mean(inside)
    for other in ("dqopt", "park+LM"):
        assert (median["poses"] < median[other]).all(), median
    assert median["poses"][1] < median["refine all"][1], median


def test_a_chain_never_crosses_a_segment_and_its_parts_add() -> None:
    """Two tracking segments: no motion across the break, no correlation between the parts — the Gaussian terms
    of the whole are the sums of each part's on its own (rᵀ Σ⁻¹ r and log det Σ)."""
    Ta, Tb, X = _poses(8, stations=12)
    segment = np.r_[np.zeros(6, dtype=np.int64), np.ones(6, dtype=np.int64)]
    whole = Chain.of(Ta, Tb, segment)
    assert len(whole.A) == 10 and list(whole.adjacent).count(False) == 1

    def terms(chain: Chain, noise: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        r, Ja, Jb = chain.residuals(X)
        return np.array(gaussian_terms(r, band_factor(*chain.blocks(Ja, Jb, *noise))))

    noise = (np.broadcast_to(_pose_noise(ROBOT), (12, 6, 6)), np.broadcast_to(_pose_noise(CAMERA), (12, 6, 6)))
    parts = [terms(Chain.of(Ta[k], Tb[k]), (noise[0][k], noise[1][k])) for k in (slice(0, 6), slice(6, 12))]
    assert terms(whole, noise) == pytest.approx(parts[0] + parts[1], rel=1e-10)
    with pytest.raises(DataError, match="consecutive motions within a segment"):
        Chain.of(Ta[:4], Tb[:4], np.array([0, 1, 2, 3]))
