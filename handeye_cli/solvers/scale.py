"""``A_i X = X B_i`` when stream b's translations have an unknown scale (monocular odometry).

Stream b's translations are in unknown units; ``s`` [m per unit of b] turns them into metres, so
each pair satisfies, with ``X = T_a_b`` (maps points b → a)::

    R_Ai R_X = R_X R_Bi                               (rotation: free of the scale)
    (R_Ai - I) t_X - s R_X t_Bi = -t_Ai               (translation: linear in t_X and s)

:func:`solve_with_scale` takes the rotation from the scale-free part (the unit quaternion
minimising ``Σ w_i |E_i q|²``, the rotational half of the paper's cost (8)), then ``t_X`` and
``s`` by linear least squares, then refines all seven jointly by nonlinear least squares over
the residuals ``[rotvec((R_X R_Bi)ᵀ R_Ai R_X), α (R_Ai t_X + t_Ai - s R_X t_Bi - t_X)]``
(radians and α-weighted metres, as cost (8) weighs them). Quaternions x-y-z-w.

Errors in variables: b's translations carry noise and are multiplied by ``s``, so least squares on
those residuals is pulled towards a smaller ``s`` (the noise's share of ``s² |t_B|²`` is cheaper to
explain away by shrinking it): by about ``−Σ var_b / Σ |t_B|²``, −0.06 % on the simulated continuous arm
of benchmarks/monocular.py (1 mm / 0.1° camera, exact kinematics; mean over 10 seeds, 1.2 of its σ),
whose mean error over 20 seeds went from −0.68 σ to −0.03 σ with the weighting below.
Given the per-axis variance of each pair's relative translation in a (``var_a`` [m²]) and in b
(``var_b`` [unit²]) — the pipeline takes them from the streams' jitter, as the fit test does — each
translation residual is divided by its standard deviation at the current ``s``, ``√(var_a + s² var_b)``
(times the median of that at the linear ``s``, to stay in metres): the maximum-likelihood (Deming)
weighting for noise on both sides, which reduces to regressing b's translations on a's when only b is
noisy and to the plain residuals when only a is. Without the variances (sparse poses, whose noise is
only assumed), the plain residuals. The linear estimate, reported beside, is not corrected.
On a short capture with small turns the scale is confounded with ``t_X`` and its σ is what the
translation then costs: kinhec's 4 s monocular sequences turn ≤ 6° between samples, and on the corpus's
smoke monocular-000000 the scale correlates 0.97 with ``t_X``'s components. Redrawing kinhec's noise
(camera 1/1/3 mm along its axes, 0.11°; robot 0.3 mm, 0.03°) on that sequence's motion 30 times, the
plain residuals erred −0.57 % ± 0.48 % and the weighted −0.09 % ± 0.47 % (σ covering 29/30), and the
translation 4.2 against 2.5 mm (0.6 mm with the true scale); the corpus's one draw is +0.76 % (1.7 σ,
4.9 mm). Weighing by the camera's anisotropic noise itself (known; 20 draws) gave ± 0.43 %, 2.3 mm: isotropic
variances lose little.

The standard deviation of ``s`` is the Gauss–Newton one, ``σ̂² (JᵀJ)⁻¹``, when the pairs are
independent. When pairs share samples (all-pairs of N stations carry about N, not N²/2,
independent observations, and a station's error — noise or robot kinematics — enters every pair
it is in), it is the delete-a-group jackknife over the samples: the samples are cut into at most
``_JACKKNIFE_GROUPS`` consecutive groups, the fit is repeated without the pairs that touch each
group, and ``var = (G-1)/G Σ (log s_g - mean)²``. On 20 simulated 15-station arm captures the
Gauss–Newton figure with a pairs-per-sample inflation under-stated the spread about twofold (RMS
of error/std 1.9); the jackknife's figure is checked in tests/analysis/test_scale.py. Ten groups, not more: the
errors of neighbouring samples are correlated (drifting odometry, an arm's kinematic errors along its path),
and short groups split what is shared — on 10 seeds of benchmarks/monocular.py, 30 groups covered the
scale's error at 95 % on 7/10 (continuous arm) and 8/10 (VIO), 10 groups on 9/10 and 10/10.

The scale is b's units in a's metres, and a's metres are only as right as a's own calibration: a
robot's link lengths and joint zeros, a motion-capture volume's wand. That error is shared by every
sample — a uniform part of it is indistinguishable from the scale — so no spread within the
recording shows it. The std therefore adds ``_REFERENCE_RELATIVE_STD`` (0.05 %) of the scale in
quadrature: a reference right to 0.2 mm in 0.4 m. The simulated UR5's kinematic errors (σ 0.2 mm on
its lengths, 0.01° on twists and zeros; simulation.arm) shrink or stretch its relative translations
by 0.056 % RMS over 20 noise-free captures, and without the term the continuous arm of
benchmarks/monocular.py covered the scale's error on 16/20 seeds (RMS of error/std 1.5). The data's
part alone is reported beside (``std_of_data``).

A scale that drifts (monocular odometry and VIO: their scale a random walk) is no one number: the fit gives
about its mean over the recording, and the jackknife's σ is of that mean — on benchmarks/monocular.py's VIO
(scale walk 0.3 %/√s) at 60 s it covered the recording's mean scale on 18/20 seeds (RMS of error/σ 1.02), but
its scale at the start on 14/20 (RMS 1.51): groups left out in turn see a walk only in their share, and
a walk of density q over T is ``qT/3`` in variance from its mean at either end. So the scale is also fitted
on each half of the recording (the pairs with both samples in the first, in the second half of the
jackknife's groups), each with the jackknife over its groups. Halves that disagree beyond ``_DRIFT_Z`` of
their joint σ are a warning (b's scale or its translations drift), and the disagreement beyond that σ,
``d² − σ₁² − σ₂²``, is added to the variance (``drift_std``): for the walk ``E d² = qT/3 + σ₁² + σ₂²``, so it
is the variance of the scale at the recording's ends about its mean. ``_DRIFT_Z`` is Student's t at
97.5 % for 8 degrees of freedom (each half's jackknife over 5 groups has 4): at 1.96, the simulated rig
of benchmarks/monocular.py, whose scale holds, was found drifting on 3/20 seeds, not 1/20. The walk is
found only when it is large against the halves' own σ (a half loses the pairs across the middle:
several times the whole's σ).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import DataError
from ..geometry import dualquat as dq
from .problem import pair_blocks, validate_motions

__all__ = ["ScaleDrift", "ScaleSolution", "drift_warning", "linear_scale", "scale_translations", "solve_with_scale"]

_MAX_RELATIVE_STD = 0.5      # a scale known worse than ±50 % is not determined
_JACKKNIFE_GROUPS = 10       # at most this many groups of samples left out in turn for the std (see the docstring)
_REFERENCE_RELATIVE_STD = 5e-4   # a's own metric error, shared by every sample: added to the std (see the docstring)
_DRIFT_Z = 2.31              # the halves' scales this many of their σ apart: the scale drifts (see the docstring)


@dataclass(frozen=True)
class ScaleDrift:
    """The scale fitted on each half of the recording (the pairs within the first, within the second half of
    the jackknife's groups) and their stds [m per unit of b]. ``drifts``: they disagree beyond
    ``_DRIFT_Z`` of their joint σ; ``drift_std``: then the disagreement beyond that σ, ``√(d² − σ₁² − σ₂²)``
    in ``scale`` units, the std of the scale at the recording's start or end about the whole's (module
    docstring), else 0."""

    halves: tuple[float, float]
    stds: tuple[float, float]
    drift_std: float

    def times(self, factor: float) -> ScaleDrift:
        """The same in units ``factor`` times larger."""
        return ScaleDrift((factor * self.halves[0], factor * self.halves[1]),
                          (factor * self.stds[0], factor * self.stds[1]), factor * self.drift_std)

    def as_dict(self) -> dict[str, Any]:
        """The result's ``scale.drift`` block."""
        return {"halves": list(self.halves), "halves_std": list(self.stds), "drift_std": self.drift_std}


def drift_warning(estimate: ScaleSolution | None) -> str | None:
    """The warning that b's scale drifts (:attr:`ScaleSolution.drift`); None when it holds, was not checked, or no
    scale was estimated."""
    drift = None if estimate is None else estimate.drift
    if drift is None or not drift.drift_std > 0:
        return None
    (a, b), (sa, sb) = drift.halves, drift.stds
    return (f"the scale of stream b drifts: {a:.6g} ± {sa:.2g} m per unit on the first half of the recording, "
            f"{b:.6g} ± {sb:.2g} on the second ({abs(b - a) / np.hypot(sa, sb):.3g} σ apart; b's scale or its "
            f"translations drift); scale.std includes the difference (drift_std {drift.drift_std:.2g}), and one "
            "scale fits the whole recording only that well: calibrate on a shorter stretch, or with an odometry "
            "that holds its scale")


@dataclass(frozen=True)
class ScaleSolution:
    """``matrix``: 4x4 ``T_a_b`` (translation in metres); ``scale``: metres per unit of stream b;
    ``scale_std``: its standard deviation, ``std_of_data`` the part of it the recording shows (without
    a's own metric error); ``linear_scale``: the linear estimate before refinement; ``cost``: half the
    sum of squared refined residuals."""

    matrix: NDArray[np.float64]
    scale: float
    scale_std: float
    linear_scale: float
    cost: float
    std_of_data: float
    drift: ScaleDrift | None = None

    def times(self, factor: float) -> ScaleSolution:
        """The same for b's translations given in ``1/factor`` of the units solved for: every scale times
        ``factor`` (the matrix, in metres, as it is)."""
        return replace(self, scale=factor * self.scale, scale_std=factor * self.scale_std,
                       linear_scale=factor * self.linear_scale, std_of_data=factor * self.std_of_data,
                       drift=None if self.drift is None else self.drift.times(factor))

    def as_dict(self) -> dict[str, Any]:
        """The result's ``scale`` block."""
        return {"value": self.scale, "std": self.scale_std, "std_of_data": self.std_of_data,
                "linear": self.linear_scale, "meaning": "metres per unit of stream b",
                **({} if self.drift is None else {"drift": self.drift.as_dict()})}


@dataclass(frozen=True)
class _Noise:
    """Per pair, the per-axis variance of a's relative translation ``var_a`` [m²] and of b's ``var_b``
    [unit²]; ``reference`` [m²]: their combination at the linear scale (median), so that the weighted
    translation residuals stay near metres and α keeps its meaning."""

    var_a: NDArray[np.float64]
    var_b: NDArray[np.float64]
    reference: float

    def subset(self, keep: NDArray[np.bool_]) -> _Noise:
        return _Noise(self.var_a[keep], self.var_b[keep], self.reference)


def scale_translations(T: NDArray[np.float64], scale: float) -> NDArray[np.float64]:
    """Copies of transforms (…, 4, 4) with their translations multiplied by ``scale``."""
    out = np.array(T, dtype=float)
    out[..., :3, 3] *= scale
    return out


def _rotation(A: NDArray[np.float64], B: NDArray[np.float64], w: NDArray[np.float64]) -> NDArray[np.float64]:
    """R_X from the rotational residuals only: eigenvector of ``Σ w EᵀE`` with the smallest eigenvalue."""
    E, _ = pair_blocks(A, B)
    _, vectors = np.linalg.eigh(np.einsum("n,nki,nkj->ij", w, E, E))
    return dq.to_matrix(vectors[:, 0])


def _linear(A: NDArray[np.float64], B: NDArray[np.float64], R_X: NDArray[np.float64],
            sw: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """t_X [m] and s from ``(R_A - I) t_X - s R_X t_B = -t_A`` by weighted linear least squares."""
    n = len(A)
    M = np.zeros((n, 3, 4))
    M[:, :, :3] = A[:, :3, :3] - np.eye(3)
    M[:, :, 3] = -B[:, :3, 3] @ R_X.T
    rhs = -A[:, :3, 3]
    sol, *_ = np.linalg.lstsq((M * sw[:, None, None]).reshape(-1, 4), (rhs * sw[:, None]).reshape(-1), rcond=None)
    return np.asarray(sol[:3], dtype=np.float64), float(sol[3])


def linear_scale(motions_a: NDArray[np.float64], motions_b: NDArray[np.float64],
                 R_X: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """t_X [m] and the scale s of b's translations [m per unit] for a given rotation ``R_X`` of ``T_a_b``,
    by linear least squares on ``(R_A - I) t_X - s R_X t_B = -t_A`` (numpy only: the quick look at whether
    b's translations fit better scaled, before :func:`solve_with_scale` is run)."""
    return _linear(np.asarray(motions_a), np.asarray(motions_b), R_X, np.ones(len(motions_a)))


def _rotation_of(p: NDArray[np.float64], q0: NDArray[np.float64]) -> NDArray[np.float64]:
    """R_X of ``p``: the rotation ``exp(δθ)`` applied to the initial rotation (x-y-z-w quaternion ``q0``)."""
    return dq.to_matrix(dq.multiply(dq.from_rotvec(p[:3]), q0))


def _residuals(p: NDArray[np.float64], A: NDArray[np.float64], B: NDArray[np.float64], q0: NDArray[np.float64],
               alpha: float, sw: NDArray[np.float64], noise: _Noise | None) -> NDArray[np.float64]:
    """Per-pair rotation [rad] and α-weighted translation residuals for ``p = [δθ (3), t_X (3), log s]``;
    with ``noise``, the translation residual in units of its noise at ``s`` (module docstring)."""
    R_X = _rotation_of(p, q0)
    s = np.exp(p[6])
    rot = dq.to_rotvec(dq.from_matrix(np.swapaxes(R_X @ B[:, :3, :3], 1, 2) @ A[:, :3, :3] @ R_X))
    trans = A[:, :3, :3] @ p[3:6] + A[:, :3, 3] - s * B[:, :3, 3] @ R_X.T - p[3:6]
    if noise is not None:
        trans = trans * np.sqrt(noise.reference / (noise.var_a + s ** 2 * noise.var_b))[:, None]
    return np.asarray(np.c_[rot, alpha * trans] * sw[:, None], dtype=np.float64).ravel()


def _undetermined(why: str) -> DataError:
    return DataError(f"the scale of stream b cannot be determined: {why}", "scale",
                     "record motion that translates the sensors (not only rotations in place), or give the "
                     "scale as a number with ⟦scale⟧")


def _gauss_newton_variance(fit: Any) -> float:
    """Variance of log s from the fit's Jacobian, ``σ̂² (JᵀJ)⁻¹`` (independent pairs)."""
    J = np.asarray(fit.jac, dtype=np.float64)          # method="lm": already a dense float array (no copy)
    cov = np.linalg.pinv(J.T @ J) * (2 * fit.cost / max(fit.fun.size - 7, 1))
    return max(float(cov[6, 6]), 0.0)


def _groups(samples: tuple[NDArray[np.int64], NDArray[np.int64]]) -> tuple[NDArray[np.int64], NDArray[np.int64], int]:
    """The group of each pair's two samples: the distinct samples in order, cut into at most
    ``_JACKKNIFE_GROUPS`` consecutive groups (stretches of time); and the number of groups."""
    i, j = samples
    distinct = np.unique(np.r_[i, j])
    group_of = np.zeros(int(distinct[-1]) + 1, dtype=np.int64)
    group_of[distinct] = np.arange(len(distinct)) * min(len(distinct), _JACKKNIFE_GROUPS) // len(distinct)
    return group_of[i], group_of[j], int(group_of[distinct].max()) + 1


def _jackknife_variance(gi: NDArray[np.int64], gj: NDArray[np.int64], groups: range,
                        refit: Callable[[NDArray[np.bool_]], float]) -> float:
    """Delete-a-group jackknife variance of log s over ``groups`` (module docstring), on the pairs whose two
    samples are both in them; ``refit(keep)`` is log s fitted on the pairs ``keep`` (a bool mask). Groups
    whose removal leaves fewer than 7 pairs are skipped; inf when fewer than two remain."""
    inside = np.isin(gi, groups) & np.isin(gj, groups)
    estimates = []
    for g in groups:
        keep = inside & (gi != g) & (gj != g)
        if keep.sum() >= 7:
            estimates.append(refit(keep))
    if len(estimates) < 2:
        return float("inf")
    theta = np.asarray(estimates)
    return float((len(theta) - 1) / len(theta) * np.sum((theta - theta.mean()) ** 2))


def _drift(gi: NDArray[np.int64], gj: NDArray[np.int64], count: int, log_s: float,
           refit: Callable[[NDArray[np.bool_]], float]) -> tuple[float, ScaleDrift] | None:
    """The drift term of the variance of log s and its report, from the halves' fits and their jackknife
    variances (module docstring); None when a half has too few pairs or groups to tell."""
    fits = []
    for groups in (range(0, count // 2), range(count // 2, count)):
        keep = np.isin(gi, groups) & np.isin(gj, groups)
        if len(groups) < 2 or keep.sum() < 7:
            return None
        var = _jackknife_variance(gi, gj, groups, refit)
        if not np.isfinite(var):
            return None
        fits.append((refit(keep), var))
    (t1, v1), (t2, v2) = fits
    excess = (t2 - t1) ** 2 - v1 - v2
    drift = excess if (t2 - t1) ** 2 > _DRIFT_Z ** 2 * (v1 + v2) else 0.0
    s = np.exp(log_s)
    return drift, ScaleDrift((float(np.exp(t1)), float(np.exp(t2))),
                             (float(np.exp(t1) * np.sqrt(v1)), float(np.exp(t2) * np.sqrt(v2))),
                             float(s * np.sqrt(drift)))


def _noise_of(translation_noise: tuple[NDArray[np.float64], NDArray[np.float64]] | None, n: int,
              s_lin: float) -> _Noise | None:
    """The checked per-pair translation variances (``solve_with_scale``'s ``translation_noise``), or None
    when not given or not positive (noise-free data: the plain residuals are then the same estimate)."""
    if translation_noise is None:
        return None
    var_a, var_b = (np.broadcast_to(np.asarray(v, dtype=np.float64), (n,)) for v in translation_noise)
    total = var_a + s_lin ** 2 * var_b
    if not (np.all(np.isfinite(total)) and np.all(var_a >= 0) and np.all(var_b >= 0) and np.all(total > 0)):
        return None
    return _Noise(var_a, var_b, float(np.median(total)))


def solve_with_scale(motions_a: NDArray[np.float64], motions_b: NDArray[np.float64], *, alpha: float = 1.0,
                     weights: NDArray[np.float64] | None = None,
                     samples: tuple[NDArray[np.int64], NDArray[np.int64]] | None = None,
                     translation_noise: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
                     ) -> ScaleSolution:
    """``T_a_b`` and the scale of b's translations (see the module docstring).

    Parameters
    ----------
    motions_a, motions_b: (N, 4, 4) motions; a in metres, b's translations in unknown units.
    alpha: weight of the translational residuals [1/m], as in cost (8).
    weights: optional (N,) non-negative pair weights.
    samples: optional sample indices (i, j) of each pair, to account for pairs sharing samples.
    translation_noise: optional per-pair (or scalar) per-axis variances of a's relative translation [m²]
        and of b's [unit²], for the errors-in-variables weighting (module docstring).

    Raises
    ------
    DataError: when the motions cannot determine the scale (no translation of b, or a scale
        known worse than ±50 %, or not positive).
    """
    from scipy.optimize import least_squares  # 0.1 s to import: only when a scale is solved for

    A, B, w = validate_motions(motions_a, motions_b, weights)
    if not np.any(np.linalg.norm(B[:, :3, 3], axis=1) * (w > 0) > 0):
        raise _undetermined("stream b does not translate")
    sw = np.sqrt(w)
    R_X = _rotation(A, B, w)
    t_X, s_lin = _linear(A, B, R_X, sw)
    if not s_lin > 0:
        raise _undetermined(f"the linear estimate is {s_lin:.3g}")
    p0 = np.r_[np.zeros(3), t_X, np.log(s_lin)]
    q0 = dq.from_matrix(R_X)
    noise = _noise_of(translation_noise, len(A), s_lin)
    fit = least_squares(_residuals, p0, args=(A, B, q0, alpha, sw, noise), method="lm", x_scale="jac")

    def refit(keep: NDArray[np.bool_]) -> float:
        return float(least_squares(_residuals, fit.x, args=(A[keep], B[keep], q0, alpha, sw[keep],
                                                             None if noise is None else noise.subset(keep)),
                                   method="lm", x_scale="jac").x[6])

    drift = None
    if samples is None:
        var_log_s = _gauss_newton_variance(fit)
    else:
        gi, gj, count = _groups(samples)
        var_log_s = _jackknife_variance(gi, gj, range(count), refit)
        found = _drift(gi, gj, count, float(fit.x[6]), refit) if np.isfinite(var_log_s) else None
        if found is not None:
            var_log_s += found[0]
            drift = found[1]
    scale = float(np.exp(fit.x[6]))
    of_data = scale * float(np.sqrt(var_log_s))           # d s = s d(log s)
    if not of_data <= _MAX_RELATIVE_STD * scale:
        raise _undetermined(f"estimate {scale:.3g} ± {of_data:.2g}")
    std = float(np.hypot(of_data, _REFERENCE_RELATIVE_STD * scale))
    X = np.eye(4)
    X[:3, :3] = _rotation_of(fit.x, q0)
    X[:3, 3] = fit.x[3:6]
    return ScaleSolution(X, scale, std, s_lin, float(fit.cost), of_data, drift)
