"""Quaternion and dual-quaternion algebra for the solvers (paper §2).

Quaternion order inside the solvers is **x, y, z, w** — the paper's ``(q⃗, q₀)`` (imaginary
part first, so its ``G = diag(1, 1, 1, 0)`` of eq 26 reads as written) and the same order as
ROS and scipy. A rigid transform ``[R | t]`` is the unit dual quaternion
``Q = q + ε q'`` with ``q`` the rotation quaternion and ``q' = ½ (t, 0) ⊗ q`` (eq 2).
The sign is fixed so that the scalar part ``w`` of ``q`` is ≥ 0 (``Q ~ -Q``).
"""
from __future__ import annotations

import numpy as np

from .._typing import FloatArray

__all__ = ["left", "right", "conjugate", "multiply", "from_transforms", "to_transform"]


# L(q)[i, j] = _L_SIGN[i, j] * q[_L_INDEX[i, j]] and likewise for R(q), in x-y-z-w order:
# q ⊗ p = L(q) p and p ⊗ q = R(q) p. Index tables keep the batched build to one gather.
_L_INDEX = np.array([[3, 2, 1, 0], [2, 3, 0, 1], [1, 0, 3, 2], [0, 1, 2, 3]])
_L_SIGN = np.array([[1, -1, 1, 1], [1, 1, -1, 1], [-1, 1, 1, 1], [-1, -1, -1, 1]], dtype=np.float64)
_R_INDEX = _L_INDEX
_R_SIGN = np.array([[1, 1, -1, 1], [-1, 1, 1, 1], [1, -1, 1, 1], [-1, -1, -1, 1]], dtype=np.float64)


def left(q: FloatArray) -> FloatArray:
    """Matrices ``L(q)`` with ``q ⊗ p = L(q) p`` for quaternions (…, 4) in x-y-z-w order."""
    return np.asarray(q, dtype=np.float64)[..., _L_INDEX] * _L_SIGN


def right(q: FloatArray) -> FloatArray:
    """Matrices ``R(q)`` with ``p ⊗ q = R(q) p`` for quaternions (…, 4) in x-y-z-w order."""
    return np.asarray(q, dtype=np.float64)[..., _R_INDEX] * _R_SIGN


def conjugate(q: FloatArray) -> FloatArray:
    """Quaternion conjugate ``q*`` (x-y-z-w)."""
    return np.asarray(q, dtype=np.float64) * np.array([-1.0, -1.0, -1.0, 1.0], dtype=np.float64)


def multiply(p: FloatArray, q: FloatArray) -> FloatArray:
    """Hamilton product ``p ⊗ q`` of quaternions (…, 4) in x-y-z-w order."""
    product: FloatArray = np.einsum("...ij,...j->...i", left(p), q)
    return product


def _shepperd_matrix() -> FloatArray:
    """(16, 16): row 4p + i gives component i of the quaternion scaled by pivot p (``4·x_p·(x, y, z, w)``)
    from a transform flattened row-major (``X[4i + j] = T_ij``); the diagonal rows 5p lack the 1 of
    ``4x_p² = 1 ± R00 ± R11 ± R22``. The ten distinct values are 4x², 4y², 4z², 4w², R01 + R10,
    R02 + R20, R12 + R21, R21 - R12, R02 - R20, R10 - R01."""
    values = [{0: 1, 5: -1, 10: -1}, {0: -1, 5: 1, 10: -1}, {0: -1, 5: -1, 10: 1}, {0: 1, 5: 1, 10: 1},
              {1: 1, 4: 1}, {2: 1, 8: 1}, {6: 1, 9: 1}, {9: 1, 6: -1}, {2: 1, 8: -1}, {4: 1, 1: -1}]
    pivot_rows = [[0, 4, 5, 7], [4, 1, 6, 8], [5, 6, 2, 9], [7, 8, 9, 3]]
    S = np.zeros((16, 16))
    for p, rows in enumerate(pivot_rows):
        for i, v in enumerate(rows):
            for col, sign in values[v].items():
                S[4 * p + i, col] = sign
    return S


def _dual_part_matrix() -> FloatArray:
    """(4, 12): ``q' = ½ (t, 0) ⊗ q`` from the products ``t_j q_k`` at 4j + k (vector part
    ``½ (t w + t × v)``, scalar part ``-½ t·v``)."""
    D = np.zeros((4, 12))
    for j in range(3):
        a, b = (j + 1) % 3, (j + 2) % 3
        D[j, 4 * j + 3] = 0.5
        D[j, 4 * a + b] += 0.5
        D[j, 4 * b + a] -= 0.5
        D[3, 4 * j + j] = -0.5
    return D


_SHEPPERD = _shepperd_matrix()
_DUAL = _dual_part_matrix()
_PIVOTS = np.arange(4)[:, None]


