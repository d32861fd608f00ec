"""Simulated recordings of the kinds users bring: drifting odometry, absolute trackers, arms.

A recording is two pose streams ``T_wa_a(t)``, ``T_wb_b(t)`` of a rigid rig (truth ``T_a_b``,
clock offset) as :func:`handeye_cli.simulation.simulate_rig` makes them noise-free, then each
stream's error model applied on top:

* :func:`absolute` (motion capture, robot kinematics, a camera seeing a fixed target): every
  pose gets independent noise, right-perturbed (σr [rad], σt [m]); errors do not grow.
* :func:`drifting` (VIO, SLAM, wheel odometry): the yaw error ψ(t) about the world's z axis, the
  position error p(t) and the scale ``s(t) = 1 + …`` are random walks (rad/√s, m/√s, 1/√s); each
  displacement is measured turned by ψ and scaled by s and integrated, as odometry does; plus
  white jitter. Errors of a relative motion grow with its span.

Conventions: ``T_a_b`` maps points from b to a; quaternions x-y-z-w; stamps int64 ns; metres.
:data:`SCENARIOS` names the recordings the accuracy benchmark and the default-strategy tests use.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..streams import PoseStream
from . import Rig, perturb, random_transform, simulate_rig

__all__ = ["SourceNoise", "absolute", "drifting", "Recording", "simulate_recording", "SCENARIOS", "scenario"]


@dataclass(frozen=True)
class SourceNoise:
    """Error model of one pose source.

    sigma_r [rad], sigma_t [m]: white noise on every pose. yaw_walk [rad/√s], position_walk
    [m/√s], scale_walk [1/√s]: random-walk densities of the drift (all 0 for an absolute source).
    """

    sigma_r: float = 0.0
    sigma_t: float = 0.0
    yaw_walk: float = 0.0
    position_walk: float = 0.0
    scale_walk: float = 0.0

    @property
    def kind(self) -> str:
        """``"drifting"`` when any random walk is set, else ``"absolute"``."""
        return "drifting" if (self.yaw_walk or self.position_walk or self.scale_walk) else "absolute"


def absolute(sigma_r_deg: float = 0.1, sigma_t_m: float = 0.001) -> SourceNoise:
    """An absolute source (mocap, kinematics, target camera): white noise σr [deg], σt [m]."""
    return SourceNoise(np.deg2rad(sigma_r_deg), sigma_t_m)


def drifting(yaw_deg_per_sqrt_s: float = 0.5, position_m_per_sqrt_s: float = 0.02,
             scale_per_sqrt_s: float = 0.003, sigma_r_deg: float = 0.05, sigma_t_m: float = 0.001) -> SourceNoise:
    """A drifting odometry source (phone VIO by default: ~4° yaw, ~15 cm and ~2 % scale after a minute)."""
    return SourceNoise(np.deg2rad(sigma_r_deg), sigma_t_m, np.deg2rad(yaw_deg_per_sqrt_s),
                       position_m_per_sqrt_s, scale_per_sqrt_s)


def _walk(t_s: np.ndarray, density: float, dims: int, rng: np.random.Generator) -> np.ndarray:
    """A Wiener process sampled at times ``t_s`` [s] (starting at 0): (N, dims)."""
    dt = np.diff(t_s, prepend=t_s[:1])
    return np.cumsum(rng.normal(size=(len(t_s), dims)) * (density * np.sqrt(dt))[:, None], axis=0)


def apply_noise(stream: PoseStream, noise: SourceNoise, rng: np.random.Generator) -> PoseStream:
    """``stream`` as seen through the source model ``noise``: drift, then white noise.

    Drift as odometry makes it: each displacement between samples is measured in a world frame
    that has turned by the yaw error ψ(t) so far and scaled by s(t), then integrated (plus the
    position walk), so an error made once carries into every later pose; orientations carry ψ(t).
    """
    T = stream.matrices()
    if noise.kind == "drifting":
        t = (stream.stamps_ns - stream.stamps_ns[0]) / 1e9
        scale = 1.0 + _walk(t, noise.scale_walk, 1, rng)
        Rz = Rotation.from_rotvec(np.c_[np.zeros((len(t), 2)), _walk(t, noise.yaw_walk, 1, rng)]).as_matrix()
        step = np.diff(T[:, :3, 3], axis=0, prepend=T[:1, :3, 3])
        T[:, :3, 3] = T[0, :3, 3] + np.cumsum(scale * np.einsum("nij,nj->ni", Rz, step), axis=0) + _walk(
            t, noise.position_walk, 3, rng)
        T[:, :3, :3] = Rz @ T[:, :3, :3]
    if noise.sigma_r or noise.sigma_t:
        T = perturb(T, rng, noise.sigma_r, noise.sigma_t)
    return PoseStream.from_matrices(stream.stamps_ns, T, frame_id=stream.frame_id,
                                    child_frame_id=stream.child_frame_id, source=stream.source)


@dataclass(frozen=True, eq=False)
class Recording:
    """A simulated recording: the two streams, the truth (``rig.T_a_b``, ``rig.time_offset_ns``) and its name."""

    a: PoseStream
    b: PoseStream
    rig: Rig
    name: str = ""
    description: str = ""


def simulate_recording(rig: Rig, noise_a: SourceNoise, noise_b: SourceNoise, *, duration_s: float = 60.0,
                       rate_a: float = 30.0, rate_b: float = 20.0, motion: str = "3d", speed: float = 1.0,
                       jumps: int = 0, seed: int = 0, name: str = "", description: str = "") -> Recording:
    """Two streams of a rig moving smoothly (see :func:`~handeye_cli.simulation.simulate_rig`:
    rates [Hz], ``speed``, ``jumps`` tracking jumps per stream), each through its error model."""
    a, b = simulate_rig(rig, duration_s=duration_s, rate_a=rate_a, rate_b=rate_b, motion=motion, jumps=jumps,
                        seed=seed, speed=speed)
    rng = np.random.default_rng([seed, 7])
    return Recording(apply_noise(a, noise_a, rng), apply_noise(b, noise_b, rng), rig, name, description)


def _rig(seed: int, offset_s: float = 0.0) -> Rig:
    return Rig(random_transform(np.random.default_rng([seed, 1]), 0.3), int(round(offset_s * 1e9)))


def _vio_vio(seed: int, d: float) -> Recording:
    return simulate_recording(_rig(seed), drifting(), drifting(), duration_s=d, rate_a=30, rate_b=30, seed=seed,
                              speed=0.5)


def _vio_mocap(seed: int, d: float) -> Recording:
    return simulate_recording(_rig(seed), drifting(), absolute(0.05, 0.0005), duration_s=d, rate_a=30,
                              rate_b=100, seed=seed, speed=0.5)


def _vio_mocap_handheld(seed: int, d: float) -> Recording:
    return simulate_recording(_rig(seed), drifting(), absolute(0.05, 0.0005), duration_s=d, rate_a=30,
                              rate_b=100, seed=seed, speed=0.5, motion="handheld")


def _mocap_mocap(seed: int, d: float) -> Recording:
    return simulate_recording(_rig(seed), absolute(0.05, 0.0005), absolute(0.2, 0.002), duration_s=d,
                              rate_a=100, rate_b=30, seed=seed, speed=0.5)


def _arm(seed: int, d: float) -> Recording:
    return simulate_recording(_rig(seed), absolute(0.01, 0.0001), absolute(0.1, 0.001), duration_s=d,
                              rate_a=10, rate_b=10, seed=seed, speed=0.25)


def _rates(seed: int, d: float) -> Recording:
    return simulate_recording(_rig(seed), drifting(), absolute(0.1, 0.001), duration_s=d, rate_a=200,
                              rate_b=15, seed=seed, speed=0.5)


def _offset(seed: int, d: float) -> Recording:
    return simulate_recording(_rig(seed, 0.04), drifting(), drifting(), duration_s=d, rate_a=30, rate_b=20,
                              seed=seed, speed=0.5, jumps=2)


#: name → (builder(seed, duration_s), what it stands for)
SCENARIOS: dict[str, tuple[Callable[[int, float], Recording], str]] = {
    "vio-vio": (_vio_vio, "two phones running VIO (drift in yaw, position, scale) at 30 Hz"),
    "vio-mocap": (_vio_mocap, "VIO at 30 Hz against a motion-capture body at 100 Hz"),
    "vio-mocap-upright": (_vio_mocap_handheld, "the same with the device held upright (mostly yaw, tilts of "
                          "±10–20°): VIO's yaw drift about gravity turns the translations like a rotation of X"),
    "mocap-mocap": (_mocap_mocap, "motion capture at 100 Hz against a camera on a target at 30 Hz"),
    "arm": (_arm, "a robot arm moving continuously: kinematics and a target camera at 10 Hz, no drift"),
    "rates": (_rates, "VIO at 200 Hz against a 15 Hz absolute tracker"),
    "clock-offset": (_offset, "VIO against VIO at 30/20 Hz, b's clock 40 ms ahead, two tracking jumps"),
}


def scenario(name: str, seed: int = 0, duration_s: float = 60.0) -> Recording:
    """The named recording of :data:`SCENARIOS` (``seed`` varies rig, motion and noise)."""
    build, description = SCENARIOS[name]
    rec = build(seed, duration_s)
    return Recording(rec.a, rec.b, rec.rig, name, description)
