"""Which parts of ``X = T_a_b`` the motions can determine, and warnings that name the rest.

Conventions: ``X = T_a_b`` (maps frame b to frame a), ``A_i X = X B_i``; directions are unit
vectors in frame a (``direction_a``) and frame b (``direction_b = R_Xᵀ direction_a``); angles in
degrees in messages, translations in metres.

Two kinds of evidence:

* **Geometry of the motions** (classic hand-eye observability, cf. the paper's degenerate
  "line" and "circle" scenarios): if every motion rotates about one axis ``n``, then
  ``t_X + c n`` fits as well as ``t_X`` (since ``R_A n = n``), so translation along ``n`` is
  unobservable; if in addition every motion is a rotation about one fixed *line*
  (``t_A = (I - R_A) p``), rotation of X about ``n`` is unobservable too. Without rotation,
  no translation is observable, and rotation about a common travel direction is not either.
* **Conditioning of cost (8)**: the sandwich covariance of :mod:`.covariance` at the estimate.
  A null direction of its Hessian, or a predicted standard deviation above a limit, is reported
  as a direction in frame a.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..errors import HandEyeError, UnderdeterminedError
from ..geometry import dualquat as dq
from ..geometry import se3
from ..solvers import Prior, build_problem, solve
from ..solvers.approximate import dqconvrlx
from ..solvers.problem import validate_motions
from .covariance import LinearCovariance, linear_covariance, select_samples

__all__ = ["ObservabilityWarning", "Observability", "assess_observability", "common_axis", "describe_direction"]

PRIOR_HINT = "pass ⟦prior=FILE⟧ (a known approximate extrinsic) to fix it"
PRIOR_GIVEN = "rely on the given prior, which alone determines it"
MIN_ROTATION_DEG = 1.0          # motions below this count as not rotating
MAX_AXIS_SPREAD_DEG = 2.0       # rotation axes spread less than this: one common axis (single_axis / planar)
NOISE_SPREAD = 4.0              # ... or spread across it by at most this many times a's rotation noise energy


@dataclass(frozen=True)
class ObservabilityWarning:
    """One finding: a stable ``code``, a human ``message`` naming what cannot be observed, a ``remedy``.

    ``kind`` is ``"translation"`` or ``"rotation"`` when a direction is named (``direction_a``
    in frame a, ``direction_b`` in frame b, unit vectors), else ``None``. Codes:
    ``too_few_pairs``, ``pure_translation``, ``small_rotations``, ``single_axis``, ``planar``,
    ``fixed_rotation_line``, ``unobservable``, ``ill_conditioned``.
    """

    code: str
    message: str
    remedy: str
    kind: str | None = None
    direction_a: tuple[float, float, float] | None = None
    direction_b: tuple[float, float, float] | None = None

    def __str__(self) -> str:
        return f"{self.message}; {self.remedy}"

    def refusal(self) -> UnderdeterminedError:
        """This finding as the refusal of a result that would rest on what it names (one line, exit 2)."""
        return UnderdeterminedError(self.message.replace("is unobservable", "is not determined by the motion"),
                                    "observability", self.remedy)

    def as_dict(self) -> dict[str, Any]:
        """Plain dict for the result file."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}


@dataclass(frozen=True, eq=False)
class Observability:
    """Result of :func:`assess_observability`.

    Attributes
    ----------
    warnings:
        The findings, most fundamental first.
    pairs, rotating_pairs:
        Pairs considered, and those rotating by at least the ``min_rotation_deg`` threshold.
    rotation_median_deg:
        Median rotation angle of the motions [deg].
    axis_a, axis_spread_deg:
        Dominant rotation axis of the motions of a (unit, frame a) and the angle-weighted RMS
        deviation of the axes from it [deg] (``None`` / nan without rotating pairs).
    covariance:
        The sandwich covariance at the estimate, or ``None`` if it could not be formed.
    """

    warnings: tuple[ObservabilityWarning, ...]
    pairs: int
    rotating_pairs: int
    rotation_median_deg: float
    axis_a: FloatArray | None
    axis_spread_deg: float
    covariance: LinearCovariance | None

    @property
    def ok(self) -> bool:
        """True when there is nothing to warn about (``--strict`` exits 3 otherwise)."""
        return not self.warnings

    @property
    def codes(self) -> list[str]:
        """The warning codes, in order."""
        return [w.code for w in self.warnings]

    def as_dict(self) -> dict[str, Any]:
        """Plain summary for the result file."""
        out: dict[str, Any] = {"pairs": self.pairs, "rotating_pairs": self.rotating_pairs,
               "rotation_median_deg": self.rotation_median_deg,
               "axis_a": None if self.axis_a is None else self.axis_a.tolist(),
               "axis_spread_deg": self.axis_spread_deg,
               "warnings": [w.as_dict() for w in self.warnings]}
        if self.covariance is not None:
            out["predicted_rotation_std_deg"] = self.covariance.rotation_std_deg.tolist()
            out["predicted_translation_std_m"] = self.covariance.translation_std_m.tolist()
        return out


