"""Associate stream b to stream a's stamps: interpolation or nearest sample, with the timestamp gate.

Conventions (see :mod:`handeye_cli.se3`): each stream holds absolute poses ``T_w_sensor(t)``;
stamps are int64 nanoseconds. The result :class:`Synced` holds both streams at a's stamps.

Time offset sign: ``time_offset_ns`` is how far b's clock is **ahead** of a's. b's sample
stamped ``s`` was taken at a's time ``s - time_offset_ns``. This matches
:class:`handeye_cli.simulation.Rig`'s ``time_offset_ns`` (b's clock reads ``t + offset``), so
passing the rig's true offset aligns the streams.

Timestamp gate: a sample is kept only when every b sample used lies within ``max_dt`` of the a
stamp — for ``nearest`` the one sample, for ``interpolate`` both bracketing samples (no
interpolation across a gap). With ``interpolate`` this needs b's sample interval to be below
``2·max_dt`` (b faster than 5 Hz for the default 0.1 s); use ``nearest`` or a larger ``max_dt``
for slower streams.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from .. import se3
from ..errors import HandEyeError
from ..streams import PoseStream

__all__ = ["Association", "Synced", "associate", "interpolate", "METHODS"]

METHODS = ("interpolate", "nearest")


@dataclass(frozen=True, eq=False)
class Association:
    """How a :class:`Synced` was made, so a later gate can re-associate from the raw samples.

    a, b: the raw streams, b already shifted into a's clock. method, max_dt_ns: as in :func:`associate`.
    """

    a: PoseStream
    b: PoseStream
    method: str
    max_dt_ns: int


@dataclass(frozen=True, eq=False)
class Synced:
    """Both streams at common stamps (a's stamps, in a's clock).

    Attributes
    ----------
    stamps_ns: int64[N] stamps [ns] in a's clock.
    T_a: (N, 4, 4) poses ``T_wa_a`` of sensor a at the stamps.
    T_b: (N, 4, 4) poses ``T_wb_b`` of sensor b at the stamps (interpolated or nearest).
    dt_ns: int64[N] the gap used: the largest distance [ns] from a stamp to a b sample used.
    segment: int64[N] non-decreasing tracking segment of each sample (0 unless the pose-jump gate
        accepted a new tracking level); motions are only formed within a segment.
    source: the raw streams and settings it was associated from (``None`` when built directly).
    """

    stamps_ns: np.ndarray
    T_a: np.ndarray
    T_b: np.ndarray
    dt_ns: np.ndarray
    segment: np.ndarray = field(default=None)  # type: ignore[assignment]
    source: Association | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.segment is None:
            object.__setattr__(self, "segment", np.zeros(len(self.stamps_ns), dtype=np.int64))

    def __len__(self) -> int:
        return len(self.stamps_ns)

    def select(self, mask_or_index: np.ndarray) -> Synced:
        """The samples selected by a boolean mask or an index array."""
        m = mask_or_index
        return Synced(self.stamps_ns[m], self.T_a[m], self.T_b[m], self.dt_ns[m], self.segment[m], self.source)


def _slerp(q_lo: np.ndarray, q_hi: np.ndarray, frac: np.ndarray) -> Rotation:
    """Per-row SLERP between x-y-z-w quaternions ``q_lo`` and ``q_hi`` at fractions ``frac`` ∈ [0, 1]."""
    r_lo = Rotation.from_quat(q_lo)
    step = (r_lo.inv() * Rotation.from_quat(q_hi)).as_rotvec()
    return r_lo * Rotation.from_rotvec(step * frac[:, None])


def _lookup(stream: PoseStream, query: np.ndarray, method: str, segment: np.ndarray | None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`interpolate`, also returning the index of a sample used (for its segment).

    With ``segment`` (int64 per stream sample), ``interpolate`` never bridges two segments:
    such queries count as outside. Returns ``(inside, used, xyz, quat_xyzw, gap_ns)``.
    """
    if method not in METHODS:
        raise HandEyeError(f"unknown association method {method!r}", "sync", f"use one of {', '.join(METHODS)}")
    stamps = stream.stamps_ns
    n = len(stamps)
    after = np.searchsorted(stamps, query, side="right")   # first sample strictly after the query
    lo = after - 1
    exact = (lo >= 0) & (stamps[np.clip(lo, 0, n - 1)] == query)
    inside = exact | ((lo >= 0) & (after < n))
    if segment is not None and method == "interpolate":
        bridge = np.flatnonzero(inside & ~exact)     # lo + 1 < n here
        inside[bridge] = segment[lo[bridge]] == segment[lo[bridge] + 1]
    lo, q, exact = lo[inside], query[inside], exact[inside]
    hi = np.where(exact, lo, np.minimum(lo + 1, n - 1))
    d_lo, d_hi = q - stamps[lo], stamps[hi] - q
    if method == "nearest":
        pick = np.where(d_hi < d_lo, hi, lo)
        return inside, pick, stream.xyz[pick], stream.quat_xyzw[pick], np.minimum(d_lo, d_hi)
    frac = np.where(exact, 0.0, d_lo / np.maximum(stamps[hi] - stamps[lo], 1))
    xyz = stream.xyz[lo] + frac[:, None] * (stream.xyz[hi] - stream.xyz[lo])
    quat = _slerp(stream.quat_xyzw[lo], stream.quat_xyzw[hi], frac).as_quat()
    return inside, lo, xyz, quat, np.maximum(d_lo, d_hi)


