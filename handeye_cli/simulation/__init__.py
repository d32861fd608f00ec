"""Synthetic data with known truth: motion pairs (the paper's appendix D.2) and simulated rigs.

Used by the tests, the benchmarks and ``sample_data/make_samples.py``. Conventions as in
:mod:`handeye_cli.geometry.se3`: ``X = T_a_b``, motions satisfy ``A_i X = X B_i``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .._typing import FloatArray
from ..geometry import se3
from ..streams import PoseStream

__all__ = ["random_transform", "perturb", "motion_pairs", "Rig", "simulate_rig", "SCENARIOS"]

SCENARIOS = ("random", "line", "circle", "planar")


def random_transform(rng: np.random.Generator, translation_scale: float = 1.0) -> FloatArray:
    """A uniformly random rotation with a translation drawn from U(-s, s)³ [m]."""
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-translation_scale, translation_scale, 3)
    return T


def perturb(T: FloatArray, rng: np.random.Generator, sigma_r: float, sigma_t: float) -> FloatArray:
    """Right-perturb transforms by small SE(3) noise, ``T ∘ [δR | δt]`` (paper eq 38).

    δR has a uniformly random axis and a normal(0, ``sigma_r`` [rad]) angle; δt has
    normal(0, ``sigma_t`` [m]) components.
    """
    T = np.asarray(T, dtype=np.float64)
    n = 1 if T.ndim == 2 else len(T)
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    D = np.tile(np.eye(4), (n, 1, 1))
    D[:, :3, :3] = Rotation.from_rotvec(axis * rng.normal(0.0, sigma_r, (n, 1))).as_matrix()
    D[:, :3, 3] = rng.normal(0.0, sigma_t, (n, 3))
    out = T @ D
    return out[0] if T.ndim == 2 else out


def _scenario_motions(n: int, scenario: str, rng: np.random.Generator) -> FloatArray:
    """Noise-free motions of sensor a for the paper's scenarios (appendix D.2) plus planar."""
    A = np.tile(np.eye(4), (n, 1, 1))
    if scenario == "random":
        A[:, :3, :3] = Rotation.random(n, random_state=rng).as_matrix()
        A[:, :3, 3] = rng.uniform(0.0, 1.0, (n, 3))
    elif scenario == "line":       # constant velocity along x from 0 to 2 m, constant orientation
        A[:, 0, 3] = 2.0 / n
    elif scenario == "circle":     # one revolution of a circle of radius 2 m, steps of 2π/n
        step = 2 * np.pi / n
        A[:, :3, :3] = Rotation.from_rotvec([0.0, 0.0, step]).as_matrix()
        A[:, :3, 3] = [2 * np.sin(step), 2 * (1 - np.cos(step)), 0.0]
    elif scenario == "planar":     # random rotations about z, random translations in xy
        A[:, :3, :3] = Rotation.from_rotvec(
            np.c_[np.zeros((n, 2)), rng.uniform(-np.pi, np.pi, n)]).as_matrix()
        A[:, :2, 3] = rng.uniform(-1.0, 1.0, (n, 2))
    else:
        raise ValueError(f"unknown scenario {scenario!r}; expected one of {SCENARIOS}")
    return A


def motion_pairs(n: int, X: FloatArray, rng: np.random.Generator, scenario: str = "random",
                 sigma_r: float = 0.0, sigma_t: float = 0.0,
                 jitter: tuple[float, float] = (np.deg2rad(0.57), 0.01)) -> tuple[FloatArray, FloatArray]:
    """N relative motion pairs ``(A, B)`` with ``A_i X = X B_i`` before noise.

    ``line`` and ``circle`` get the paper's symmetry-breaking ``jitter`` (σr [rad], σt [m]) on
    the true motions; both streams then get measurement noise ``sigma_r``/``sigma_t`` (eq 38).
    """
    A = _scenario_motions(n, scenario, rng)
    if scenario in ("line", "circle"):
        A = perturb(A, rng, *jitter)
    B = se3.inverse(X) @ A @ X
    if sigma_r or sigma_t:
        A = perturb(A, rng, sigma_r, sigma_t)
        B = perturb(B, rng, sigma_r, sigma_t)
    return A, B


