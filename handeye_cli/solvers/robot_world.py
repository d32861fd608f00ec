"""Robot-world / hand-eye calibration on absolute poses: ``A_i X = Y B_i``.

For station captures where both sensors' absolute poses are measured at the same instants:
``A_i = T_wa_a(t_i)`` (sensor a in its world), ``B_i = T_wb_b(t_i)`` (sensor b in its world).
The unknowns are the extrinsic ``X = T_a_b`` (pose of b in a; maps points from b to a) and the
pose of b's world in a's world ``Y = T_wa_wb``; then ``T_wa_a X = T_wa_b = Y T_wb_b``. Unlike
``A_i X = X B_i`` on motions, no pose is differenced, so each station counts once.

Closed forms (OpenCV's ``calibrateRobotWorldHandEye`` with ``A_i`` = its ``world2cam``, ``B_i``
= its ``base2gripper``; it returns ``X`` as ``base2world`` and ``Y`` as ``gripper2cam``):

``shah``
    Shah (2013): ``R_A R_X R_Bᵀ = R_Y`` gives ``vec(R_Y) = (R_B ⊗ R_A) vec(R_X)`` (column-major
    ``vec``); the top singular vectors of ``Σ R_B ⊗ R_A`` are ``vec(R_X)`` and ``vec(R_Y)`` up to
    scale, each projected onto SO(3); then the translations by linear least squares
    ``R_A t_X - t_Y = R_Y t_B - t_A``.
``li``
    Li, Wang & Wu (2010): one linear system in ``vec(R_X)``, ``vec(R_Y)``, ``t_X``, ``t_Y``
    (row-major ``vec``); the rotation blocks are projected onto SO(3), the translations kept.

:func:`robot_world` then refines both by nonlinear least squares on the per-station residual
``(Y B_i)⁻¹ A_i X`` (rotation vector [rad] and α × translation [m]).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..errors import ConfigError, DataError
from ..geometry import se3
from ..geometry.lie import nearest_rotation
from .classical import _transform, _weighted_lstsq

__all__ = ["RW_METHODS", "RobotWorldSolution", "robot_world", "shah", "li", "station_residuals"]

Array = NDArray[np.float64]
RW_METHODS = ("shah", "li")


@dataclass(frozen=True, eq=False)
class RobotWorldSolution:
    """``X = T_a_b`` and ``Y = T_wa_wb`` (4x4 each) solving ``A_i X = Y B_i``.

    cost: ``Σ w_i (|rotvec_i|² + α² |trans_i|²)`` of the station residuals ``(Y B_i)⁻¹ A_i X``
    [rad², m²·α²]; method: ``shah`` or ``li`` (the closed form); refined: whether the
    nonlinear refinement ran; alpha [1/m]: its translation weight.
    """

    X: Array
    Y: Array
    cost: float
    method: str
    refined: bool
    alpha: float


def _rotation_blocks(A: Array, B: Array) -> tuple[Array, Array, Array, Array]:
    return A[:, :3, :3], B[:, :3, :3], A[:, :3, 3], B[:, :3, 3]


def _translations(A: Array, B: Array, Ry: Array, w: Array) -> tuple[Array, Array]:
    """``t_X``, ``t_Y`` [m] from ``R_A t_X - t_Y = R_Y t_B - t_A`` given ``R_Y``."""
    Ra, _, ta, tb = _rotation_blocks(A, B)
    M = np.concatenate((Ra, np.broadcast_to(-np.eye(3), Ra.shape)), axis=2)
    t = _weighted_lstsq(M, tb @ Ry.T - ta, w)
    return t[:3], t[3:]


def shah(A: Array, B: Array, w: Array) -> tuple[Array, Array]:
    """Shah's closed form: ``(X, Y)`` from absolute poses ``A_i``, ``B_i`` (N, 4, 4) and weights (N,)."""
    Ra, Rb, _, _ = _rotation_blocks(A, B)
    K = np.einsum("n,nij,nkl->ikjl", w, Rb, Ra).reshape(9, 9)      # Σ w R_B ⊗ R_A
    U, _, Vt = np.linalg.svd(K)
    Rx = nearest_rotation(Vt[0].reshape(3, 3).T, up_to_sign=True)                   # column-major vec
    Ry = nearest_rotation(U[:, 0].reshape(3, 3).T, up_to_sign=True)
    tx, ty = _translations(A, B, Ry, w)
    return _transform(Rx, tx), _transform(Ry, ty)


