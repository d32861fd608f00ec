"""The pose stream: what every reader returns and every later stage consumes."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, Generic, TypeVar

import numpy as np
from numpy.typing import NDArray

from .errors import DataError
from .geometry import dualquat as dq
from .geometry import se3

__all__ = ["PoseStream", "Samples", "SAMPLING", "StreamMemo", "bracket"]

SAMPLING = ("interpolate", "nearest")
"""How :meth:`PoseStream.sample` reads a stream between its samples."""


def bracket(stamps_ns: NDArray[np.int64], query_ns: NDArray[np.int64]
            ) -> tuple[NDArray[np.bool_], NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """The samples around each query (int64 ns, the stamps' clock): ``(inside, lo, hi, frac)`` with
    ``value(query) = (1 - frac) value[lo] + frac value[hi]``, ``hi = lo + 1``, or ``hi = lo`` and
    ``frac = 0`` at an exact stamp. ``inside`` marks the queries within the stamps' span; the other
    entries are meaningless for the rest (indices are clipped to the samples)."""
    n = len(stamps_ns)
    after = np.searchsorted(stamps_ns, query_ns, side="right")   # first sample strictly after the query
    lo = np.maximum(after - 1, 0)
    exact = stamps_ns[lo] == query_ns
    inside = exact | ((after >= 1) & (after < n))
    hi = np.where(exact, lo, np.minimum(lo + 1, n - 1))
    frac = np.where(exact, 0.0, (query_ns - stamps_ns[lo]) / np.maximum(stamps_ns[hi] - stamps_ns[lo], 1))
    return inside, lo, hi, frac


@dataclass(frozen=True, eq=False)
class Samples:
    """A stream read at query stamps (:meth:`PoseStream.sample`). ``inside`` (Q,) marks the queries
    sampled; the other arrays hold only those: ``used`` the index of a stream sample each one used
    (the lower neighbour, or the nearest), ``xyz`` [m], ``quat_xyzw`` (x-y-z-w), and ``gap_ns`` the
    distance [ns] to the farther neighbour used (to the nearest sample for ``nearest``)."""

    inside: NDArray[np.bool_]
    used: NDArray[np.int64]
    xyz: NDArray[np.float64]
    quat_xyzw: NDArray[np.float64]
    gap_ns: NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class PoseStream:
    """A time series of poses ``T_frame_child(t)`` of one sensor.

    Attributes
    ----------
    stamps_ns:
        int64[N] timestamps in nanoseconds (``header.stamp`` by default, see ``time_source``); float
        stamps are refused (:meth:`from_seconds` converts seconds).
    xyz:
        float64[N, 3] positions of ``child_frame_id`` in ``frame_id`` [m].
    quat_xyzw:
        float64[N, 4] unit orientations, Hamilton, order x, y, z, w.
    frame_id, child_frame_id:
        The frames: each sample is ``T_frame_child``.
    source:
        Where it came from, e.g. ``"log.mcap:/cam0/pose"``; used in messages.
    time_source:
        ``"header"`` or ``"log"``.
    duplicates_dropped:
        How many samples with a repeated stamp the reader removed (the first of each stamp is kept).
    warnings:
        What the reader noticed and repaired (dropped invalid poses, conflicting duplicates, a clock
        jumping back, a guessed time unit or quaternion order, a recovered truncated file), one
        line each; the calibration result carries them.
    recovered_truncated:
        How many messages were recovered from a truncated (crashed) recording; 0 for a complete file.
    quaternion_order:
        For a text file whose quaternion order came from its format (TUM x-y-z-w, EuRoC w-x-y-z, a CSV's
        column names) rather than from the user: the order its columns were read in, which the pipeline
        may overturn when the other order fits decisively better
        (:func:`handeye_cli.analysis.readings.choose_quaternion_order`). None: not open to question (a
        log's named fields, ``--wxyz-*`` / ``--no-wxyz-*``, a stream built in memory).

    Examples
    --------
    >>> from handeye_cli import PoseStream
    >>> s = PoseStream([0, 100_000_000], [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]], [[0, 0, 0, 1], [0, 0, 0, 1]],
    ...                frame_id="world", child_frame_id="cam0")
    >>> len(s), s.stamps_ns.dtype.name, s.matrices().shape
    (2, 'int64', (2, 4, 4))
    >>> inv = s.inverted()                       # T_cam0_world: the frames swap
    >>> inv.frame_id, inv.child_frame_id, float(inv.xyz[1, 0])
    ('cam0', 'world', -0.1)
    >>> s.shifted(50_000_000).stamps_ns.tolist()  # + 50 ms
    [50000000, 150000000]
    """

    stamps_ns: np.ndarray
    xyz: np.ndarray
    quat_xyzw: np.ndarray
    frame_id: str = ""
    child_frame_id: str = ""
    source: str = ""
    time_source: str = "header"
    duplicates_dropped: int = 0
    warnings: tuple[str, ...] = ()
    recovered_truncated: int = 0
    quaternion_order: str | None = None

    def __post_init__(self) -> None:
        given = np.asarray(self.stamps_ns)
        if given.size and given.dtype.kind not in "iu":     # a cast would turn seconds into garbage nanoseconds
            raise DataError(f"stamps_ns of {given.dtype.name} values, e.g. {given.reshape(-1)[0].item()!r}",
                            self.source or "PoseStream", "stamps must be int64 nanoseconds; use "
                            "PoseStream.from_seconds(stamps_s, xyz, quat_xyzw) for seconds")
        stamps = np.ascontiguousarray(given, dtype=np.int64)
        xyz = np.ascontiguousarray(self.xyz, dtype=np.float64).reshape(-1, 3)
        quat = np.ascontiguousarray(self.quat_xyzw, dtype=np.float64).reshape(-1, 4)
        if not (len(stamps) == len(xyz) == len(quat)):
            raise ValueError(f"PoseStream arrays differ in length: {len(stamps)}, {len(xyz)}, {len(quat)}")
        object.__setattr__(self, "stamps_ns", stamps)
        object.__setattr__(self, "xyz", xyz)
        object.__setattr__(self, "quat_xyzw", quat)

    def __len__(self) -> int:
        return len(self.stamps_ns)

    @classmethod
    def from_seconds(cls, stamps_s: Any, xyz: Any, quat_xyzw: Any, **kw: Any) -> PoseStream:
        """Build a stream from stamps in (float) seconds, rounded to the nearest nanosecond; other
        arguments as the constructor's.

        >>> PoseStream.from_seconds([0.5, 1.25], [[0.0, 0, 0]] * 2, [[0.0, 0, 0, 1]] * 2).stamps_ns.tolist()
        [500000000, 1250000000]
        """
        t = np.asarray(stamps_s, dtype=np.float64).reshape(-1)
        ok = np.isfinite(t) & (np.abs(t) < 9.2e9)                          # int64 ns reach ±292 years
        if not ok.all():
            bad = float(t[~ok][0])
            raise DataError(f"stamp {bad!r} s", kw.get("source") or "PoseStream.from_seconds",
                            "give finite seconds within ±9.2e9 (int64 nanoseconds)")
        whole = np.floor(t)              # whole seconds exactly, then the fraction: no rounding of 1e9·t
        ns = whole.astype(np.int64) * 1_000_000_000 + np.round((t - whole) * 1e9).astype(np.int64)
        return cls(ns, xyz, quat_xyzw, **kw)

    @classmethod
    def from_matrices(cls, stamps_ns: np.ndarray, T: np.ndarray, **kw: Any) -> PoseStream:
        """Build a stream from (N, 4, 4) transforms ``T_frame_child``."""
        xyz, quat = se3.to_xyz_quat(np.asarray(T).reshape(-1, 4, 4))
        return cls(stamps_ns, xyz, quat, **kw)

    def matrices(self) -> np.ndarray:
        """(N, 4, 4) homogeneous transforms ``T_frame_child``."""
        return se3.from_xyz_quat(self.xyz, self.quat_xyzw).reshape(-1, 4, 4)

    def inverted(self) -> PoseStream:
        """The stream of inverse poses ``T_child_frame`` (e.g. camera-observes-target → target-in-camera).
        The frames swap; where the parent is unnamed (a text file's world) the sensor keeps its name.
        ``quaternion_order`` is closed: the file's columns no longer map to the stream's quaternions."""
        xyz, quat = se3.to_xyz_quat(se3.inverse(self.matrices()))
        frame, child = (self.child_frame_id, self.frame_id) if self.frame_id else ("", self.child_frame_id)
        return replace(self, xyz=xyz, quat_xyzw=quat, frame_id=frame, child_frame_id=child, quaternion_order=None)

    def scaled(self, factor: float) -> PoseStream:
        """The same stream with its translations multiplied by ``factor`` (e.g. metres per unit of a monocular
        stream); orientations unchanged."""
        return replace(self, xyz=self.xyz * float(factor))

    def select(self, mask_or_index: np.ndarray) -> PoseStream:
        """A stream with only the samples selected by a boolean mask or index array."""
        return replace(self, stamps_ns=self.stamps_ns[mask_or_index], xyz=self.xyz[mask_or_index],
                       quat_xyzw=self.quat_xyzw[mask_or_index])

    def sample(self, query_ns: Any, method: str = "interpolate", segment: NDArray[np.int64] | None = None
               ) -> Samples:
        """The poses at the stamps ``query_ns`` (int64 ns, the stream's clock).

        ``"interpolate"``: linear position and SLERP between the bracketing samples; ``"nearest"``:
        the closer sample. Queries outside the stream's span are not sampled. With ``segment``
        (an int64 label per stream sample), interpolation never bridges two segments: such queries
        count as outside.
        """
        query = np.asarray(query_ns, dtype=np.int64)
        stamps = self.stamps_ns
        inside, lo, hi, frac = bracket(stamps, query)
        if segment is not None and method != "nearest":
            inside &= segment[lo] == segment[hi]
        lo, hi, frac, q = lo[inside], hi[inside], frac[inside], query[inside]
        d_lo, d_hi = q - stamps[lo], stamps[hi] - q
        if method == "nearest":
            pick = np.where(d_hi < d_lo, hi, lo)
            return Samples(inside, pick, self.xyz[pick], self.quat_xyzw[pick], np.minimum(d_lo, d_hi))
        xyz = self.xyz[lo] + frac[:, None] * (self.xyz[hi] - self.xyz[lo])
        return Samples(inside, lo, xyz, dq.slerp(self.quat_xyzw[lo], self.quat_xyzw[hi], frac), np.maximum(d_lo, d_hi))

    def shifted(self, offset_ns: int) -> PoseStream:
        """The same stream with ``offset_ns`` added to every stamp."""
        return replace(self, stamps_ns=self.stamps_ns + np.int64(offset_ns))


Value = TypeVar("Value")


class StreamMemo(Generic[Value]):
    """``compute(stream, *args)`` of each stream and arguments computed once: a rig's stream is in several pairs
    (its jitter for their fit tests) and its reference in every clock offset (its orientations on the ω grid, at
    each grid step). Streams are told apart by identity; the memo holds them, so no two of them share an ``id``
    while it lives (a memo lives as long as one rig's stage: bounded by its streams)."""

    def __init__(self, compute: Callable[..., Value]) -> None:
        self._compute = compute
        self._seen: dict[tuple[int, tuple[Any, ...]], tuple[PoseStream, Value]] = {}

    def __call__(self, stream: PoseStream, *args: Any) -> Value:
        key = id(stream), args
        hit = self._seen.get(key)
        if hit is None or hit[0] is not stream:
            hit = self._seen[key] = (stream, self._compute(stream, *args))
        return hit[1]
