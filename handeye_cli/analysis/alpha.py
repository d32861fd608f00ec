"""Choosing the weight α [1/m] of the translational residuals in cost (8) from the data.

Conventions: ``X = T_a_b`` (maps frame b to frame a), ``A_i X = X B_i``; quaternions x-y-z-w.

The paper treats α as a tunable constant (§3.1, "Choice of α" in §4) and picks the best value
per dataset against ground truth. Without ground truth, :func:`auto_alpha` predicts the error
for each α on a log grid with the sandwich covariance (:mod:`.covariance`) — which measures the
noise from the residuals, so it stays right when α weighs them wrongly — and returns the α
whose predicted rotation and translation errors are *both* closest to their own minimum over
the grid (min over α of the larger of the two ratios). :func:`residual_ratio_alpha` is the
cheaper textbook rule α = σ_rot / σ_trans from the residuals of a first solve, iterated.
:func:`noise_model_alpha` is the maximum-likelihood α under the recording's noise model
(:mod:`.noise_model`): α² = σ_rot²/σ_trans² with both variances predicted per pair in the
cost's own units (the translation one including rotation noise times the motion's lever),
combined as the geometric mean over the pairs — the rule the default ``auto`` uses, capped by
:func:`blocked_alpha`: the ML α assumes the pairs' errors independent, and on drifting odometry they
are not — the yaw drift of a VIO turns every later displacement about gravity, an error shared by
the pairs of one stretch of time and shaped like a rotation of X, which the translational residuals
then tilt X's rotation by. :func:`blocked_alpha` lowers α to where the cluster-robust sandwich
(blocks of time as clusters) predicts the rotation and translation errors best.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..solvers import Prior, solve
from ..solvers.problem import validate_motions
from .covariance import linear_covariance
from .noise_model import NoiseModel, PairFeatures, cost_residuals, fit_noise_model
from .residuals import residuals_batch

__all__ = ["AlphaChoice", "auto_alpha", "residual_ratio_alpha", "noise_model_alpha", "blocked_alpha", "time_blocks",
           "DEFAULT_GRID"]

_EXACT_DEG, _EXACT_M = 1e-9, 1e-9         # predicted errors this small mean noise-free data
_ROUNDING = 1e-12                          # residuals [rad], [m] at rounding level
TIME_BLOCKS = 20                           # blocks of time the cluster-robust sandwich treats as independent
_BLOCKED_STEPS = 9                         # α tried by blocked_alpha: the cap, then down by 10^¼ each step (to 1/100)

#: The paper's α range, 10⁻² … 10^1.7 [1/m] (appendix D), 25 log-spaced values.
DEFAULT_GRID = np.logspace(-2.0, 1.7, 25)


@dataclass(frozen=True, eq=False)
class AlphaChoice:
    """The chosen α [1/m] and the evidence for it.

    ``grid`` (K,) are the α tried; ``rotation_rms_deg`` and ``translation_rms_m`` (K,) the
    predicted RMS errors of X at each [deg], [m] (NaN for the residual-ratio rule, which predicts
    none); ``index`` locates the chosen α in the grid; ``method`` is ``"sandwich"`` or
    ``"residual-ratio"``.
    """

    alpha: float
    method: str
    grid: np.ndarray
    rotation_rms_deg: np.ndarray
    translation_rms_m: np.ndarray

    @property
    def index(self) -> int:
        """Position of the chosen α in the grid."""
        return int(np.argmin(np.abs(np.log(self.grid / self.alpha))))

    def as_dict(self) -> dict[str, Any]:
        """Plain summary for the result file."""
        i = self.index
        rot, trans = float(self.rotation_rms_deg[i]), float(self.translation_rms_m[i])
        return {"alpha": self.alpha, "method": self.method,
                "predicted_rotation_rms_deg": rot if np.isfinite(rot) else None,
                "predicted_translation_rms_m": trans if np.isfinite(trans) else None}


def _predicted_errors(A: np.ndarray, B: np.ndarray, grid: np.ndarray, prior: Prior | None,
                      weights: np.ndarray, blocks: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Predicted RMS rotation [deg] and translation [m] error of DQOpt at each α of the grid
    (cluster-robust over ``blocks`` when given, see :func:`~.covariance.linear_covariance`)."""
    rot, trans = np.empty(len(grid)), np.empty(len(grid))
    for k, a in enumerate(grid):
        X = solve(A, B, alpha=float(a), prior=prior, weights=weights).matrix
        c = linear_covariance(A, B, X, alpha=float(a), prior=prior, weights=weights, blocks=blocks)
        rot[k], trans[k] = c.rotation_rms_deg, c.translation_rms_m
    return rot, trans


