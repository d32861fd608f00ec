"""Maximum-likelihood refinement of ``X = T_a_b`` from a start (dqopt's optimum), weighed by the motions' noise.

Cost (8) weighs every pair's rotation and translation by one α. When the noise of the two streams
differs in kind — a camera whose rotation noise, carried to the motion's translation by the lever,
dwarfs its translation noise — that single weight cannot be right for every pair (issue 35: on real
data Park + LM beat dqopt in rotation). :func:`refine` minimises instead the first-order
errors-in-variables negative log-likelihood::

    J(X, s) = Σ_i r_iᵀ Σ_i(X, s)⁻¹ r_i,      Σ_i = J_a,i cov_a,i J_a,iᵀ + J_b,i cov_b,i J_b,iᵀ

with, for motions ``A_i = (R_A, t_A)``, ``B_i = (R_B, t_B)`` and ``X = (R, t)``, the residual of
``A_i X = X B_i`` (6-vector, rotation [rad] first, then translation [m])::

    r_rot = Log(Rᵀ R_A R R_Bᵀ)                (frame b at the pair's start)
    r_tra = R_A t + t_A − s R t_B − t        (frame a at the pair's start; s = 1 unless a scale is refined)

and ``J_a``, ``J_b`` the exact derivatives of ``r`` by the motions' noise at the measured motions.
Σ is evaluated afresh at each iterate (iteratively re-weighted generalised least squares); the
fixed point minimises ``Σ rᵀ Σ(X̂)⁻¹ r`` with Σ frozen at the answer (the log-determinant of Σ is
not part of the cost).

Two ways to weigh the pairs:

* :func:`refine` treats them as independent (block-diagonal Σ): right for motions that share no
  pose (a motion-pairs file). Pairs that share a pose (all-with-all, consecutive) are correlated,
  which neither its weights nor its covariance see: on look-at stations its 95 % ellipsoid held the
  truth in 97 % of 60 captures of disjoint pairs, 80 % with consecutive pairs, 7 % all with all.
* :func:`refine_poses` takes the poses themselves: the consecutive motions of the samples, whose
  residuals share one pose with each neighbour, so that Σ is block-tridiagonal, with the exact
  first-order covariance of neighbours (:func:`_chain_maps`), factored as a band (LAPACK ``pbtrf``,
  O(N)). With white pose noise, the consecutive motions carry all that every pair of the samples
  carries (any motion is a product of consecutive ones), so this is the maximum-likelihood estimate
  from the samples, whatever pairs a solver was given. A drift (noise that grows with the span, a
  random walk's independent increments) adds to each consecutive motion's own covariance.

Noise of a motion (:func:`motion_covariances`), ordered ``(ε_rot, ε_tra)``: the motion ``M = (R_M, t_M)``
is measured as ``(R_M Exp(ε_rot), t_M + ε_tra)``: ``ε_rot`` a rotation vector [rad] in the sensor's
frame at the pair's end (right perturbation), ``ε_tra`` [m] in its frame at the pair's start.

Unknowns: the right perturbation ``X ← (R Exp(ω), t + R v)`` (first order ``X Exp(δ)``, ``δ = (ω, v)``:
``ω`` a rotation vector [rad] in frame b, ``v`` [m] in frame b), and with a scale ``log s`` (s stays > 0);
Levenberg–Marquardt with the analytic Jacobian. Quaternions anywhere are x-y-z-w.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_solve_banded, cholesky_banded

from .._typing import BoolArray, FloatArray, IntArray
from ..errors import ConfigError, DataError, UnderdeterminedError
from ..geometry import dualquat as dq
from ..geometry import se3
from ..geometry.lie import skew
from .problem import validate_motions

__all__ = ["Chain", "Refined", "band_factor", "gaussian_terms", "motion_covariances", "refine", "refine_poses",
           "residual_covariances"]

_SMALL_ANGLE = 1e-4          # below it, the series of the inverse Jacobian's coefficient
_TOLERANCE = 1e-6            # converged: the Gauss–Newton step is this many standard deviations long (below it,
#                              the re-weighted iterations creep at rounding level)
_DAMPING = (1e-6, 1e12)      # Levenberg–Marquardt's first and largest damping (relative to diag H)


@dataclass(frozen=True, eq=False)
class Refined:
    """The result of :func:`refine`.

    matrix: (4, 4) ``T_a_b`` (pose of b in a, maps points b → a), metres.
    scale: b's translations are multiplied by it (metres per b unit), or None when not refined.
    cost_start, cost: ``Σ rᵀ Σ(X)⁻¹ r`` (Σ at that X; twice the negative log-likelihood without its
        log-determinant and constant) at the start and at the end; ≈ χ² with 6N − 6 (− 1) degrees of
        freedom when the noise model holds.
    iterations: Levenberg–Marquardt steps taken; converged: the last Gauss–Newton step was below
        ``tolerance`` standard deviations.
    covariance: (6, 6), or (7, 7) with a scale: ``(Jᵀ Σ⁻¹ J)⁻¹`` at the end (inverse Fisher information)
        of the perturbation ``(ω [rad], v [m] (, log s))``, ``ω`` and ``v`` in frame b (module docstring);
        optimistic where pairs share poses (module docstring).
    """

    matrix: FloatArray
    scale: float | None
    cost_start: float
    cost: float
    iterations: int
    converged: bool
    covariance: FloatArray

    @property
    def quaternion_xyzw(self) -> FloatArray:
        """Rotation of ``T_a_b`` as a unit quaternion x, y, z, w with w ≥ 0."""
        q: FloatArray = dq.from_matrix(self.matrix[:3, :3])
        return q


def motion_covariances(T_i: FloatArray, T_j: FloatArray, sigma_rotation: float, sigma_translation: float,
                       extra: FloatArray | None = None) -> FloatArray:
    """First-order covariances (N, 6, 6) of motions ``T_i⁻¹ T_j`` whose poses carry independent noise.

    Each pose ``T_w_s`` (N, 4, 4) is measured as ``T ∘ [Exp(φ) | δ]`` (``simulation.perturb``'s form, so its
    position moves by ``R δ``): ``φ`` a rotation vector [rad] in the sensor frame, ``δ`` [m], both
    isotropic with per-axis standard deviations ``sigma_rotation`` and ``sigma_translation`` (as
    :func:`~handeye_cli.analysis.stream_noise.stream_noise` gives them). ``simulation.perturb(σ_r, σ_t)``
    draws an angle of σ_r about a random axis: per axis that is ``σ_r / √3``, and ``σ_t``.

    The motion's noise (module docstring's ``(ε_rot, ε_tra)`` order) is ``ε_rot = φ_j − R_Mᵀ φ_i`` and
    ``ε_tra = [t_M]× φ_i − δ_i + R_M δ_j``: pose i's rotation noise turns the motion's translation by its
    lever, correlated with the motion's rotation noise (the maps of :func:`_chain_maps`). ``extra`` adds per pair a
    covariance of its own (drift that grows with the span): (N, 6, 6) as is, or (N, 2) per-axis variances [rad²,
    m²] added to the rotation and translation diagonals.
    """
    T_i, T_j = (np.asarray(T, dtype=np.float64) for T in (T_i, T_j))
    if T_i.ndim != 3 or T_i.shape[1:] != (4, 4) or T_j.shape != T_i.shape:
        raise DataError(f"poses of shapes {T_i.shape} and {T_j.shape}", "T_i, T_j",
                        "pass two (N, 4, 4) arrays of the same shape")
    if not (np.isfinite(T_i).all() and np.isfinite(T_j).all()):
        raise DataError("the poses contain NaN or inf", "T_i, T_j", "remove or repair those poses")
    sigmas = np.array([sigma_rotation, sigma_translation], dtype=np.float64)
    if not (np.isfinite(sigmas).all() and (sigmas >= 0).all()):
        raise ConfigError(f"noise σ {sigmas.tolist()}", "sigma_rotation, sigma_translation",
                          "give finite per-axis standard deviations ≥ 0 (rad, m)")
    pose = np.diag(np.repeat(sigmas ** 2, 3))
    S, E = _chain_maps(se3.relative(T_i, T_j))
    cov = S @ pose @ np.swapaxes(S, 1, 2) + E @ pose @ np.swapaxes(E, 1, 2)
    if extra is not None:
        cov += _extra(np.asarray(extra, dtype=np.float64), len(cov))
    return cov


def _extra(extra: FloatArray, n: int) -> FloatArray:
    """``motion_covariances``' extra term as (N, 6, 6), checked."""
    if not np.isfinite(extra).all():
        raise DataError("the extra covariance contains NaN or inf", "extra", "pass finite variances")
    if extra.shape == (n, 2):
        if (extra < 0).any():
            raise DataError("a negative extra variance", "extra", "pass variances ≥ 0 (rad², m²)")
        return np.asarray(np.repeat(extra, 3, axis=1)[:, :, None] * np.eye(6), dtype=np.float64)
    if extra.shape == (n, 6, 6):
        return extra
    raise DataError(f"extra has shape {extra.shape}", "extra", f"pass ({n}, 2) variances or ({n}, 6, 6) covariances")


