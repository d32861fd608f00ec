"""Relative-motion pairs ``(A_k, B_k)`` from synchronised poses.

``A_k = T_wa_a(t_i)⁻¹ T_wa_a(t_j)`` and ``B_k = T_wb_b(t_i)⁻¹ T_wb_b(t_j)`` (i < j), so that
``A_k X = X B_k`` with ``X = T_a_b``. Motions never span two tracking segments (see
:mod:`handeye_cli.gates`).

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
Candidate pairs are counted and chosen by index before any motion is built, so ``all`` on many
thousand samples stays cheap in memory.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Callable, Iterator

import numpy as np
from scipy.spatial.transform import Rotation

from . import se3
from .errors import HandEyeError
from .sync import Synced

__all__ = ["Pairs", "make_pairs", "STRATEGIES"]

STRATEGIES = ("keyframes", "consecutive", "stride:K", "all", "random:N")
_BLOCK = 1 << 22     # candidate pairs examined per block when scanning all i < j


@dataclass(frozen=True, eq=False)
class Pairs:
    """Relative motions of both sensors between synced samples ``i[k] < j[k]``.

    A: (N, 4, 4) motions of a, ``T_a(t_i)⁻¹ T_a(t_j)``; B: (N, 4, 4) motions of b, likewise.
    i, j: int64 indices into the :class:`~handeye_cli.sync.Synced` they came from.
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
    raise HandEyeError(f"unknown pair strategy {strategy!r}", "pairs",
                       f"use one of {', '.join(STRATEGIES)} (K, N positive integers)")


def _quats(T: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(T[:, :3, :3]).as_quat()


def keyframes(synced: Synced, rotation_rad: float, translation_m: float) -> np.ndarray:
    """Indices of keyframes: the first sample, then each sample where either sensor moved
    ≥ ``rotation_rad`` or ≥ ``translation_m`` since the last keyframe (or a new segment starts)."""
    n = len(synced)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    pos = (synced.T_a[:, :3, 3], synced.T_b[:, :3, 3])
    quat = (_quats(synced.T_a), _quats(synced.T_b))
    cos_half = np.cos(rotation_rad / 2)
    out, start, window = [0], 1, 64
    while start < n:
        k = out[-1]
        cand = np.arange(start, min(n, start + window))
        moved = synced.segment[cand] != synced.segment[k]
        for p, q in zip(pos, quat):
            moved |= np.linalg.norm(p[cand] - p[k], axis=1) >= translation_m
            moved |= np.abs(q[cand] @ q[k]) <= cos_half
        hit = np.flatnonzero(moved)
        if len(hit):
            out.append(int(cand[hit[0]]))
            start, window = out[-1] + 1, 64
        else:                                   # nothing yet: look further, in growing windows
            start, window = cand[-1] + 1, window * 2
    return np.asarray(out, dtype=np.int64)


def _candidate_blocks(qa: np.ndarray, seg: np.ndarray, cos_half: float) -> Iterator[tuple[int, np.ndarray]]:
    """Yield ``(r0, mask)`` row blocks of the valid-pair matrix: ``mask[r, j]`` is true when
    i = r0 + r < j, both lie in one segment and a rotates by ≥ the angle with ``cos_half``."""
    n = len(qa)
    rows = max(1, _BLOCK // max(n, 1))
    for r0 in range(0, n, rows):
        r1 = min(n, r0 + rows)
        mask = np.abs(qa[r0:r1] @ qa.T) <= cos_half
        mask &= seg[r0:r1, None] == seg[None, :]
        mask &= np.arange(n)[None, :] > np.arange(r0, r1)[:, None]
        yield r0, mask


def _choose(qa: np.ndarray, seg: np.ndarray, cos_half: float, pick: Callable[[int], np.ndarray]
            ) -> tuple[np.ndarray, np.ndarray, int]:
    """Two passes over all valid i < j: count them, then extract the (i, j)-ordered positions
    ``pick(count)`` — no motion is built for a pair that is not kept."""
    total = int(sum(int(m.sum()) for _, m in _candidate_blocks(qa, seg, cos_half)))
    want = np.sort(pick(total))
    out_i, out_j, seen = [], [], 0
    for r0, mask in _candidate_blocks(qa, seg, cos_half):
        count = int(mask.sum())
        sel = want[(want >= seen) & (want < seen + count)] - seen
        if len(sel):
            i, j = np.nonzero(mask)
            out_i.append(i[sel] + r0)
            out_j.append(j[sel])
        seen += count
    empty = np.zeros(0, dtype=np.int64)
    return np.concatenate(out_i or [empty]), np.concatenate(out_j or [empty]), total


def _spread(total: int, cap: int) -> np.ndarray:
    """``cap`` evenly spaced positions out of ``total`` (all when ``total <= cap``)."""
    if total <= cap:
        return np.arange(total)
    return ((np.arange(cap) + 0.5) * total / cap).astype(np.int64)


def make_pairs(synced: Synced, strategy: str = "keyframes", *, keyframe_rotation_rad: float = np.deg2rad(5),
               keyframe_translation_m: float = 0.02, min_rotation_rad: float = np.deg2rad(10),
               max_pairs: int = 2000, seed: int = 0) -> tuple[Pairs, dict]:
    """Form relative motions ``A_k = T_a(t_i)⁻¹ T_a(t_j)``, ``B_k`` likewise, by ``strategy``.

    See the module docstring for the strategies. Angles in radians, distances in metres.

    Returns
    -------
    (Pairs, counts ``{"keyframes", "candidate_pairs", "pairs"}``): ``keyframes`` is the number of
    samples the pairs were formed from (all samples except for ``keyframes``),
    ``candidate_pairs`` the pairs eligible before the cap.

    Raises
    ------
    HandEyeError: for an unknown strategy string.
    """
    name, arg = _parse(strategy)
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
        args = (_quats(synced.T_a[nodes]), seg, np.cos(min(min_rotation_rad, np.pi) / 2))
        if name == "random":
            rng = np.random.default_rng(seed)
            i, j, total = _choose(*args, lambda m: rng.choice(m, size=min(arg, m), replace=False))
        else:
            i, j, total = _choose(*args, lambda m: _spread(m, max_pairs))
    i, j = nodes[i], nodes[j]
    pairs = Pairs(se3.relative(synced.T_a[i], synced.T_a[j]), se3.relative(synced.T_b[i], synced.T_b[j]),
                  i, j, synced.stamps_ns[i], synced.stamps_ns[j])
    return pairs, {"keyframes": int(n), "candidate_pairs": int(total), "pairs": len(pairs)}
