"""The white noise of one pose stream, from the stream alone: its high-frequency jitter.

Conventions: a stream holds ``T_world_sensor(t)`` (stamps int64 ns, positions [m], quaternions
x-y-z-w); rotation noise is a rotation vector in the sensor frame (right perturbation, the form
:func:`handeye_cli.simulation.perturb` draws; its ``sigma_r`` is the angle's, ``sigma_r / √3`` per axis); σ is per
axis, per pose.

Each sample i is predicted from its four neighbours i-2, i-1, i+1, i+2 by the cubic through them,
evaluated at ``t_i`` (Lagrange weights ``w`` from the actual stamps, so uneven sampling is exact):
positions directly, orientations as rotation vectors ``log(q_i⁻¹ q_k)`` of the neighbours relative
to sample i (0 for i itself). A smooth motion is predicted to 4th order, so what is left is the
noise: ``e_i = x_i - Σ w_k x_k`` has variance ``σ² (1 + Σ w_k²)`` for white noise σ, and σ is
the robust scale (1.4826 × median |e| / √(1 + Σ w²)) over the samples of each axis, the three axes'
combined as their root mean square (the isotropic σ of the same total variance: a planar stream's
rotation noise is all about one axis, which a median pooled over the axes would read as 0). Samples whose window
spans a gap longer than ``_MAX_GAP_STEPS`` median steps, or turns by more than ``_MAX_TURN_RAD``,
are not used.

Bounded work: at most ``MAX_WINDOWS`` windows, their centres spread evenly over the stream (every
window of a shorter stream). σ combines a median over them per axis, whose relative standard error for
isotropic normal noise is ≈ 1.16 / √(3 · windows) once the three axes are combined: 0.5 % at 20,000
windows, where the fit test's allowance is 15×; an hour at 100 Hz (360,000 samples) costs what 3 minutes do.

The estimate needs neither the other stream nor the extrinsic, so the fit test
(:mod:`handeye_cli.analysis.fit_test`) can judge the residuals at ``X`` by it. It sees only what
changes from sample to sample: slow drift and systematic errors (kinematic errors, target
detection biases) are invisible here by construction, and so is the noise of a stream that was
smoothed or up-sampled before it was recorded.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._typing import FloatArray
from ..geometry import dualquat as dq
from ..streams import PoseStream

__all__ = ["MAX_WINDOWS", "StreamNoise", "stream_noise"]

MAX_WINDOWS = 20_000        # windows the estimate reads at most, spread evenly (module docstring)

_MAX_GAP_STEPS = 3.0        # a window spanning a longer gap (in median steps) is not used
_MAX_TURN_RAD = 0.5         # ... nor one that turns more than this (the cubic would not follow it)
_MIN_SAMPLES = 8            # fewer usable windows: the noise is unknown
_MAD = 1.4826               # median absolute deviation → σ of a normal distribution


@dataclass(frozen=True)
class StreamNoise:
    """White noise of one stream, per axis and per pose: rotation [rad], translation [m], and the
    number of samples it was estimated from."""

    sigma_rotation_rad: float
    sigma_translation_m: float
    samples: int
    step_rotation_rad: float = 0.0
    step_translation_m: float = 0.0
    bend_rotation_rad: float = 0.0
    bend_translation_m: float = 0.0

    def interpolation_sigma(self, method: str) -> tuple[float, float]:
        """Per-axis error (rotation [rad], translation [m]) of this stream read between its samples:
        ``nearest`` misses by up to half a step, linear interpolation by an eighth of the bend
        (the second difference) at mid-step — both taken at their median, per axis."""
        if method == "nearest":
            return 0.5 * self.step_rotation_rad, 0.5 * self.step_translation_m
        return 0.125 * self.bend_rotation_rad, 0.125 * self.bend_translation_m

    def as_dict(self) -> dict[str, Any]:
        """For the result file: σ in degrees and metres."""
        return {"sigma_rotation_deg": float(np.rad2deg(self.sigma_rotation_rad)),
                "sigma_translation_m": self.sigma_translation_m, "samples": self.samples}


def _cubic_weights(t: FloatArray) -> FloatArray:
    """(N, 4) Lagrange weights of the nodes ``t[:, [0, 1, 3, 4]]`` at ``t[:, 2]`` (t: (N, 5) times [s])."""
    nodes = t[:, [0, 1, 3, 4]]
    at = t[:, 2:3]
    w = np.ones_like(nodes)
    for k in range(4):
        for m in range(4):
            if m != k:
                w[:, k] *= (at[:, 0] - nodes[:, m]) / (nodes[:, k] - nodes[:, m])
    return w


def stream_noise(stream: PoseStream) -> StreamNoise | None:
    """The white noise σ of ``stream`` per axis and pose (module docstring), or None when fewer than
    ``_MIN_SAMPLES`` samples have four close neighbours (sparse captures)."""
    n = len(stream)
    if n < 5:
        return None
    t = (stream.stamps_ns - stream.stamps_ns[0]) / 1e9
    steps = np.diff(t)
    median = float(np.median(steps))
    centres = np.arange(2, n - 2)
    if len(centres) > MAX_WINDOWS:
        centres = np.unique(np.linspace(2, n - 3, MAX_WINDOWS).round().astype(np.int64))
    idx = centres[:, None] + np.arange(-2, 3)[None, :]                       # (M, 5) windows
    tw = t[idx]
    span_ok = (tw[:, -1] - tw[:, 0]) <= 4 * _MAX_GAP_STEPS * max(median, 1e-12)
    distinct = np.all(np.diff(tw, axis=1) > 0, axis=1)
    q = stream.quat_xyzw[idx]
    q /= np.linalg.norm(q, axis=2, keepdims=True)
    rel = dq.to_rotvec(dq.relative(q[:, 2:3], q[:, [0, 1, 3, 4]]))           # (M, 4, 3) in sensor i's frame
    turn_ok = np.max(np.linalg.norm(rel, axis=2), axis=1) <= _MAX_TURN_RAD
    use = span_ok & distinct & turn_ok
    if np.count_nonzero(use) < _MIN_SAMPLES:
        return None
    w = _cubic_weights(tw[use])
    gain = np.sqrt(1.0 + np.sum(w * w, axis=1))[:, None]                     # std of e per unit σ
    e_rot = -np.einsum("nk,nkd->nd", w, rel[use]) / gain
    xyz = stream.xyz[idx[use]]
    e_pos = (xyz[:, 2] - np.einsum("nk,nkd->nd", w, xyz[:, [0, 1, 3, 4]])) / gain
    step_rot = rel[use][:, 2]                                                # sample i → i+1
    bend_rot = rel[use][:, 2] + rel[use][:, 1]                              # (i+1 − i) − (i − (i−1))
    step_pos, bend_pos = xyz[:, 3] - xyz[:, 2], xyz[:, 3] - 2 * xyz[:, 2] + xyz[:, 1]
    med = [_per_axis(v) for v in (e_rot, e_pos, step_rot, step_pos, bend_rot, bend_pos)]
    return StreamNoise(_MAD * med[0], _MAD * med[1], int(np.count_nonzero(use)), *med[2:])


def _per_axis(v: FloatArray) -> float:
    """The median of ``|v|`` (N, 3) on each axis, combined as their root mean square: the isotropic per-axis
    value of the same total variance. A planar stream (wheel odometry, a 2-D localiser) moves and errs about
    one rotation axis and along two translation axes only; a median pooled over the axes would read its
    rotation noise as 0 where all of it is about the vertical."""
    return float(np.sqrt(np.mean(np.median(np.abs(v), axis=0) ** 2)))

