"""Which degrees of freedom of ``X = T_a_b`` the motions determine, and a reduced solve for planar motion.

Conventions: ``X = T_a_b`` (maps frame b to frame a), ``A_i X = X B_i``. The degrees of freedom
are those of a URDF joint origin in frame a: translation ``x, y, z`` [m] and roll-pitch-yaw
[deg] with ``R_X = Rz(yaw) Ry(pitch) Rx(roll)``.

When every motion rotates about one axis ``n_a`` (a ground robot: z of base_link), cost (8) of
the paper is flat along ``t_X + c n_a`` and the full solve's value there is the solver's
null-space choice, not a measurement. The **reduced in-plane solve** here estimates only what
the motion determines:

* roll and pitch from the alignment of the rotation axes, ``R_X n_b = n_a`` (``n_b`` the
  principal rotation axis of b), when both are measured well (predicted tilt standard deviation
  ≤ ``max_tilt_std_deg``), else from the nominal;
* yaw (rotation about ``n_a``) and the translation across ``n_a`` from the translation rows
  ``(R_A − I) t_X = R_X t_B − t_A`` (paper eq 4), a 3-parameter nonlinear least squares;
* the translation along ``n_a`` from the nominal (``from_prior``), failing that the full
  solve's value marked ``unobservable``.

Why this and not the prior term (eq 26): the prior term adds ``a δqᵀGδq + b|δq'|²`` to every
direction, so a wrong nominal pulls the determined degrees of freedom by an amount that depends
on the weights and the number of pairs, and the weakly determined ones end up a blend of data
and nominal that cannot be labelled either. The reduced solve keeps the two apart exactly: the
estimated degrees of freedom do not depend on the nominal at all, the others equal it. Measured
on :func:`~handeye_cli.simulation.ground.simulate_ground` diff-drive seeds 0–2 with a nominal
wrong by yaw +1°, pitch +1°, y +2 cm: eq 26 at weights (1, 1) moves yaw by up to 0.34° and the
plane by 4 mm; at (0.01, 0.01) z no longer reaches the nominal (330 mm off on seed 0); the reduced
solve: yaw within 0.005°, the plane within 0.4 mm, z equal to the nominal.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._typing import FloatArray
from ..geometry import dualquat as dq
from .covariance import LinearCovariance
from .observability import Observability, describe_direction

__all__ = ["DOF_NAMES", "Dof", "Subspace", "observable_subspace", "all_estimated", "dof_values", "from_values",
           "with_values_of", "ESTIMATED", "ADVICE"]

DOF_NAMES = ("x", "y", "z", "roll", "pitch", "yaw")
ESTIMATED, FROM_PRIOR, UNOBSERVABLE = "estimated", "from_prior", "unobservable"
AXIS_Z_TOLERANCE_DEG = 15.0     # a common rotation axis this close to z of frame a is the ground robot's
ADVICE = {
    "z": "tilt the sensor head or drive over a ramp (rotation about a horizontal axis) to determine z",
    "roll": "turn in place for longer, both directions, so the rotation axes are measured well",
    "pitch": "turn in place for longer, both directions, so the rotation axes are measured well",
    "yaw": "drive a figure eight (translate while turning, not only around one fixed point)",
    "x": "drive a figure eight (translate while turning, not only around one fixed point)",
    "y": "drive a figure eight (translate while turning, not only around one fixed point)",
}
PRIOR_ADVICE = "pass the robot's nominal instead: ⟦prior='robot.urdf'⟧ (a URDF, launch file, " \
               "static_transform_publisher arguments, Kalibr YAML or handeye result)"


@dataclass(frozen=True)
class Dof:
    """One degree of freedom: ``name`` (x, y, z [m]; roll, pitch, yaw [deg], URDF rpy of ``T_a_b``),
    ``status`` (``estimated``, ``from_prior`` or ``unobservable``), its ``value`` in the result, the
    predicted standard deviation ``std`` where estimated, and ``reason`` when not."""

    name: str
    status: str
    value: float
    std: float | None = None
    reason: str | None = None

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"status": self.status, "value": self.value}
        if self.std is not None:
            out["std"] = self.std
        if self.reason is not None:
            out["reason"] = self.reason
        return out


@dataclass(frozen=True, eq=False)
class Subspace:
    """Result of :func:`observable_subspace`: the matrix ``T_a_b`` (4, 4), each degree of freedom,
    the common rotation axis (frame a, unit), and advice for the degrees of freedom not estimated."""

    matrix: FloatArray
    dofs: tuple[Dof, ...]
    axis_a: FloatArray | None
    advice: tuple[str, ...]

    @property
    def skipped(self) -> dict[str, str]:
        """Names of the degrees of freedom not estimated, with their status and reason."""
        return {d.name: f"{d.status}: {d.reason}" for d in self.dofs if d.status != ESTIMATED}

    def as_dict(self) -> dict[str, Any]:
        return {d.name: d.as_dict() for d in self.dofs}


def dof_values(X: FloatArray) -> FloatArray:
    """(6,) x, y, z [m] and roll, pitch, yaw [deg] (``R = Rz Ry Rx``) of a 4x4 ``T_a_b``."""
    R = X[:3, :3]
    rpy = (np.arctan2(R[2, 1], R[2, 2]), np.arcsin(np.clip(-R[2, 0], -1.0, 1.0)), np.arctan2(R[1, 0], R[0, 0]))
    return np.asarray(np.r_[X[:3, 3], np.rad2deg(rpy)], dtype=np.float64)


def from_values(v: FloatArray) -> FloatArray:
    """The 4x4 ``T_a_b`` of x, y, z [m] and roll, pitch, yaw [deg] (inverse of :func:`dof_values`)."""
    roll, pitch, yaw = np.deg2rad(v[3:])
    T = np.eye(4)
    T[:3, :3] = _rot(np.array([0.0, 0.0, 1.0]), yaw) @ _rot(np.array([0.0, 1.0, 0.0]), pitch) \
        @ _rot(np.array([1.0, 0.0, 0.0]), roll)
    T[:3, 3] = v[:3]
    return T


def with_values_of(N: FloatArray, X: FloatArray, names: Iterable[str]) -> FloatArray:
    """``N`` (4x4 ``T_a_b``) with the degrees of freedom ``names`` (of :data:`DOF_NAMES`) taken from ``X``."""
    v, x = dof_values(N), dof_values(X)
    for name in names:
        k = DOF_NAMES.index(name)
        v[k] = x[k]
    return from_values(v)


def all_estimated(X: FloatArray, cov: LinearCovariance | None) -> Subspace:
    """Every degree of freedom estimated (non-degenerate motion), with the sandwich covariance's std
    (rotation about x, y, z of frame a for roll, pitch, yaw: first order for small tilts)."""
    std = None if cov is None else np.r_[cov.translation_std_m, cov.rotation_std_deg]
    v = dof_values(X)
    return Subspace(X, tuple(Dof(n, ESTIMATED, float(v[k]), None if std is None else float(std[k]))
                             for k, n in enumerate(DOF_NAMES)), None, ())


def _rot(axis: FloatArray, angle: float) -> FloatArray:
    """Rotation matrix of ``angle`` [rad] about the unit ``axis`` (Rodrigues)."""
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.asarray(np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * (K @ K), dtype=np.float64)


def _align(n_b: FloatArray, n_a: FloatArray) -> FloatArray:
    """The smallest rotation taking unit ``n_b`` to unit ``n_a``."""
    c = np.cross(n_b, n_a)
    s = np.linalg.norm(c)
    return _rot(c / s, float(np.arctan2(s, n_b @ n_a))) if s > 1e-15 else np.eye(3)


def _axes(A: FloatArray, B: FloatArray, w: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Principal rotation axes ``n_a``, ``n_b`` (signs consistent) of the weighted rotation vectors,
    and those vectors (N, 3) of a and b (``√w`` times the rotation vector [rad])."""
    ra = dq.to_rotvec(dq.from_matrix(A[:, :3, :3])) * np.sqrt(w)[:, None]
    rb = dq.to_rotvec(dq.from_matrix(B[:, :3, :3])) * np.sqrt(w)[:, None]
    n_a = np.linalg.eigh(ra.T @ ra)[1][:, 2]
    n_a = n_a if n_a[2] >= 0 else -n_a
    n_b = np.linalg.eigh(rb.T @ rb)[1][:, 2]
    n_b = n_b if np.sum((ra @ n_a) * (rb @ n_b)) >= 0 else -n_b
    return n_a, n_b, ra, rb