def interpolate(stream: PoseStream, query_ns: np.ndarray, *, method: str = "interpolate"
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sample ``stream`` at the stamps ``query_ns`` (int64 ns, same clock as the stream).

    ``"interpolate"``: linear position and SLERP between the bracketing samples; the gap is the
    larger distance to the two. ``"nearest"``: the closer sample; the gap is its distance.
    Queries outside the stream's span are not sampled.

    Returns ``(inside, xyz, quat_xyzw, gap_ns)``: ``inside`` is a bool mask over ``query_ns``; the
    other arrays hold only the inside queries (positions [m], x-y-z-w quaternions, gaps [ns]).
    """
    inside, _, xyz, quat, gap = _lookup(stream, np.asarray(query_ns, dtype=np.int64), method, None)
    return inside, xyz, quat, gap


def associate_raw(a: PoseStream, b: PoseStream, method: str, max_dt_ns: int,
                  segment_a: np.ndarray | None = None, segment_b: np.ndarray | None = None
                  ) -> tuple[Synced, np.ndarray]:
    """Associate b (already in a's clock) to a's stamps without any checks; may return no sample.

    ``segment_a`` / ``segment_b``: optional non-decreasing tracking segments per raw sample; a
    sample's segment in the result is their sum (it grows whenever either does), and ``interpolate``
    never bridges a segment boundary of b. Returns ``(Synced, inside)`` with ``inside`` the bool
    mask over a's samples that b's span covers (the rest were dropped as outside the span).
    """
    inside, used, xyz, quat, gap = _lookup(b, a.stamps_ns, method, segment_b)
    keep = gap <= max_dt_ns
    idx = np.flatnonzero(inside)[keep]
    segment = np.zeros(len(idx), dtype=np.int64)
    if segment_a is not None:
        segment += segment_a[idx]
    if segment_b is not None:
        segment += segment_b[used[keep]]
    T_b = se3.from_xyz_quat(xyz[keep], quat[keep]).reshape(-1, 4, 4)
    synced = Synced(a.stamps_ns[idx], se3.from_xyz_quat(a.xyz[idx], a.quat_xyzw[idx]).reshape(-1, 4, 4), T_b,
                    gap[keep].astype(np.int64), segment, Association(a, b, method, int(max_dt_ns)))
    return synced, inside


def _span(stream: PoseStream) -> str:
    return f"{stream.stamps_ns[0] / 1e9:.3f}–{stream.stamps_ns[-1] / 1e9:.3f} s"


def associate(a: PoseStream, b: PoseStream, *, method: str = "interpolate", max_dt_ns: int = 100_000_000,
              time_offset_ns: int = 0) -> tuple[Synced, dict]:
    """Sample stream b at stream a's stamps, keeping only samples that pass the timestamp gate.

    Parameters
    ----------
    a, b: poses ``T_wa_a(t)`` and ``T_wb_b(t)``; stamps int64 ns, sorted.
    method: ``"interpolate"`` (linear position + SLERP between the bracketing b samples) or
        ``"nearest"`` (the closest b sample).
    max_dt_ns: the timestamp gate [ns]: a sample is kept only when every b sample used lies within
        this distance of the a stamp (the paper's 0.1 s).
    time_offset_ns: how far b's clock is ahead of a's [ns]: b's sample stamped ``s`` belongs to
        a's time ``s - time_offset_ns`` (the convention of ``simulation.Rig.time_offset_ns``).

    Returns
    -------
    (Synced at a's stamps, counts ``{"read_a", "read_b", "synced", "dropped_outside_span",
    "dropped_timestamp_gate"}``).

    Raises
    ------
    HandEyeError: for an empty stream, an unknown method, streams that do not overlap in time,
        or when no sample passes the gate.
    """
    for name, stream in (("a", a), ("b", b)):
        if len(stream) == 0:
            raise HandEyeError(f"pose stream {name} is empty", stream.source or f"stream {name}",
                               "check the topic / frames selected for both streams")
    b = b.shifted(-int(time_offset_ns))
    if a.stamps_ns[-1] < b.stamps_ns[0] or b.stamps_ns[-1] < a.stamps_ns[0]:
        raise HandEyeError(
            "the two pose streams do not overlap in time",
            f"a spans {_span(a)}, b spans {_span(b)} after a time offset of {time_offset_ns / 1e9:.6f} s",
            "use --time-offset auto to estimate the clock offset, or give a fixed --time-offset")
    synced, inside = associate_raw(a, b, method, max_dt_ns)
    counts = {"read_a": len(a), "read_b": len(b), "synced": len(synced),
              "dropped_outside_span": int(len(a) - inside.sum()),
              "dropped_timestamp_gate": int(inside.sum() - len(synced))}
    if len(synced) == 0:
        raise HandEyeError(
            "no sample passed the timestamp gate",
            f"max_dt {max_dt_ns / 1e9:.3f} s; {counts['dropped_timestamp_gate']} samples of a too far from "
            f"b's, {counts['dropped_outside_span']} outside b's span",
            "raise max_dt, use nearest association for a slow stream b, or fix the time offset "
            "(--time-offset auto)")
    return synced, counts