def _inverse_jacobian(phi: FloatArray) -> FloatArray:
    """``J_l⁻¹(φ)`` (N, 3, 3) of SO(3) for rotation vectors (N, 3): ``Log(Exp(ε) Exp(φ)) ≈ φ + J_l⁻¹(φ) ε``
    (and ``J_r⁻¹(φ) = J_l⁻¹(φ)ᵀ`` for ``Log(Exp(φ) Exp(ε))``)."""
    theta = np.linalg.norm(phi, axis=1)
    small = theta < _SMALL_ANGLE
    th = np.where(small, 1.0, theta)
    c = np.where(small, 1.0 / 12.0 + theta ** 2 / 720.0,
                 1.0 / th ** 2 - (1.0 + np.cos(th)) / (2.0 * th * np.sin(th)))
    K = skew(phi)
    return np.asarray(np.eye(3) - 0.5 * K + c[:, None, None] * (K @ K), dtype=np.float64)


def _model(A: FloatArray, B: FloatArray, X: FloatArray, s: float
           ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Residuals r (N, 6), their Jacobian (N, 6, 7) by ``(ω, v, log s)`` and by the noise of A and B
    (N, 6, 6 each), at ``X`` and scale ``s`` (module docstring)."""
    R, t = X[:3, :3], X[:3, 3]
    Ra, ta, Rb, tb = A[:, :3, :3], A[:, :3, 3], B[:, :3, :3], B[:, :3, 3]
    C = R.T @ Ra @ R
    r_rot = dq.to_rotvec(dq.from_matrix(C @ np.swapaxes(Rb, 1, 2)))
    r_tra = Ra @ t + ta - s * tb @ R.T - t
    Jinv = _inverse_jacobian(r_rot)
    eye = np.eye(3)
    J = np.zeros((len(A), 6, 7))
    J[:, :3, :3] = Jinv @ (C - eye)
    J[:, 3:, :3] = s * R @ skew(tb)
    J[:, 3:, 3:6] = (Ra - eye) @ R
    J[:, 3:, 6] = -s * tb @ R.T
    Ja, Jb = np.zeros((len(A), 6, 6)), np.zeros((len(A), 6, 6))
    Ja[:, :3, :3] = Jinv @ R.T @ Ra
    Ja[:, 3:, :3] = -Ra @ skew(np.broadcast_to(t, ta.shape))
    Ja[:, 3:, 3:] = eye
    Jb[:, :3, :3] = -np.swapaxes(Jinv, 1, 2) @ Rb
    Jb[:, 3:, 3:] = -s * R
    return np.concatenate((r_rot, r_tra), axis=1), J, Ja, Jb


def _precisions(Ja: FloatArray, Jb: FloatArray, cov_a: FloatArray, cov_b: FloatArray) -> FloatArray:
    """``Σ_i⁻¹`` (N, 6, 6) of the residuals; refuses a singular Σ_i."""
    sigma = Ja @ cov_a @ np.swapaxes(Ja, 1, 2) + Jb @ cov_b @ np.swapaxes(Jb, 1, 2)
    sigma = 0.5 * (sigma + np.swapaxes(sigma, 1, 2))
    try:
        L_inv = np.linalg.inv(np.linalg.cholesky(sigma))
    except np.linalg.LinAlgError:
        raise DataError("a pair's residual covariance is singular", "cov_a, cov_b",
                        "give both streams rotation and translation noise > 0") from None
    return np.asarray(np.swapaxes(L_inv, 1, 2) @ L_inv, dtype=np.float64)


def residual_covariances(motions_a: FloatArray, motions_b: FloatArray, X: FloatArray, cov_a: FloatArray,
                         cov_b: FloatArray, scale: float | None = None) -> FloatArray:
    """``Σ_i`` (N, 6, 6) of the residuals ``(r_rot [rad], r_tra [m])`` at ``X`` (4, 4) and ``scale`` (module
    docstring), from the motions' noise ``cov_a``, ``cov_b`` (N, 6, 6) (:func:`motion_covariances`)."""
    A, B, X, ca, cb, s = _checked(motions_a, motions_b, X, cov_a, cov_b, scale)
    _, _, Ja, Jb = _model(A, B, X, s)
    return np.asarray(Ja @ ca @ np.swapaxes(Ja, 1, 2) + Jb @ cb @ np.swapaxes(Jb, 1, 2), dtype=np.float64)


def _checked(motions_a: FloatArray, motions_b: FloatArray, X0: FloatArray, cov_a: FloatArray, cov_b: FloatArray,
             scale: float | None) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, float]:
    """Checked motions, start (:func:`_start`) and motion covariances, as (N, …) arrays."""
    A, B, _ = validate_motions(motions_a, motions_b)
    X, s = _start(X0, scale)
    covs = [_covariances(c, len(A), name) for name, c in (("cov_a", cov_a), ("cov_b", cov_b))]
    return A, B, X, covs[0], covs[1], s