def _yaw_about(R: FloatArray, R_tilt: FloatArray, n_a: FloatArray) -> float:
    """The angle [rad] about ``n_a`` of ``R R_tiltᵀ`` (the yaw that brings ``Rot(n_a, θ) R_tilt`` closest to ``R``)."""
    return float(dq.to_rotvec(dq.from_matrix((R @ R_tilt.T)[None]))[0] @ n_a)


def _tilt_std(ra: FloatArray, rb: FloatArray, R: FloatArray, n_a: FloatArray) -> float:
    """Predicted std [rad] per component of the axis alignment: rotation residuals ``R rb − ra`` across
    ``n_a`` (variance per component, pairs taken as independent) over the summed squared angles."""
    e = rb @ R.T - ra
    e_perp = e - np.outer(e @ n_a, n_a)
    return float(np.sqrt(np.sum(e_perp ** 2) / (2 * len(ra)) / max(np.sum((ra @ n_a) ** 2), 1e-300)))


def _gauss_newton(residual: Callable[[FloatArray], FloatArray], p: FloatArray,
                  iterations: int = 20) -> tuple[FloatArray, FloatArray]:
    """Minimise ``|residual(p)|²`` by Gauss–Newton with a forward-difference Jacobian (a few smooth
    parameters; scipy.optimize stays unimported on the calibrate path). Returns ``(p, J)``."""
    J = np.zeros((0, len(p)))
    for _ in range(iterations):
        r = residual(p)
        J = np.stack([(residual(p + h) - r) / 1e-7 for h in np.eye(len(p)) * 1e-7], axis=1)
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        p = p + step
        if np.abs(step).max() < 1e-12:
            break
    return p, J