def describe_direction(v: FloatArray, frame: str) -> str:
    """``"z of frame a"`` when ``v`` is within 15° of an axis (sign ignored), else the components."""
    v = np.asarray(v, dtype=np.float64) / np.linalg.norm(v)
    i = int(np.argmax(np.abs(v)))
    if abs(v[i]) >= np.cos(np.deg2rad(15.0)):
        return f"{'xyz'[i]} of frame {frame}"
    v = v if v[i] > 0 else -v
    return f"direction [{v[0]:.2f}, {v[1]:.2f}, {v[2]:.2f}] of frame {frame}"


def _principal(vectors: FloatArray) -> tuple[FloatArray, float]:
    """Dominant direction of (K, 3) vectors (sign-free) and the RMS angle [deg] of their spread about it."""
    lam, V = np.linalg.eigh(vectors.T @ vectors)
    spread = np.degrees(np.arctan(np.sqrt(max(lam[0] + lam[1], 0.0) / max(lam[2], 1e-300))))
    return V[:, 2], float(spread)


def _rotations(A: FloatArray, B: FloatArray, min_rotation_deg: float) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Rotation vectors of the motions of a (N, 3) [rad], each pair's rotation angle (mean of a's and b's)
    [deg], and which pairs rotate by at least ``min_rotation_deg``."""
    rotvec = dq.to_rotvec(dq.from_matrix(A[:, :3, :3]))
    angles = np.degrees(0.5 * (np.linalg.norm(rotvec, axis=1) + se3.rotation_angle(B)))
    return rotvec, angles, angles >= min_rotation_deg


def common_axis(motions_a: FloatArray, motions_b: FloatArray, *, min_rotation_deg: float = MIN_ROTATION_DEG,
                max_axis_spread_deg: float = MAX_AXIS_SPREAD_DEG) -> FloatArray | None:
    """The common rotation axis (unit, frame a) when the motions that rotate all rotate about one axis
    (the ``single_axis`` / ``planar`` finding of :func:`assess_observability`, with the same thresholds),
    else ``None``. Translation of ``X`` along it does not change the fit (``R_A n = n``).

    ``motions_a``, ``motions_b``: (N, 4, 4) motions, ``A_i X = X B_i``."""
    rotvec, _, rotating = _rotations(np.asarray(motions_a, dtype=np.float64),
                                     np.asarray(motions_b, dtype=np.float64), min_rotation_deg)
    if not rotating.any():
        return None
    axis, spread = _principal(rotvec[rotating])
    return axis if spread < max_axis_spread_deg else None


def _warning(code: str, message: str, remedy: str, kind: str | None = None,
             d_a: FloatArray | None = None, R_x: FloatArray | None = None) -> ObservabilityWarning:
    """Build a warning; frame-b direction is ``R_Xᵀ d_a`` when the rotation of X is known."""
    if d_a is None:
        return ObservabilityWarning(code, message, remedy, kind)
    d_b = None if R_x is None else _vec3(R_x.T @ d_a)
    return ObservabilityWarning(code, message, remedy, kind, _vec3(d_a), d_b)


def _vec3(v: FloatArray) -> tuple[float, float, float]:
    """A 3-vector as a tuple of Python floats."""
    x, y, z = (float(c) for c in v)
    return x, y, z


def _estimate(A: FloatArray, B: FloatArray, alpha: float, prior: Prior | None, w: FloatArray) -> FloatArray:
    """DQOpt estimate, or the DQConvRlx one (Alg. 3) when the solver refuses a degenerate problem."""
    try:
        return solve(A, B, alpha=alpha, prior=prior, weights=w).matrix
    except UnderdeterminedError:
        r = dqconvrlx(build_problem(A, B, alpha=alpha, prior=prior, weights=w))
        return dq.to_transform(r.q, r.qd)


def _pure_translation(A: FloatArray, angles: FloatArray, max_spread: float,
                      R_x: FloatArray) -> list[ObservabilityWarning]:
    """Warnings when no motion rotates: all translation, and rotation about a common travel line."""
    n = len(A)
    out = [_warning("pure_translation",
                    f"translation of the extrinsic is unobservable along all axes: none of the {n} motions "
                    f"rotates (largest rotation {angles.max():.2f}°)",
                    f"rotate the rig between samples, about two different axes, or {PRIOR_HINT}", "translation")]
    t = A[:, :3, 3]
    moving = np.linalg.norm(t, axis=1) > 0
    if moving.sum() >= 1:
        d, spread = _principal(t[moving])
        if spread < max_spread:
            out.append(_warning("pure_translation",
                                f"rotation of the extrinsic about the travel direction ({describe_direction(d, 'a')}) "
                                f"is unobservable: all {int(moving.sum())} motions translate along one line "
                                f"(spread {spread:.2f}°)",
                                f"move in a second direction and rotate the rig, or {PRIOR_HINT}", "rotation", d, R_x))
    return out


def _fixed_line_residual(A: FloatArray, axis: FloatArray) -> float:
    """How far the motions are from rotations about one fixed line ``t_A = (I - R_A) p`` (0 = exactly)."""
    P = np.eye(3) - np.outer(axis, axis)
    t = A[:, :3, 3] @ P                                           # translation across the axis
    M = (np.eye(3) - A[:, :3, :3]) @ P                            # (I - R_A) restricted to the plane
    p = np.linalg.lstsq(M.reshape(-1, 3), t.reshape(-1), rcond=None)[0]
    res = t - M @ p
    scale = np.sqrt(np.mean(np.sum(t * t, axis=1)))
    return float(np.sqrt(np.mean(np.sum(res * res, axis=1))) / scale) if scale > 0 else 0.0


def _single_axis(A: FloatArray, total: int, axis: FloatArray, spread: float, max_spread: float,
                 line_tol: float, R_x: FloatArray) -> list[ObservabilityWarning]:
    """Warnings for rotating motions ``A`` (of ``total``) that all rotate about one axis (e.g. planar motion)."""
    n = len(A)
    t = A[:, :3, 3]
    along = np.sqrt(np.mean((t @ axis) ** 2))
    planar = along <= np.tan(np.deg2rad(max_spread)) * max(np.sqrt(np.mean(np.sum(t * t, 1))), 1e-300)
    name = describe_direction(axis, "a")
    code = "planar" if planar else "single_axis"
    who = f"all {n} motions" if n == total else f"all {n} motions that rotate (of {total})"
    what = who + " rotate about one axis" + (" and translate in the plane across it" if planar else "")
    out = [_warning(code, f"translation along the common rotation axis ({name}) is unobservable: {what} "
                          f"(spread {spread:.2f}°)",
                    f"add rotation about another axis (tilt or roll the rig), or {PRIOR_HINT}",
                    "translation", axis, R_x)]
    rel = _fixed_line_residual(A, axis)
    if rel <= line_tol:
        out.append(_warning("fixed_rotation_line",
                            f"rotation of the extrinsic about the common rotation axis ({name}) is unobservable: "
                            f"every motion is a rotation about one fixed line (off by {100 * rel:.1f}% of the "
                            "translations)", f"also translate the rig without turning about that line, rotate "
                            f"about another axis, or {PRIOR_HINT}", "rotation", axis, R_x))
    return out


def _already_named(named: list[ObservabilityWarning], kind: str, d: FloatArray) -> bool:
    """Whether a warning of this kind covers direction ``d`` (no direction = all directions)."""
    return any(w.kind == kind and (w.direction_a is None or abs(np.dot(w.direction_a, d)) > np.cos(np.deg2rad(20.0)))
               for w in named)


def _weak_directions(cov: LinearCovariance, block: slice, limit: float) -> list[tuple[FloatArray, float, bool]]:
    """(direction, predicted std, null) for the Hessian's null directions, else covariance axes above ``limit``."""
    hv, hV = np.linalg.eigh(cov.hessian[block, block])
    null = hv <= 1e-9 * max(abs(cov.hessian).max(), 1e-300)
    if null.any():
        return [(hV[:, i], float("inf"), True) for i in np.flatnonzero(null)]
    var, V = np.linalg.eigh(cov.covariance[block, block])
    std = np.sqrt(np.clip(var, 0.0, None))
    return [(V[:, i], float(std[i]), False) for i in np.argsort(-std) if std[i] > limit]


