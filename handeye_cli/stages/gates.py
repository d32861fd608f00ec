"""The paper's pose-jump gate (appendix D.1), applied to each raw stream before association.

A raw sample of a stream is dropped when its sensor moved more than ``max_translation_m`` [m]
(in the stream's own world frame) or ``max_rotation_rad`` [rad] since the stream's previous
**kept** sample (moved on at its recent velocity across any dropped samples, see
:func:`stream_jump_gate`): tracking failures show up as such jumps. Comparing with the last kept
sample, not the previous raw one, means a single outlier drops only itself.

Why the raw streams and not the synchronised samples: interpolating b at a's stamps smears one
bad b sample over its neighbours (a ramp of partial jumps, each possibly under the limits, that
hides the jump), and nearest association repeats it at several a stamps. So the gate runs on
each stream's own samples and the kept samples are associated again with the settings of the
:class:`~handeye_cli.stages.sync.Synced` being gated (its ``source``); a Synced built without a source
is gated as two streams sampled at its stamps.

Recovery rule (a real re-localisation shifts every later pose): when ``accept_after``
consecutive samples are all jumps relative to the last kept sample *and* consistent with
each other (each within the limits of its predecessor), the tracker has settled on a new
level: those samples are kept and start a new ``segment``. Interpolation never bridges a
segment boundary and motions are only formed within a segment (see :mod:`handeye_cli.stages.pairs`),
so no motion spans the jump. A data gap long enough for the sensor to move beyond the limits
is treated the same way.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import HandEyeError
from ..streams import PoseStream
from .sync import Association, Synced, associate_raw

__all__ = ["pose_jump_gate", "stream_jump_gate"]


def _beyond(p0: np.ndarray, q0: np.ndarray, p1: np.ndarray, q1: np.ndarray, max_t: float, cos_half: float
            ) -> np.ndarray:
    """Whether poses ``(p1, q1)`` lie beyond the limits from ``(p0, q0)`` (rows or single poses)."""
    return (np.linalg.norm(p1 - p0, axis=-1) > max_t) | (np.abs(np.sum(q1 * q0, axis=-1)) < cos_half)


def _reference(stream: PoseStream, keep: np.ndarray, last: int, i: int) -> tuple[np.ndarray, np.ndarray]:
    """The pose sample ``i`` is compared with: the last kept sample, moved on across the dropped
    samples ``last+1 … i-1`` at the velocity between ``last`` and the kept sample before it."""
    xyz, quat, stamps = stream.xyz, stream.quat_xyzw, stream.stamps_ns
    if i == last + 1 or last == 0 or not keep[last - 1] or stamps[last] <= stamps[last - 1]:
        return xyz[last], quat[last]
    ratio = (stamps[i - 1] - stamps[last]) / (stamps[last] - stamps[last - 1])
    r_last = Rotation.from_quat(quat[last])
    step = (Rotation.from_quat(quat[last - 1]).inv() * r_last).as_rotvec()
    return xyz[last] + ratio * (xyz[last] - xyz[last - 1]), (r_last * Rotation.from_rotvec(step * ratio)).as_quat()


def stream_jump_gate(stream: PoseStream, *, max_translation_m: float | None = 0.10,
                     max_rotation_rad: float | None = np.deg2rad(11.5),
                     accept_after: int = 3) -> tuple[np.ndarray, np.ndarray, int]:
    """The pose-jump gate on one raw stream (see the module docstring).

    A sample right after a kept one is compared with it (the paper's rule). After dropped
    samples, the last kept sample is first moved on at its recent velocity to the sample before
    the one compared: otherwise fast motion at a low rate (two intervals' motion beyond the limit)
    would make the samples after a lone outlier look like a new tracking level.

    Parameters
    ----------
    stream: poses ``T_w_sensor(t)``, sorted by stamp.
    max_translation_m: position change limit [m]; ``None`` switches it off.
    max_rotation_rad: rotation angle limit [rad]; ``None`` switches it off.
    accept_after: after this many consecutive, mutually consistent jumps (≥ 1) the new level is
        accepted: the samples are kept and start a new segment.

    Returns
    -------
    (keep: bool[N], segment: int64[N] non-decreasing tracking level per sample, accepted: the
    number of new levels accepted).
    """
    if accept_after < 1:
        raise HandEyeError(f"accept_after must be at least 1, not {accept_after}", "pose-jump gate",
                           "give the number of consistent samples that confirm a new tracking level")
    n = len(stream)
    limits = (np.inf if max_translation_m is None else float(max_translation_m),
              -1.0 if max_rotation_rad is None else float(np.cos(min(max_rotation_rad, np.pi) / 2)))
    xyz, quat = stream.xyz, stream.quat_xyzw
    step_jump = np.zeros(n, dtype=bool)
    step_jump[1:] = _beyond(xyz[:-1], quat[:-1], xyz[1:], quat[1:], *limits)

    keep = np.ones(n, dtype=bool)
    segment = np.zeros(n, dtype=np.int64)
    accepted = 0
    i = 1
    while i < n:
        # While the previous sample is kept and consecutive steps are small, every sample is kept.
        later = np.flatnonzero(step_jump[i:])
        if len(later) == 0:
            break
        i += int(later[0])
        last, run = i - 1, []
        while i < n:      # sequential mode: compare with the last kept sample
            if not _beyond(*_reference(stream, keep, last, i), xyz[i], quat[i], *limits):
                break
            keep[i] = False
            consistent = run and not _beyond(xyz[run[-1]], quat[run[-1]], xyz[i], quat[i], *limits)
            run = run + [i] if consistent else [i]
            if len(run) == accept_after:
                keep[run] = True
                accepted += 1
                segment[run[0]:] += 1
                break
            i += 1
        i += 1      # sample i is kept (or past the end): resume the fast scan after it
    return keep, segment, accepted


def pose_jump_gate(synced: Synced, *, max_translation_m: float | None = 0.10,
                   max_rotation_rad: float | None = np.deg2rad(11.5),
                   accept_after: int = 3) -> tuple[Synced, dict]:
    """Drop the samples that use a pose jump of either sensor (see the module docstring).

    Parameters
    ----------
    synced: the associated streams (from :func:`handeye_cli.stages.sync.associate`).
    max_translation_m, max_rotation_rad, accept_after: as in :func:`stream_jump_gate`, for both streams.

    Returns
    -------
    (kept samples, counts ``{"dropped_pose_jump", "jumps_a", "jumps_b", "accepted_jumps"}``):
    synced samples dropped; raw samples of a and of b the gate dropped; new tracking levels
    accepted (new segments) in both streams.
    """
    source = synced.source or Association(PoseStream.from_matrices(synced.stamps_ns, synced.T_a),
                                          PoseStream.from_matrices(synced.stamps_ns, synced.T_b), "nearest", 0)
    limits = dict(max_translation_m=max_translation_m, max_rotation_rad=max_rotation_rad, accept_after=accept_after)
    keep_a, seg_a, new_a = stream_jump_gate(source.a, **limits)
    keep_b, seg_b, new_b = stream_jump_gate(source.b, **limits)
    regated, _ = associate_raw(source.a.select(keep_a), source.b.select(keep_b), source.method,
                               source.max_dt_ns, seg_a[keep_a], seg_b[keep_b])
    # Keep only what ``synced`` held (it may be a selection), adding any segments it had.
    pos = np.clip(np.searchsorted(synced.stamps_ns, regated.stamps_ns), 0, max(len(synced) - 1, 0))
    held = np.zeros(len(regated), dtype=bool) if len(synced) == 0 else synced.stamps_ns[pos] == regated.stamps_ns
    out = regated.select(held)
    out = Synced(out.stamps_ns, out.T_a, out.T_b, out.dt_ns, out.segment + synced.segment[pos[held]], source)
    counts = {"dropped_pose_jump": len(synced) - len(out), "jumps_a": int((~keep_a).sum()),
              "jumps_b": int((~keep_b).sum()), "accepted_jumps": new_a + new_b}
    return out, counts