def _across(n_a: FloatArray) -> FloatArray:
    """(3, 2) the unit basis ``u1, u2`` of the plane across unit ``n_a`` (right-handed: ``u1 × u2 = n_a``), the
    coordinates of :func:`_in_plane`'s translation."""
    u1 = np.cross(np.cross(n_a, [1.0, 0.0, 0.0] if abs(n_a[0]) < 0.9 else [0.0, 1.0, 0.0]), n_a)
    u1 /= np.linalg.norm(u1)
    return np.stack([u1, np.cross(n_a, u1)], axis=1)


def _in_plane(A: FloatArray, B: FloatArray, w: FloatArray, n_a: FloatArray, R_tilt: FloatArray, z: float,
              yaw0: float | None) -> tuple[float, FloatArray, FloatArray]:
    """Yaw about ``n_a`` [rad], translation across ``n_a`` (2,) in the basis ``u1, u2``, and their 3x3
    covariance, from eq 4's rows with the tilt and the translation along ``n_a`` (``z`` [m]) fixed.
    ``yaw0`` fixes the yaw too (then only the translation is solved)."""
    u1, u2 = _across(n_a).T
    sw = np.sqrt(w)[:, None]
    RA_I = A[:, :3, :3] - np.eye(3)
    tA, u = A[:, :3, 3], B[:, :3, 3] @ R_tilt.T
    cols = np.stack([RA_I @ u1, RA_I @ u2], axis=2)              # (N, 3, 2)
    base = RA_I @ (z * n_a) + tA

    def residual(p: FloatArray) -> FloatArray:
        yaw = yaw0 if yaw0 is not None else p[2]
        r = cols @ p[:2] + base - u @ _rot(n_a, float(yaw)).T
        return np.asarray((r * sw).ravel(), dtype=np.float64)

    # linear start: Rot(n, θ) u = c (u − (n·u) n) + s (n × u) + (n·u) n, unknowns (t1, t2, c, s)
    nu = u @ n_a
    M = np.concatenate([cols, -(u - np.outer(nu, n_a))[:, :, None], -np.cross(n_a, u)[:, :, None]], axis=2)
    rhs = np.outer(nu, n_a) - base
    lin = np.linalg.lstsq((M * sw[:, :, None]).reshape(-1, 4), (rhs * sw).ravel(), rcond=None)[0]
    p0 = np.r_[lin[:2], np.arctan2(lin[3], lin[2])] if yaw0 is None else lin[:2]
    p, J = _gauss_newton(residual, np.asarray(p0, dtype=np.float64))
    r = residual(p)
    dof = max(J.shape[0] - J.shape[1], 1)
    cov = np.linalg.pinv(J.T @ J) * (float(r @ r) / dof)
    yaw = float(yaw0 if yaw0 is not None else p[2])
    full = np.zeros((3, 3))
    full[:len(p), :len(p)] = cov
    t = p[0] * u1 + p[1] * u2
    return yaw, t, full


