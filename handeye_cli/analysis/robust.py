"""Outlier rejection among motion pairs: RANSAC on minimal sets, then the weighted optimal solve.

Conventions: ``X = T_a_b`` (maps frame b to frame a), ``A_i X = X B_i``; quaternions x-y-z-w;
residuals as in :mod:`.residuals` (rotation [rad] inside, [deg] in results; translation [m]).

Algorithm (:func:`robust_solve`):

1. **Hypotheses.** ``hypotheses`` random minimal sets of ``sample_size`` pairs are solved at once,
   vectorised, with the two-step method (DQ2Steps, Alg. 2): the rotation is the smallest
   eigenvector of ``Σ E_iᵀE_i`` (eq 19, E_i from eq 7), the translation the least-squares
   solution of ``(R_Ai - I) t = R_X t_Bi - t_Ai``.
2. **Scoring without a threshold (LMedS).** Every hypothesis is scored by the median over the
   pairs (a random subset of ``score_pairs`` for large N) of ``(r_rot/s_rot)² + (r_t/s_t)²``, where ``s``
   is the smallest per-hypothesis median residual; the best hypothesis survives up to 50 % outliers.
3. **Data-derived threshold.** For residual magnitudes the median is the MAD about zero;
   a pair is an inlier when both its residuals are ≤ ``k`` × the inliers' median residual
   (k = 3: a 3-D Gaussian residual exceeds 3 × its median with probability ≈ 1e-4).
4. **Refinement.** The weighted optimal solve (dqopt with 0/1 weights, cost (8)) on the inliers,
   new residuals, new threshold; repeated until the inlier set no longer changes.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..errors import HandEyeError, TooFewPairsError
from ..geometry import dualquat as dq
from ..solvers import Prior, Solution, solve
from ..solvers.problem import pair_blocks, validate_motions
from .residuals import Residuals, pair_residuals, residuals_batch

__all__ = ["RobustResult", "robust_solve", "minimal_hypotheses", "consensus_share", "longest_disagreement",
           "moved_during", "MOVED_GAIN", "MOVED_MIN_SIDE"]

MOVED_GAIN = 3.0             # the samples before and after one stamp fit their own extrinsics this much better
MOVED_MIN_SIDE = 5           # ... with at least this many samples a side


def _agreeing(inliers: BoolArray, i: IntArray, j: IntArray) -> BoolArray:
    """Per pose sample that pairs use (pair ``k`` joins samples ``i[k]``, ``j[k]``), in time order: whether at
    least half of its pairs are ``inliers``."""
    n = int(max(i.max(), j.max())) + 1 if len(i) else 0
    used = np.bincount(i, minlength=n) + np.bincount(j, minlength=n)
    good = np.bincount(i, weights=inliers, minlength=n) + np.bincount(j, weights=inliers, minlength=n)
    seen = used > 0
    return np.asarray(good[seen] >= 0.5 * used[seen])


def consensus_share(inliers: BoolArray, i: IntArray, j: IntArray) -> float:
    """The share of the pose samples that agree with the consensus (at least half of their pairs inliers)."""
    agree = _agreeing(inliers, i, j)
    return float(agree.mean()) if len(agree) else 0.0


def longest_disagreement(inliers: BoolArray, i: IntArray, j: IntArray) -> float:
    """The longest run of consecutive samples that disagree with the consensus, as a share of the samples: bad
    detections are scattered, a sensor that moved disagrees from the moment it moved on."""
    agree = _agreeing(inliers, i, j)
    if not len(agree):
        return 1.0
    edges = np.flatnonzero(np.diff(np.r_[0, (~agree).astype(np.int8), 0]))
    return float(np.max(edges[1::2] - edges[::2], initial=0)) / len(agree)


@dataclass(frozen=True, eq=False)
class RobustResult:
    """Outcome of :func:`robust_solve`.

    Attributes
    ----------
    solution:
        The weighted optimal solve on the inliers (``solution.matrix`` is ``T_a_b``).
    inliers:
        (N,) bool mask over the input pairs.
    rejected:
        (K,) int indices of the rejected pairs, ascending.
    threshold_rotation_deg, threshold_translation_m:
        The final inlier thresholds [deg], [m].
    residuals:
        Residuals of every input pair at ``solution.matrix``.
    hypotheses, refinements:
        Number of minimal-set hypotheses scored and of refinement solves run.
    """

    solution: Solution
    inliers: BoolArray
    rejected: IntArray
    threshold_rotation_deg: float
    threshold_translation_m: float
    residuals: Residuals
    hypotheses: int
    refinements: int

    def as_dict(self) -> dict[str, Any]:
        """Plain summary for the result file (the rejected indices, not the mask)."""
        return {"inliers": int(self.inliers.sum()), "rejected": [int(i) for i in self.rejected],
                "threshold_rotation_deg": self.threshold_rotation_deg,
                "threshold_translation_m": self.threshold_translation_m,
                "hypotheses": self.hypotheses, "refinements": self.refinements}


def _sample_sets(n: int, size: int, count: int, rng: np.random.Generator) -> IntArray:
    """``count`` sets of ``size`` distinct pair indices in ``range(n)``, shape (count, size)."""
    return np.argpartition(rng.random((count, n)), size - 1, axis=1)[:, :size]


def minimal_hypotheses(motions_a: FloatArray, motions_b: FloatArray, sets: IntArray) -> FloatArray:
    """Solve every minimal set of pairs with the two-step method (DQ2Steps, Alg. 2), vectorised.

    Parameters
    ----------
    motions_a, motions_b:
        (N, 4, 4) validated motions.
    sets:
        (H, s) pair indices, s ≥ 2.

    Returns
    -------
    (H, 4, 4) candidate ``T_a_b``: rotation from the smallest eigenvector of ``Σ E_iᵀE_i`` (eq 19),
    translation [m] from the least-squares ``(R_Ai - I) t = R_X t_Bi - t_Ai`` (pseudo-inverse,
    so a set rotating about one axis gives the minimum-norm translation along it).
    """
    E, _ = pair_blocks(motions_a, motions_b)
    EtE = np.einsum("nki,nkj->nij", E, E)
    _, V = np.linalg.eigh(EtE[sets].sum(axis=1))
    Rx = dq.to_matrix(V[:, :, 0])                                        # (H, 3, 3)
    D = motions_a[sets, :3, :3] - np.eye(3)                              # (H, s, 3, 3)
    rhs = np.einsum("hij,hsj->hsi", Rx, motions_b[sets, :3, 3]) - motions_a[sets, :3, 3]
    N = np.einsum("hski,hskj->hij", D, D)
    g = np.einsum("hski,hsk->hi", D, rhs)
    X = np.tile(np.eye(4), (len(sets), 1, 1))
    X[:, :3, :3] = Rx
    X[:, :3, 3] = np.einsum("hij,hj->hi", np.linalg.pinv(N, hermitian=True), g)
    return X


def _chunked_residuals(A: FloatArray, B: FloatArray, cand: FloatArray,
                       budget: int = 1 << 20) -> tuple[FloatArray, FloatArray]:
    """:func:`residuals_batch` over the candidates in chunks of about ``budget`` (candidate, pair) cells."""
    step = max(1, budget // len(A))
    parts = [residuals_batch(A, B, cand[i:i + step]) for i in range(0, len(cand), step)]
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


def _lmeds_best(rot: FloatArray, trans: FloatArray) -> int:
    """Index of the hypothesis with the least median of the normalised squared residuals."""
    tiny = np.finfo(float).tiny
    s_r = max(float(np.median(rot, axis=1).min()), tiny)
    s_t = max(float(np.median(trans, axis=1).min()), tiny)
    score = np.median((rot / s_r) ** 2 + (trans / s_t) ** 2, axis=1)
    return int(np.argmin(score))


def _inlier_mask(rot: FloatArray, trans: FloatArray, basis: IntArray | BoolArray,
                 k: float) -> tuple[BoolArray, float, float]:
    """Inliers: both residuals ≤ k × their median over the pairs in ``basis`` (indices or a mask); also the
    thresholds."""
    floor = 1e-12
    tau_r = k * max(float(np.median(rot[basis])), floor)
    tau_t = k * max(float(np.median(trans[basis])), floor)
    return (rot <= tau_r) & (trans <= tau_t), tau_r, tau_t


def robust_solve(motions_a: FloatArray, motions_b: FloatArray, *, method: str = "dqopt",
                 alpha: float = 1.0, prior: Prior | None = None, hypotheses: int = 256,
                 sample_size: int = 3, k: float = 3.0, max_refinements: int = 10,
                 score_pairs: int = 2000, seed: int = 0) -> RobustResult:
    """Estimate ``T_a_b`` from motion pairs of which a minority are gross outliers.

    Parameters
    ----------
    motions_a, motions_b:
        (N, 4, 4) relative motions, ``A_i X = X B_i``.
    method, alpha, prior:
        Passed to :func:`handeye_cli.solvers.solve` for the final weighted solve (α in 1/m).
    hypotheses, sample_size:
        Number of random minimal sets and their size (2 pairs determine X when their rotation
        axes differ; 3 is more robust to noise).
    k:
        Inlier threshold in multiples of the inliers' median residual (rotation and translation).
    max_refinements:
        Cap on the solve / re-threshold rounds of step 4 (one round always runs).
    score_pairs:
        Hypotheses are scored on a random subset of this many pairs when there are more.
    seed:
        Seed of the sampling; the result is deterministic for a given seed.

    Returns
    -------
    :class:`RobustResult` with the solution, the (N,) inlier mask and the rejected indices.

    Raises
    ------
    HandEyeError
        Malformed motions, fewer than ``2 × sample_size`` pairs, or an inlier set the solver
        refuses (e.g. all inliers rotate about one axis and no prior is given).
    """
    A, B, _ = validate_motions(motions_a, motions_b)
    n = len(A)
    if sample_size < 2 or n < 2 * sample_size:
        raise TooFewPairsError(f"{n} motion pairs are too few for outlier rejection with samples of "
                           f"{sample_size}", "robust", f"record at least {2 * max(sample_size, 2)} "
                           "motion pairs, or solve without ⟦robust=True⟧")
    rng = np.random.default_rng(seed)
    cand = minimal_hypotheses(A, B, _sample_sets(n, sample_size, hypotheses, rng))
    scored = np.sort(rng.choice(n, score_pairs, replace=False)) if n > score_pairs else slice(None)
    best = _lmeds_best(*_chunked_residuals(A[scored], B[scored], cand))
    r, t = residuals_batch(A, B, cand[best:best + 1])
    rot, trans = r[0], t[0]
    order = np.argsort((rot / max(np.median(rot), 1e-300)) ** 2 + (trans / max(np.median(trans), 1e-300)) ** 2)
    mask, tau_r, tau_t = _inlier_mask(rot, trans, order[: max(n // 2, sample_size)], k)   # scale: best half
    refinements = 0
    while True:
        refinements += 1
        solution = solve(A, B, method=method, alpha=alpha, prior=prior, weights=mask.astype(np.float64))
        r, t = residuals_batch(A, B, solution.matrix[None])
        rot, trans = r[0], t[0]
        new, tau_r, tau_t = _inlier_mask(rot, trans, mask, k)
        if np.array_equal(new, mask) or new.sum() < sample_size:
            break
        mask = new
        if refinements >= max_refinements:
            break
    return RobustResult(solution, mask, np.flatnonzero(~mask), float(np.rad2deg(tau_r)), float(tau_t),
                        Residuals(np.rad2deg(rot), trans), int(len(cand)), refinements)


def moved_during(motions_a: FloatArray, motions_b: FloatArray, i: IntArray, j: IntArray, residuals: Residuals, *,
                 method: str = "dqopt", alpha: float = 1.0, prior: Prior | None = None,
                 min_side: int = MOVED_MIN_SIDE) -> tuple[int, float] | None:
    """Whether the extrinsic changed during a capture (a mount that slipped between two stations: the samples
    before one stamp fit one ``T_a_b``, those after another). Each split of the samples (``i[k] < j[k]`` sample
    indices of the motions ``A_k = T_a(t_i)⁻¹ T_a(t_j)``, at least ``min_side`` samples a side) is solved apart
    on the pairs inside each side; where both sides fit their own extrinsic ``MOVED_GAIN`` times better than
    the solution of all pairs fits them (``residuals``, every pair's at it; median rotation or translation),
    the capture held two. A consensus of scattered inliers (:func:`robust_solve`) cannot find it: one period
    is less than half of the all-with-all pairs. Returns the first sample after the best split and its gain,
    or None."""
    n = int(max(i.max(), j.max())) + 1 if len(i) else 0
    best: tuple[int, float] | None = None
    for cut in range(min_side, n - min_side + 1):
        sides = [j < cut, i >= cut]
        if min(int(m.sum()) for m in sides) < 2 * min_side:
            continue
        own_rot, own_trans, all_rot, all_trans = [], [], [], []
        for m in sides:
            try:
                X = solve(motions_a[m], motions_b[m], method=method, alpha=alpha, prior=prior).matrix
            except HandEyeError:
                return None
            r = pair_residuals(motions_a[m], motions_b[m], X)
            own_rot.append(r.rotation_deg)
            own_trans.append(r.translation_m)
            all_rot.append(residuals.rotation_deg[m])
            all_trans.append(residuals.translation_m[m])
        gain = max(float(np.median(np.concatenate(a)) / max(float(np.median(np.concatenate(o))), 1e-300))
                   for a, o in ((all_rot, own_rot), (all_trans, own_trans)))
        if best is None or gain > best[1]:
            best = (cut, gain)
    return best if best is not None and best[1] >= MOVED_GAIN else None