def _from_flat(X: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Unit dual quaternions ``(q, q')`` as (4, M) arrays of transforms flattened batch-last, X (16, M).

    The rotation by Shepperd's method: of the four expressions ``4x², 4y², 4z², 4w²`` (from the
    trace and the diagonal) the largest is taken as the pivot, so no division by a small number
    occurs. It is what ``scipy``'s ``Rotation.from_matrix`` does for one matrix, without its per-call
    overhead; with the batch on the last axis each step is one pass over contiguous rows.
    Then ``q' = ½ (t, 0) ⊗ q`` (eq 2), with the sign that makes ``w ≥ 0``.
    """
    G = _SHEPPERD @ X                                        # the four pivots' scaled quaternions
    G[::5] += 1.0
    pick = np.argmax(G[::5].T, axis=1) == _PIVOTS           # (4, M) one-hot
    q = (G.reshape(4, 4, -1) * pick[:, None]).sum(0)         # ∝ 4·pivot·(x, y, z, w)
    q *= np.where(q[3] < 0, -1.0, 1.0) / np.sqrt(np.einsum("im,im->m", q, q))
    qd = _DUAL @ (X[3:12:4, None] * q).reshape(12, -1)
    return q, qd


def _block_matrix() -> FloatArray:
    """(8, 16): ``vec(L(p) - R(r)) = [p, r] @ _BLOCK`` for row vectors p, r (row-major 4x4)."""
    B = np.zeros((8, 16))
    for i in range(4):
        for j in range(4):
            B[_L_INDEX[i, j], 4 * i + j] += _L_SIGN[i, j]
            B[4 + _R_INDEX[i, j], 4 * i + j] -= _R_SIGN[i, j]
    return B


_BLOCK = _block_matrix()


def pair_difference_blocks(Ta: FloatArray, Tb: FloatArray, alpha: float = 1.0) -> tuple[FloatArray, FloatArray]:
    """``L(q_a) - R(q_b)`` and ``L(q'_a) - R(q'_b)`` (…, 4, 4) of the (broadcast) transforms
    ``Ta``, ``Tb`` (…, 4, 4): both stacks are converted in one pass and the blocks formed by one product.

    The blocks need the signs of ``Q_a`` and ``Q_b`` to agree (``Q_a = Q_X ⊗ Q_b ⊗ Q_X*``, not
    ``-Q_X ⊗ Q_b ⊗ Q_X*``). Conjugation keeps the dual scalar part ``(w, w')`` (the screw's angle and
    pitch invariants), so the sign of ``Q_b`` is the one whose ``(w_b, w'_b)`` has a non-negative
    product ``w_a w_b + α² w'_a w'_b`` with ``(w_a, w'_a)`` (α [1/m]: the cost's weight of the dual
    part). Away from a half-turn that is the sign making ``w ≥ 0``; near a half-turn (``w ≈ 0``) noise
    can flip one ``w`` — a pair then costs as much as a 180° error — and the pitch part ``w' = -½ t·v``
    decides."""
    Ta, Tb = np.asarray(Ta, dtype=np.float64), np.asarray(Tb, dtype=np.float64)
    if Ta.shape != Tb.shape:
        Ta, Tb = np.broadcast_arrays(Ta, Tb)
    shape = Ta.shape[:-2] + (4, 4)
    a, b = Ta.reshape(-1, 16), Tb.reshape(-1, 16)
    n = len(a)
    q, qd = _from_flat(np.concatenate((a, b)).T.copy())
    flip = q[3, :n] * q[3, n:] + alpha * alpha * qd[3, :n] * qd[3, n:] < 0     # Q_b ~ -Q_b: agree with Q_a
    if flip.any():
        q[:, n:][:, flip] *= -1.0
        qd[:, n:][:, flip] *= -1.0
    pairs = np.empty((2 * n, 8))                 # rows [q_a, q_b] for E, then [q'_a, q'_b] for F
    pairs[:n, :4] = q[:, :n].T
    pairs[:n, 4:] = q[:, n:].T
    pairs[n:, :4] = qd[:, :n].T
    pairs[n:, 4:] = qd[:, n:].T
    blocks = pairs @ _BLOCK
    return blocks[:n].reshape(shape), blocks[n:].reshape(shape)


def from_transforms(T: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Unit dual quaternions ``(q, q')`` of transforms (…, 4, 4), scalar part of ``q`` ≥ 0 (eq 2)."""
    T = np.asarray(T, dtype=np.float64)
    q, qd = _from_flat(np.ascontiguousarray(T.reshape(-1, 16).T))
    shape = T.shape[:-2] + (4,)
    return q.T.reshape(shape).copy(), qd.T.reshape(shape).copy()


def to_transform(q: FloatArray, qd: FloatArray) -> FloatArray:
    """The 4x4 transform of a dual quaternion ``q + ε q'`` (normalised so |q| = 1).

    The translation is ``t = 2 q' ⊗ q*`` (vector part), from eq 2. Written out on Python floats:
    for one transform that is several times faster than the equivalent numpy calls.
    """
    x, y, z, w = np.asarray(q, dtype=np.float64).tolist()
    a, b, c, d = np.asarray(qd, dtype=np.float64).tolist()
    s = 1.0 / (x * x + y * y + z * z + w * w)          # |q|⁻²: rotation terms are quadratic in q
    x2, y2, z2 = 2.0 * x, 2.0 * y, 2.0 * z
    xx, yy, zz = x * x2 * s, y * y2 * s, z * z2 * s
    xy, xz, yz = x * y2 * s, x * z2 * s, y * z2 * s
    xw, yw, zw = x2 * w * s, y2 * w * s, z2 * w * s
    # 2 q' ⊗ q* / |q|² (vector part) = 2 (w a⃗ - d q⃗ - a⃗ × q⃗) / |q|²
    s2 = 2.0 * s
    return np.array([[1.0 - yy - zz, xy - zw, xz + yw, s2 * (w * a - d * x - (b * z - c * y))],
                     [xy + zw, 1.0 - xx - zz, yz - xw, s2 * (w * b - d * y - (c * x - a * z))],
                     [xz - yw, yz + xw, 1.0 - xx - yy, s2 * (w * c - d * z - (a * y - b * x))],
                     [0.0, 0.0, 0.0, 1.0]])
