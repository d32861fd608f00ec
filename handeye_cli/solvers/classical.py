"""The classical hand-eye methods that OpenCV's ``calibrateHandEye`` offers, on motion pairs.

Each solves ``A_i X = X B_i`` for ``X = T_a_b`` (the pose of frame b in frame a; maps points
from b to a) from (N, 4, 4) motions ``A_i``, ``B_i`` and non-negative per-pair weights ``w_i``
(each pair's equations are scaled by ``√w_i``). Rotation first, then the translation from the
linear least squares ``(R_Ai - I) t = R t_Bi - t_Ai`` (except Andreff, which solves both at once):

``tsai``
    Tsai & Lenz (1989): modified Rodrigues vectors ``p = 2 sin(θ/2) n`` of both motions satisfy
    ``[p_A + p_B]× p' = p_B - p_A`` for ``p' = p_X / √(4 - |p_X|²)``.
``park``
    Park & Martin (1994): the rotation axes (rotation vectors) obey ``a_i = R_X b_i``; ``R_X``
    is the orthogonal Procrustes solution (``(MᵀM)^-½ Mᵀ`` with ``M = Σ b aᵀ``, by SVD).
``horaud``
    Horaud & Dornaika (1995): the unit quaternion ``q_X`` (x-y-z-w, scalar ≥ 0 for every motion)
    minimising ``Σ |q_A ⊗ q_X - q_X ⊗ q_B|²``: the smallest eigenvector of ``Σ E_iᵀE_i``.
``andreff``
    Andreff, Horaud & Espiau (1999): the linear system ``(I₉ - R_A ⊗ R_B) vec(R) = 0``,
    ``(I₃ ⊗ t_Bᵀ) vec(R) + (I - R_A) t = t_A`` (row-major ``vec``) in the 12 unknowns; the
    rotation block is then projected onto SO(3) (sign of the determinant, then SVD).

OpenCV forms its motions from consecutive absolute poses as ``Hg_j⁻¹ Hg_i`` for all i < j; fed
the same motions these functions return its results (``tests/solvers/test_classical.py``). OpenCV reads
the quaternions of rotations beyond 120° with either sign (it picks the branch by the largest
diagonal entry); here every quaternion has its scalar part ≥ 0, as Tsai's and Horaud's
equations need.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ..geometry import dualquat as dq
from ..geometry.lie import nearest_rotation, skew
from .problem import eigh, pair_blocks

__all__ = ["CLASSICAL", "tsai", "park", "horaud", "andreff"]

Array = NDArray[np.float64]


def _weighted_lstsq(M: Array, y: Array, w: Array) -> Array:
    """Minimum-norm least squares of the stacked per-pair blocks ``M`` (N, r, c), ``y`` (N, r),
    each pair's rows scaled by ``√w``."""
    s = np.sqrt(w)
    c = M.shape[-1]
    x = np.linalg.lstsq((M * s[:, None, None]).reshape(-1, c), (y * s[:, None]).reshape(-1), rcond=None)[0]
    return np.asarray(x, dtype=np.float64)


def _translation(A: Array, B: Array, R: Array, w: Array) -> Array:
    """``t`` [m] from ``(R_Ai - I) t = R t_Bi - t_Ai`` (the translation rows of ``A_i X = X B_i``)."""
    return _weighted_lstsq(A[:, :3, :3] - np.eye(3), B[:, :3, 3] @ R.T - A[:, :3, 3], w)


def _transform(R: Array, t: Array) -> Array:
    X = np.eye(4)
    X[:3, :3], X[:3, 3] = R, t
    return X


def _unit_quaternions(T: Array) -> Array:
    """x-y-z-w quaternions of the rotation blocks, scalar part ≥ 0."""
    return dq.from_matrix(T[:, :3, :3])


def tsai(A: Array, B: Array, w: Array) -> Array:
    """Tsai–Lenz: ``X = T_a_b`` (4x4) from motions ``A_i X = X B_i`` (N, 4, 4) and weights (N,)."""
    pa, pb = 2.0 * _unit_quaternions(A)[:, :3], 2.0 * _unit_quaternions(B)[:, :3]
    p_ = _weighted_lstsq(skew(pa + pb), pb - pa, w)
    half = p_ / np.sqrt(1.0 + p_ @ p_)              # p_X / 2 = sin(θ/2) n: the quaternion's vector part
    R = dq.to_matrix(np.r_[half, np.sqrt(max(1.0 - float(half @ half), 0.0))])
    return _transform(R, _translation(A, B, R, w))


def park(A: Array, B: Array, w: Array) -> Array:
    """Park–Martin: ``X = T_a_b`` (4x4) from motions ``A_i X = X B_i`` (N, 4, 4) and weights (N,)."""
    a = dq.to_rotvec(dq.from_matrix(A[:, :3, :3]))
    b = dq.to_rotvec(dq.from_matrix(B[:, :3, :3]))
    R = nearest_rotation((a * w[:, None]).T @ b)          # a_i = R b_i
    return _transform(R, _translation(A, B, R, w))


def horaud(A: Array, B: Array, w: Array) -> Array:
    """Horaud–Dornaika: ``X = T_a_b`` (4x4) from motions ``A_i X = X B_i`` (N, 4, 4) and weights (N,)."""
    E, _ = pair_blocks(A, B)                          # E_i q = q_A ⊗ q - q ⊗ q_B
    _, V = eigh(np.einsum("n,nki,nkj->ij", w, E, E))
    R = dq.to_matrix(V[:, 0])
    return _transform(R, _translation(A, B, R, w))


def andreff(A: Array, B: Array, w: Array) -> Array:
    """Andreff: ``X = T_a_b`` (4x4) from motions ``A_i X = X B_i`` (N, 4, 4) and weights (N,)."""
    n = len(A)
    Ra, Rb, ta, tb = A[:, :3, :3], B[:, :3, :3], A[:, :3, 3], B[:, :3, 3]
    M = np.zeros((n, 12, 12))
    M[:, :9, :9] = np.eye(9) - np.einsum("nij,nkl->nikjl", Ra, Rb).reshape(n, 9, 9)
    M[:, 9:, :9] = np.einsum("ij,nk->nijk", np.eye(3), tb).reshape(n, 3, 9)
    M[:, 9:, 9:] = np.eye(3) - Ra
    y = np.zeros((n, 12))
    y[:, 9:] = ta
    x = _weighted_lstsq(M, y, w)
    return _transform(nearest_rotation(x[:9].reshape(3, 3), up_to_sign=True), x[9:])


CLASSICAL: dict[str, Callable[[Array, Array, Array], Array]] = {
    "tsai": tsai, "park": park, "horaud": horaud, "andreff": andreff}
