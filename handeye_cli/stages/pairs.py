"""Relative-motion pairs ``(A_k, B_k)`` from synchronised poses.

``A_k = T_wa_a(t_i)⁻¹ T_wa_a(t_j)`` and ``B_k = T_wb_b(t_i)⁻¹ T_wb_b(t_j)`` (i < j), so that
``A_k X = X B_k`` with ``X = T_a_b``. Motions never span two tracking segments (see
:mod:`handeye_cli.stages.gates`).

Strategies (``strategy`` string):

``keyframes`` (default)
    Keep a keyframe whenever either sensor moved ≥ ``keyframe_rotation_rad`` or
    ``keyframe_translation_m`` since the last keyframe, then pair keyframes whose relative rotation
    of a is ≥ ``min_rotation_rad``. Use it for hand-held or vehicle logs at 30–100 Hz: consecutive
    samples rotate too little for the translation to be observable.
``consecutive``
    Every (i, i+1), as in the paper (5 Hz data). No minimum rotation.
``stride:K``
    Every (i, i+K): consecutive pairs of a sub-sampled stream. No minimum rotation.
``all``
    Every i < j whose rotation of a is ≥ ``min_rotation_rad``; for short robot-arm captures of a
    few dozen stations.
``random:N``
    N pairs drawn uniformly (seeded) from all i < j whose rotation is ≥ ``min_rotation_rad``.

Every strategy is capped at ``max_pairs`` (``random:N`` at N): the kept pairs are evenly spaced
in the (i, j)-ordered list, so they are deterministic and spread over the whole recording.
Candidate pairs are chosen by index before any motion is built. Pairing is linear in the
recording: up to ``_EXACT_LIMIT`` pairs i < j the valid ones are counted exactly; beyond, a
stratified sample of evenly spaced positions in the (i, j)-ordered list of all pairs is tested
(growing until it yields the cap) and ``candidate_pairs`` is the estimate from it.

``auto`` (the default of ``handeye calibrate``) chooses and weighs pairs by a noise model fitted
to the recording: see :mod:`handeye_cli.analysis.selection`.
"""
from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .sync import Synced

__all__ = ["Pairs", "make_pairs", "STRATEGIES"]

STRATEGIES = ("keyframes", "consecutive", "stride:K", "all", "random:N")
_BLOCK = 1 << 16     # entries of the pair matrix examined at once (cache-sized; larger blocks measured slower)
_EXACT_LIMIT = 1 << 22   # pairs i < j counted exactly up to this many; sampled beyond (linear time)
_KF_BLOCK = 64           # samples compared all-with-all at once when choosing keyframes
_FIRST_SAMPLE = 8        # the sample starts at this many candidates per pair wanted, and grows ×4


@dataclass(frozen=True, eq=False)
class Pairs:
    """Relative motions of both sensors between synced samples ``i[k] < j[k]``.

    A: (N, 4, 4) motions of a, ``T_a(t_i)⁻¹ T_a(t_j)``; B: (N, 4, 4) motions of b, likewise.
    i, j: int64 indices into the :class:`~handeye_cli.stages.sync.Synced` they came from.
    t_i_ns, t_j_ns: int64 stamps [ns] of the two samples.
    """

    A: np.ndarray
    B: np.ndarray
    i: np.ndarray
    j: np.ndarray
    t_i_ns: np.ndarray
    t_j_ns: np.ndarray

    def __len__(self) -> int:
        return len(self.i)


def _parse(strategy: str) -> tuple[str, int]:
    """Split ``"stride:K"`` / ``"random:N"`` into name and a positive integer."""
    name, _, arg = strategy.strip().partition(":")
    if name in ("keyframes", "consecutive", "all") and not arg:
        return name, 0
    if name in ("stride", "random") and re.fullmatch(r"[0-9]+", arg) and int(arg) > 0:
        return name, int(arg)
    if name == "auto":
        raise ConfigError("the auto strategy needs a solve", "make_pairs",
                           "call handeye_cli.analysis.selection.select_pairs for auto")
    raise ConfigError(f"unknown pair strategy {strategy!r}", "pairs",
                       f"use one of {', '.join(STRATEGIES)} (K, N positive integers)")


def _unit(quat: np.ndarray) -> np.ndarray:
    """The x-y-z-w quaternions (N, 4) scaled to unit length (their sign does not matter here)."""
    return np.asarray(quat / np.linalg.norm(quat, axis=1, keepdims=True), dtype=np.float64)