def _start(X0: FloatArray, scale: float | None) -> tuple[FloatArray, float]:
    """The start ``X0`` (4, 4) and scale (1 when None), checked."""
    X = np.asarray(X0, dtype=np.float64)
    if X.shape != (4, 4) or not np.isfinite(X).all() or not se3.is_rotation(X[:3, :3]):
        raise DataError("the start X0 is not a finite rigid transform (4, 4)", "X0", "pass dqopt's T_a_b")
    s = 1.0 if scale is None else float(scale)
    if not (np.isfinite(s) and s > 0):
        raise ConfigError(f"scale {scale!r}", "scale", "start the scale at a finite number > 0, or pass None")
    return X, s


def _moved(X: FloatArray, s: float, step: FloatArray) -> tuple[FloatArray, float]:
    """``(R Exp(ω), t + R v)`` and ``s·exp(step[6])`` (when refined)."""
    out = X.copy()
    out[:3, :3] = X[:3, :3] @ dq.to_matrix(dq.from_rotvec(step[:3]))
    out[:3, 3] = X[:3, 3] + X[:3, :3] @ step[3:6]
    return out, s * float(np.exp(step[6])) if len(step) > 6 else s


def refine(motions_a: FloatArray, motions_b: FloatArray, X0: FloatArray, cov_a: FloatArray, cov_b: FloatArray, *,
           scale: float | None = None, max_iterations: int = 50, tolerance: float = _TOLERANCE) -> Refined:
    """Refine ``X = T_a_b`` from ``X0`` by the maximum likelihood of the module docstring.

    Parameters
    ----------
    motions_a, motions_b:
        (N, 4, 4) motions ``A_i = T_wa(t_i)⁻¹ T_wa(t_j)``, ``B_i`` likewise; ``A_i X = X B_i``.
    X0:
        (4, 4) start, dqopt's optimum (a nearby start: the cost is minimised locally).
    cov_a, cov_b:
        (N, 6, 6) or (6, 6) covariances of each motion's noise ``(ε_rot [rad], ε_tra [m])``
        (:func:`motion_covariances`; b's translations in b's own units when a scale is refined).
    scale:
        None: b's translations are metres. A number > 0: the start of a scale ``s`` multiplying b's
        translations, refined with X.
    max_iterations, tolerance:
        Levenberg–Marquardt steps at most; converged when the Gauss–Newton step is shorter than
        ``tolerance`` standard deviations (``√(δᵀ H δ)``).

    Raises
    ------
    DataError
        Bad shapes or non-finite values, non-rotations, a singular residual covariance;
        :class:`~handeye_cli.errors.UnderdeterminedError` when the motions cannot determine X.
    ConfigError
        A bad scale start, ``max_iterations`` or ``tolerance``.
    """
    A, B, X, ca, cb, s = _checked(motions_a, motions_b, X0, cov_a, cov_b, scale)

    def weigh(Ja: FloatArray, Jb: FloatArray) -> _Precision:
        P = _precisions(Ja, Jb, ca, cb)
        return lambda M: np.asarray(P @ M.reshape(len(P), 6, -1), dtype=np.float64).reshape(M.shape)

    return _minimise(A, B, X, s, scale is not None, weigh, max_iterations, tolerance)


