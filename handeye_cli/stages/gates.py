"""Pose-jump gates: drop the samples of a tracking failure, at any sampling rate; sync and gate in one call.

``auto`` (default): the motion-consistency gate on the synchronised samples
    For a rigid rig every motion of a, ``A = T_a(t_i)⁻¹ T_a(t_j)``, is the motion of b seen
    through the extrinsic, ``A = X B X⁻¹``; so, whatever ``X`` is, both motions rotate by the same
    angle and translate equally along their rotation axis (``t_A·r_A = t_B·r_B`` with ``r`` the
    rotation vector), and without rotation ``|t_A| = |t_B|``. For each step between consecutive
    synchronised samples the gate measures how far these invariants disagree and compares the
    disagreement with its own robust scale: the median of the same residual over the block of
    ``WINDOW`` consecutive steps around it. A step whose residual exceeds ``THRESHOLD`` × that
    scale breaks the tracking. The test needs neither the extrinsic nor a model of the motion, so
    it works at any sampling interval: measured on the issue-13 simulation (hand-held motion, 0.02°/0.5 mm noise, 100 Hz
    against 100…0.5 Hz), clean steps stay below ~10 scales while a 0.3 m / 20° jump lies at
    50–1400 scales, where a stream's own constant-velocity prediction already errs by 0.2–2 m and
    20–140° between samples at 2–0.5 Hz (benchmarks/rates.py prints both).
    With ``--sync auto`` the slower stream's samples are the synchronised samples themselves, so
    a jump in it drops exactly its sample; a jump in the faster stream only reaches the samples it
    is interpolated into, weighted by the interpolation fraction, and is caught when that matters.
``paper``: the paper's per-step gate (appendix D.1), meant for ~5 Hz data
    On each raw stream before association, a sample is a jump when its sensor moved more than
    ``max_translation_m`` or rotated more than ``max_rotation_rad`` since the previous sample (the
    paper's 10 cm / 11.5° for hand-held 5 Hz tracking). Slower streams move more than that between
    samples in ordinary motion; faster ones rarely reach it even when they jump.

Both gates resolve the broken steps alike, vectorised: the steps cut the samples into runs; a run
shorter than ``accept_after`` samples (a glitch) is dropped; a longer one is kept, and it starts a
new tracking ``segment`` unless it is consistent with the previous kept run across the dropped
samples (a real re-localisation shifts every later pose: motions must not span it; see
:mod:`handeye_cli.stages.pairs`).

Conventions: poses ``T_w_sensor(t)`` as positions [m] and x-y-z-w quaternions; stamps int64 ns.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ConfigError, DataError
from ..geometry import dualquat as dq
from ..streams import PoseStream
from .sync import Synced, associate, median_step_ns, rates_text

__all__ = ["GATES", "pose_jump_gate", "paper_gate", "sync_and_gate", "robust_scores", "THRESHOLD", "WINDOW"]

GATES = ("auto", "paper", "off")
THRESHOLD = 16.0     # a step breaks the tracking beyond this many robust scales of its residual
_LONE = 0.5         # a sample both of whose steps exceed this fraction of the threshold is a glitch if the
                    # motion over it holds
WINDOW = 51          # steps per block whose median gives the robust scale
# Smallest scales: below them residuals are rounding and interpolation error (noise-free data).
_FLOORS = (1e-5, 1e-7, 1e-5)    # rotation angle [rad], t·r [m·rad], |t| [m]

Floats = NDArray[np.float64]
Ints = NDArray[np.int64]
Mask = NDArray[np.bool_]


def _motion(xyz: Floats, quat: Floats, i: Ints, j: Ints) -> tuple[Floats, Floats, Floats]:
    """Invariants of the motions ``T(t_i)⁻¹ T(t_j)``: rotation angle [rad], t·r [m·rad], |t| [m]."""
    rotvec = dq.to_rotvec(dq.relative(quat[i], quat[j]))
    t = np.einsum("nji,nj->ni", dq.to_matrix(quat[i]), xyz[j] - xyz[i])      # R_iᵀ (p_j - p_i)
    return np.linalg.norm(rotvec, axis=1), np.einsum("ij,ij->i", t, rotvec), np.linalg.norm(t, axis=1)


def _residuals(synced: Synced, i: Ints, j: Ints) -> Floats:
    """(3, M) disagreement of a's and b's motions from sample i to j in the three invariants."""
    inv_a = _motion(synced.xyz_a, synced.quat_a, i, j)
    inv_b = _motion(synced.xyz_b, synced.quat_b, i, j)
    return np.abs(np.array(inv_a) - np.array(inv_b))


def _scale(residual: Floats, window: int) -> Floats:
    """(3, M) robust scale of the residuals of M consecutive steps: the median of the block of about
    ``window`` steps each step lies in (the last block takes the remainder), at least the floors."""
    m = residual.shape[1]
    blocks = max(m // window, 1)
    med = np.median(residual[:, : blocks * (m // blocks)].reshape(3, blocks, -1), axis=2)
    scale: Floats = np.maximum(med[:, np.minimum(np.arange(m) // (m // blocks), blocks - 1)],
                               np.array(_FLOORS)[:, None])
    return scale


def robust_scores(synced: Synced, window: int = WINDOW) -> Floats:
    """Per consecutive step, the largest of its invariant residuals in robust scales (what the
    ``auto`` gate compares with ``THRESHOLD``); for benchmarks and diagnostics."""
    steps = np.arange(len(synced) - 1)
    residual = _residuals(synced, steps, steps + 1)
    scores: Floats = (residual / _scale(residual, window)).max(axis=0)
    return scores


def _resolve(broken: Mask, accept_after: int, bridge_breaks: Callable[[Ints, Ints], Mask]
             ) -> tuple[Mask, Ints, int]:
    """Keep mask, non-decreasing segments and new segments from the broken steps (module docstring).

    ``broken[k]``: step k → k+1 breaks the tracking; ``bridge_breaks(l, f)``: whether the motion
    from sample ``l`` to a later sample ``f`` breaks it too. Where two kept runs meet at a single
    broken step, the step's last or first sample is the glitch when leaving it out mends the
    tracking (the bridge around it holds); only otherwise does the later run start a new segment.
    """
    if accept_after < 1:
        raise ConfigError(f"accept_after must be at least 1, not {accept_after}", "pose-jump gate",
                          "give the number of consistent samples that confirm a new tracking level")
    run = np.concatenate([[0], np.cumsum(broken)])
    keep = np.bincount(run)[run] >= accept_after
    kept = np.flatnonzero(keep)
    boundary = np.flatnonzero(np.diff(run[kept]) != 0)       # kept[b] ends a run, kept[b + 1] starts one
    last, first = kept[boundary], kept[boundary + 1]
    new = np.ones(len(boundary), dtype=bool)
    across = np.flatnonzero(first > last + 1)
    new[across] = bridge_breaks(last[across], first[across])
    if accept_after >= 2:                     # runs of ≥ 2 samples: last - 1 and first + 1 are in them
        meet = np.flatnonzero(first == last + 1)
        drop_last = meet[~bridge_breaks(last[meet] - 1, first[meet])]
        rest = np.setdiff1d(meet, drop_last)
        drop_first = rest[~bridge_breaks(last[rest], first[rest] + 1)]
        keep[last[drop_last]] = keep[first[drop_first]] = False
        new[drop_last] = new[drop_first] = False
    starts = np.zeros(len(run), dtype=np.int64)
    starts[first[new]] = 1
    return keep, np.cumsum(starts), int(new.sum())


def pose_jump_gate(synced: Synced, *, threshold: float = THRESHOLD, window: int = WINDOW, accept_after: int = 3
                ) -> tuple[Synced, dict[str, int]]:
    """The ``auto`` gate: drop synchronised samples whose motion disagrees with the other stream's.

    Parameters
    ----------
    synced: both streams at common stamps (see :func:`handeye_cli.stages.sync.associate`).
    threshold: a step breaks the tracking when a residual exceeds this many robust scales.
    window: steps per block whose median gives each step's robust scale.
    accept_after: the fewest consecutive consistent samples kept after a break (≥ 1).

    Returns
    -------
    (kept samples, counts ``{"dropped_pose_jump", "accepted_jumps"}``).
    """
    n = len(synced)
    if n < 3:
        return synced, {"dropped_pose_jump": 0, "accepted_jumps": 0}
    steps = np.arange(n - 1)
    residual = _residuals(synced, steps, steps + 1)
    limit = threshold * _scale(residual, window)

    def breaks(i: Ints, j: Ints) -> Mask:
        return np.asarray((_residuals(synced, i, j) > limit[:, i]).any(axis=0))

    score = (residual / limit).max(axis=0)                 # 1 = at the threshold
    broken = score > 1
    # A lone glitch just under the threshold: both its steps are elevated and the bridge over it holds.
    lone = np.flatnonzero(np.minimum(score[:-1], score[1:]) > _LONE) + 1
    lone = lone[~breaks(lone - 1, lone + 1)]
    broken[lone - 1] = broken[lone] = True
    keep, segment, accepted = _resolve(broken, accept_after, breaks)
    out = synced.select(keep)
    out = Synced(out.stamps_ns, out.xyz_a, out.quat_a, out.xyz_b, out.quat_b, out.dt_ns,
                 out.segment + segment[keep], out.reference, out.step_ns)
    return out, {"dropped_pose_jump": int(n - keep.sum()), "accepted_jumps": accepted}


def paper_gate(stream: PoseStream, *, max_translation_m: float | None = 0.10,
               max_rotation_rad: float | None = np.deg2rad(11.5), accept_after: int = 3
               ) -> tuple[Mask, Ints, int]:
    """The paper's gate on one raw stream: a step moving beyond either limit breaks the tracking.

    Parameters
    ----------
    stream: poses ``T_w_sensor(t)``, sorted by stamp.
    max_translation_m: position change limit [m]; ``None`` switches it off.
    max_rotation_rad: rotation angle limit [rad]; ``None`` switches it off.
    accept_after: the fewest consecutive consistent samples kept after a jump (≥ 1).

    Returns
    -------
    (keep: bool[N], segment: int64[N] non-decreasing tracking segment per sample, accepted: the
    number of new segments).
    """
    max_t = np.inf if max_translation_m is None else float(max_translation_m)
    cos_half = -1.0 if max_rotation_rad is None else float(np.cos(min(max_rotation_rad, np.pi) / 2))
    xyz, quat = stream.xyz, stream.quat_xyzw

    def breaks(i: Ints, j: Ints) -> Mask:
        broken: Mask = (np.linalg.norm(xyz[j] - xyz[i], axis=1) > max_t) | (
            np.abs(np.einsum("ij,ij->i", quat[i], quat[j])) < cos_half)
        return broken

    steps = np.arange(max(len(stream) - 1, 0))
    return _resolve(breaks(steps, steps + 1), accept_after, breaks)


def _too_few(kept: int, need: int, counts: dict[str, int], gate: str, max_dt_ns: int | None,
             steps: tuple[int, int]) -> DataError:
    """The error when the gates leave fewer than ``need`` samples: what dropped them, each stream's rate,
    and which flags relax the gates."""
    by_time = counts.get("dropped_timestamp_gate", 0) + counts.get("dropped_outside_span", 0)
    by_jump = counts["dropped_pose_jump"]
    dt = "the default max_dt" if max_dt_ns is None else f"max_dt {max_dt_ns / 1e9:g} s"
    story = (f"{rates_text(steps)}; the timestamp gate ({dt}) dropped {counts.get('dropped_timestamp_gate', 0)} "
             f"and {counts.get('dropped_outside_span', 0)} lay outside the other stream's span; the pose-jump gate "
             f"(⟦gate='{gate}'⟧) dropped {by_jump}")
    if by_jump > by_time:
        fix = ("the pose-jump gate dropped most: try ⟦gate='auto'⟧ (it follows the sampling rate), ⟦gate='paper'⟧ with "
               "wider ⟦max_jump⟧/⟦max_jump_deg⟧, or ⟦gate='off'⟧; if the streams are not aligned in time, "
               "⟦time_offset=SECONDS⟧ (auto, the default, estimates it where the data allow)")
    else:
        fix = ("the timestamp gate dropped most: let the slower stream set the sample times with ⟦sync='auto'⟧, widen "
               "⟦max_dt⟧, or give the clock offset with ⟦time_offset=SECONDS⟧")
    return DataError(f"only {kept} sample(s) left after the gates, {need} needed", story, fix)


def sync_and_gate(a: PoseStream, b: PoseStream, *, sync: str = "auto", max_dt_ns: int | None = None,
                  time_offset_ns: int = 0, gate: str = "auto", max_translation_m: float | None = 0.10,
                  max_rotation_rad: float | None = np.deg2rad(11.5), min_samples: int = 2
                  ) -> tuple[Synced, dict[str, Any]]:
    """Associate the streams once and gate them: ``gate="paper"`` on each raw stream before the
    association, ``"auto"`` on the synchronised samples after it, ``"off"`` not at all.

    Arguments as :func:`handeye_cli.stages.sync.associate`, :func:`paper_gate` (the limits, which
    only the paper gate uses) and :func:`pose_jump_gate`. Returns (kept samples, counts of
    ``SampleCounts``: read, synced, dropped per gate, jumps per stream (paper gate), synced_kept).

    Raises
    ------
    ConfigError for an unknown gate; DataError (naming the flags that relax the gates and each
    stream's rate) when fewer than ``min_samples`` samples are left.
    """
    if gate not in GATES:
        raise ConfigError(f"unknown pose-jump gate {gate!r}", "gate", f"use one of {', '.join(GATES)}")
    steps = (median_step_ns(a), median_step_ns(b))
    jumps: dict[str, int] = {"dropped_pose_jump": 0, "accepted_jumps": 0, "jumps_a": 0, "jumps_b": 0}
    seg: dict[str, Ints | None] = {"segment_a": None, "segment_b": None}
    if gate == "paper":
        (keep_a, seg_a, new_a), (keep_b, seg_b, new_b) = (
            paper_gate(s, max_translation_m=max_translation_m, max_rotation_rad=max_rotation_rad) for s in (a, b))
        a, b, seg = a.select(keep_a), b.select(keep_b), {"segment_a": seg_a[keep_a], "segment_b": seg_b[keep_b]}
        jumps.update(jumps_a=int((~keep_a).sum()), jumps_b=int((~keep_b).sum()), accepted_jumps=new_a + new_b)
        jumps["dropped_pose_jump"] = jumps["jumps_a"] + jumps["jumps_b"]
        if min(len(a), len(b)) < min_samples:
            raise _too_few(min(len(a), len(b)), min_samples, jumps, gate, max_dt_ns, steps)
    synced, counts = associate(a, b, method=sync, max_dt_ns=max_dt_ns, time_offset_ns=time_offset_ns, **seg)
    kept = synced
    if gate == "auto":
        kept, found = pose_jump_gate(synced)
        jumps.update(found)
    counts = {**counts, **jumps, "read_a": counts["read_a"] + jumps["jumps_a"],
              "read_b": counts["read_b"] + jumps["jumps_b"], "synced_kept": len(kept)}
    if len(kept) < min_samples:
        raise _too_few(len(kept), min_samples, counts, gate, max_dt_ns, steps)
    return kept, counts
