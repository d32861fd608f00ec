"""The README's eye-in-hand and eye-to-hand recipes give the extrinsic they promise."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from handeye_cli import PoseStream
from handeye_cli.calibration import calibrate
from handeye_cli.config import load_options
from handeye_cli.geometry import se3
from handeye_cli.simulation import perturb

ROOT = Path(__file__).resolve().parents[2]


def _stations(rng: np.random.Generator, n: int = 30) -> np.ndarray:
    """Gripper poses ``T_base_gripper`` of an arm visiting ``n`` stations (±40° tilts, ~0.3 m reach)."""
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(rng.uniform(-0.7, 0.7, (n, 3))).as_matrix()
    T[:, :3, 3] = [0.5, 0.0, 0.4] + rng.uniform(-0.15, 0.15, (n, 3))
    return T


def _stream(T: np.ndarray) -> PoseStream:
    return PoseStream.from_matrices(np.arange(len(T), dtype=np.int64) * 1_000_000_000, T)


def _calibrate(a: np.ndarray, b: np.ndarray, **flags) -> np.ndarray:
    a_s, b_s = _stream(a), _stream(b)
    a_s = a_s.inverted() if flags.get("invert_a") else a_s
    b_s = b_s.inverted() if flags.get("invert_b") else b_s
    return calibrate(a_s, b_s, load_options(preset="robot-arm")).matrix


@pytest.mark.parametrize("noise", [0.0, 1.0])
def test_eye_in_hand(noise):
    """Camera on the gripper, target fixed: a = T_base_gripper, b = T_camera_target inverted → T_gripper_camera."""
    rng = np.random.default_rng(1)
    X = se3.from_xyz_quat(np.array([0.03, -0.05, 0.08]), np.array([0.1, 0.2, 0.0, 0.97]))
    T_base_target = se3.from_xyz_quat(np.array([0.6, 0.1, 0.0]), np.array([1.0, 0.0, 0.0, 0.0]))
    T_bg = _stations(rng)
    T_cam_target = se3.inverse(T_bg @ X) @ T_base_target
    T_cam_target = perturb(T_cam_target, rng, np.deg2rad(0.1) * noise, 0.001 * noise)
    got = _calibrate(T_bg, T_cam_target, invert_b=True)
    assert np.abs(got - X).max() < (1e-9 if noise == 0 else 5e-3)


@pytest.mark.parametrize("noise", [0.0, 1.0])
def test_eye_to_hand(noise):
    """Camera fixed, target on the gripper: a = T_base_gripper inverted, b = T_camera_target inverted
    → T_base_camera."""
    rng = np.random.default_rng(2)
    Y = se3.from_xyz_quat(np.array([1.2, 0.3, 0.9]), np.array([0.6, -0.6, 0.3, 0.4]))      # T_base_camera
    Z = se3.from_xyz_quat(np.array([0.0, 0.0, 0.1]), np.array([0.0, 0.0, 0.0, 1.0]))       # T_gripper_target
    T_bg = _stations(rng)
    T_cam_target = se3.inverse(Y) @ T_bg @ Z
    T_cam_target = perturb(T_cam_target, rng, np.deg2rad(0.1) * noise, 0.001 * noise)
    got = _calibrate(T_bg, T_cam_target, invert_a=True, invert_b=True)
    assert np.abs(got - Y).max() < (1e-9 if noise == 0 else 1e-2)
