"""Simulated rigs of several pose sources with known extrinsics, for tests, benchmarks and samples.

Every sensor k is rigidly mounted at ``T_ref_k`` (pose of k in the reference sensor's frame; maps
points from k to ref) and tracked in its own world: ``T_wk_k(t) = D_k(t) G_k T_w_ref(t) T_ref_k``
with a random world offset ``G_k``, an odometry drift ``D_k(t) = Exp(t ξ_k)`` (a constant twist
[rad/s, m/s] in the world), its own rate [Hz] with timing jitter, pose noise (σr [rad], σt [m],
eq 38), a clock ``time_offset_ns`` ahead of the reference's, and ``gaps`` (time windows [s]
without samples: tracking lost). Three deliberate faults make a
stream "bad": ``scale`` (translations scaled, e.g. monocular VO), ``wobble_deg`` (the mount is
not rigid: the extrinsic rotates by a slow sinusoid of that amplitude) and ``slip`` (a loose
mount: from ``slip_s`` seconds on, the extrinsic is ``T_ref_k Exp(slip)``). Quaternions x-y-z-w.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ..geometry import dualquat as dq
from ..simulation import _smooth_trajectory, perturb, random_transform
from ..streams import PoseStream

__all__ = ["SimSensor", "simulate_streams", "with_fault", "FAULTS", "START_NS"]

START_NS = 1_700_000_000_000_000_000
FAULTS = ("scale", "offset", "slip")


@dataclass(frozen=True, eq=False)
class SimSensor:
    """One simulated pose source: ``T_ref_k`` (4x4), rate [Hz], noise σr [rad] / σt [m], clock
    offset [ns] (its clock ahead of the reference's), drift twist (6,) [rad/s (3), m/s (3)], the
    faults ``scale``, ``wobble_deg`` and ``slip`` (6,) (rotation vector [rad], translation [m] in
    the sensor's frame, from ``slip_s`` [s] on), and ``gaps`` ((start, end) [s] without samples)."""

    name: str
    T_ref_k: NDArray[np.float64]
    rate_hz: float
    sigma_r: float = 0.0
    sigma_t: float = 0.0
    time_offset_ns: int = 0
    drift: tuple[float, ...] = (0.0,) * 6
    scale: float = 1.0
    wobble_deg: float = 0.0
    slip: tuple[float, ...] = (0.0,) * 6
    slip_s: float = 0.0
    gaps: tuple[tuple[float, float], ...] = ()


def _stamps(rate: float, duration_s: float, rng: np.random.Generator) -> NDArray[np.float64]:
    n = int(duration_s * rate)
    return np.sort(np.arange(n) / rate + rng.uniform(-0.1, 0.1, n) / rate)


def _drift(t: NDArray[np.float64], twist: tuple[float, ...]) -> NDArray[np.float64]:
    """``Exp(t ξ)`` for a constant twist (first-order: rotation and translation grow linearly)."""
    D = np.tile(np.eye(4), (len(t), 1, 1))
    D[:, :3, :3] = dq.to_matrix(dq.from_rotvec(t[:, None] * np.asarray(twist[:3])))
    D[:, :3, 3] = t[:, None] * np.asarray(twist[3:])
    return D


def _mount(sensor: SimSensor, t: NDArray[np.float64]) -> NDArray[np.float64]:
    """The (possibly wobbling or slipped) mount ``T_ref_k(t)``."""
    M = np.tile(sensor.T_ref_k, (len(t), 1, 1))
    if sensor.wobble_deg:
        angle = np.deg2rad(sensor.wobble_deg) * np.sin(2 * np.pi * t / 7.0)
        M[:, :3, :3] = M[:, :3, :3] @ dq.to_matrix(dq.from_rotvec(angle[:, None] * np.array([0.6, 0.0, 0.8])))
    if any(sensor.slip):
        slip = np.eye(4)
        slip[:3, :3] = dq.to_matrix(dq.from_rotvec(np.asarray(sensor.slip[:3])))
        slip[:3, 3] = sensor.slip[3:]
        M[t >= sensor.slip_s] = M[t >= sensor.slip_s] @ slip
    return M


def simulate_streams(sensors: list[SimSensor], *, duration_s: float = 60.0, seed: int = 0, speed: float = 0.5,
                     start_ns: int = START_NS) -> dict[str, PoseStream]:
    """Pose streams ``T_wk_k(t)`` (int64 ns stamps in each sensor's clock) of a rigid rig moving
    in 3-D for ``duration_s`` seconds; the first sensor should be the reference (``T_ref_k = I``)."""
    rng = np.random.default_rng(seed)
    traj_seed = int(rng.integers(2**63))
    out = {}
    for k, sensor in enumerate(sensors):
        t = _stamps(sensor.rate_hz, duration_s, rng)
        for start, end in sensor.gaps:
            t = t[(t < start) | (t >= end)]
        G = np.eye(4) if k == 0 else random_transform(rng, 5.0)
        T_w_ref = _smooth_trajectory(speed * t, "3d", np.random.default_rng(traj_seed))
        T = _drift(t, sensor.drift) @ G @ T_w_ref @ _mount(sensor, t)
        T[:, :3, 3] *= sensor.scale
        if sensor.sigma_r or sensor.sigma_t:
            T = perturb(T, rng, sensor.sigma_r, sensor.sigma_t)
        ns = start_ns + np.round(t * 1e9).astype(np.int64) + sensor.time_offset_ns
        out[sensor.name] = PoseStream.from_matrices(ns, T, frame_id=f"world_{sensor.name}", child_frame_id=sensor.name,
                                                    source=f"simulated:{sensor.name}")
    return out


def with_fault(sensors: list[SimSensor], k: int, fault: str, rng: np.random.Generator, *, slip_s: float = 15.0
               ) -> tuple[list[SimSensor], float]:
    """Sensor k made bad, as the rig tests and benchmark make it: ``scale`` (translations × 0.8),
    ``offset`` (the clock offset the user gives is 30 ms wrong: returned as the error [s] to add to
    it; the sensor is unchanged) or ``slip`` (the mount turns 1° about a random axis and moves 5 mm
    in a random direction at ``slip_s`` seconds). Returns the sensors and that clock-offset error (0
    but for ``offset``)."""
    out = list(sensors)
    if fault == "scale":
        out[k] = replace(out[k], scale=0.8)
    elif fault == "slip":
        axis, shift = (v / np.linalg.norm(v) for v in rng.normal(size=(2, 3)))
        out[k] = replace(out[k], slip=(*(axis * np.deg2rad(1.0)), *(shift * 0.005)), slip_s=slip_s)
    elif fault != "offset":
        raise ValueError(f"unknown fault {fault!r}; expected one of {FAULTS}")
    return out, 0.03 if fault == "offset" else 0.0
