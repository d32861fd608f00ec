"""Simulated ground robots with known truth: a differential-drive base and a near-planar car.

Kinds (see :func:`simulate_ground`):

``diff-drive``
    A wheeled base driving figure eights, arcs and turns in place on a flat floor. Its wheel
    odometry (``odom → base_link``) integrates the measured forward speed and yaw rate: the speed
    has a slip scale error and noise, the yaw rate a gyro bias (yaw drift) and noise; it is 2-D
    (z, roll and pitch are 0). A lidar odometry (``odom_lidar → lidar``) at another rate composes
    the true lidar increments with small noise (it drifts slowly, like scan matching). A localiser
    (``map → base_link``, AMCL-like) publishes at 1–2 Hz with absolute noise and occasional jumps.
``car``
    A car on a near-planar road whose suspension pitches and rolls the body by ±1–2° (with
    braking and cornering); stream a is the body's ground truth / INS pose (6-DOF), stream b a
    camera visual odometry (z forward) at another rate.

Conventions: ``T_a_b`` is the pose of b in a (maps points b → a); quaternions x-y-z-w; time
int64 ns; positions metres; base_link has x forward, z up. The truth ``T_base_sensor`` is what
``handeye calibrate`` returns with stream a = the base stream and b = the sensor stream.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..geometry import se3
from ..streams import PoseStream
from . import perturb

__all__ = ["GROUND_KINDS", "GroundRecording", "LIDAR_MOUNT", "CAMERA_MOUNT", "simulate_ground"]

GROUND_KINDS = ("diff-drive", "car")
_START_NS = 1_700_000_000_000_000_000
_SIM_RATE = 200.0                      # [Hz] the truth's integration rate


def _mount(xyz: tuple[float, float, float], rpy_deg: tuple[float, float, float]) -> NDArray[np.float64]:
    """``T_base_sensor`` from URDF-style xyz [m] and roll-pitch-yaw [deg] (R = Rz(y) Ry(p) Rx(r))."""
    q = Rotation.from_euler("xyz", rpy_deg, degrees=True).as_quat()
    return se3.from_xyz_quat(np.asarray(xyz, dtype=np.float64), q)


LIDAR_MOUNT = _mount((0.12, -0.03, 0.35), (0.4, -0.6, 2.0))           # a lidar a little tilted on its mast
CAMERA_MOUNT = _mount((1.6, 0.25, 1.3), (-90.0 - 1.0, 0.5, -90.0 + 3.0))  # z forward, x right, y down


@dataclass(frozen=True, eq=False)
class GroundRecording:
    """A simulated ground-robot log and its truth.

    base: ``T_odom_base_link(t)`` (diff-drive: wheel odometry) or ``T_world_base_link(t)`` (car: ground truth).
    sensor: ``T_odom_lidar_lidar(t)`` (diff-drive: lidar odometry) or ``T_vo_camera(t)`` (car: visual odometry).
    localiser: ``T_map_base_link(t)`` at 1–2 Hz with jumps (diff-drive; None for the car).
    truth: ``T_base_link_sensor`` (4, 4), what a calibration of ``base`` against ``sensor`` returns.
    jumped: bool mask of the localiser samples displaced by a jump (empty for the car).
    """

    kind: str
    base: PoseStream
    sensor: PoseStream
    localiser: PoseStream | None
    truth: NDArray[np.float64]
    jumped: NDArray[np.bool_]


def _controls(t: NDArray[np.float64], kind: str, rng: np.random.Generator, turning: float, spin_period_s: float
              ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Forward speed v [m/s] and yaw rate ω [rad/s]: figure eights and arcs (yaw rate times ``turning``)
    and (diff-drive) a turn in place every ``spin_period_s`` [s] (``inf``: never)."""
    f = rng.uniform(0.03, 0.08)
    omega = np.sin(2 * np.pi * f * t) * (0.8 if kind == "diff-drive" else 0.25)            # figure eights
    omega += 0.3 * np.sin(2 * np.pi * rng.uniform(0.1, 0.2) * t + rng.uniform(0, 2 * np.pi))
    omega *= turning
    v = (0.5 if kind == "diff-drive" else 8.0) * (1.0 + 0.4 * np.sin(2 * np.pi * rng.uniform(0.02, 0.05) * t))
    if kind == "diff-drive":       # turns in place, about a sixth of the period long, ramped (limited acceleration)
        r = np.clip((np.sin(2 * np.pi * t / spin_period_s) - 0.75) / 0.2, 0.0, 1.0)
        spin = r * r * (3 - 2 * r)
        v = (1 - spin) * v
        omega = (1 - spin) * omega + spin * 1.0
    return v, omega


