"""The paper's pose-jump gate (appendix D.1) on synchronised samples.

A sample is dropped when either sensor moved more than ``max_translation_m`` [m] or
``max_rotation_rad`` [rad] since the previous **kept** sample (tracking failures show up as
such jumps). Comparing with the last kept sample, not the previous raw one, means a single
outlier drops only itself.

Recovery rule (a real re-localisation shifts every later pose): when ``accept_after``
consecutive samples are all jumps relative to the last kept sample *and* consistent with
each other (each within the limits of its predecessor), the tracker has settled on a new
level: those samples are kept and start a new ``segment``. Motions are only formed within a
segment (see :mod:`handeye_cli.pairs`), so no motion spans the jump.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .sync import Synced

__all__ = ["pose_jump_gate"]


def _moved(pa: np.ndarray, qa: np.ndarray, pb: np.ndarray, qb: np.ndarray, i, j,
           max_t: float, cos_half: float) -> np.ndarray:
    """Whether either sensor moved beyond the limits between samples ``i`` and ``j`` (arrays or ints)."""
    over = np.zeros(np.shape(i), dtype=bool)
    for p, q in ((pa, qa), (pb, qb)):
        over |= np.linalg.norm(p[j] - p[i], axis=-1) > max_t
        over |= np.abs(np.sum(q[j] * q[i], axis=-1)) < cos_half
    return over


def pose_jump_gate(synced: Synced, *, max_translation_m: float | None = 0.10,
                   max_rotation_rad: float | None = np.deg2rad(11.5),
                   accept_after: int = 3) -> tuple[Synced, dict]:
    """Drop samples where either sensor jumped since the last kept sample.

    Parameters
    ----------
    synced: the associated streams.
    max_translation_m: position change limit [m] of either sensor (in its own world frame);
        ``None`` switches it off.
    max_rotation_rad: rotation angle limit [rad] of either sensor; ``None`` switches it off.
    accept_after: after this many consecutive, mutually consistent jumps the new level is
        accepted (see the module docstring); the samples are kept and start a new segment.

    Returns
    -------
    (kept samples, ``{"dropped_pose_jump": n, "accepted_jumps": n}``), where ``accepted_jumps``
    counts the new tracking levels accepted (new segments).
    """
    n = len(synced)
    max_t = np.inf if max_translation_m is None else float(max_translation_m)
    cos_half = -1.0 if max_rotation_rad is None else float(np.cos(min(max_rotation_rad, np.pi) / 2))
    pa, pb = synced.T_a[:, :3, 3], synced.T_b[:, :3, 3]
    qa = Rotation.from_matrix(synced.T_a[:, :3, :3]).as_quat()
    qb = Rotation.from_matrix(synced.T_b[:, :3, :3]).as_quat()
    args = (pa, qa, pb, qb)
    step_jump = np.zeros(n, dtype=bool)
    step_jump[1:] = _moved(*args, np.arange(n - 1), np.arange(1, n), max_t, cos_half)

    keep = np.ones(n, dtype=bool)
    segment = synced.segment.copy()
    new_segments = 0
    i = 1
    while True:
        # While the previous sample is kept and consecutive steps are small, every sample is kept.
        later = np.flatnonzero(step_jump[i:])
        if len(later) == 0:
            break
        i += int(later[0])
        last, run = i - 1, []
        while i < n:      # sequential mode: compare with the last kept sample
            if not _moved(*args, last, i, max_t, cos_half):
                break
            keep[i] = False
            run = run + [i] if run and not _moved(*args, run[-1], i, max_t, cos_half) else [i]
            if len(run) == accept_after:
                keep[run] = True
                new_segments += 1
                segment[run[0]:] += 1
                break
            i += 1
        i += 1      # i is kept (or past the end): resume the fast scan after it
        if i >= n:
            break
    counts = {"dropped_pose_jump": int((~keep).sum()), "accepted_jumps": new_segments}
    out = Synced(synced.stamps_ns, synced.T_a, synced.T_b, synced.dt_ns, segment)
    return out.select(keep), counts