def time_blocks(t_i_ns: np.ndarray, t_j_ns: np.ndarray, count: int = TIME_BLOCKS) -> np.ndarray:
    """(N,) block of each pair: ``count`` equal stretches of time, by the pair's midpoint."""
    mid = (np.asarray(t_i_ns, dtype=float) + np.asarray(t_j_ns, dtype=float)) / 2
    span = max(float(mid.max() - mid.min()), 1.0)
    blocks: np.ndarray = np.minimum(((mid - mid.min()) / span * count).astype(np.int64), count - 1)
    return blocks


def blocked_alpha(motions_a: np.ndarray, motions_b: np.ndarray, cap: float, blocks: np.ndarray, *,
                  prior: Prior | None = None, weights: np.ndarray | None = None) -> AlphaChoice:
    """α [1/m] ≤ ``cap`` whose errors predicted by the cluster-robust sandwich (pairs of one of
    ``blocks`` may share errors) are both closest to their minimum over α = cap·10^(-k/4), k < 9
    (:func:`_minimax_ratio`; ties to the larger α). Shared drift that tilts the rotation shows as
    a larger predicted rotation error at the larger α; independent errors keep α = ``cap``.
    Noise-free data (predicted errors at rounding level) keeps ``cap``."""
    A, B, w = validate_motions(motions_a, motions_b, weights)
    grid = cap * 10.0 ** (-np.arange(_BLOCKED_STEPS) / 4)
    rot, trans = _predicted_errors(A, B, grid, prior, w, blocks)
    if (rot.max() < _EXACT_DEG and trans.max() < _EXACT_M) or not (np.isfinite(rot).all() and np.isfinite(trans).all()):
        return AlphaChoice(cap, "blocked-sandwich", grid, rot, trans)
    return AlphaChoice(float(grid[_minimax_ratio(rot, trans)]), "blocked-sandwich", grid, rot, trans)


def _minimax_ratio(rot: np.ndarray, trans: np.ndarray) -> int:
    """Grid index minimising max(rot/min rot, trans/min trans); ties go to the smaller index."""
    tiny = np.finfo(float).tiny
    ratio = np.maximum(rot / max(rot.min(), tiny), trans / max(trans.min(), tiny))
    return int(np.argmin(np.round(ratio, 9)))


def auto_alpha(motions_a: np.ndarray, motions_b: np.ndarray, *, prior: Prior | None = None,
               weights: np.ndarray | None = None, grid: np.ndarray | None = None) -> AlphaChoice:
    """Choose α [1/m] by minimising the sandwich-predicted error of ``T_a_b`` over a log grid.

    Parameters
    ----------
    motions_a, motions_b:
        (N, 4, 4) relative motions, ``A_i X = X B_i``.
    prior, weights:
        As for :func:`handeye_cli.solvers.solve` (e.g. an inlier mask as weights).
    grid:
        Candidate α values [1/m]; default :data:`DEFAULT_GRID`.

    Raises
    ------
    HandEyeError
        As :func:`handeye_cli.solvers.solve` (e.g. exactly degenerate motion without a prior).

    Returns
    -------
    :class:`AlphaChoice`. Noise-free data (all predicted errors below 1e-9 deg and 1e-9 m, where
    every α gives the same answer) falls back to the residual-ratio rule's answer, or α = 1.
    """
    A, B, w = validate_motions(motions_a, motions_b, weights)
    grid = DEFAULT_GRID if grid is None else np.asarray(grid, dtype=float)
    rot, trans = _predicted_errors(A, B, grid, prior, w)
    exact = rot.max() < _EXACT_DEG and trans.max() < _EXACT_M
    if exact or not (np.isfinite(rot).all() and np.isfinite(trans).all()):
        fallback = residual_ratio_alpha(A, B, prior=prior, weights=w)
        return AlphaChoice(fallback.alpha, "residual-ratio", grid, rot, trans)
    return AlphaChoice(float(grid[_minimax_ratio(rot, trans)]), "sandwich", grid, rot, trans)