_Precision = Callable[[FloatArray], FloatArray]
"""``Σ⁻¹ M`` for a (6N, m) array M whose rows are the residuals' (pair by pair, rotation then translation)."""


def _minimise(A: FloatArray, B: FloatArray, X: FloatArray, s: float, scaled: bool,
              weigh: Callable[[FloatArray, FloatArray], _Precision], max_iterations: int, tolerance: float) -> Refined:
    """Levenberg–Marquardt on ``Σ rᵀ Σ(X)⁻¹ r`` from ``X`` (and the scale ``s`` when ``scaled``), ``weigh``
    giving Σ⁻¹ from the residuals' Jacobians by the noise of A and of B (each (N, 6, 6))."""
    if not (isinstance(max_iterations, (int, np.integer)) and max_iterations >= 0):
        raise ConfigError(f"max_iterations {max_iterations!r}", "max_iterations", "give a whole number ≥ 0")
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise ConfigError(f"tolerance {tolerance!r}", "tolerance", "give a number > 0")
    k = 7 if scaled else 6

    def state(X: FloatArray, s: float) -> tuple[_Precision, FloatArray, FloatArray, float]:
        r, J, Ja, Jb = _model(A, B, X, s)
        precision = weigh(Ja, Jb)
        rJ = np.concatenate((r.reshape(-1, 1), J[:, :, :k].reshape(-1, k)), axis=1)
        P = precision(rJ)
        return precision, rJ[:, 1:].T @ P[:, 1:], rJ[:, 1:].T @ P[:, 0], float(rJ[:, 0] @ P[:, 0])

    def frozen(X: FloatArray, s: float, precision: _Precision) -> float:
        r = _model(A, B, X, s)[0].reshape(-1, 1)
        return float((r.T @ precision(r))[0, 0])

    precision, H, g, cost = state(X, s)
    cost_start, damping, converged, iterations = cost, _DAMPING[0], False, 0
    while iterations < max_iterations:
        length = float(np.sqrt(max(-float(_solve(H, -g) @ g), 0.0)))     # √(δᵀHδ) of the Gauss–Newton step
        if length < tolerance:
            converged = True
            break
        while damping <= _DAMPING[1]:
            X_new, s_new = _moved(X, s, _solve(H + damping * np.diag(np.diag(H)), -g))
            if frozen(X_new, s_new, precision) <= cost:
                break
            damping *= 10.0
        else:                                     # no step lowers the cost: rounding level
            converged = length < 1e3 * tolerance
            break
        X, s, iterations = X_new, s_new, iterations + 1
        damping = max(damping / 10.0, _DAMPING[0])
        precision, H, g, cost = state(X, s)
    return Refined(X, s if scaled else None, cost_start, cost, iterations, converged,
                   np.asarray(np.linalg.inv(H), dtype=np.float64))