def _moved(pos: np.ndarray, quat: np.ndarray, seg: np.ndarray, rows: slice, cols: slice, t2: float,
           cos_half: float) -> np.ndarray:
    """``moved[r, c]``: sample ``cols[c]`` moved ≥ the limits (either sensor) or changed segment from ``rows[r]``.

    Distances by ``|p|² + |p'|² - 2 p·p'`` about the rows' first position, dot products by matrix
    products: a few BLAS calls per block instead of elementwise passes over (r, c, 2, 3) arrays."""
    moved: np.ndarray = np.asarray(seg[rows][:, None] != seg[cols][None])
    for s in range(pos.shape[1]):
        p, q = pos[rows, s] - pos[rows.start, s], pos[cols, s] - pos[rows.start, s]
        d2 = np.einsum("ij,ij->i", p, p)[:, None] + np.einsum("ij,ij->i", q, q)[None] - 2.0 * (p @ q.T)
        moved |= (d2 >= t2) | (np.abs(quat[rows, s] @ quat[cols, s].T) <= cos_half)
    return moved


def keyframes(synced: Synced, rotation_rad: float, translation_m: float) -> np.ndarray:
    """Indices of keyframes: the first sample, then each sample where either sensor moved
    ≥ ``rotation_rad`` or ≥ ``translation_m`` since the last keyframe (or a new segment starts).

    Blocks of ``_KF_BLOCK`` samples are compared all-with-all at once (each sample's first later
    sample that moved from it), and the keyframe chain is walked through the block; a keyframe with
    no successor in its block is searched for row-wise in growing windows. Linear in the samples.
    """
    n = len(synced)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    pos = np.stack([synced.xyz_a, synced.xyz_b], axis=1)                          # (n, 2, 3)
    quat = np.stack([_unit(synced.quat_a), _unit(synced.quat_b)], axis=1)         # (n, 2, 4)
    seg = synced.segment
    cos_half, t2 = np.cos(rotation_rad / 2), translation_m ** 2
    out, k = [0], 0
    while k < n - 1:
        stop = min(n, k + _KF_BLOCK)
        moved = np.triu(_moved(pos, quat, seg, slice(k, stop), slice(k, stop), t2, cos_half), 1)
        has: list[bool] = np.asarray(moved.any(axis=1)).tolist()
        first: list[int] = np.asarray(moved.argmax(axis=1)).tolist()
        r = 0
        while has[r]:
            r = first[r]
            out.append(k + r)
        if r > 0:
            k += r
            continue
        start, window, hit = stop, 2 * _KF_BLOCK, None         # k's successor lies beyond the block
        while start < n and hit is None:
            row = _moved(pos, quat, seg, slice(k, k + 1), slice(start, min(n, start + window)), t2, cos_half)[0]
            hit = int(np.argmax(row)) + start if row.any() else None
            start, window = start + window, 2 * window
        if hit is None:
            break
        out.append(hit)
        k = hit
    return np.asarray(out, dtype=np.int64)


def _valid_block(qa: np.ndarray, seg_end: np.ndarray, cos_half: float, r0: int, r1: int
                 ) -> tuple[int, np.ndarray]:
    """Rows ``r0 ≤ i < r1`` of the valid-pair matrix as ``(c0, mask)``: ``mask[i - r0, j - c0]`` is
    true when i < j < ``seg_end[i]`` (one segment) and a rotates by ≥ the angle with ``cos_half``."""
    c0, c1 = r0 + 1, int(seg_end[r1 - 1])
    mask = np.abs(qa[r0:r1] @ qa[c0:c1].T) <= cos_half
    mask[:, : r1 - c0] &= ~np.tri(r1 - r0, max(r1 - c0, 0), k=-1, dtype=bool)    # j > i
    if seg_end[r0] != c1:                                   # the rows end in different segments
        mask &= np.arange(c0, c1)[None, :] < seg_end[r0:r1, None]
    return c0, mask


