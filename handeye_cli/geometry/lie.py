"""Lie-group helpers on SO(3) and SE(3): the one projection onto SO(3), the cross-product matrix, the adjoint,
and the log of transforms near the identity (the error coordinates of the analysis and the rig).

Twists and errors are ordered ``(ω, v)``: rotation vector [rad] first, then translation [m].
Perturbations are on the left: ``T = Exp(ξ) T̂``.
"""
from __future__ import annotations

import numpy as np

from .._typing import FloatArray
from . import dualquat as dq

__all__ = ["nearest_rotation", "skew", "adjoint", "log_errors"]


def nearest_rotation(H: FloatArray, up_to_sign: bool = False) -> FloatArray:
    """The rotation ``R`` (…, 3, 3) maximising ``tr(Rᵀ H)`` for each 3x3 ``H`` (…, 3, 3): the
    orthogonal Procrustes / Kabsch solution ``U diag(1, 1, det(U Vᵀ)) Vᵀ`` from ``H = U S Vᵀ``.

    It is the rotation nearest to ``H`` in the Frobenius norm, and the rotation minimising
    ``Σ |a_i − R b_i|²`` when ``H = Σ a_i b_iᵀ``. Always det +1: a reflection is never returned.
    ``up_to_sign``: ``H`` is known only up to its sign (a null vector, a least-squares block):
    it is first flipped to a positive determinant.

    >>> import numpy as np
    >>> R = nearest_rotation(np.diag([2.0, 1.0, 0.5]))
    >>> R.round(12).tolist()
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    >>> bool(np.isclose(np.linalg.det(nearest_rotation(-np.eye(3))), 1.0))
    True
    >>> nearest_rotation(-np.eye(3), up_to_sign=True).round(12).tolist() == np.eye(3).tolist()
    True
    """
    H = np.asarray(H, dtype=np.float64)
    if up_to_sign:
        H = np.where(np.linalg.det(H)[..., None, None] < 0, -H, H)
    U, _, Vt = np.linalg.svd(H)
    flip = np.linalg.det(U @ Vt) < 0
    U = U.copy()
    U[..., :, 2] *= np.where(flip, -1.0, 1.0)[..., None]
    return np.asarray(U @ Vt, dtype=np.float64)


def skew(v: FloatArray) -> FloatArray:
    """Cross-product matrices ``[v]×`` (…, 3, 3) of vectors (…, 3): ``[v]× u = v × u``."""
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return out


def adjoint(T: FloatArray) -> FloatArray:
    """``Ad_T`` (N, 6, 6) of transforms T (N, 4, 4) on twists ``(ω, v)``: ``T Exp(ξ) T⁻¹ = Exp(Ad_T ξ)``."""
    R = T[:, :3, :3]
    Ad = np.zeros((len(T), 6, 6))
    Ad[:, :3, :3] = Ad[:, 3:, 3:] = R
    Ad[:, 3:, :3] = skew(T[:, :3, 3]) @ R
    return Ad


def log_errors(T: FloatArray) -> FloatArray:
    """``(ω, t)`` (…, 6) of transforms T (…, 4, 4) near the identity: the rotation vector [rad] of
    each rotation block and the translation [m] as it stands (the first-order log of SE(3))."""
    rotvec = dq.to_rotvec(dq.from_matrix(T[..., :3, :3]))
    return np.concatenate((rotvec, T[..., :3, 3]), axis=-1)