def _chain_maps(M: FloatArray) -> tuple[FloatArray, FloatArray]:
    """For consecutive motions ``M_p = T_p⁻¹ T_(p+1)`` (P, 4, 4): the maps (P, 6, 6 each) of the start pose's
    and of the end pose's noise ``n = (φ, δ)`` (:func:`motion_covariances`' form) to the motion's noise
    ``ε_p = S_p n_p + E_p n_(p+1)``, ``ε = (ε_rot, ε_tra)``: ``S = [[−R_Mᵀ, 0], [[t_M]×, −I]]``,
    ``E = [[I, 0], [0, R_M]]``."""
    R = M[:, :3, :3]
    S, E = np.zeros((len(M), 6, 6)), np.zeros((len(M), 6, 6))
    S[:, :3, :3] = -np.swapaxes(R, 1, 2)
    S[:, 3:, :3] = skew(M[:, :3, 3])
    S[:, 3:, 3:] = -np.eye(3)
    E[:, :3, :3] = np.eye(3)
    E[:, 3:, 3:] = R
    return S, E


def _band(D: FloatArray, U: FloatArray) -> FloatArray:
    """The lower band (12, 6P) (``scipy.linalg.cholesky_banded``'s layout) of the symmetric block-tridiagonal
    matrix with diagonal blocks ``D`` (P, 6, 6) and upper blocks ``U`` (P − 1, 6, 6): ``U_p = Σ_(p, p+1)``."""
    P = len(D)
    band = np.zeros((12, 6 * P))
    r, c = np.tril_indices(6)
    band[(r - c)[:, None], 6 * np.arange(P) + c[:, None]] = D[:, r, c].T
    r, c = np.indices((6, 6)).reshape(2, -1)
    band[(6 + r - c)[:, None], 6 * np.arange(P - 1) + c[:, None]] = U[:, c, r].T      # Σ_(p+1, p) = U_pᵀ
    return band


