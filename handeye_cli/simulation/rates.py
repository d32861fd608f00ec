"""A simulated hand-held rig whose two pose streams run at any rates, for the rate-mix tests and benchmark.

Built on :func:`handeye_cli.simulation.simulate_rig` (smooth sums of sinusoids, absolute pose
noise, per-stream timing jitter, clock offset); this module only fixes the defaults of issue 13
(4 minutes, 0.02° / 0.5 mm pose noise) and adds tracking jumps of a fixed size to either stream.

Conventions as in :mod:`handeye_cli.geometry.se3`: streams hold ``T_world_sensor(t)``, positions [m],
quaternions x-y-z-w, stamps int64 ns; ``Rig.time_offset_ns`` is how far b's clock is ahead of a's.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..streams import PoseStream
from . import Rig, simulate_rig

__all__ = ["Jumps", "RateRecording", "simulate_rates", "add_jumps"]


@dataclass(frozen=True)
class Jumps:
    """Tracking jumps injected into one stream: ``count`` excursions, each displacing ``length``
    consecutive samples by ``translation_m`` [m] (random direction) and ``rotation_deg`` [deg]
    (random axis, applied in the sensor frame) before the tracking returns to the truth."""

    count: int = 0
    translation_m: float = 0.3
    rotation_deg: float = 20.0
    length: int = 1


@dataclass(frozen=True, eq=False)
class RateRecording:
    """Both simulated streams and which of their samples were displaced by a tracking jump (bool masks)."""

    a: PoseStream
    b: PoseStream
    jumped_a: np.ndarray
    jumped_b: np.ndarray


def add_jumps(stream: PoseStream, jumps: Jumps, rng: np.random.Generator) -> tuple[PoseStream, np.ndarray]:
    """``stream`` with ``jumps`` injected at random places (never in its first or last 5 samples).

    Returns ``(stream, jumped)`` with ``jumped`` the bool mask of the displaced samples.
    """
    n = len(stream)
    jumped = np.zeros(n, dtype=bool)
    if jumps.count == 0:
        return stream, jumped
    slots = (n - 10) // (2 * jumps.length)          # non-overlapping, non-adjacent excursions
    if slots < jumps.count:
        raise ValueError(f"{jumps.count} jumps of {jumps.length} samples do not fit in {n} samples")
    starts = 5 + 2 * jumps.length * np.sort(rng.choice(slots, size=jumps.count, replace=False))
    idx = (starts[:, None] + np.arange(jumps.length)).ravel()
    jumped[idx] = True
    direction = rng.normal(size=(jumps.count, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    axis = rng.normal(size=(jumps.count, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    turn = Rotation.from_rotvec(np.repeat(axis * np.deg2rad(jumps.rotation_deg), jumps.length, axis=0))
    xyz, quat = stream.xyz.copy(), stream.quat_xyzw.copy()
    xyz[idx] += np.repeat(direction * jumps.translation_m, jumps.length, axis=0)
    quat[idx] = (Rotation.from_quat(quat[idx]) * turn).as_quat()
    return PoseStream(stream.stamps_ns, xyz, quat, frame_id=stream.frame_id, child_frame_id=stream.child_frame_id,
                      source=stream.source), jumped


def simulate_rates(rig: Rig, rate_a: float, rate_b: float, *, duration_s: float = 240.0,
                   sigma_r: float = np.deg2rad(0.02), sigma_t: float = 0.0005, speed: float = 1.0,
                   jumps_a: Jumps = Jumps(), jumps_b: Jumps = Jumps(), seed: int = 0
                   ) -> RateRecording:
    """Streams ``T_wa_a(t)`` at ``rate_a`` [Hz] and ``T_wb_b(t)`` at ``rate_b`` [Hz] of a rigid rig.

    The rig moves by hand (:func:`~handeye_cli.simulation.simulate_rig` at ``speed``: 1 is up to
    ~2 m/s and ~1 rad/s) for ``duration_s`` [s] with absolute pose noise σ = ``sigma_r`` [rad] and
    ``sigma_t`` [m]; b's clock runs ``rig.time_offset_ns`` ahead of a's. ``jumps_a`` / ``jumps_b``
    inject tracking jumps into each stream (see :class:`Jumps`).
    """
    a, b = simulate_rig(rig, duration_s=duration_s, rate_a=rate_a, rate_b=rate_b, sigma_r=sigma_r,
                        sigma_t=sigma_t, speed=speed, seed=seed)
    rng = np.random.default_rng([seed, 13])
    (a, jumped_a), (b, jumped_b) = add_jumps(a, jumps_a, rng), add_jumps(b, jumps_b, rng)
    return RateRecording(a, b, jumped_a, jumped_b)