def _choose(qa: np.ndarray, seg: np.ndarray, cos_half: float, pick: Callable[[int], np.ndarray]
            ) -> tuple[np.ndarray, np.ndarray, int]:
    """Count the valid pairs i < j row by row (in blocks of about ``_BLOCK`` entries), then extract
    the (i, j)-ordered positions ``pick(count)`` — no motion is built for a pair that is not kept.
    ``seg`` must be non-decreasing (segments are contiguous)."""
    n = len(qa)
    seg_end = np.searchsorted(seg, seg, side="right")      # first index of the next segment
    counts = np.zeros(n, dtype=np.int64)
    r0 = 0
    while r0 < n:
        r1 = min(n, r0 + max(1, _BLOCK // max(n - r0, 1)))
        counts[r0:r1] = _valid_block(qa, seg_end, cos_half, r0, r1)[1].sum(axis=1)
        r0 = r1
    total = int(counts.sum())
    want = np.sort(pick(total))
    first = np.cumsum(counts) - counts                      # position of each row's first pair
    rows = np.searchsorted(first, want, side="right") - 1
    out_j = np.empty(len(want), dtype=np.int64)
    for r in np.unique(rows):
        c0, mask = _valid_block(qa, seg_end, cos_half, int(r), int(r) + 1)
        at = rows == r
        out_j[at] = c0 + np.flatnonzero(mask[0])[want[at] - first[r]]
    return rows.astype(np.int64), out_j, total


def _sample(qa: np.ndarray, seg: np.ndarray, cos_half: float, want: int, rng: np.random.Generator | None
            ) -> tuple[np.ndarray, np.ndarray, int]:
    """:func:`_choose` without counting every pair: positions in the (i, j)-ordered list of all
    pairs i < j within a segment — evenly spaced, or uniform from ``rng`` — are tested for the
    rotation, more each round until ``want`` valid ones are found or every pair was tested.
    Returns ``want`` (or fewer) valid pairs spread over those found, and the estimated number of
    valid pairs. Work: O(n + pairs tested), no quadratic term."""
    n = len(qa)
    seg_end = np.searchsorted(seg, seg, side="right")
    per_row = seg_end - np.arange(n) - 1
    first = np.cumsum(per_row) - per_row
    total = int(per_row.sum())
    tried = min(total, _FIRST_SAMPLE * want)
    while True:
        pos = (_spread(total, tried) if rng is None else
               np.unique(rng.integers(0, total, tried)) if tried < total else np.arange(total))
        i = np.searchsorted(first, pos, side="right") - 1
        j = i + 1 + pos - first[i]
        ok = np.abs(np.einsum("ij,ij->i", qa[i], qa[j])) <= cos_half
        found = int(np.count_nonzero(ok))
        if found >= want or tried >= total:
            break
        tried = min(total, 4 * tried)
    keep = np.flatnonzero(ok)[_spread(found, want)]
    return i[keep], j[keep], int(round(found * total / max(len(pos), 1)))


def _spread(total: int, cap: int) -> np.ndarray:
    """``cap`` evenly spaced positions out of ``total`` (all when ``total <= cap``)."""
    if total <= cap:
        return np.arange(total)
    return ((np.arange(cap) + 0.5) * total / cap).astype(np.int64)


def make_pairs(synced: Synced, strategy: str = "keyframes", *, keyframe_rotation_rad: float = np.deg2rad(5),
               keyframe_translation_m: float = 0.02, min_rotation_rad: float = np.deg2rad(10),
               max_pairs: int = 2000, seed: int = 0) -> tuple[Pairs, dict[str, int]]:
    """Form relative motions ``A_k = T_a(t_i)⁻¹ T_a(t_j)``, ``B_k`` likewise, by ``strategy``.

    See the module docstring for the strategies. Angles in radians, distances in metres.

    Returns
    -------
    (Pairs, counts ``{"keyframes", "candidate_pairs", "pairs"}``): ``keyframes`` is the number of
    samples the pairs were formed from (all samples except for ``keyframes``),
    ``candidate_pairs`` the pairs eligible before the cap.

    Raises
    ------
    ConfigError: for an unknown strategy string.
    """
    name, arg = _parse(strategy)
    if np.any(np.diff(synced.segment) < 0):
        raise ValueError("Synced.segment must be non-decreasing (each tracking segment contiguous in time)")
    nodes = (keyframes(synced, keyframe_rotation_rad, keyframe_translation_m) if name == "keyframes"
             else np.arange(len(synced)))
    seg = synced.segment[nodes]
    n = len(nodes)
    if name in ("consecutive", "stride"):
        step = 1 if name == "consecutive" else arg
        i = np.arange(max(n - step, 0))
        i = i[seg[i] == seg[i + step]]
        total = len(i)
        keep = _spread(total, max_pairs)
        i, j = i[keep], i[keep] + step
    else:
        args = (_unit(synced.quat_a[nodes]), seg, np.cos(min(min_rotation_rad, np.pi) / 2))
        rng = np.random.default_rng(seed) if name == "random" else None
        want = arg if name == "random" else max_pairs
        seg_end = np.searchsorted(seg, seg, side="right")
        if int((seg_end - np.arange(n) - 1).sum()) > _EXACT_LIMIT:
            i, j, total = _sample(*args, want, rng)
        elif rng is not None:
            i, j, total = _choose(*args, lambda m: rng.choice(m, size=min(arg, m), replace=False))
        else:
            i, j, total = _choose(*args, lambda m: _spread(m, max_pairs))
    i, j = nodes[i], nodes[j]
    pairs = Pairs(*synced.motions(i, j), i, j, synced.stamps_ns[i], synced.stamps_ns[j])
    return pairs, {"keyframes": int(n), "candidate_pairs": int(total), "pairs": len(pairs)}