@dataclass(frozen=True, eq=False)
class Chain:
    """The consecutive motions of S samples in time order, ``A_m = T_a(p_m)⁻¹ T_a(p_m + 1)`` and ``B_m`` likewise,
    for the samples ``p_m`` whose successor is in the same tracking segment (motions are never formed across a
    re-localisation); ``adjacent[m]``: motions m and m + 1 share the pose ``p_m + 1``. ``maps``: a's and b's
    (start, end) maps of the poses' noise to the motions' (:func:`_chain_maps`)."""

    A: FloatArray
    B: FloatArray
    start: IntArray
    adjacent: BoolArray
    samples: int
    maps: tuple[tuple[FloatArray, FloatArray], tuple[FloatArray, FloatArray]]

    @classmethod
    def of(cls, poses_a: FloatArray, poses_b: FloatArray, segment: IntArray | None = None) -> Chain:
        """The chain of poses (S, 4, 4) each, ``T_wa_a`` and ``T_wb_b`` at the same instants, with their
        ``segment`` (S,) (None: one segment); at least two motions."""
        Ta, Tb = (np.asarray(T, dtype=np.float64) for T in (poses_a, poses_b))
        if Ta.ndim != 3 or Ta.shape[1:] != (4, 4) or Tb.shape != Ta.shape:
            raise DataError(f"poses of shapes {Ta.shape} and {Tb.shape}", "poses_a, poses_b",
                            "pass two (S, 4, 4) arrays of the same S instants")
        seg = np.zeros(len(Ta), dtype=np.int64) if segment is None else np.asarray(segment, dtype=np.int64)
        if seg.shape != (len(Ta),):
            raise DataError(f"segment has shape {seg.shape}", "segment", f"pass ({len(Ta)},) segment numbers")
        start = np.flatnonzero(seg[:-1] == seg[1:]) if len(Ta) > 1 else np.zeros(0, dtype=np.int64)
        if len(start) < 2:
            raise DataError(f"{len(start)} consecutive motions within a segment", "poses_a, poses_b",
                            "pass at least three samples of one tracking segment")
        A, B, _ = validate_motions(se3.relative(Ta[start], Ta[start + 1]), se3.relative(Tb[start], Tb[start + 1]))
        return cls(A, B, start, np.diff(start) == 1, len(Ta), (_chain_maps(A), _chain_maps(B)))

    def blocks(self, Ja: FloatArray, Jb: FloatArray, noise_a: FloatArray | None, noise_b: FloatArray | None,
               drift_a: FloatArray | None = None, drift_b: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
        """The residuals' covariance as its diagonal blocks (M, 6, 6) and upper blocks (M − 1, 6, 6) (zero between
        motions that share no pose), from the residuals' Jacobians by a's and b's motion noise ``Ja``, ``Jb``
        (M, 6, 6), the poses' white noise (S, 6, 6) and each motion's own (M, 6, 6) or (M, 2) per-axis variances
        [rad², m²] (None: none)."""
        D, U = np.zeros((len(self.A), 6, 6)), np.zeros((len(self.A) - 1, 6, 6))
        p = self.start
        for J, (S, E), C, extra in zip((Ja, Jb), self.maps, (noise_a, noise_b), (drift_a, drift_b), strict=True):
            if C is not None:
                start, end = J @ S, J @ E                  # the residual's maps of its start and end pose's noise
                D += start @ C[p] @ np.swapaxes(start, 1, 2) + end @ C[p + 1] @ np.swapaxes(end, 1, 2)
                U += end[:-1] @ C[p[:-1] + 1] @ np.swapaxes(start[1:], 1, 2) * self.adjacent[:, None, None]
            if extra is not None:
                D += J @ _extra(np.asarray(extra, dtype=np.float64), len(J)) @ np.swapaxes(J, 1, 2)
        return 0.5 * (D + np.swapaxes(D, 1, 2)), U

    def residuals(self, X: FloatArray, scale: float | None = None) -> tuple[FloatArray, FloatArray, FloatArray]:
        """At ``X`` (and b's ``scale``): the residuals (M, 6) and their Jacobians by a's and b's motion noise."""
        r, _, Ja, Jb = _model(self.A, self.B, X, 1.0 if scale is None else scale)
        return r, Ja, Jb


def band_factor(D: FloatArray, U: FloatArray) -> FloatArray:
    """The lower Cholesky factor, as a band (:func:`scipy.linalg.cholesky_banded`), of the block-tridiagonal
    covariance with diagonal blocks ``D`` and upper blocks ``U`` (:meth:`Chain.blocks`); refuses a singular one."""
    try:
        return np.asarray(cholesky_banded(_band(D, U), lower=True), dtype=np.float64)
    except np.linalg.LinAlgError:
        raise DataError("the residuals' covariance is singular", "noise_a, noise_b",
                        "give both streams rotation and translation noise > 0") from None


def gaussian_terms(r: FloatArray, factor: FloatArray) -> tuple[float, float]:
    """``(rᵀ Σ⁻¹ r, log det Σ)`` of residuals r (M, 6) under the covariance whose :func:`band_factor` is given:
    twice the Gaussian negative log-likelihood is their sum (plus a constant)."""
    flat = r.reshape(-1)
    return float(flat @ cho_solve_banded((factor, True), flat)), float(2.0 * np.log(factor[0]).sum())


def refine_poses(chain: Chain, X0: FloatArray, noise_a: FloatArray, noise_b: FloatArray, *,
                 drift_a: FloatArray | None = None, drift_b: FloatArray | None = None, scale: float | None = None,
                 max_iterations: int = 50, tolerance: float = _TOLERANCE) -> Refined:
    """Refine ``X = T_a_b`` from ``X0`` by the maximum likelihood of the samples' poses (module docstring).

    Parameters
    ----------
    chain:
        The samples' consecutive motions (:meth:`Chain.of`: synced samples, or the averaged stations of a capture).
    X0:
        (4, 4) start, dqopt's optimum.
    noise_a, noise_b:
        (S, 6, 6) or (6, 6) covariance of each pose's white noise ``(φ [rad], δ [m])``, the pose measured as
        ``T ∘ [Exp(φ) | δ]`` (:func:`motion_covariances`' form; b's units when a scale is refined).
    drift_a, drift_b:
        Optional noise of each consecutive motion of its own, independent from motion to motion (a random walk's
        increments): (M, 6, 6), or (M, 2) per-axis variances [rad², m²] (:func:`motion_covariances`), M the
        chain's motions.
    scale, max_iterations, tolerance:
        As :func:`refine`.
    """
    noise_a, noise_b = _covariances(noise_a, chain.samples, "noise_a"), _covariances(noise_b, chain.samples, "noise_b")
    X, s = _start(X0, scale)                  # the chain's motions are checked already (Chain.of)

    def weigh(Ja: FloatArray, Jb: FloatArray) -> _Precision:
        factor = band_factor(*chain.blocks(Ja, Jb, noise_a, noise_b, drift_a, drift_b))
        return lambda M: np.asarray(cho_solve_banded((factor, True), M), dtype=np.float64)

    return _minimise(chain.A, chain.B, X, s, scale is not None, weigh, max_iterations, tolerance)


def _covariances(c: FloatArray, n: int, name: str) -> FloatArray:
    """A (6, 6) or (n, 6, 6) covariance argument as (n, 6, 6), checked."""
    c = np.asarray(c, dtype=np.float64)
    if c.shape not in ((6, 6), (n, 6, 6)):
        raise DataError(f"{name} has shape {c.shape}", name, f"pass (6, 6) or ({n}, 6, 6) covariances")
    if not np.isfinite(c).all():
        raise DataError(f"{name} contains NaN or inf", name, "pass finite covariances")
    return np.broadcast_to(c, (n, 6, 6))


def _solve(H: FloatArray, y: FloatArray) -> FloatArray:
    """``H⁻¹ y`` for the normal matrix, refusing one the motions leave singular."""
    w = np.linalg.eigvalsh(H)
    if not w[0] > 1e-12 * w[-1]:
        raise UnderdeterminedError("the motions cannot determine the extrinsic (the normal matrix is singular)",
                                   "motions", "add motion about a second rotation axis")
    return np.asarray(np.linalg.solve(H, y), dtype=np.float64)
