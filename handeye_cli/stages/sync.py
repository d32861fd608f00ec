"""Associate the two pose streams in time: both streams' poses at common stamps, with the timestamp gate.

Conventions (see :mod:`handeye_cli.geometry.se3`): each stream holds absolute poses ``T_w_sensor(t)``;
stamps are int64 nanoseconds; positions [m]; quaternions x-y-z-w. :class:`Synced` holds both
streams' poses (positions + quaternions, no 4×4 matrices) at common stamps in a's clock.

Methods
-------
``auto`` (default): the slower stream (the larger median sample step) sets the sample times and
    the faster stream is interpolated at them (linear position + SLERP between its two
    neighbours). The faster stream's neighbours are close, so the interpolation is accurate and
    every sample of the slow stream is used. The reference is a on a tie.
``interpolate``: b is interpolated at a's stamps (a is the reference).
``nearest``: b's closest sample at each of a's stamps.

Timestamp gate: a sample is kept only when every sample of the interpolated stream it uses lies
within ``max_dt`` of the reference stamp — for ``nearest`` the one sample, otherwise both
neighbours (so nothing is interpolated across a gap). The default ``max_dt`` follows the data:
``max(0.1 s, 2.5 × the interpolated stream's median step)`` — the paper's 0.1 s for streams faster
than 25 Hz; for slower ones, a gap of one dropped sample plus stamp jitter is bridged, two are not.

Time offset sign: ``time_offset_ns`` is how far b's clock is **ahead** of a's. b's sample
stamped ``s`` was taken at a's time ``s - time_offset_ns``. This matches
:class:`handeye_cli.simulation.Rig`'s ``time_offset_ns`` (b's clock reads ``t + offset``), so
passing the rig's true offset aligns the streams.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ConfigError, DataError
from ..geometry import se3
from ..streams import PoseStream

__all__ = ["Synced", "associate", "median_step_ns", "default_max_dt_ns", "rates_text",
           "METHODS"]

METHODS = ("auto", "interpolate", "nearest")
_MIN_MAX_DT_NS = 100_000_000     # the paper's timestamp gate [ns]: the floor of the default
_MAX_DT_STEPS = 2.5              # the default gate in median steps of the interpolated stream

Floats = NDArray[np.float64]
Ints = NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class Synced:
    """Both streams at common stamps (in a's clock).

    Attributes
    ----------
    stamps_ns: int64[N] stamps [ns] in a's clock.
    xyz_a, quat_a: (N, 3) positions [m] and (N, 4) x-y-z-w quaternions of ``T_wa_a`` at the stamps.
    xyz_b, quat_b: the same of ``T_wb_b`` (interpolated or nearest where b is not the reference).
    dt_ns: int64[N] the gap used: the largest distance [ns] from a stamp to a sample of the
        interpolated stream used (0 where the reference's samples are used as they are).
    segment: int64[N] non-decreasing tracking segment of each sample (0 unless the pose-jump gate
        found that a stream re-localised); motions are only formed within a segment.
    reference: which stream's samples set the stamps: ``"a"`` or ``"b"``.
    step_ns: (a, b) median sample step [ns] of each stream as read (0: fewer than 2 samples).
    """

    stamps_ns: Ints
    xyz_a: Floats
    quat_a: Floats
    xyz_b: Floats
    quat_b: Floats
    dt_ns: Ints
    segment: Ints = field(default=None)  # type: ignore[arg-type]  # filled in by __post_init__
    reference: str = "a"
    step_ns: tuple[int, int] = (0, 0)

    def __post_init__(self) -> None:
        if self.segment is None:
            object.__setattr__(self, "segment", np.zeros(len(self.stamps_ns), dtype=np.int64))

    @classmethod
    def from_matrices(cls, stamps_ns: Ints, T_a: Floats, T_b: Floats, dt_ns: Ints, segment: Ints | None = None,
                      **kw: Any) -> Synced:
        """Build from (N, 4, 4) poses ``T_wa_a`` and ``T_wb_b``."""
        (xyz_a, quat_a), (xyz_b, quat_b) = se3.to_xyz_quat(np.asarray(T_a)), se3.to_xyz_quat(np.asarray(T_b))
        stamps = np.asarray(stamps_ns, dtype=np.int64)
        return cls(stamps, xyz_a, quat_a, xyz_b, quat_b, np.asarray(dt_ns, dtype=np.int64),
                   np.zeros(len(stamps), dtype=np.int64) if segment is None else segment, **kw)

    def __len__(self) -> int:
        return len(self.stamps_ns)

    @property
    def T_a(self) -> Floats:
        """(N, 4, 4) poses ``T_wa_a`` (built on each access: keep the result if used repeatedly)."""
        return se3.from_xyz_quat(self.xyz_a, self.quat_a).reshape(-1, 4, 4)

    @property
    def T_b(self) -> Floats:
        """(N, 4, 4) poses ``T_wb_b`` (built on each access)."""
        return se3.from_xyz_quat(self.xyz_b, self.quat_b).reshape(-1, 4, 4)

    def motions(self, i: Ints, j: Ints) -> tuple[Floats, Floats]:
        """(A, B): the relative motions ``T_wa_a(i)⁻¹ T_wa_a(j)`` and ``T_wb_b(i)⁻¹ T_wb_b(j)`` (K, 4, 4) between
        samples ``i`` and ``j``, built from those samples' rows only (not every sample's pose)."""
        def of(xyz: Floats, quat: Floats) -> Floats:
            return se3.relative(se3.from_xyz_quat(xyz[i], quat[i]).reshape(-1, 4, 4),
                                se3.from_xyz_quat(xyz[j], quat[j]).reshape(-1, 4, 4))
        return of(self.xyz_a, self.quat_a), of(self.xyz_b, self.quat_b)

    @property
    def rates_hz(self) -> tuple[float, float]:
        """Rate [Hz] of streams a and b (from their median steps; 0 when unknown)."""
        return tuple(1e9 / s if s > 0 else 0.0 for s in self.step_ns)  # type: ignore[return-value]

    def select(self, mask_or_index: NDArray[Any]) -> Synced:
        """The samples selected by a boolean mask or an index array."""
        m = mask_or_index
        return Synced(self.stamps_ns[m], self.xyz_a[m], self.quat_a[m], self.xyz_b[m], self.quat_b[m],
                      self.dt_ns[m], self.segment[m], self.reference, self.step_ns)

    def describe(self) -> dict[str, Any]:
        """For the result: which stream set the sample times, and each stream's rate [Hz]."""
        rate_a, rate_b = self.rates_hz
        return {"reference": self.reference, "rate_a_hz": round(rate_a, 4), "rate_b_hz": round(rate_b, 4)}


def median_step_ns(stream: PoseStream) -> int:
    """Median interval [ns] between consecutive stamps (0 for fewer than 2 samples)."""
    return int(np.median(np.diff(stream.stamps_ns))) if len(stream) > 1 else 0


def default_max_dt_ns(step_ns: int) -> int:
    """The default timestamp gate [ns] for an interpolated stream whose median step is ``step_ns``."""
    return max(_MIN_MAX_DT_NS, int(_MAX_DT_STEPS * step_ns))


def rates_text(step_ns: tuple[int, int]) -> str:
    """``"a 100 Hz, b 1 Hz"`` from the median steps [ns] of a and b."""
    def rate(step: int) -> str:
        hz = 1e9 / step if step > 0 else 0.0
        return "a single sample" if step <= 0 else f"{hz:.0f} Hz" if hz >= 10 else f"{hz:.2g} Hz"

    return ", ".join(f"{name} {rate(step)}" for name, step in zip("ab", step_ns, strict=True))


def _check(a: PoseStream, b: PoseStream, method: str, time_offset_ns: int) -> None:
    if method not in METHODS:
        raise ConfigError(f"unknown association method {method!r}", "sync", f"use one of {', '.join(METHODS)}")
    for name, stream in (("a", a), ("b", b)):
        if len(stream) == 0:
            raise DataError(f"pose stream {name} is empty", stream.source or f"stream {name}",
                            "check the topic / frames selected for both streams")
    if a.stamps_ns[-1] < b.stamps_ns[0] or b.stamps_ns[-1] < a.stamps_ns[0]:
        span = {n: f"{s.stamps_ns[0] / 1e9:.3f}–{s.stamps_ns[-1] / 1e9:.3f} s" for n, s in (("a", a), ("b", b))}
        raise DataError(
            "the two pose streams do not overlap in time",
            f"a spans {span['a']}, b spans {span['b']} after a time offset of {time_offset_ns / 1e9:.6f} s",
            ("the default ⟦time_offset='auto'⟧ found no offset it could apply (too little rotation to correlate, "
             "or outside ⟦max_time_offset⟧): give it with ⟦time_offset=SECONDS⟧"))


def associate(a: PoseStream, b: PoseStream, *, method: str = "auto", max_dt_ns: int | None = None,
              time_offset_ns: int = 0, segment_a: Ints | None = None, segment_b: Ints | None = None
              ) -> tuple[Synced, dict[str, int]]:
    """Both streams at the reference stream's stamps, keeping only samples that pass the timestamp gate.

    Parameters
    ----------
    a, b: poses ``T_wa_a(t)`` and ``T_wb_b(t)``; stamps int64 ns, sorted.
    method: ``"auto"``, ``"interpolate"`` or ``"nearest"`` (see the module docstring).
    max_dt_ns: the timestamp gate [ns] on the interpolated stream's samples; ``None``: the default
        :func:`default_max_dt_ns` of the interpolated stream's median step.
    time_offset_ns: how far b's clock is ahead of a's [ns]: b's sample stamped ``s`` belongs to
        a's time ``s - time_offset_ns`` (the convention of ``simulation.Rig.time_offset_ns``).
    segment_a, segment_b: optional non-decreasing tracking segments per raw sample (from a
        pose-jump gate on the raw streams); a sample's segment is their sum, and the interpolated
        stream is never interpolated across a segment boundary.

    Returns
    -------
    (Synced, counts ``{"read_a", "read_b", "synced", "dropped_outside_span", "dropped_timestamp_gate"}``):
    the two dropped counts are of the reference stream's samples.

    Raises
    ------
    ConfigError for an unknown method; DataError for an empty stream, streams that do not
    overlap in time, or when no sample passes the gate (naming the flags that relax it).
    """
    b = b.shifted(-int(time_offset_ns))
    _check(a, b, method, time_offset_ns)
    steps = (median_step_ns(a), median_step_ns(b))
    reference = "b" if method == "auto" and steps[1] > steps[0] else "a"
    (ref, seg_ref), (other, seg_other) = ((b, segment_b), (a, segment_a)) if reference == "b" else \
        ((a, segment_a), (b, segment_b))
    gate_ns = default_max_dt_ns(median_step_ns(other)) if max_dt_ns is None else int(max_dt_ns)
    found = other.sample(ref.stamps_ns, "nearest" if method == "nearest" else "interpolate", seg_other)
    inside, used, xyz, quat, gap = found.inside, found.used, found.xyz, found.quat_xyzw, found.gap_ns
    keep = gap <= gate_ns
    idx = np.flatnonzero(inside)[keep]
    segment = np.zeros(len(idx), dtype=np.int64)
    if seg_ref is not None:
        segment += seg_ref[idx]
    if seg_other is not None:
        segment += seg_other[used[keep]]
    poses = ((ref.xyz[idx], ref.quat_xyzw[idx]), (xyz[keep], quat[keep]))
    (xyz_a, quat_a), (xyz_b, quat_b) = poses if reference == "a" else poses[::-1]
    synced = Synced(ref.stamps_ns[idx], xyz_a, quat_a, xyz_b, quat_b, gap[keep].astype(np.int64), segment,
                    reference, steps)
    counts = {"read_a": len(a), "read_b": len(b), "synced": len(synced),
              "dropped_outside_span": int(len(ref) - inside.sum()),
              "dropped_timestamp_gate": int(inside.sum() - len(synced))}
    if len(synced) == 0:
        o = "b" if reference == "a" else "a"
        raise DataError(
            "no sample passed the timestamp gate",
            f"{rates_text(steps)}; max_dt {gate_ns / 1e9:.3f} s; {counts['dropped_timestamp_gate']} samples of "
            f"{reference} too far from {o}'s, {counts['dropped_outside_span']} outside {o}'s span",
            "let the slower stream set the sample times with ⟦sync='auto'⟧, widen ⟦max_dt⟧, or fix the clock offset "
            "with ⟦time_offset=SECONDS⟧ (auto, the default, estimates it where the data allow)")
    return synced, counts
