"""Quaternion and dual-quaternion algebra for the solvers (paper §2).

Quaternion order inside the solvers is **x, y, z, w** — the paper's ``(q⃗, q₀)`` (imaginary
part first, so its ``G = diag(1, 1, 1, 0)`` of eq 26 reads as written) and the same order as
ROS and scipy. A rigid transform ``[R | t]`` is the unit dual quaternion
``Q = q + ε q'`` with ``q`` the rotation quaternion and ``q' = ½ (t, 0) ⊗ q`` (eq 2).
The sign is fixed so that the scalar part ``w`` of ``q`` is ≥ 0 (``Q ~ -Q``).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["left", "right", "conjugate", "multiply", "from_transforms", "to_transform"]


# L(q)[i, j] = _L_SIGN[i, j] * q[_L_INDEX[i, j]] and likewise for R(q), in x-y-z-w order:
# q ⊗ p = L(q) p and p ⊗ q = R(q) p. Index tables keep the batched build to one gather.
_L_INDEX = np.array([[3, 2, 1, 0], [2, 3, 0, 1], [1, 0, 3, 2], [0, 1, 2, 3]])
_L_SIGN = np.array([[1, -1, 1, 1], [1, 1, -1, 1], [-1, 1, 1, 1], [-1, -1, -1, 1]], dtype=float)
_R_INDEX = _L_INDEX
_R_SIGN = np.array([[1, 1, -1, 1], [-1, 1, 1, 1], [1, -1, 1, 1], [-1, -1, -1, 1]], dtype=float)


def left(q: np.ndarray) -> np.ndarray:
    """Matrices ``L(q)`` with ``q ⊗ p = L(q) p`` for quaternions (…, 4) in x-y-z-w order."""
    return np.asarray(q, dtype=float)[..., _L_INDEX] * _L_SIGN


def right(q: np.ndarray) -> np.ndarray:
    """Matrices ``R(q)`` with ``p ⊗ q = R(q) p`` for quaternions (…, 4) in x-y-z-w order."""
    return np.asarray(q, dtype=float)[..., _R_INDEX] * _R_SIGN


def conjugate(q: np.ndarray) -> np.ndarray:
    """Quaternion conjugate ``q*`` (x-y-z-w)."""
    return np.asarray(q, dtype=float) * np.array([-1.0, -1.0, -1.0, 1.0])


def multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` of quaternions (…, 4) in x-y-z-w order."""
    return np.einsum("...ij,...j->...i", left(p), q)


def from_transforms(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit dual quaternions ``(q, q')`` of transforms (…, 4, 4), scalar part of ``q`` ≥ 0 (eq 2)."""
    T = np.asarray(T, dtype=float)
    flat = T.reshape(-1, 4, 4)
    q = Rotation.from_matrix(flat[:, :3, :3]).as_quat(canonical=True)
    t = flat[:, :3, 3]
    qd = np.empty_like(q)                      # ½ (t, 0) ⊗ q
    qd[:, :3] = 0.5 * (t * q[:, 3:] + np.cross(t, q[:, :3]))
    qd[:, 3] = -0.5 * np.einsum("ij,ij->i", t, q[:, :3])
    shape = T.shape[:-2] + (4,)
    return q.reshape(shape), qd.reshape(shape)


def to_transform(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """The 4x4 transform of a dual quaternion ``q + ε q'`` (normalised so |q| = 1).

    The translation is ``t = 2 q' ⊗ q*`` (vector part), from eq 2.
    """
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    n = np.linalg.norm(q)
    q, qd = q / n, qd / n
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(q).as_matrix()
    T[:3, 3] = 2.0 * multiply(qd, conjugate(q))[:3]
    return T