def _reduced(A: FloatArray, B: FloatArray, w: FloatArray, X: FloatArray,
             axes: tuple[FloatArray, FloatArray, FloatArray, FloatArray], nominal: FloatArray | None,
             yaw_fixed: bool, max_tilt_std_deg: float) -> tuple[FloatArray, float, bool, FloatArray]:
    """The reduced solve about the common axis ``n_a`` (``axes``: :func:`_axes`' ``n_a, n_b, ra, rb``): the tilt
    from the axes' alignment when they are measured well (else the nominal's), the translation along ``n_a``
    (and, on a fixed rotation line, the angle about it) from the nominal, failing that from the full solve
    ``X``; yaw and the translation across ``n_a`` from eq 4's rows. Returns ``(T_a_b, tilt std [rad], tilt
    estimated, covariance of yaw and the in-plane translation)``."""
    n_a, n_b, ra, rb = axes
    R_meas = _align(n_b, n_a)
    tilt_std = _tilt_std(ra, rb, _rot(n_a, _yaw_about(X[:3, :3], R_meas, n_a)) @ R_meas, n_a)
    tilt_ok = bool(np.rad2deg(tilt_std) <= max_tilt_std_deg)
    R_tilt = R_meas if tilt_ok or nominal is None else _align(nominal[:3, :3].T @ n_a, n_a)
    src = nominal if nominal is not None else X
    along = float(src[:3, 3] @ n_a)
    yaw0 = _yaw_about(src[:3, :3], R_tilt, n_a) if yaw_fixed else None
    yaw, t_perp, cov = _in_plane(A, B, w, n_a, R_tilt, along, yaw0)
    out = np.eye(4)
    out[:3, :3] = _rot(n_a, yaw) @ R_tilt
    out[:3, 3] = t_perp + along * n_a
    return out, tilt_std, tilt_ok, cov


def _oblique(A: FloatArray, B: FloatArray, w: FloatArray, X: FloatArray, obs: Observability, axis_a: FloatArray,
             nominal: FloatArray | None, max_tilt_std_deg: float) -> Subspace:
    """One rotation axis ``n_a`` that is not z of frame a (an arm turned about one joint).

    The translation along ``n_a`` is open, and ``n_a`` is oblique to the result's axes, so every one
    of x, y, z holds part of it: none could be labelled as measured, and unlike a ground robot's z
    (one named coordinate the user fixes by a tape measure or ``--prior``) no coordinate of the
    result would be right. Without a nominal this is refused naming the direction and the fix; with
    one, the reduced solve about ``n_a`` takes the translation along it (and, where the axes do not
    determine them, the tilt; on a fixed rotation line also the angle about it) from the nominal, and
    the coordinates that hold more than ``sin(AXIS_Z_TOLERANCE_DEG)`` of a prior direction are marked
    ``from_prior``.
    """
    finding = next(f for f in obs.warnings if f.code in ("planar", "single_axis"))
    if nominal is None:
        raise finding.refusal()
    n_a, n_b, ra, rb = _axes(A, B, w)
    if n_a @ axis_a < 0:                                        # the finding's sign (signs stay paired)
        n_a, n_b = -n_a, -n_b
    yaw_fixed = "fixed_rotation_line" in set(obs.codes)
    out, tilt_std, tilt_ok, cov = _reduced(A, B, w, X, (n_a, n_b, ra, rb), nominal, yaw_fixed, max_tilt_std_deg)
    v = dof_values(out)
    mixed = np.abs(n_a) > np.sin(np.deg2rad(AXIS_Z_TOLERANCE_DEG))
    name = describe_direction(n_a, "a")
    t_why = f"its part along the common rotation axis ({name}) is the prior's: the motion rotates about it only"
    basis = _across(n_a)                                            # translation across n_a: t = basis @ p
    t_std = np.sqrt(np.clip(np.diag(basis @ cov[:2, :2] @ basis.T), 0, None))
    dofs = [Dof(n, FROM_PRIOR, float(v[k]), reason=t_why) if mixed[k] else Dof(n, ESTIMATED, float(v[k]),
                                                                               float(t_std[k]))
            for k, n in enumerate(DOF_NAMES[:3])]
    r_std = float(np.rad2deg(np.hypot(tilt_std, np.sqrt(max(cov[2, 2], 0.0)))))
    r_open = not tilt_ok or yaw_fixed
    r_why = ("the rotation axes are not measured well enough" if not tilt_ok else
             "every motion is a rotation about one fixed line") + ": part of the rotation is the prior's"
    dofs += [Dof(n, FROM_PRIOR, float(v[k]), reason=r_why) if r_open else Dof(n, ESTIMATED, float(v[k]), r_std)
             for k, n in ((3, "roll"), (4, "pitch"), (5, "yaw"))]
    return Subspace(out, tuple(dofs), n_a, ())