def li(A: Array, B: Array, w: Array) -> tuple[Array, Array]:
    """Li's closed form: ``(X, Y)`` from absolute poses ``A_i``, ``B_i`` (N, 4, 4) and weights (N,)."""
    Ra, Rb, ta, tb = _rotation_blocks(A, B)
    n, eye = len(A), np.eye(3)
    M = np.zeros((n, 12, 24))
    M[:, :9, :9] = np.einsum("nij,kl->nikjl", Ra, eye).reshape(n, 9, 9)              # R_A ⊗ I
    M[:, :9, 9:18] = -np.einsum("ij,nlk->nikjl", eye, Rb).reshape(n, 9, 9)           # -I ⊗ R_Bᵀ
    M[:, 9:, 9:18] = np.einsum("ij,nk->nijk", eye, tb).reshape(n, 3, 9)              # I ⊗ t_Bᵀ
    M[:, 9:, 18:21] = -Ra
    M[:, 9:, 21:] = eye
    y = np.zeros((n, 12))
    y[:, 9:] = ta
    x = _weighted_lstsq(M, y, w)
    return (_transform(nearest_rotation(x[:9].reshape(3, 3), up_to_sign=True), x[18:21]),
            _transform(nearest_rotation(x[9:18].reshape(3, 3), up_to_sign=True), x[21:]))


def station_residuals(A: Array, B: Array, X: Array, Y: Array) -> tuple[Array, Array]:
    """Per-station residuals of ``A_i X = Y B_i``: rotation angle [rad] and translation [m] (frame wa)."""
    D = se3.inverse(Y @ B) @ A @ X
    angles: Array = np.asarray(se3.rotation_angle(D), dtype=np.float64)
    distances: Array = np.linalg.norm((A @ X)[:, :3, 3] - (Y @ B)[:, :3, 3], axis=1)
    return angles, distances


def _refine(A: Array, B: Array, X0: Array, Y0: Array, w: Array, alpha: float) -> tuple[Array, Array, float]:
    """Nonlinear least squares on ``(Y B_i)⁻¹ A_i X`` from ``(X0, Y0)``; returns ``(X, Y, cost)``."""
    from scipy.optimize import least_squares  # 0.1 s to import: only for the robot-world methods

    sw = np.sqrt(w)[:, None]

    def unpack(p: Array) -> tuple[Array, Array]:
        X, Y = X0.copy(), Y0.copy()
        X[:3, :3] = X0[:3, :3] @ Rotation.from_rotvec(p[:3]).as_matrix()
        Y[:3, :3] = Y0[:3, :3] @ Rotation.from_rotvec(p[6:9]).as_matrix()
        X[:3, 3] += p[3:6]
        Y[:3, 3] += p[9:]
        return X, Y

    def residuals(p: Array) -> Array:
        X, Y = unpack(p)
        AX, YB = A @ X, Y @ B
        rot = Rotation.from_matrix(np.swapaxes(YB[:, :3, :3], 1, 2) @ AX[:, :3, :3]).as_rotvec()
        return np.concatenate(((rot * sw).ravel(), (alpha * (AX[:, :3, 3] - YB[:, :3, 3]) * sw).ravel()))

    r = least_squares(residuals, np.zeros(12), method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    X, Y = unpack(r.x)
    return X, Y, float(r.fun @ r.fun)


def robot_world(A: Array, B: Array, *, method: str = "shah", refine: bool = True, alpha: float = 1.0,
                weights: Array | None = None) -> RobotWorldSolution:
    """Solve ``A_i X = Y B_i`` for ``X = T_a_b`` and ``Y = T_wa_wb`` from absolute poses
    ``A_i = T_wa_a(t_i)``, ``B_i = T_wb_b(t_i)`` (N, 4, 4; metres), N ≥ 3 stations with at least
    two distinct rotation axes; closed form ``method`` (``shah`` or ``li``), then (``refine``) the
    nonlinear least squares with translation weight ``alpha`` [1/m] and per-station ``weights``."""
    if method not in RW_METHODS:
        raise ConfigError(f"unknown robot-world method {method!r}", "method", f"choose one of {', '.join(RW_METHODS)}")
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    w = np.ones(len(A)) if weights is None else np.asarray(weights, dtype=float)
    if len(A) < 3 or A.shape != B.shape or A.shape[1:] != (4, 4):
        raise DataError(f"{len(A)} station(s) of shapes {A.shape} and {B.shape}", "robot-world",
                        "give at least 3 synchronised absolute poses of both sensors")
    X, Y = (shah if method == "shah" else li)(A, B, w)
    if refine:
        X, Y, cost = _refine(A, B, X, Y, w, alpha)
    else:
        rot, trans = station_residuals(A, B, X, Y)
        cost = float(w @ (rot ** 2 + (alpha * trans) ** 2))
    return RobotWorldSolution(X, Y, cost, method, refine, float(alpha))
