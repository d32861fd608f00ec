"""The ``auto`` pair strategy: pairs chosen and weighted by a noise model fitted to the recording.

Conventions: synced poses ``T_wa_a(t)``, ``T_wb_b(t)``; motions ``A_k = T_a(t_i)⁻¹ T_a(t_j)``,
``B_k`` likewise, ``A_k X = X B_k`` with ``X = T_a_b``; stamps int64 ns; metres, radians.

Candidate pairs are ``(i, i + K)`` for strides K on a ladder of factor √2 (1, 2, 3, 4, 6, 8, …,
up to the longest segment), each stride a *level*. First, the gate's segment boundaries across which the world
did not move (pairs spanning them fit the probe's ``X`` as its noise model predicts) are joined up
(:func:`_rejoined`): a gap or a glitch is no re-localisation. Per round:

1. a probe of every level (at most ``probe`` pairs each, evenly spread) is solved for ``X``;
2. the probe's residuals at ``X`` fit the :class:`~handeye_cli.analysis.noise_model.NoiseModel`
   (variance vs span: floor for absolute sources, + k·Δ for drift);
3. each pair gets its maximum-likelihood weights under the model, folded into one weight and one
   α (the solver takes one α): ``log α² = mean log(σ_rot²/σ_trans²)``, ``w = 1/(σ_rot σ_trans α)``;
4. each level's predicted covariance of ``X`` is ``H⁻¹`` with ``H`` the cost's curvature on the
   level's probe, scaled to the pairs the level would contribute under the ``max_pairs`` cap and
   divided by the overlap of those pairs: pairs ``(i, i+K)`` and ``(i+m, i+m+K)`` share K − m samples
   of drift, so they count as ``1 + ρ (K/m − 1)`` times fewer independent pairs (ρ: drift share);
5. the levels between the shortest and the longest whose predicted rotation and translation errors
   are both within 1.5× of the best level's (1.2× on a drifting model: the kept levels share their drift, which
   each level's own prediction does not count, so a wider band only adds correlated error) are kept, and
   every longer level whose variance is
   mostly the absolute floor (short rotating spans when drift dominates, all long spread spans when
   it does not: pairs of many spans average each absolute pose's noise best). On planar motion a
   level whose drift share exceeds a quarter must also lengthen b's median translation by more than
   drift's σ grows (2^¼ per ladder step of √2, a random walk's): there the translations alone carry the
   yaw, and their lever stops growing once the spans outlast the loops the vehicle drives while the
   drift keeps growing (a 1.5 Hz localiser against 10 Hz lidar odometry, 24 seeds: yaw 0.054° with
   every long level, 0.045° so; the best fixed stride's 0.045°). The cap is shared between the
   kept levels, and ``X`` is solved again with the weights and α.
6. after the last round, a drifting model's α is lowered where the cluster-robust sandwich (blocks
   of time) predicts smaller errors: :func:`~handeye_cli.analysis.alpha.blocked_alpha` (shared
   drift that tilts the rotation; issue 19's VIO against motion capture).

Rounds repeat until the kept levels stop changing (at most ``rounds``). Everything is linear in
the number of samples: no candidate pair is enumerated beyond the probes and the kept pairs.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from ..errors import HandEyeError
from ..geometry import dualquat as dq
from ..solvers import Prior, solve
from ..solvers.problem import pair_forms
from ..stages.pairs import Pairs
from ..stages.sync import Synced
from .alpha import blocked_alpha, time_blocks
from .covariance import tangent_basis
from .noise_model import NoiseModel, PairFeatures, cost_residuals, fit_noise_model, pair_features
from .observability import common_axis

__all__ = ["Selection", "select_pairs", "ladder"]

_KEEP_RATIO = 1.5           # levels within this factor of the best predicted error are kept
_KEEP_RATIO_DRIFTING = 1.2  # ... on a drifting model (step 5)
_ABSOLUTE_SHARE = 0.5       # ... and every longer level whose variance is mostly the absolute floor
_ABSOLUTE_SHARE_PLANAR = 0.25  # ... on planar motion, beyond which a longer level must still add lever:
_LEVER_GROWTH = 2 ** 0.25   # b's median translation growing faster than drift's σ from one ladder level to the next
_MIN_LEVEL_PAIRS = 8
_Q_PRIME_FIRST = np.r_[4:8, 0:4]   # rows of the tangent basis (x = [q; q']) in the cost forms' [q'; q] order
_T = TypeVar("_T")
_SPREAD_SEED = 0            # the jitter of the evenly spread pairs (fixed: a recording always gives one answer)
_CROSSING = 5               # pairs across a segment boundary that test whether the world stayed the same
_SAME_WORLD = 6.0           # ... when their median residual is within this many predicted variances (the model's trim)


@dataclass(frozen=True, eq=False)
class Selection:
    """What ``auto`` chose: the pairs, their weights, α [1/m], the noise model and the kept strides (``band``:
    every stride from the shortest kept, as absolute sources are paired)."""

    pairs: Pairs
    weights: NDArray[np.float64]
    alpha: float
    model: NoiseModel | None
    strides: tuple[int, ...]
    rounds: int
    candidate_pairs: int
    rejoined: int = 0
    band: bool = False

    def on(self, synced: Synced, max_pairs: int) -> Pairs:
        """The pairs these strides make of other synchronised samples (the same streams at another clock
        offset): like compared with like, without selecting again."""
        return _kept_pairs(synced, _Segments.of(synced.segment), np.asarray(self.strides, dtype=np.int64),
                           max_pairs, self.band)[0]

    def as_dict(self) -> dict[str, Any]:
        """The result's ``noise_model`` entry: the model (None: too few pairs to fit one) plus what the
        selection made of it: strides [samples], spans [s] of the pairs, α [1/m], rounds."""
        spans = (self.pairs.t_j_ns - self.pairs.t_i_ns) / 1e9
        return {**(self.model.as_dict() if self.model else {"kind": None}), "strides": list(self.strides),
                "span_s": [float(spans.min()), float(spans.max())] if len(spans) else [],
                "alpha": self.alpha, "rounds": self.rounds, "segments_rejoined": self.rejoined}

    def counts(self, samples: int) -> dict[str, int]:
        """Counts in the form :func:`~handeye_cli.stages.pairs.make_pairs` returns them."""
        return {"keyframes": samples, "candidate_pairs": self.candidate_pairs, "pairs": len(self.pairs)}


def ladder(longest: int) -> NDArray[np.int64]:
    """Strides 1, 2, 3, 4, 6, 8, 11, … (factor √2) below ``longest`` samples."""
    if longest < 2:
        return np.zeros(0, dtype=np.int64)
    m = int(np.floor(2 * np.log2(longest - 1))) + 1
    return np.unique(np.round(np.sqrt(2.0) ** np.arange(m)).astype(np.int64))


@dataclass(frozen=True)
class _Segments:
    """Contiguous tracking segments of the synced samples: first index and length of each."""

    start: NDArray[np.int64]
    length: NDArray[np.int64]

    @classmethod
    def of(cls, segment: NDArray[np.int64]) -> _Segments:
        start = np.flatnonzero(np.r_[True, segment[1:] != segment[:-1]]) if len(segment) else np.zeros(0, int)
        return cls(start.astype(np.int64), np.diff(np.r_[start, len(segment)]).astype(np.int64))

    def count(self, stride: int) -> int:
        """Number of pairs ``(i, i + stride)`` inside one segment."""
        return int(np.clip(self.length - stride, 0, None).sum())

    def starts(self, stride: int, n: int) -> NDArray[np.int64]:
        """``n`` first indices i of pairs ``(i, i + stride)``, evenly spread over all such pairs."""
        per = np.clip(self.length - stride, 0, None)
        total = int(per.sum())
        if total == 0 or n <= 0:
            return np.zeros(0, dtype=np.int64)
        first = np.cumsum(per) - per
        pos = _spread(total, n)
        seg = np.searchsorted(first, pos, side="right") - 1
        return self.start[seg] + pos - first[seg]

    def band(self, lo: int, hi: int, n: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """``n`` pairs ``(i, j)`` with ``lo ≤ j - i ≤ hi`` in one segment, evenly spread over all such
        pairs ordered by stride then i (so each stride gets its share of every such pair, as ``all``)."""
        strides = np.arange(lo, hi + 1)
        per = np.clip(self.length[None, :] - strides[:, None], 0, None)          # (strides, segments)
        per_stride = per.sum(axis=1)
        first = np.cumsum(per_stride) - per_stride
        pos = _spread(int(per_stride.sum()), n, jitter=True)
        k = np.searchsorted(first, pos, side="right") - 1
        rank = pos - first[k]
        seg_first = np.cumsum(per[k], axis=1) - per[k]                            # (picks, segments)
        seg = (seg_first <= rank[:, None]).sum(axis=1) - 1
        i = self.start[seg] + rank - seg_first[np.arange(len(k)), seg]
        return i, i + strides[k]


def _spread(total: int, n: int, *, jitter: bool = False) -> NDArray[np.int64]:
    """``n`` evenly spread positions in ``range(total)`` (all of them when ``n >= total``): the
    centres of ``n`` equal cells, or with ``jitter`` one seeded random place in each cell (the
    same positions on every run).

    :meth:`_Segments.band` jitters: its positions run over pairs ordered by stride then start, and
    a regular lattice there aliases with the strides — dropping one sample at the start of a
    simulated absolute-tracker recording (issue 13's 30/100 Hz rig) moved its translation error
    between 0.02 and 0.38 mm with the same number of pairs; jittered, 20 shifts stayed within
    0.014–0.060 mm, the spread of random pairs (0.017–0.047 mm). One stride's starts stay regular:
    evenly spaced spans of drifting odometry overlap least."""
    if n >= total:
        return np.arange(total)
    offset = np.random.default_rng(_SPREAD_SEED).random(n) if jitter else 0.5
    return np.minimum(((np.arange(n) + offset) * total / n).astype(np.int64), total - 1)


def _pairs(synced: Synced, i: NDArray[np.int64], j: NDArray[np.int64]) -> Pairs:
    return Pairs(*synced.motions(i, j), i, j, synced.stamps_ns[i], synced.stamps_ns[j])


def _ml_weights(model: NoiseModel, f: PairFeatures) -> tuple[NDArray[np.float64], float]:
    """One weight per pair and one α [1/m] closest (in log) to the per-pair ML weights 1/σ_rot², 1/σ_trans²."""
    vr, vd = model.rot_variance(f), model.dual_variance(f)
    alpha = float(np.exp(0.5 * np.mean(np.log(vr / vd))))
    return 1.0 / (np.sqrt(vr * vd) * alpha), alpha


def _level_errors(A: NDArray[np.float64], B: NDArray[np.float64], w: NDArray[np.float64], alpha: float,
                  X: NDArray[np.float64], level: NDArray[np.int64], scale: NDArray[np.float64],
                  axis: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """(L, 2) predicted RMS rotation [rad] and translation [m] error of X from each level's pairs
    (motions ``A``, ``B``, weights ``w``, ladder index ``level``; α [1/m]), level l's ``scale[l]``
    times over: ``tr`` of the blocks of ``H⁻¹``, with ``H = Dᵀ Q D`` the curvature of cost (8) on the
    level's pairs in the tangent ``δ = (ω, v)``.

    ``axis`` (unit, frame a): the common rotation axis of planar motion; the translation along it is
    held fixed (``H`` restricted to the other five directions), as the reduced in-plane solve holds it
    (:mod:`.subspace`). The data do not determine it: what curvature ``H`` has there is the noise's
    tilt of the rotation axes, and its inverse (metres to tens of metres, varying from level to level
    by chance) would otherwise decide the levels, keeping one long stride whose few spans starve the
    yaw the translations alone carry."""
    q, qd = dq.from_transforms(X)
    Q = np.zeros((len(scale), 8, 8))                          # each level's cost form, [q'; q] order: its pairs'
    np.add.at(Q, level, w[:, None, None] * pair_forms(A, B, alpha, X).sum(axis=1))   # summed (no (L, N) product)
    P = np.eye(6) if axis is None else _without_translation_along(axis)     # δ = P η
    D = tangent_basis(q, qd)[_Q_PRIME_FIRST] @ P              # dx/dη with x = [q'; q]
    cov = P @ np.linalg.pinv(scale[:, None, None] * (D.T @ Q @ D), hermitian=True) @ P.T
    traces = np.stack([np.trace(cov[:, :3, :3], axis1=1, axis2=2), np.trace(cov[:, 3:, 3:], axis1=1, axis2=2)], 1)
    errors: NDArray[np.float64] = np.sqrt(np.maximum(traces, 0.0))
    return errors


def _without_translation_along(axis: NDArray[np.float64]) -> NDArray[np.float64]:
    """(6, 5) orthonormal basis of the tangent ``δ = (ω, v)`` without translation along the unit ``axis``."""
    P = np.zeros((6, 5))
    P[:3, :3] = np.eye(3)
    P[3:, 3:] = np.linalg.svd(np.eye(3) - np.outer(axis, axis))[0][:, :2]
    return P


@dataclass(frozen=True, eq=False)
class _Probe:
    """Probe pairs of every level: ``level[k]`` is the ladder index of pair k."""

    pairs: Pairs
    level: NDArray[np.int64]
    strides: NDArray[np.int64]
    available: NDArray[np.int64]


def _probe(synced: Synced, segs: _Segments, per_level: int) -> _Probe:
    strides = ladder(int(segs.length.max()) if len(segs.length) else 0)
    available = np.array([segs.count(int(k)) for k in strides], dtype=np.int64)
    strides, available = strides[available > 0], available[available > 0]
    starts = [segs.starts(int(k), per_level) for k in strides]
    i = np.concatenate(starts) if starts else np.zeros(0, dtype=np.int64)
    j = i + np.repeat(strides, [len(s) for s in starts])
    level = np.repeat(np.arange(len(strides)), [len(s) for s in starts])
    return _Probe(_pairs(synced, i, j), level, strides, available)


def _overlap(stride: int, available: int, used: int, drift_share: float) -> float:
    """How many times fewer independent pairs ``used`` evenly spread pairs of one stride are worth
    (their drift is shared where their spans overlap; step 4 of the module docstring)."""
    return 1.0 + drift_share * max(stride * used / available - 1.0, 0.0)


def _choose_levels(probe: _Probe, w: NDArray[np.float64], alpha: float, share: NDArray[np.float64],
                   X: NDArray[np.float64], max_pairs: int, axis: NDArray[np.float64] | None,
                   keep_ratio: float) -> NDArray[np.int64]:
    """Ladder indices of the levels to keep (see the module docstring, step 4–5); ``axis``: the common
    rotation axis of planar motion (frame a), along which the errors are not judged."""
    counts = np.bincount(probe.level, minlength=len(probe.strides))
    budget = max(max_pairs // 4, _MIN_LEVEL_PAIRS)       # what one level would get when a few are kept
    used = np.minimum(probe.available, budget)
    level_share = np.bincount(probe.level, weights=share, minlength=len(counts)) / np.maximum(counts, 1)
    overlap = [_overlap(int(k), int(a), int(u), float(s))
               for k, a, u, s in zip(probe.strides, probe.available, used, level_share, strict=True)]
    errors = _level_errors(probe.pairs.A, probe.pairs.B, w, alpha, X, probe.level,
                           used / np.maximum(counts, 1) / np.asarray(overlap), axis)
    errors[counts < _MIN_LEVEL_PAIRS] = np.inf
    if not np.isfinite(errors).any():
        return np.arange(len(probe.strides))
    ratio = np.max(errors / errors.min(axis=0), axis=1)
    good = np.flatnonzero(ratio <= keep_ratio * ratio.min())
    lo, hi = int(good[0]), int(good[-1])
    lever = _level_lever(probe) if axis is not None else None

    def mostly_absolute(k: int) -> bool:     # a longer level only adds lever and diversity (step 5)
        return bool(level_share[k] < _ABSOLUTE_SHARE and (lever is None or level_share[k] < _ABSOLUTE_SHARE_PLANAR
                                                          or lever[k] > _LEVER_GROWTH * lever[k - 1]))

    while hi + 1 < len(errors) and np.isfinite(errors[hi + 1, 0]) and mostly_absolute(hi + 1):
        hi += 1
    return np.arange(lo, hi + 1)


def _level_lever(probe: _Probe) -> NDArray[np.float64]:
    """Median length [m] of b's translations over each level's probe pairs."""
    t = np.linalg.norm(probe.pairs.B[:, :3, 3], axis=1)
    return np.array([float(np.median(t[probe.level == k])) if np.any(probe.level == k) else 0.0
                     for k in range(len(probe.strides))])


def _kept_pairs(synced: Synced, segs: _Segments, strides: NDArray[np.int64], max_pairs: int, band: bool
                ) -> tuple[Pairs, NDArray[np.float64]]:
    """The pairs of the kept strides and each pair's overlap factor ``stride · used / available``
    (see :func:`_overlap`). ``band``: every stride from the shortest kept to the longest segment,
    pairs spread as ``all`` spreads them (absolute sources); else the kept strides share the cap."""
    if band:
        i, j = segs.band(int(strides[0]), int(segs.length.max()) - 1, max_pairs)
        return _pairs(synced, i, j), np.ones(len(i))
    per = max(max_pairs // max(len(strides), 1), 1)
    starts = [segs.starts(int(k), per) for k in strides]
    sizes = [len(s) for s in starts]
    i = np.concatenate(starts)
    crowding = np.repeat([k * n / max(segs.count(int(k)), 1) for k, n in zip(strides, sizes, strict=True)], sizes)
    return _pairs(synced, i, i + np.repeat(strides, sizes)), crowding


def _without_prior_first(fit: Callable[[Prior | None], _T], prior: Prior | None) -> _T:
    """``fit(None)``, or ``fit(prior)`` when the pairs cannot be solved without the prior (a
    :class:`~handeye_cli.errors.HandEyeError`). The selection judges the data alone where they determine the
    extrinsic: along what they leave open the residuals do not change, and where they determine it a wrong
    prior's term (eq 26) pulls ``X``, inflating the residuals the noise model is fitted to (a diff-drive
    with a prior wrong by yaw +1°, pitch +1°, y +2 cm moved its pair weights and with them the estimated yaw
    by 1.3e-4°), and counts as exact information in the predicted errors of :func:`_blocked`."""
    try:
        return fit(None)
    except HandEyeError:
        if prior is None:
            raise
        return fit(prior)


def _blocked(pairs: Pairs, cap: float, weights: NDArray[np.float64], prior: Prior | None) -> float:
    """:func:`~.alpha.blocked_alpha` of the pairs (see :func:`_without_prior_first`): with a prior's term in the
    predicted errors every smaller α looks better, and the translations that alone determine a ground vehicle's
    yaw lose their weight to a prior that may be wrong (a car with a prior 1° off in yaw: yaw 0.0005–0.005°
    without it, 0.012–0.067° with it)."""
    blocks = time_blocks(pairs.t_i_ns, pairs.t_j_ns)
    return _without_prior_first(
        lambda p: blocked_alpha(pairs.A, pairs.B, cap, blocks, prior=p, weights=weights).alpha, prior)


def _solved(A: NDArray[np.float64], B: NDArray[np.float64], prior: Prior | None, **options: Any) -> NDArray[np.float64]:
    """``X`` of :func:`~handeye_cli.solvers.solve` on the pairs (see :func:`_without_prior_first`)."""
    return _without_prior_first(lambda p: solve(A, B, prior=p, **options).matrix, prior)


def _rejoined(synced: Synced, segs: _Segments, path: NDArray[np.float64], X: NDArray[np.float64],
              model: NoiseModel) -> NDArray[np.int64] | None:
    """The synced samples' segments with every boundary across which the world stayed the same joined up, or
    None when none did.

    The pose-jump gate starts a segment where the motion over dropped samples breaks its per-step scale: a real
    re-localisation (a SLAM map that jumped) moves every later pose, but so does no glitch, and a gap of a
    camera losing its target for half a second breaks the scale of 30 Hz steps as well (the ETH PrimeSense
    recording: 21 segments, the longest 159 of 1486 samples, and pairs only inside them: 98 mm where the
    same pairs across the gaps give 8 mm). With the probe's ``X`` and noise model, up to ``_CROSSING`` pairs
    ``(l - k, f + k)`` span each boundary (``l`` the last sample before it, ``f`` the first after): where their
    median residual, over the variance the model predicts for their span, stays within ``_SAME_WORLD`` in
    rotation and translation, the world did not move and the segments are one. Only for a model judged
    absolute: drift's variance at the span of a gap hides a re-localisation's jump of centimetres (and a
    mount's slip), so on drifting data the test has no power and the gate's segments stand."""
    ends = segs.start[1:] - 1                                 # last sample of each segment but the last
    k = np.arange(_CROSSING)
    before = np.repeat(segs.length[:-1], _CROSSING) > np.tile(k, len(ends))
    after = np.repeat(segs.length[1:], _CROSSING) > np.tile(k, len(ends))
    i = (np.repeat(ends, _CROSSING) - np.tile(k, len(ends)))
    j = (np.repeat(ends + 1, _CROSSING) + np.tile(k, len(ends)))
    ok = before & after
    boundary = np.repeat(np.arange(len(ends)), _CROSSING)[ok]
    pairs = _pairs(synced, i[ok], j[ok])
    f = pair_features(synced.stamps_ns, path, pairs.i, pairs.j, pairs.B, X)
    r_rot, r_dual = cost_residuals(pairs.A, pairs.B, X)
    z = np.maximum(r_rot ** 2 / model.rot_variance(f), r_dual ** 2 / model.dual_variance(f))
    same = np.array([float(np.median(z[boundary == b])) <= _SAME_WORLD     # k = 0 spans every boundary
                     for b in range(len(ends))])
    if not same.any():
        return None
    new = np.zeros(len(synced), dtype=np.int64)
    new[segs.start[1:][~same]] = 1
    return np.cumsum(new)


def _probe_solve(pr: _Probe, prior: Prior | None, method: str) -> NDArray[np.float64]:
    """``X`` of the probe, every level weighted alike (each pair by one over its level's count)."""
    count = np.bincount(pr.level, minlength=len(pr.strides)).astype(float)
    return _solved(pr.pairs.A, pr.pairs.B, prior, method=method, weights=1.0 / count[pr.level])


def select_pairs(synced: Synced, *, max_pairs: int = 2000, method: str = "dqopt", prior: Prior | None = None,
                 probe: int = 200, rounds: int = 3) -> Selection:
    """The ``auto`` strategy (module docstring): pairs, weights, α and noise model for ``synced``. ``prior``
    enters a solve only where the pairs cannot be solved without it (:func:`_without_prior_first`).

    Raises :class:`~handeye_cli.errors.HandEyeError` when the probe cannot be solved (too few
    samples or motions that cannot determine the extrinsic; the solver's message says which).
    """
    segs = _Segments.of(synced.segment)
    pr = _probe(synced, segs, probe)
    if len(pr.pairs) < _MIN_LEVEL_PAIRS:       # too little to fit a model: every pair there is, as is
        return Selection(pr.pairs, np.ones(len(pr.pairs)), 1.0, None, tuple(int(k) for k in pr.strides), 0,
                         len(pr.pairs))
    path = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(synced.xyz_a, axis=0), axis=1))]
    X = _probe_solve(pr, prior, method)
    rejoined = 0
    if len(segs.length) > 1:          # segments the gate split where the world did not move are one
        f = pair_features(synced.stamps_ns, path, pr.pairs.i, pr.pairs.j, pr.pairs.B, X)
        first = fit_noise_model(*cost_residuals(pr.pairs.A, pr.pairs.B, X), f)
        joined = _rejoined(synced, segs, path, X, first) if first.kind == "absolute" else None
        if joined is not None:
            rejoined = len(segs.length) - int(joined[-1]) - 1
            segs = _Segments.of(joined)
            pr = _probe(synced, segs, probe)
            X = _probe_solve(pr, prior, method)
    axis = common_axis(pr.pairs.A, pr.pairs.B)          # planar: translation along it is not the data's
    kept, done = np.zeros(0, dtype=np.int64), 0
    while done < rounds:
        done += 1
        f = pair_features(synced.stamps_ns, path, pr.pairs.i, pr.pairs.j, pr.pairs.B, X)
        model = fit_noise_model(*cost_residuals(pr.pairs.A, pr.pairs.B, X), f)
        w, alpha = _ml_weights(model, f)
        keep = _KEEP_RATIO_DRIFTING if model.kind == "drifting" else _KEEP_RATIO
        levels = _choose_levels(pr, w, alpha, model.drift_share(f), X, max_pairs, axis, keep)
        if np.array_equal(levels, kept):
            break
        kept = levels
        band = kept[-1] == len(pr.strides) - 1 and model.kind == "absolute"
        pairs, crowding = _kept_pairs(synced, segs, pr.strides[kept], max_pairs, band)
        fk = pair_features(synced.stamps_ns, path, pairs.i, pairs.j, pairs.B, X)
        weights, alpha = _ml_weights(model, fk)
        weights = weights / (1.0 + model.drift_share(fk) * np.clip(crowding - 1.0, 0.0, None))
        X = _solved(pairs.A, pairs.B, prior, method=method, alpha=alpha, weights=weights)
    if model.kind == "drifting":       # errors shared across time: the ML α is an upper bound (analysis.alpha)
        alpha = _blocked(pairs, alpha, weights, prior)
    return Selection(pairs, weights / weights.mean(), alpha, model, tuple(int(k) for k in pr.strides[kept]), done,
                     int(pr.available[kept].sum()), rejoined, band)