def _covariance_warnings(cov: LinearCovariance, R_x: FloatArray, max_rot_deg: float, max_trans_m: float,
                         named: list[ObservabilityWarning]) -> list[ObservabilityWarning]:
    """Null or weak directions of the sandwich covariance not already named by a geometric warning."""
    out: list[ObservabilityWarning] = []
    for kind, block, limit in (("rotation", slice(0, 3), np.deg2rad(max_rot_deg)),
                               ("translation", slice(3, 6), max_trans_m)):
        for d, std, null in _weak_directions(cov, block, limit):
            if _already_named(named + out, kind, d):
                continue
            what = f"{kind} {'about' if kind == 'rotation' else 'along'} {describe_direction(d, 'a')}"
            shown = f"{np.rad2deg(std):.3g}°" if kind == "rotation" else f"{std:.3g} m"
            if null:
                out.append(_warning("unobservable", f"{what} is unobservable: cost (8) is flat in that direction",
                                    f"add motion that excites it, or {PRIOR_HINT}", kind, d, R_x))
            else:
                out.append(_warning("ill_conditioned", f"{what} is poorly determined: predicted standard "
                                    f"deviation {shown}", f"add motion that excites it, or {PRIOR_HINT}",
                                    kind, d, R_x))
    return out


def _rotation_checks(A: FloatArray, rotvec: FloatArray, angles: FloatArray, rotating: BoolArray,
                     noise: FloatArray | None, R_x: FloatArray, small_rotation_deg: float, max_axis_spread_deg: float,
                     fixed_line_tolerance: float) -> tuple[FloatArray | None, float, list[ObservabilityWarning]]:
    """The principal rotation axis, its spread [deg] and the warnings about how the motions rotate:
    not at all, too little, or about a single axis (``noise``: a's per-pair rotation variance, or None)."""
    if not rotating.any():
        return None, float("nan"), _pure_translation(A, angles, max_axis_spread_deg, R_x)
    found: list[ObservabilityWarning] = []
    axis, spread = _principal(rotvec[rotating])
    if float(np.median(angles)) < small_rotation_deg:
        found.append(_warning("small_rotations", f"the motions rotate little (median {np.median(angles):.2f}°, "
                              f"{100 * np.mean(angles < small_rotation_deg):.0f}% below {small_rotation_deg:g}°): "
                              "the extrinsic is sensitive to noise", "pair samples further apart in time, "
                              "or rotate the rig more"))
    if spread < max_axis_spread_deg or (noise is not None and _spread_is_noise(rotvec[rotating], axis,
                                                                                noise[rotating])):
        found += _single_axis(A[rotating], len(A), axis, spread, max_axis_spread_deg, fixed_line_tolerance, R_x)
    return axis, spread, found


