"""Station captures: find where both sensors stood still, and make each such station one pose.

A robot arm calibration visits a few dozen *stations*. The recording is either **sparse** (a
handful of poses with large steps between them, maybe a few frames per station) or a continuous
log in which the arm **dwells** at each station. Neither suits the pipeline's continuous-tracking
stages: the pose-jump gate drops every sparse step, and keyframe pairs of a dwelling log are
mostly noise. :func:`detect_stations` recognises both kinds on the two raw pose streams and
returns one averaged pose per station and sensor, to be paired all with all.

Per stream (stamps int64 ns, poses ``T_world_sensor``, positions m, quaternions x-y-z-w):

* **sparse**: consecutive samples that moved less than ``_GROUP_DEG`` / ``_GROUP_M`` form one
  group; the stream is sparse when there are at least ``min_stations`` groups, the median
  rotation between consecutive groups is at least ``sparse_rotation_deg`` and the median group
  holds at most ``_SPARSE_GROUP`` samples (a continuous stream cut by a few tracking jumps is not
  sparse). Each group is a run.
* **dwells**: the per-sample noise σ is estimated from second differences (robust, per axis);
  sample i is at rest when the pose a dwell window ``min_dwell_s`` later lies within
  ``max(floor, 6σ)`` of it (translation and rotation). A dwell is a maximal stretch covered by
  such windows.

A station is a time interval where a run of a and a run of b overlap (b shifted into a's clock,
``max_dt_ns`` of slack). Its pose per stream is a robust average of that stream's samples in the
overlap: rotation by :func:`.dualquat.mean` (scipy's ``Rotation.mean``) over the samples within
3 robust σ (at least ``_INLIER_FLOOR_DEG``) of the first mean, translation by the per-axis median
of those inliers.

The capture counts as a station capture when at least ``min_stations`` stations are found and
either a stream is sparse or the stations cover at least ``min_rest_fraction`` of the time both
streams span: a hand-held log with a few pauses is not a station capture.

Pairing stations all with all is what OpenCV's ``calibrateHandEye`` does. With equal weights, the
rotational part of cost (8) over all pairs equals N times the spread of the per-station
estimates ``A_k X B_k⁻¹`` of the world-to-world transform about their mean, i.e. the least-squares
``AX = YB`` problem with Y eliminated; the pairs' correlation needs no further weighting (measured:
all-pairs dqopt matches the ``AX = YB`` linear translation solve and Daniilidis within 2 %, while
pairs relative to one base station are three times worse).
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..geometry import dualquat as dq
from ..geometry import se3
from ..streams import PoseStream
from .sync import Synced

__all__ = ["Stations", "detect_stations"]

_GROUP_DEG, _GROUP_M = 2.0, 0.02          # consecutive sparse samples closer than this are one station
_SPARSE_GROUP = 10                         # a sparse capture holds at most this many samples per station (median)
_FLOOR_DEG, _FLOOR_M = 0.05, 0.0005       # smallest rest tolerance (noise-free streams)
_REST_SIGMAS = 6.0                         # rest tolerance in estimated noise σ (difference of two samples)
_MAX_DIFFERENCES = 20_000                  # second differences the noise σ is the median of, at most (spread evenly)
_INLIER_FLOOR_DEG = 0.05


@dataclass(frozen=True, eq=False)
class Stations:
    """Stations found in a capture, one averaged pose per sensor each.

    synced: the stations as :class:`~handeye_cli.stages.sync.Synced` samples: stamps [ns] at the
        middle of each station (a's clock), ``T_a`` / ``T_b`` the averaged poses ``T_world_sensor``,
        ``dt_ns`` the station's duration, one tracking segment.
    kind: ``"sparse"`` (both streams sparse), ``"dwell"`` (both dwell) or ``"mixed"``.
    samples_a, samples_b: int64 (S,) samples averaged per station; inliers_a, inliers_b: those kept.
    spread_a, spread_b: (S, 2) robust scatter of the inliers about the average: rotation [deg],
        translation [m] (0 for a single sample).
    """

    synced: Synced
    kind: str
    samples_a: NDArray[np.int64]
    inliers_a: NDArray[np.int64]
    spread_a: NDArray[np.float64]
    samples_b: NDArray[np.int64]
    inliers_b: NDArray[np.int64]
    spread_b: NDArray[np.float64]

    def __len__(self) -> int:
        return len(self.synced)

    def as_dict(self) -> dict[str, Any]:
        """The result's ``stations`` block: how many, of which kind, the samples averaged and the
        median scatter within a station (rotation [deg], translation [m]) per stream."""
        return {"count": len(self), "kind": self.kind, "pose_jump_gate": "not applied",
                "samples_a": int(self.samples_a.sum()), "samples_b": int(self.samples_b.sum()),
                "outliers": int((self.samples_a - self.inliers_a).sum() + (self.samples_b - self.inliers_b).sum()),
                "median_spread_a": [float(v) for v in np.median(self.spread_a, axis=0)],
                "median_spread_b": [float(v) for v in np.median(self.spread_b, axis=0)]}


@dataclass(frozen=True)
class _Runs:
    """Runs of one stream: sample index ranges ``[start, stop)`` and whether the stream is sparse."""

    start: NDArray[np.int64]
    stop: NDArray[np.int64]
    sparse: bool


def _angle_deg(q1: NDArray[np.float64], q2: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation angle [deg] between unit quaternions (rows, x-y-z-w), exact near 0 (q ~ -q)."""
    d = np.minimum(np.sum((q1 - q2) ** 2, axis=-1), np.sum((q1 + q2) ** 2, axis=-1))
    return np.asarray(np.rad2deg(4.0 * np.arcsin(np.clip(0.5 * np.sqrt(d), 0.0, 1.0))), dtype=np.float64)


def _steps(stream: PoseStream) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rotation [deg] and translation [m] between consecutive samples."""
    q = stream.quat_xyzw
    return _angle_deg(q[:-1], q[1:]), np.linalg.norm(np.diff(stream.xyz, axis=0), axis=1)


def _runs_of(mask: NDArray[np.bool_]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Start and stop indices of the maximal runs of True in ``mask``."""
    edges = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return np.flatnonzero(edges == 1).astype(np.int64), np.flatnonzero(edges == -1).astype(np.int64)


def _sparse_runs(stream: PoseStream, min_stations: int, sparse_rotation_deg: float) -> _Runs | None:
    """Groups of samples separated by clear moves, when the stream is a sparse capture."""
    rot, trans = _steps(stream)
    move = (rot >= _GROUP_DEG) | (trans >= _GROUP_M)
    start = np.r_[0, np.flatnonzero(move) + 1].astype(np.int64)
    if len(start) < min_stations or np.median(rot[move]) < sparse_rotation_deg:
        return None
    if np.median(np.diff(np.r_[start, len(stream)])) > _SPARSE_GROUP:   # long runs split by a few tracking
        return None                                                         # jumps: continuous tracking
    return _Runs(start, np.r_[start[1:], len(stream)].astype(np.int64), True)


def _noise(stream: PoseStream) -> tuple[float, float]:
    """Robust per-axis noise σ of rotation [deg] and translation [m] from second differences
    (rotation steps as small-angle rotation vectors ``2 sign(w) vec(q_i* ⊗ q_i+1)``), at most
    ``_MAX_DIFFERENCES`` of them, spread evenly (bounded work: a median of 60,000 values, per axis, is known
    to about 0.5 %)."""
    if len(stream) < 3:
        return 0.0, 0.0
    centre = np.arange(1, len(stream) - 1)
    if len(centre) > _MAX_DIFFERENCES:
        centre = np.unique(np.linspace(1, len(stream) - 2, _MAX_DIFFERENCES).round().astype(np.int64))
    q, xyz = stream.quat_xyzw, stream.xyz
    before, after = dq.relative(q[centre - 1], q[centre]), dq.relative(q[centre], q[centre + 1])
    d_rot = 2.0 * (after[:, :3] * np.sign(after[:, 3:]) - before[:, :3] * np.sign(before[:, 3:]))
    d_pos = (xyz[centre + 1] - xyz[centre]) - (xyz[centre] - xyz[centre - 1])
    scale = 1.4826 / np.sqrt(6.0)           # MAD → σ, and Var(x₋ − 2x + x₊) = 6σ²
    return float(np.rad2deg(np.median(np.abs(d_rot))) * scale), float(np.median(np.abs(d_pos)) * scale)


def _dwell_runs(stream: PoseStream, min_dwell_s: float) -> _Runs:
    """Dwells: stretches covered by windows of ``min_dwell_s`` over which the pose stays within tolerance."""
    n = len(stream)
    sigma_deg, sigma_m = _noise(stream)
    tol_deg, tol_m = max(_FLOOR_DEG, _REST_SIGMAS * sigma_deg), max(_FLOOR_M, _REST_SIGMAS * sigma_m)
    later = np.searchsorted(stream.stamps_ns, stream.stamps_ns + int(min_dwell_s * 1e9), side="left")
    i = np.flatnonzero(later < n)
    j = later[i]
    rest = ((_angle_deg(stream.quat_xyzw[i], stream.quat_xyzw[j]) <= tol_deg)
            & (np.linalg.norm(stream.xyz[j] - stream.xyz[i], axis=1) <= tol_m) & (j > i + 1))
    cover = np.bincount(i[rest], minlength=n + 1) - np.bincount(j[rest] + 1, minlength=n + 1)
    start, stop = _runs_of(np.cumsum(cover)[:n] > 0)
    return _Runs(start, stop, False)


@dataclass(frozen=True)
class _Average:
    """One stream's pose at one station: ``T`` (4x4 ``T_world_sensor``), samples averaged, inliers kept,
    spread (rotation [deg], translation [m]) of the inliers about ``T``."""

    T: NDArray[np.float64]
    samples: int
    inliers: int
    spread: NDArray[np.float64]


def _robust_mean(stream: PoseStream, lo: int, hi: int) -> _Average:
    """Robust average of samples ``lo:hi`` (see the module docstring)."""
    quat = stream.quat_xyzw[lo:hi]
    quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    xyz = stream.xyz[lo:hi]
    angle = _angle_deg(dq.mean(quat), quat)
    limit = max(_INLIER_FLOOR_DEG, 3 * 1.4826 * float(np.median(angle)))
    inl = angle <= limit
    mean = dq.mean(quat[inl])
    pos = np.median(xyz[inl], axis=0)
    spread = np.array([float(np.sqrt(np.mean(_angle_deg(mean, quat[inl]) ** 2))),
                       float(np.sqrt(np.mean(np.sum((xyz[inl] - pos) ** 2, axis=1))))])
    return _Average(se3.from_xyz_quat(pos, mean), hi - lo, int(inl.sum()), spread)


def _in_window(stream: PoseStream, runs: _Runs, k: int, t0: int, t1: int, slack: int) -> tuple[int, int]:
    """Sample range of run ``k`` within the overlap ``[t0, t1]`` [ns] (widened by ``slack`` when it is a
    single instant); the whole run when no sample falls inside."""
    if t1 <= t0:
        t0, t1 = t0 - slack, t1 + slack
    s, e = int(runs.start[k]), int(runs.stop[k])
    lo = s + int(np.searchsorted(stream.stamps_ns[s:e], t0, side="left"))
    hi = s + int(np.searchsorted(stream.stamps_ns[s:e], t1, side="right"))
    return (lo, hi) if hi > lo else (s, e)


def _match(a: PoseStream, ra: _Runs, b: PoseStream, rb: _Runs, slack: int) -> list[tuple[int, int, int, int]]:
    """Runs of a and b that overlap within ``slack``, one to one: (run of a, run of b, overlap start, overlap
    end) [ns], in a's order. Each run pairs with at most one run of the other stream, the one it overlaps
    longest (for single samples: the nearest), so a slack wider than the spacing of the stations — stamps
    read in the wrong unit — cannot pair every station with every other (15 stations made 225)."""
    a_lo, a_hi = a.stamps_ns[ra.start], a.stamps_ns[ra.stop - 1]
    b_lo, b_hi = b.stamps_ns[rb.start], b.stamps_ns[rb.stop - 1]
    candidates = []
    for k in range(len(ra.start)):
        first = int(np.searchsorted(b_hi, a_lo[k] - slack, side="left"))
        last = int(np.searchsorted(b_lo, a_hi[k] + slack, side="right"))
        for m in range(first, last):
            t0, t1 = int(max(a_lo[k], b_lo[m])), int(min(a_hi[k], b_hi[m]))
            candidates.append((t1 - t0, k, m, t0, t1))          # overlap [ns]; negative: the gap between them
    used_a: set[int] = set()
    used_b: set[int] = set()
    out = []
    for _, k, m, t0, t1 in sorted(candidates, key=lambda c: -c[0]):
        if k not in used_a and m not in used_b:
            used_a.add(k)
            used_b.add(m)
            out.append((k, m, t0, t1))
    return sorted(out)


_SEEN: weakref.WeakKeyDictionary[PoseStream, dict[tuple[int, float, float], _Runs]] = weakref.WeakKeyDictionary()
"""Each stream's runs per setting, while the stream lives: they depend on its samples and the differences of its
stamps only, not on the clock offset, and a calibration asks for them at its estimated offset and at 0."""


def _runs(stream: PoseStream, min_stations: int, sparse_rotation_deg: float, min_dwell_s: float) -> _Runs:
    known = _SEEN.setdefault(stream, {})
    key = (min_stations, sparse_rotation_deg, min_dwell_s)
    if key not in known:
        known[key] = _sparse_runs(stream, min_stations, sparse_rotation_deg) or _dwell_runs(stream, min_dwell_s)
    return known[key]


def detect_stations(a: PoseStream, b: PoseStream, *, time_offset_ns: int = 0, max_dt_ns: int = 100_000_000,
                    min_stations: int = 5, min_dwell_s: float = 0.3, sparse_rotation_deg: float = 15.0,
                    min_rest_fraction: float = 0.25) -> Stations | None:
    """The stations of a station capture, or ``None`` when the streams are continuous tracking.

    Parameters
    ----------
    a, b: the raw streams ``T_wa_a(t)``, ``T_wb_b(t)`` (int64 ns stamps, sorted).
    time_offset_ns: how far b's clock is ahead of a's [ns] (as :func:`~handeye_cli.stages.sync.associate`).
    max_dt_ns: slack [ns] when matching a's and b's runs in time (the timestamp gate's ``max_dt``).
    min_stations: fewer stations than this is not a station capture.
    min_dwell_s: shortest dwell [s] in a continuous log.
    sparse_rotation_deg: median rotation [deg] between consecutive samples (groups) of a sparse capture.
    min_rest_fraction: share of the common time span that dwells must cover (sparse captures exempt).

    See the module docstring for the rules.
    """
    if len(a) < 1 or len(b) < 1:
        return None
    ra, rb = (_runs(s, min_stations, sparse_rotation_deg, min_dwell_s) for s in (a, b))   # b's as read: the same
    b = b.shifted(-int(time_offset_ns))
    matches = _match(a, ra, b, rb, int(max_dt_ns))
    if len(matches) < min_stations:
        return None
    span = min(a.stamps_ns[-1], b.stamps_ns[-1]) - max(a.stamps_ns[0], b.stamps_ns[0])
    covered = sum(t1 - t0 for _, _, t0, t1 in matches)
    if not (ra.sparse or rb.sparse) and covered < min_rest_fraction * max(span, 1):
        return None
    slack = int(max_dt_ns)
    per_a = [_robust_mean(a, *_in_window(a, ra, k, t0, t1, slack)) for k, _, t0, t1 in matches]
    per_b = [_robust_mean(b, *_in_window(b, rb, m, t0, t1, slack)) for _, m, t0, t1 in matches]
    t0s, t1s = (np.array([x[i] for x in matches], dtype=np.int64) for i in (2, 3))
    synced = Synced.from_matrices((t0s + t1s) // 2, np.array([p.T for p in per_a]), np.array([p.T for p in per_b]),
                                  t1s - t0s)
    kind = "sparse" if ra.sparse and rb.sparse else "dwell" if not (ra.sparse or rb.sparse) else "mixed"
    return Stations(synced, kind, *_columns(per_a), *_columns(per_b))


def _columns(per: list[_Average]) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """Samples, inliers and spreads of one stream's station averages, as arrays."""
    return (np.array([p.samples for p in per], dtype=np.int64), np.array([p.inliers for p in per], dtype=np.int64),
            np.array([p.spread for p in per], dtype=np.float64))