@dataclass(frozen=True)
class Rig:
    """Ground truth of a simulated rig: the extrinsic ``T_a_b`` and the clock offset.

    ``time_offset_ns`` is added to stream b's stamps: b's clock reads ``t + offset``.
    """

    T_a_b: FloatArray
    time_offset_ns: int = 0


def _smooth_trajectory(t: FloatArray, motion: str, rng: np.random.Generator) -> FloatArray:
    """Poses ``T_w_a(t)`` for times ``t`` [s]: sums of sinusoids, smooth and repeatable."""
    k = 4
    freqs = rng.uniform(0.05, 0.35, (k, 6))
    phases = rng.uniform(0, 2 * np.pi, (k, 6))
    amps = rng.uniform(0.3, 1.0, (k, 6)) / k
    wave = np.einsum("kd,tkd->td", amps, np.sin(2 * np.pi * freqs[None] * t[:, None, None] + phases[None]))
    rotvec = wave[:, :3] * np.array([1.6, 1.6, 3.0])     # ~±50–90° excursions, ~1 rad/s
    pos = wave[:, 3:] * np.array([2.0, 2.0, 0.8])        # ~±1–2 m
    if motion == "planar":
        rotvec[:, :2] = 0.0
        pos[:, 2] = 0.0
    elif motion == "handheld":     # a device held upright (gravity along z): full yaw, tilts of ±10–20°
        rotvec[:, :2] *= 0.2
    elif motion == "linear":
        rotvec[:] = 0.0
        pos[:, 1:] = 0.0
    elif motion != "3d":
        raise ValueError(f"unknown motion {motion!r}; expected 3d, handheld, planar or linear")
    T = np.tile(np.eye(4), (len(t), 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:, :3, 3] = pos
    return T


def simulate_rig(rig: Rig, *, duration_s: float = 60.0, rate_a: float = 30.0, rate_b: float = 20.0,
                 start_ns: int = 1_700_000_000_000_000_000, motion: str = "3d",
                 sigma_r: float = 0.0, sigma_t: float = 0.0, jumps: int = 0, seed: int = 0,
                 T_wb_wa: FloatArray | None = None, speed: float = 1.0) -> tuple[PoseStream, PoseStream]:
    """Two pose streams of a rigid rig: ``T_wa_a(t)`` and ``T_wb_b(t)`` with ``T_a_b`` fixed.

    Each stream has its own world frame (b's world is ``T_wb_wa`` away from a's), its own
    rate [Hz] and timing jitter, absolute pose noise (σr [rad], σt [m]) and ``jumps`` tracking
    jumps (a sample displaced by 0.3–1 m and 20–60°). ``speed`` scales how fast the rig moves
    (1: up to ~2 m/s and ~1 rad/s; the excursions stay the same).
    """
    rng = np.random.default_rng(seed)
    traj_rng = np.random.default_rng(rng.integers(2**63))
    G = random_transform(rng, 5.0) if T_wb_wa is None else np.asarray(T_wb_wa, dtype=np.float64)

    def stamps(rate: float) -> FloatArray:
        n = int(duration_s * rate)
        t = np.arange(n) / rate + rng.uniform(-0.1, 0.1, n) / rate
        return np.sort(t)

    def stream(t: FloatArray, T: FloatArray, frame: str, child: str, offset_ns: int) -> PoseStream:
        T = perturb(T, rng, sigma_r, sigma_t) if (sigma_r or sigma_t) else T
        for i in rng.choice(len(T), size=jumps, replace=False) if jumps else []:
            T[i] = T[i] @ perturb(np.eye(4), rng, np.deg2rad(rng.uniform(20, 60)), 0.0)
            T[i, :3, 3] += rng.normal(size=3) * rng.uniform(0.3, 1.0) / np.sqrt(3)
        ns = start_ns + np.round(t * 1e9).astype(np.int64) + offset_ns
        return PoseStream.from_matrices(ns, T, frame_id=frame, child_frame_id=child, source="simulated")

    t_a, t_b = stamps(rate_a), stamps(rate_b)
    traj_seed = traj_rng.integers(2**63)
    T_wa = _smooth_trajectory(speed * t_a, motion, np.random.default_rng(traj_seed))
    T_wb = G @ _smooth_trajectory(speed * t_b, motion, np.random.default_rng(traj_seed)) @ rig.T_a_b
    return (stream(t_a, T_wa, "world_a", "a", 0),
            stream(t_b, T_wb, "world_b", "b", rig.time_offset_ns))
