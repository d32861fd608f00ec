"""A simulated robot arm with a camera and a calibration target: station captures with known truth.

The arm is a six-joint serial manipulator in standard Denavit–Hartenberg form (UR5 nominal
parameters, metres and radians). Its controller reports the flange pose ``T_base_flange`` from the
*nominal* parameters and the *measured* joint angles, while the true flange pose uses perturbed
parameters (link lengths, offsets, twists, joint zero offsets) and the true angles, so the robot
stream carries the systematic kinematic errors of a real arm plus encoder noise.

Set-ups (see :class:`ArmCapture` for the flags that calibrate each one):

``eye-in-hand``
    The camera rides on the flange (``T_flange_camera``), the target is fixed in the base frame.
``eye-to-hand``
    The camera is fixed (``T_base_camera``), the target rides on the flange (``T_flange_target``).

The camera stream holds what a target detector publishes: ``T_camera_target(t)`` with pose noise
(σr [rad] on a random axis, σt [m] per component, as :func:`handeye_cli.simulation.perturb`).
Stations are drawn by rejection: random joint offsets around a home pose in which the camera
looks straight at the target, kept when the target is in front of the camera, within its field
of view and facing it.

Captures are either **sparse** (one sample per station in each stream, as a capture script
saves them) or **continuous** (both streams at their rates while the arm dwells at each station
and moves between stations by a smooth joint-space profile; camera samples where the target is
out of view are not published). :func:`monocular` turns a camera stream into the trajectory of
a monocular visual odometry, whose translations have an unknown (optionally drifting) scale.

Conventions: ``T_a_b`` is the pose of b in a (maps points b → a); quaternions x-y-z-w; time
int64 ns; positions metres.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..geometry import se3
from ..streams import PoseStream
from . import perturb

__all__ = ["ArmCapture", "DH_UR5", "forward_kinematics", "look_at_stations", "monocular", "simulate_arm"]

# Standard DH rows (d [m], a [m], alpha [rad]) of a UR5; joint i: Rz(θ_i) Tz(d_i) Tx(a_i) Rx(alpha_i).
DH_UR5: NDArray[np.float64] = np.array([
    [0.089159, 0.0, np.pi / 2],
    [0.0, -0.425, 0.0],
    [0.0, -0.39225, 0.0],
    [0.10915, 0.0, np.pi / 2],
    [0.09465, 0.0, -np.pi / 2],
    [0.0823, 0.0, 0.0],
])
_HOME = np.array([0.0, -1.9, 1.9, -1.571, -1.571, 0.0])     # flange pointing down, ~0.4 m above the table
_SPREAD = np.array([0.5, 0.25, 0.3, 0.45, 0.45, 1.2])        # joint range around home [rad] for stations
_START_NS = 1_700_000_000_000_000_000
_MOUNTED = se3.from_xyz_quat(np.array([0.04, -0.03, 0.06]), Rotation.from_rotvec([0.05, -0.1, 0.3]).as_quat())


def forward_kinematics(dh: NDArray[np.float64], q: NDArray[np.float64],
                       zero: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """Flange poses ``T_base_flange`` (N, 4, 4) for joint angles ``q`` (N, 6) [rad] and DH rows ``dh`` (6, 3).

    ``zero`` (6,) [rad] is added to every joint angle (joint zero offsets).
    """
    q = np.atleast_2d(q) + (0.0 if zero is None else zero)
    T = np.tile(np.eye(4), (len(q), 1, 1))
    for k, (d, a, alpha) in enumerate(dh):
        c, s = np.cos(q[:, k]), np.sin(q[:, k])
        ca, sa = np.cos(alpha), np.sin(alpha)
        L = np.zeros((len(q), 4, 4))
        L[:, 0] = np.c_[c, -s * ca, s * sa, a * c]
        L[:, 1] = np.c_[s, c * ca, -c * sa, a * s]
        L[:, 2] = [0.0, sa, ca, d]
        L[:, 3, 3] = 1.0
        T = T @ L
    return T


@dataclass(frozen=True, eq=False)
class ArmCapture:
    """A simulated capture and its truth.

    robot: ``T_base_flange(t)`` as the controller reports it (nominal kinematics, measured joints).
    camera: ``T_camera_target(t)`` as the target detector publishes it.
    truth: the ``T_a_b`` that ``handeye calibrate`` must return with stream a = ``robot``, b = ``camera``
        and the flags ``invert_a`` / ``invert_b`` (eye-in-hand: ``T_flange_camera`` with
        ``--invert-b``; eye-to-hand: ``T_base_camera`` with ``--invert-a --invert-b``).
    station_times_ns: int64 (S,) the time [ns] of each station's middle (dwell or capture instant).
    joints: (S, 6) true joint angles [rad] at the stations.
    """

    robot: PoseStream
    camera: PoseStream
    truth: NDArray[np.float64]
    invert_a: bool
    invert_b: bool
    station_times_ns: NDArray[np.int64]
    joints: NDArray[np.float64]


def _mount(setup: str, T_home: NDArray[np.float64], distance: float) -> tuple[NDArray[np.float64], ...]:
    """(T_flange_camera or T_flange_target, T_base_target or T_base_camera): the fixed frames of a set-up."""
    look = np.eye(4)
    look[:3, :3] = Rotation.from_rotvec([np.pi, 0.0, 0.0]).as_matrix()     # facing back along z
    look[2, 3] = distance
    mounted = _MOUNTED.copy()
    if setup == "eye-in-hand":
        return mounted, T_home @ mounted @ look            # T_flange_camera, T_base_target
    if setup == "eye-to-hand":
        return mounted, T_home @ mounted @ look            # T_flange_target, T_base_camera
    raise ValueError(f"unknown setup {setup!r}; expected eye-in-hand or eye-to-hand")


def _camera_target(setup: str, T_flange: NDArray[np.float64], mounted: NDArray[np.float64],
                   fixed: NDArray[np.float64]) -> NDArray[np.float64]:
    """True ``T_camera_target`` for true flange poses (N, 4, 4)."""
    if setup == "eye-in-hand":
        return se3.inverse(T_flange @ mounted) @ fixed
    return se3.inverse(fixed) @ T_flange @ mounted


def _visible(T_cam_target: NDArray[np.float64], fov_deg: float = 30.0) -> NDArray[np.bool_]:
    """Target in front of the camera (0.15–1.2 m), within ``fov_deg`` of the optical axis, facing it."""
    p = T_cam_target[:, :3, 3]
    dist = np.linalg.norm(p, axis=1)
    in_view = p[:, 2] > dist * np.cos(np.deg2rad(fov_deg))
    facing = -np.einsum("ni,ni->n", T_cam_target[:, :3, 2], p) > 0.5 * dist     # target z towards the camera
    return np.asarray((dist > 0.15) & (dist < 1.2) & in_view & facing, dtype=bool)


def _stations(rng: np.random.Generator, n: int, setup: str, mounted: NDArray[np.float64],
              fixed: NDArray[np.float64], dh_true: NDArray[np.float64], zero: NDArray[np.float64]
              ) -> NDArray[np.float64]:
    """``n`` joint configurations (n, 6) from which the camera sees the target."""
    found: list[NDArray[np.float64]] = []
    while len(found) < n:
        q = _HOME + rng.uniform(-1.0, 1.0, (64, 6)) * _SPREAD
        ok = _visible(_camera_target(setup, forward_kinematics(dh_true, q, zero), mounted, fixed))
        found.extend(q[ok])
    return np.asarray(found[:n])


def _timeline(n: int, dwell_s: float, move_s: float, rate: float, rng: np.random.Generator
              ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Sample times [s] at ``rate`` with ±10 % jitter over n dwells joined by moves, and for each
    sample the station it leaves (index) and the progress of the move (0 at rest, smooth to 1)."""
    period = dwell_s + move_s
    count = int(((n - 1) * period + dwell_s) * rate)
    t = np.sort(np.arange(count) / rate + rng.uniform(-0.1, 0.1, count) / rate)
    t = t[(t >= 0) & (t <= (n - 1) * period + dwell_s)]
    k = np.minimum((t // period).astype(int), n - 1)
    u = np.clip((t - k * period - dwell_s) / max(move_s, 1e-9), 0.0, 1.0)
    return t, k, 0.5 - 0.5 * np.cos(np.pi * u)


def simulate_arm(n_stations: int = 15, *, setup: str = "eye-in-hand", sparse: bool = False,
                 dwell_s: float = 2.0, move_s: float = 2.0, rate_robot: float = 100.0, rate_camera: float = 30.0,
                 camera_sigma_r: float = np.deg2rad(0.1), camera_sigma_t: float = 0.001,
                 robot_sigma_r: float = 0.0, robot_sigma_t: float = 0.0, joint_noise: float = np.deg2rad(0.002),
                 dh_error: float = 1.0, target_distance: float = 0.45, seed: int = 0) -> ArmCapture:
    """Simulate an arm visiting ``n_stations`` stations with a camera and a target (see the module docstring).

    sparse: one sample per station and stream, both stamped at the capture instant (1 s apart);
        otherwise continuous streams at ``rate_robot`` / ``rate_camera`` [Hz] with ``dwell_s`` [s] at
        each station and ``move_s`` [s] between stations (``dwell_s=0``: continuous motion).
    camera_sigma_r [rad], camera_sigma_t [m]: detector noise on ``T_camera_target``.
    robot_sigma_r [rad], robot_sigma_t [m]: extra noise on the reported flange pose (on top of
        ``joint_noise`` [rad] encoder noise per joint).
    dh_error: scale of the kinematic errors (1: σ 0.2 mm on d and a, 0.01° on twists and joint zeros).
    """
    rng = np.random.default_rng(seed)
    errors = rng.normal(0.0, 1.0, (6, 3)) * np.array([2e-4, 2e-4, np.deg2rad(0.01)]) * dh_error
    dh_true, zero = DH_UR5 + errors, rng.normal(0.0, np.deg2rad(0.01), 6) * dh_error
    mounted, fixed = _mount(setup, forward_kinematics(DH_UR5, _HOME)[0], target_distance)
    joints = _stations(rng, n_stations, setup, mounted, fixed, dh_true, zero)

    def sample(rate: float) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        if sparse:
            t, q = np.arange(n_stations, dtype=float), joints
        else:
            t, k, s = _timeline(n_stations, dwell_s, move_s, rate, rng)
            q = joints[k] + s[:, None] * (joints[np.minimum(k + 1, n_stations - 1)] - joints[k])
        return _START_NS + np.round(t * 1e9).astype(np.int64), q

    t_r, q_r = sample(rate_robot)
    reported = forward_kinematics(DH_UR5, q_r + rng.normal(0.0, joint_noise, q_r.shape))
    if robot_sigma_r or robot_sigma_t:
        reported = perturb(reported, rng, robot_sigma_r, robot_sigma_t)
    t_c, q_c = sample(rate_camera)
    seen = _camera_target(setup, forward_kinematics(dh_true, q_c, zero), mounted, fixed)
    keep = _visible(seen)
    seen = perturb(seen[keep], rng, camera_sigma_r, camera_sigma_t)
    period = 1.0 if sparse else dwell_s + move_s
    mid = _START_NS + np.round((np.arange(n_stations) * period + (0 if sparse else dwell_s / 2)) * 1e9)
    return ArmCapture(
        robot=PoseStream.from_matrices(t_r, reported, frame_id="base", child_frame_id="flange", source="simulated"),
        camera=PoseStream.from_matrices(t_c[keep], seen, frame_id="camera", child_frame_id="target",
                                        source="simulated"),
        truth=mounted if setup == "eye-in-hand" else fixed, invert_a=setup == "eye-to-hand", invert_b=True,
        station_times_ns=mid.astype(np.int64), joints=joints)


def look_at_stations(n: int, rng: np.random.Generator, *, distance: tuple[float, float] = (0.1, 0.3),
                     cone_deg: float = 50.0) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Noise-free stations of an eye-in-hand camera looking at a target: no kinematics, exact truth.

    The camera stands ``distance`` [m] (uniform) from the target, in a direction drawn uniformly within
    ``cone_deg`` of the target's normal (its z axis), its optical axis (z) through the target's origin
    and a uniform roll about it. Returns ``(T_base_flange, T_target_camera, T_flange_camera)``: the two
    streams (n, 4, 4) — a: the flange in the base frame, b: the camera in the target frame — and their
    ``T_a_b`` (4, 4), the mount of :func:`simulate_arm`. The base holds the target 0.5 m ahead, turned.
    """
    cos_max = np.cos(np.deg2rad(cone_deg))
    z = rng.uniform(cos_max, 1.0, n)
    azimuth = rng.uniform(-np.pi, np.pi, n)
    u = np.c_[np.sqrt(1.0 - z * z) * np.cos(azimuth), np.sqrt(1.0 - z * z) * np.sin(azimuth), z]
    axis = -u                                                    # the optical axis, towards the target
    helper = np.where(np.abs(axis[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    x = np.cross(helper, axis)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    look = np.stack([x, np.cross(axis, x), axis], axis=2)        # columns: camera x, y, z in the target frame
    T_target_camera = np.tile(np.eye(4), (n, 1, 1))
    T_target_camera[:, :3, :3] = look @ Rotation.from_rotvec(np.c_[np.zeros((n, 2)), rng.uniform(-np.pi, np.pi, n)]
                                                               ).as_matrix()
    T_target_camera[:, :3, 3] = u * rng.uniform(*distance, n)[:, None]
    T_base_target = se3.from_xyz_quat(np.array([0.5, 0.0, 0.0]), Rotation.from_rotvec([0.0, 0.0, 0.7]).as_quat())
    return T_base_target @ T_target_camera @ se3.inverse(_MOUNTED), T_target_camera, _MOUNTED.copy()


def monocular(stream: PoseStream, scale: float, drift_per_s: float = 0.0) -> PoseStream:
    """The stream a monocular odometry would publish for ``stream`` (``T_world_camera``, metres).

    Positions are divided by ``scale`` (metres per odometry unit), times ``1 + drift_per_s·(t - t0)``
    [1/s] for a slowly drifting scale: multiplying the result's translations by ``scale`` restores
    metres at the start. Rotations are unchanged.
    """
    t = (stream.stamps_ns - stream.stamps_ns[0]) / 1e9
    return replace(stream, xyz=stream.xyz / scale * (1.0 + drift_per_s * t)[:, None])