def residual_ratio_alpha(motions_a: np.ndarray, motions_b: np.ndarray, *, prior: Prior | None = None,
                         weights: np.ndarray | None = None, iterations: int = 2,
                         start: float = 1.0) -> AlphaChoice:
    """α = RMS rotation residual [rad] / RMS translation residual [m], re-solving ``iterations`` times.

    The maximum-likelihood weight if rotational and translational residuals were independent
    with those scales; cheap, but blind to the rotation noise that the lever arm carries into
    the translation residuals. Returns α = ``start`` when the residuals are at rounding level
    (noise-free data).
    """
    A, B, w = validate_motions(motions_a, motions_b, weights)
    a = float(start)
    for _ in range(iterations):
        X = solve(A, B, alpha=a, prior=prior, weights=w).matrix
        r, t = residuals_batch(A, B, X[None])
        sr, st = np.sqrt(np.average(r[0] ** 2, weights=w)), np.sqrt(np.average(t[0] ** 2, weights=w))
        if not (sr > _ROUNDING and st > _ROUNDING):
            break
        a = float(sr / st)
    grid = np.array([a])
    return AlphaChoice(a, "residual-ratio", grid, np.full(1, np.nan), np.full(1, np.nan))


def ml_alpha(model: NoiseModel, features: PairFeatures) -> float:
    """α [1/m] = geometric mean over the pairs of σ_rot/σ_trans predicted by ``model``."""
    return float(np.exp(0.5 * np.mean(np.log(model.rot_variance(features) / model.dual_variance(features)))))


def noise_model_alpha(motions_a: np.ndarray, motions_b: np.ndarray, *, prior: Prior | None = None,
                      weights: np.ndarray | None = None, spans_s: np.ndarray | None = None,
                      path_m: np.ndarray | None = None, iterations: int = 2, start: float = 1.0) -> AlphaChoice:
    """The maximum-likelihood α [1/m] under a noise model fitted to the residuals, re-solving ``iterations`` times.

    ``spans_s`` [s] and ``path_m`` [m] per pair let the model see drift (default: none). Noise-free
    data (residuals at rounding level) keeps α = ``start``.
    """
    A, B, w = validate_motions(motions_a, motions_b, weights)
    zeros = np.zeros(len(A))
    dt = zeros if spans_s is None else np.asarray(spans_s, dtype=float)
    ds = zeros if path_m is None else np.asarray(path_m, dtype=float)
    a, keep = float(start), w > 0
    for _ in range(iterations):
        X = solve(A, B, alpha=a, prior=prior, weights=w).matrix
        r_rot, r_dual = cost_residuals(A[keep], B[keep], X)
        if not (r_rot.max() > _ROUNDING and r_dual.max() > _ROUNDING):
            break
        lever = X[:3, :3] @ B[keep][:, :3, 3].T + X[:3, 3:4]
        f = PairFeatures(dt[keep], ds[keep], np.sum(lever * lever, axis=0))
        a = ml_alpha(fit_noise_model(r_rot, r_dual, f), f)
    return AlphaChoice(a, "noise-model", np.array([a]), np.full(1, np.nan), np.full(1, np.nan))