def _integrate(dt: float, v: NDArray[np.float64], omega: NDArray[np.float64]
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """x, y [m] and yaw [rad] of a unicycle integrated (midpoint) from speeds."""
    yaw = np.concatenate([[0.0], np.cumsum(omega[:-1] * dt)])
    mid = yaw + 0.5 * omega * dt
    x = np.concatenate([[0.0], np.cumsum(v[:-1] * np.cos(mid[:-1]) * dt)])
    y = np.concatenate([[0.0], np.cumsum(v[:-1] * np.sin(mid[:-1]) * dt)])
    return x, y, yaw


def _poses(x: NDArray[np.float64], y: NDArray[np.float64], z: NDArray[np.float64],
           rpy: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N, 4, 4) poses from positions and roll-pitch-yaw columns (R = Rz Ry Rx) [rad]."""
    T = np.tile(np.eye(4), (len(x), 1, 1))
    T[:, :3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()
    T[:, :3, 3] = np.c_[x, y, z]
    return T


def _sample(t_sim: NDArray[np.float64], rate: float, duration_s: float, rng: np.random.Generator
            ) -> NDArray[np.int64]:
    """Indices into the truth's time line of a sensor at ``rate`` [Hz] with ±10 % timing jitter."""
    n = int(duration_s * rate)
    t = np.sort(np.arange(n) / rate + rng.uniform(-0.1, 0.1, n) / rate)
    idx = np.round(t * _SIM_RATE).astype(np.int64)
    return np.asarray(np.clip(idx, 0, len(t_sim) - 1), dtype=np.int64)


def _odometry(T: NDArray[np.float64], rng: np.random.Generator, sigma_r: float, sigma_t: float
              ) -> NDArray[np.float64]:
    """An odometry of true poses ``T`` (N, 4, 4): true increments composed with noise (σr [rad], σt [m])."""
    inc = se3.inverse(T[:-1]) @ T[1:]
    noisy = perturb(inc, rng, sigma_r, sigma_t)
    out = np.empty_like(T)
    out[0] = np.eye(4)
    for k in range(1, len(T)):
        out[k] = out[k - 1] @ noisy[k - 1]
    return out


def _stream(stamps_s: NDArray[np.floating[Any]], T: NDArray[np.float64], frame: str, child: str) -> PoseStream:
    ns = _START_NS + np.round(stamps_s * 1e9).astype(np.int64)
    return PoseStream.from_matrices(ns, T, frame_id=frame, child_frame_id=child, source="simulated")


def simulate_ground(kind: str = "diff-drive", *, duration_s: float = 240.0, seed: int = 0,
                    mount: NDArray[np.float64] | None = None, base_rate: float = 50.0,
                    sensor_rate: float = 10.0, localiser_rate: float = 1.5, slip: float = 0.002,
                    gyro_bias_deg_s: float = 0.002, localiser_jumps: int = 3, turning: float = 1.0,
                    spin_period_s: float = 30.0) -> GroundRecording:
    """A ground robot's log: base pose stream, sensor odometry and (diff-drive) a localiser.

    ``kind`` is ``diff-drive`` or ``car``; ``mount`` the true ``T_base_link_sensor`` (default
    :data:`LIDAR_MOUNT` / :data:`CAMERA_MOUNT`). Rates [Hz]: ``base_rate`` (wheel odometry or
    ground truth), ``sensor_rate`` (lidar or visual odometry), ``localiser_rate``. Wheel odometry:
    speed scale error ``slip`` (fraction, plus 0.2 % slip noise per step while turning), yaw-rate bias
    ``gyro_bias_deg_s`` [deg/s]. The localiser has 2 cm / 0.3° absolute noise and
    ``localiser_jumps`` jumps of 0.2–0.5 m and 3–8°. Motion: ``turning`` scales the yaw rate of the
    arcs (below 1: longer, straighter runs); the diff-drive turns in place every ``spin_period_s`` [s]
    (``math.inf``: never). Seeded and deterministic.
    """
    if kind not in GROUND_KINDS:
        raise ValueError(f"unknown ground kind {kind!r}; expected one of {GROUND_KINDS}")
    rng = np.random.default_rng(seed)
    X = np.asarray(mount if mount is not None else (LIDAR_MOUNT if kind == "diff-drive" else CAMERA_MOUNT),
                   dtype=np.float64)
    dt = 1.0 / _SIM_RATE
    t_sim = np.arange(int(duration_s * _SIM_RATE) + 1, dtype=np.float64) * dt
    v, omega = _controls(t_sim, kind, rng, turning, spin_period_s)
    x, y, yaw = _integrate(dt, v, omega)
    z = np.zeros_like(x)
    roll, pitch = np.zeros_like(x), np.zeros_like(x)
    if kind == "car":                          # suspension: lean into corners, pitch with braking, road wobble
        accel = np.gradient(v, dt)
        lateral = v * omega
        roll = np.deg2rad(np.clip(0.8 * lateral, -1.5, 1.5)) + np.deg2rad(0.4) * np.sin(2 * np.pi * 0.7 * t_sim)
        pitch = np.deg2rad(np.clip(-0.6 * accel, -1.5, 1.5)) + np.deg2rad(0.4) * np.sin(2 * np.pi * 0.9 * t_sim + 1)
        z = 0.02 * np.sin(2 * np.pi * 0.05 * t_sim)
    T_true = _poses(x, y, z, np.c_[roll, pitch, yaw])
    i_base = _sample(t_sim, base_rate, duration_s, rng)
    i_sensor = _sample(t_sim, sensor_rate, duration_s, rng)
    if kind == "diff-drive":
        in_turn = np.abs(omega) > 0.3
        v_meas = v * (1.0 + slip + 0.002 * rng.normal(size=len(v)) * in_turn) + 0.002 * rng.normal(size=len(v))
        w_meas = omega + np.deg2rad(gyro_bias_deg_s) + np.deg2rad(0.05) * rng.normal(size=len(v))
        xo, yo, yawo = _integrate(dt, v_meas, w_meas)
        base = _poses(xo, yo, np.zeros_like(xo), np.c_[np.zeros_like(xo), np.zeros_like(xo), yawo])[i_base]
        sensor = _odometry(T_true[i_sensor] @ X, rng, np.deg2rad(0.01), 0.0005)
        base_frame, sensor_frames = ("odom", "base_link"), ("odom_lidar", "lidar")
    else:
        base = perturb(T_true[i_base], rng, np.deg2rad(0.01), 0.002)
        sensor = _odometry(T_true[i_sensor] @ X, rng, np.deg2rad(0.01), 0.002)
        base_frame, sensor_frames = ("world", "base_link"), ("vo", "camera")
    base_stream = _stream(i_base * dt, base, *base_frame)
    sensor_stream = _stream(i_sensor * dt, sensor, *sensor_frames)
    localiser, jumped = None, np.zeros(0, dtype=bool)
    if kind == "diff-drive":
        i_loc = _sample(t_sim, localiser_rate, duration_s, rng)
        noise = np.c_[rng.normal(0, 0.02, (len(i_loc), 2)), np.deg2rad(0.3) * rng.normal(size=len(i_loc))]
        jumped = np.zeros(len(i_loc), dtype=bool)
        jumped[rng.choice(np.arange(5, len(i_loc) - 5), size=localiser_jumps, replace=False)] = True
        k = int(jumped.sum())
        direction = rng.uniform(0, 2 * np.pi, k)
        noise[jumped, :2] += rng.uniform(0.2, 0.5, (k, 1)) * np.c_[np.cos(direction), np.sin(direction)]
        noise[jumped, 2] += np.deg2rad(rng.uniform(3, 8, k)) * rng.choice([-1, 1], k)
        zero = np.zeros(len(i_loc))
        M = _mount((3.0, -2.0, 0.0), (0.0, 0.0, 30.0))       # the map's origin in odom's start
        loc = M @ _poses(x[i_loc] + noise[:, 0], y[i_loc] + noise[:, 1], zero,
                         np.c_[zero, zero, yaw[i_loc] + noise[:, 2]])
        localiser = _stream(i_loc * dt, loc, "map", "base_link")
    return GroundRecording(kind, base_stream, sensor_stream, localiser, X, jumped)