def _spread_is_noise(rotvec: FloatArray, axis: FloatArray, noise: FloatArray) -> bool:
    """Whether the rotating motions' spread about ``axis`` is a's rotation noise: the median energy [rad²] of a's
    rotation vectors ``rotvec`` across the axis within :data:`NOISE_SPREAD` times the median of what a's noise puts
    there, ``2 · noise`` (``noise``: each pair's per-axis variance of a's rotation [rad²], from the stream's own
    jitter; two axes across). Small rotations about one axis (consecutive samples) spread by their noise by degrees:
    an arm turned about one joint, paired sample by sample at 10 Hz with 0.2° of noise, spread 7–14° about it,
    and the translation along it, which the motion does not determine, was left unnamed, 45 mm off."""
    across = rotvec - np.outer(rotvec @ axis, axis)
    return bool(np.median(np.sum(across * across, axis=1)) <= NOISE_SPREAD * np.median(2.0 * noise))


def assess_observability(motions_a: FloatArray, motions_b: FloatArray, T_a_b: FloatArray | None = None, *,
                         alpha: float = 1.0, prior: Prior | None = None, weights: FloatArray | None = None,
                         min_pairs: int = 10, min_rotation_deg: float = MIN_ROTATION_DEG,
                         small_rotation_deg: float = 2.0, max_axis_spread_deg: float = MAX_AXIS_SPREAD_DEG,
                         fixed_line_tolerance: float = 0.02,
                         max_rotation_std_deg: float = 1.0, max_translation_std_m: float = 0.05,
                         samples: tuple[IntArray, IntArray] | None = None,
                         rotation_noise: FloatArray | None = None) -> Observability:
    """Detect degenerate motion and name the unobservable directions of ``T_a_b``.

    Parameters
    ----------
    motions_a, motions_b:
        (N, 4, 4) relative motions, ``A_i X = X B_i``.
    T_a_b:
        The estimate, if already solved; otherwise DQOpt (or DQConvRlx on degenerate data) is run.
    alpha, prior, weights:
        As for :func:`handeye_cli.solvers.solve`; pairs with zero weight are ignored.
    min_pairs:
        Fewer pairs than this → ``too_few_pairs``.
    min_rotation_deg, small_rotation_deg:
        Motions below ``min_rotation_deg`` count as not rotating (none rotating →
        ``pure_translation``); a median below ``small_rotation_deg`` → ``small_rotations``.
    max_axis_spread_deg:
        Rotation axes spread less than this (angle-weighted RMS) → ``single_axis`` / ``planar``.
    fixed_line_tolerance:
        Relative misfit below which single-axis motions count as rotations about one fixed line.
    max_rotation_std_deg, max_translation_std_m:
        Predicted standard deviations above these → ``ill_conditioned``.
    samples:
        Optional ``(i, j)`` pose-sample indices of each pair, for the dyadic-robust covariance
        when pairs share samples (see :func:`.linear_covariance`).
    rotation_noise:
        Optional per-pair per-axis variance of a's rotation [rad²] (its samples' jitter): axes spread by no
        more than it (:data:`NOISE_SPREAD`) are one axis too, whatever ``max_axis_spread_deg`` says.

    Returns
    -------
    :class:`Observability`; ``ok`` is False when any warning was raised.
    """
    A, B, w = validate_motions(motions_a, motions_b, weights)
    keep = w > 0
    A, B, w = A[keep], B[keep], w[keep]
    noise = None if rotation_noise is None else np.asarray(rotation_noise, dtype=np.float64)[keep]
    samples = select_samples(samples, keep)
    X = np.asarray(T_a_b, dtype=np.float64) if T_a_b is not None else _estimate(A, B, alpha, prior, w)
    R_x = X[:3, :3]
    rotvec, angles, rotating = _rotations(A, B, min_rotation_deg)
    found: list[ObservabilityWarning] = []
    if len(A) < min_pairs:
        found.append(_warning("too_few_pairs", f"only {len(A)} motion pairs", "record more motion, or pair "
                              f"more samples (at least {min_pairs} pairs are advised)"))
    axis, spread, rotation_warnings = _rotation_checks(A, rotvec, angles, rotating, noise, R_x, small_rotation_deg,
                                                       max_axis_spread_deg, fixed_line_tolerance)
    found += rotation_warnings
    try:
        cov = linear_covariance(A, B, X, alpha=alpha, prior=prior, weights=w, samples=samples)
    except (HandEyeError, np.linalg.LinAlgError):
        cov = None
    if cov is not None:
        found += _covariance_warnings(cov, R_x, max_rotation_std_deg, max_translation_std_m, found)
    if prior is not None:
        found = [replace(w, remedy=w.remedy.replace(PRIOR_HINT, PRIOR_GIVEN)) for w in found]
    return Observability(tuple(found), int(len(A)), int(rotating.sum()), float(np.median(angles)),
                         axis, spread, cov)
