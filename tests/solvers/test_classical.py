"""The classical hand-eye methods (Tsai–Lenz, Park–Martin, Horaud–Dornaika, Andreff) and the
robot-world formulation (Shah, Li): exact on noise-free data, OpenCV's results on noisy data."""
from __future__ import annotations

import json

import cv2  # opencv-python-headless, in the test extra
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from handeye_cli.analysis import extrinsic_error
from handeye_cli.cli import main
from handeye_cli.errors import ConfigError, DataError
from handeye_cli.geometry import se3
from handeye_cli.simulation import perturb
from handeye_cli.solvers import METHODS, solve
from handeye_cli.solvers.classical import CLASSICAL
from handeye_cli.solvers.robot_world import RW_METHODS, robot_world, station_residuals

OPENCV = {"tsai": "CALIB_HAND_EYE_TSAI", "park": "CALIB_HAND_EYE_PARK", "horaud": "CALIB_HAND_EYE_HORAUD",
          "andreff": "CALIB_HAND_EYE_ANDREFF"}


def _pose(rotvec: list[float], t: list[float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = t
    return T


X_TRUE = _pose([0.3, -0.5, 0.8], [0.1, -0.2, 0.3])        # T_a_b
Y_TRUE = _pose([1.3, 0.2, -0.4], [1.0, 2.0, 0.5])         # T_wa_wb


def _stations(n: int, seed: int, noise: float) -> tuple[np.ndarray, np.ndarray]:
    """Absolute poses ``T_wa_a``, ``T_wb_b`` (n, 4, 4) of a rig with ``X_TRUE``; noise 1 = 0.57° / 5 mm."""
    rng = np.random.default_rng(seed)
    Ta = np.tile(np.eye(4), (n, 1, 1))
    Ta[:, :3, :3] = Rotation.from_rotvec(rng.normal(0, 0.6, (n, 3))).as_matrix()
    Ta[:, :3, 3] = rng.normal(0, 0.5, (n, 3))
    Tb = se3.inverse(Y_TRUE) @ Ta @ X_TRUE
    if noise:
        Ta, Tb = perturb(Ta, rng, 0.01 * noise, 0.005 * noise), perturb(Tb, rng, 0.01 * noise, 0.005 * noise)
    return Ta, Tb


def _opencv_motions(Ta: np.ndarray, Tb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The motions OpenCV forms: ``Hg_j⁻¹ Hg_i`` and ``Hc_j Hc_i⁻¹`` (``Hc = T_wb_b⁻¹``) for all i < j."""
    i, j = np.triu_indices(len(Ta), 1)
    return se3.inverse(Ta[j]) @ Ta[i], se3.inverse(Tb[j]) @ Tb[i]


def test_registered_as_methods() -> None:
    assert set(CLASSICAL) == {"tsai", "park", "horaud", "andreff"}
    assert set(CLASSICAL) <= set(METHODS)


@pytest.mark.parametrize("method", sorted(CLASSICAL))
def test_noise_free_exact(method: str) -> None:
    A, B = _opencv_motions(*_stations(10, 3, 0.0))
    sol = solve(A, B, method=method)
    assert np.abs(sol.matrix - X_TRUE).max() < 1e-9
    assert sol.cost < 1e-18 and sol.method == method


@pytest.mark.parametrize("method", sorted(CLASSICAL))
def test_matches_opencv_on_noisy_data(method: str) -> None:
    Ta, Tb = _stations(12, 1, 1.0)
    A, B = _opencv_motions(Ta, Tb)
    if method == "tsai":       # OpenCV ≥ 4.10 drops motions with 2 sin(θ/2) outside [0.3, 1.7] for Tsai only
        chord = [2 * np.sin(se3.rotation_angle(T) / 2) for T in (A, B)]
        keep = np.all([(c >= 0.3) & (c <= 1.7) for c in chord], axis=0)
        A, B = A[keep], B[keep]
    Hc = se3.inverse(Tb)
    R, t = cv2.calibrateHandEye(list(Ta[:, :3, :3]), list(Ta[:, :3, 3]), list(Hc[:, :3, :3]), list(Hc[:, :3, 3]),
                                method=getattr(cv2, OPENCV[method]))
    X = solve(A, B, method=method).matrix
    assert np.abs(X[:3, :3] - R).max() < 1e-6
    assert np.abs(X[:3, 3] - t.ravel()).max() < 1e-6 * np.linalg.norm(t)
    rot_deg, trans_m = extrinsic_error(X, X_TRUE)
    assert 0 < rot_deg < 2 and 0 < trans_m < 0.05          # noisy, so not exact, but close


def test_weights_select_pairs() -> None:
    """A zero weight removes a pair: corrupting it then changes nothing."""
    A, B = _opencv_motions(*_stations(8, 5, 0.5))
    w = np.ones(len(A))
    w[0] = 0.0
    B_bad = B.copy()
    B_bad[0] = B[0] @ _pose([0.5, 0, 0], [0.3, 0, 0])
    for method in CLASSICAL:
        assert np.abs(solve(A, B, method=method, weights=w).matrix
                      - solve(A, B_bad, method=method, weights=w).matrix).max() < 1e-12


@pytest.mark.parametrize("method", RW_METHODS)
def test_robot_world_noise_free_exact(method: str) -> None:
    A, B = _stations(6, 7, 0.0)
    for refine in (False, True):
        sol = robot_world(A, B, method=method, refine=refine)
        assert np.abs(sol.X - X_TRUE).max() < 1e-9 and np.abs(sol.Y - Y_TRUE).max() < 1e-9
        rot, trans = station_residuals(A, B, sol.X, sol.Y)
        assert rot.max() < 1e-9 and trans.max() < 1e-9


@pytest.mark.parametrize("method", RW_METHODS)
def test_robot_world_matches_opencv_then_refines(method: str) -> None:
    A, B = _stations(12, 1, 1.0)
    flag = getattr(cv2, f"CALIB_ROBOT_WORLD_HAND_EYE_{method.upper()}")
    Rx, tx, Ry, ty = cv2.calibrateRobotWorldHandEye(list(A[:, :3, :3]), list(A[:, :3, 3]), list(B[:, :3, :3]),
                                                    list(B[:, :3, 3]), method=flag)
    closed = robot_world(A, B, method=method, refine=False)
    assert np.abs(closed.X[:3, :3] - Rx).max() < 1e-6 and np.abs(closed.X[:3, 3] - tx.ravel()).max() < 1e-6
    assert np.abs(closed.Y[:3, :3] - Ry).max() < 1e-6 and np.abs(closed.Y[:3, 3] - ty.ravel()).max() < 1e-6
    refined = robot_world(A, B, method=method)
    assert refined.refined and refined.cost < closed.cost


def test_robot_world_errors() -> None:
    A, B = _stations(6, 7, 0.0)
    with pytest.raises(ConfigError):
        robot_world(A, B, method="kabsch")
    with pytest.raises(DataError):
        robot_world(A[:2], B[:2])


def test_cli_solve_with_classical_method(tmp_path, capsys) -> None:
    A, B = _opencv_motions(*_stations(8, 2, 0.0))
    path = tmp_path / "pairs.npz"
    np.savez(path, A=A, B=B)
    with pytest.raises(SystemExit) as e:
        main(["solve", str(path), "--method", "park", "--format", "json"])
    assert e.value.code == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["method"] == "park"
    assert np.abs(np.array(doc["matrix"]) - X_TRUE).max() < 1e-9