def observable_subspace(A: FloatArray, B: FloatArray, X: FloatArray, obs: Observability, *,
                        weights: FloatArray | None = None, nominal: FloatArray | None = None,
                        max_tilt_std_deg: float = 0.1) -> Subspace:
    """The degrees of freedom of ``T_a_b`` the motions (A, B: (N, 4, 4), ``A_i X = X B_i``) determine.

    ``X`` is the full solve, ``obs`` its observability (:func:`.assess_observability`); ``nominal``
    a 4x4 ``T_a_b`` for what the data leave open. Without a ``planar`` / ``single_axis`` finding,
    every degree of freedom is estimated (:func:`all_estimated`). About z of frame a (within
    ``AXIS_Z_TOLERANCE_DEG``): the reduced in-plane solve of the module docstring. About another axis,
    :func:`_oblique`: with a nominal the same solve about that axis; without one the motion is
    refused (:class:`~handeye_cli.errors.UnderdeterminedError`).
    """
    codes = set(obs.codes)
    w = np.ones(len(A)) if weights is None else np.asarray(weights, dtype=np.float64)
    keep = w > 0
    A, B, w = A[keep], B[keep], w[keep]
    if not codes & {"planar", "single_axis"} or obs.axis_a is None:
        return all_estimated(X, obs.covariance)
    if abs(obs.axis_a[2]) < np.cos(np.deg2rad(AXIS_Z_TOLERANCE_DEG)):
        return _oblique(A, B, w, X, obs, obs.axis_a, nominal, max_tilt_std_deg)
    n_a, n_b, ra, rb = _axes(A, B, w)
    yaw_fixed = "fixed_rotation_line" in codes
    out, tilt_std, tilt_ok, cov = _reduced(A, B, w, X, (n_a, n_b, ra, rb), nominal, yaw_fixed, max_tilt_std_deg)
    v = dof_values(out)
    open_status = FROM_PRIOR if nominal is not None else UNOBSERVABLE
    why_z = "the motion rotates about one axis only (z of frame a): translation along it does not change the fit"
    why_tilt = (f"the rotation axes are not measured well enough (tilt std {np.rad2deg(tilt_std):.2g}° > "
                f"{max_tilt_std_deg:g}°)")
    why_yaw = "every motion is a rotation about one fixed line: yaw trades off against the in-plane translation"
    t_std = np.sqrt(np.clip(np.diag(cov)[:2], 0, None))
    dofs = [Dof("x", ESTIMATED, float(v[0]), float(t_std[0])), Dof("y", ESTIMATED, float(v[1]), float(t_std[1])),
            Dof("z", open_status, float(v[2]), reason=why_z)]
    dofs += [Dof(n, ESTIMATED, float(v[k]), float(np.rad2deg(tilt_std))) if tilt_ok
             else Dof(n, open_status, float(v[k]), reason=why_tilt) for k, n in ((3, "roll"), (4, "pitch"))]
    dofs.append(Dof("yaw", open_status, float(v[5]), reason=why_yaw) if yaw_fixed
                else Dof("yaw", ESTIMATED, float(v[5]), float(np.rad2deg(np.sqrt(max(cov[2, 2], 0.0))))))
    if yaw_fixed:
        dofs[0] = Dof("x", open_status, float(v[0]), reason=why_yaw)
        dofs[1] = Dof("y", open_status, float(v[1]), reason=why_yaw)
    missing = [d.name for d in dofs if d.status != ESTIMATED]
    advice = tuple(dict.fromkeys(ADVICE[n] for n in missing))
    if missing and nominal is None:
        advice += (f"for {', '.join(missing)}: {PRIOR_ADVICE}",)
    return Subspace(out, tuple(dofs), n_a, advice)
