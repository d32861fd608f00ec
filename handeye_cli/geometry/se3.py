"""Batched rigid transforms as 4x4 homogeneous matrices.

Conventions used throughout handeye:

* ``T_a_b`` is the pose of frame b expressed in frame a; it maps points from b to a,
  ``p_a = T_a_b @ p_b``.
* Quaternions are Hamilton, ordered **x, y, z, w** (as ROS and ``scipy.spatial.transform``).
* Translations are in metres, angles in radians.

All functions accept a single transform of shape (4, 4) or a stack of shape (N, 4, 4).

Examples
--------
>>> import numpy as np
>>> from handeye_cli.geometry import se3
>>> half = np.sqrt(0.5)
>>> T_a_b = se3.from_xyz_quat(np.array([0.1, 0.0, 0.0]), np.array([0.0, 0.0, half, half]))  # 90° about z
>>> p_b = np.array([1.0, 0.0, 0.0, 1.0])      # 1 m along b's x axis (homogeneous)
>>> (T_a_b @ p_b).round(9).tolist()           # in frame a: b's x axis is a's y axis, b's origin at x = 0.1
[0.1, 1.0, 0.0, 1.0]
"""
from __future__ import annotations

import numpy as np

from .._typing import BoolArray, FloatArray
from .dualquat import from_matrix, to_matrix

__all__ = [
    "from_xyz_quat",
    "to_xyz_quat",
    "inverse",
    "relative",
    "rotation_angle",
    "is_rotation",
    "rotation_residuals",
]


def from_xyz_quat(xyz: FloatArray, quat_xyzw: FloatArray) -> FloatArray:
    """Build homogeneous transforms from translations (…, 3) [m] and x-y-z-w quaternions (…, 4).

    Quaternions need not be unit length; they are normalised.

    Examples
    --------
    >>> import numpy as np
    >>> from handeye_cli.geometry import se3
    >>> se3.from_xyz_quat(np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.0, 0.0, 2.0]))
    array([[1., 0., 0., 1.],
           [0., 1., 0., 2.],
           [0., 0., 1., 3.],
           [0., 0., 0., 1.]])
    >>> se3.from_xyz_quat(np.zeros((5, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (5, 1))).shape
    (5, 4, 4)
    """
    xyz = np.asarray(xyz, dtype=float)
    quat = np.asarray(quat_xyzw, dtype=float)
    single = xyz.ndim == 1
    xyz2, quat2 = np.atleast_2d(xyz), np.atleast_2d(quat)
    out = np.zeros((len(xyz2), 4, 4))
    out[:, :3, :3] = to_matrix(quat2)
    out[:, :3, 3] = xyz2
    out[:, 3, 3] = 1.0
    return out[0] if single else out


def to_xyz_quat(T: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Split transforms into translations (…, 3) [m] and x-y-z-w quaternions (…, 4), w ≥ 0.

    Examples
    --------
    >>> import numpy as np
    >>> from handeye_cli.geometry import se3
    >>> T = se3.from_xyz_quat(np.array([0.5, 0.0, 0.0]), np.array([-0.1, -0.5, -0.5, -0.7]))
    >>> xyz, q = se3.to_xyz_quat(T)
    >>> xyz.tolist(), q.round(9).tolist()      # the sign is fixed so that w ≥ 0
    ([0.5, 0.0, 0.0], [0.1, 0.5, 0.5, 0.7])
    """
    T = np.asarray(T, dtype=float)
    single = T.ndim == 2
    T2 = T[None] if single else T
    quat = from_matrix(T2[:, :3, :3])
    xyz = T2[:, :3, 3].copy()
    return (xyz[0], quat[0]) if single else (xyz, quat)


def inverse(T: FloatArray) -> FloatArray:
    """Invert rigid transforms exactly (transpose the rotation, no general matrix inverse).

    Examples
    --------
    >>> import numpy as np
    >>> from handeye_cli.geometry import se3
    >>> T_a_b = se3.from_xyz_quat(np.array([0.1, 0.2, 0.3]), np.array([0.1, 0.2, 0.3, 0.9]))
    >>> T_b_a = se3.inverse(T_a_b)
    >>> bool(np.allclose(T_b_a @ T_a_b, np.eye(4)))
    True
    """
    T = np.asarray(T, dtype=float)
    R = T[..., :3, :3]
    Rt = np.swapaxes(R, -1, -2)
    out = np.zeros_like(T)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def relative(T_w_i: FloatArray, T_w_j: FloatArray) -> FloatArray:
    """Relative motions ``T_i_j = T_w_i⁻¹ · T_w_j`` (the pose of j expressed in i).

    Examples
    --------
    A sensor at x = 1 m facing along the world's y axis moves 2 m along the world's y axis: in
    its own frame at ``t_i`` it moved 2 m along its x axis.

    >>> import numpy as np
    >>> from handeye_cli.geometry import se3
    >>> half = np.sqrt(0.5)
    >>> T_w_i = se3.from_xyz_quat(np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, half, half]))
    >>> T_w_j = se3.from_xyz_quat(np.array([1.0, 2.0, 0.0]), np.array([0.0, 0.0, half, half]))
    >>> se3.relative(T_w_i, T_w_j)[:3, 3].round(9).tolist()
    [2.0, 0.0, 0.0]
    """
    return inverse(T_w_i) @ np.asarray(T_w_j, dtype=np.float64)


def rotation_angle(T_or_R: FloatArray) -> FloatArray | np.float64:
    """Rotation angle [rad] of transforms (…, 4, 4) or rotation matrices (…, 3, 3); a numpy scalar for one.

    Uses the numerically robust ``atan2(|skew|, trace-1)`` form, exact near 0 and π.

    Examples
    --------
    >>> import numpy as np
    >>> from handeye_cli.geometry import se3
    >>> T = se3.from_xyz_quat(np.zeros(3), np.array([0.0, np.sin(0.25), 0.0, np.cos(0.25)]))   # 0.5 rad about y
    >>> round(float(se3.rotation_angle(T)), 12)
    0.5
    """
    R = np.asarray(T_or_R, dtype=np.float64)[..., :3, :3]
    skew = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                     R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    trace = R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2]
    skew_norm: FloatArray | np.float64 = np.linalg.norm(skew, axis=-1)
    return np.arctan2(skew_norm, trace - 1.0)


def rotation_residuals(C: FloatArray, work: FloatArray | None = None) -> FloatArray:
    """The seven numbers that vanish for a proper rotation, per matrix of a batch-last stack:
    ``C`` (3, 3, N) with ``C[i, j]`` the (N,) entries ``R_ij``; returns (7, N): the distinct entries
    of ``RᵀR - I`` (the diagonal, then (0,1), (1,2), (0,2)) and ``det R - 1``.

    Each step is one elementwise pass over rows of the batch (numpy's batched 3x3 products and
    reductions over short inner axes are slow); :func:`is_rotation` and the solvers' validation
    of motions (:mod:`handeye_cli.solvers.problem`) both use it. ``work`` (≥ 16, N), if given, is
    used for every intermediate and its first seven rows are returned, so nothing is allocated.
    """
    n = C.shape[2]
    w = np.empty((16, n)) if work is None else work
    out, products = w[:7], w[7:16].reshape(3, 3, n)
    np.multiply(C, C, out=products)
    products.sum(0, out=out[0:3])
    out[0:3] -= 1.0
    np.multiply(C[:, :2], C[:, 1:], out=products[:, :2])
    products[:, :2].sum(0, out=out[3:5])
    np.multiply(C[:, 0], C[:, 2], out=products[:, 0])
    products[:, 0].sum(0, out=out[5])
    r0, r1, r2 = C                                             # det R = R_0 · (R_1 × R_2)
    cross, tmp = products[0], products[1]
    for k, (i, j) in enumerate(((1, 2), (2, 0), (0, 1))):
        np.multiply(r1[i], r2[j], out=cross[k])
        np.multiply(r1[j], r2[i], out=tmp[k])
    cross -= tmp
    cross *= r0
    cross.sum(0, out=out[6])
    out[6] -= 1.0
    return out


def is_rotation(R: FloatArray, tol: float = 1e-6) -> BoolArray | np.bool_:
    """Boolean mask (a numpy scalar for one matrix): which (…, 3, 3) matrices are proper rotations within ``tol``:
    ``|RᵀR - I|`` (largest entry) and ``|det R - 1|`` both at most ``tol`` (see :func:`rotation_residuals`).

    Examples
    --------
    >>> import numpy as np
    >>> from handeye_cli.geometry import se3
    >>> se3.is_rotation(np.stack([np.eye(3), 2 * np.eye(3), -np.eye(3)])).tolist()   # scaled; reflection
    [True, False, False]
    """
    R = np.asarray(R, dtype=float)
    shape = R.shape[:-2]
    C = np.ascontiguousarray(R.reshape(-1, 3, 3).transpose(1, 2, 0))     # C[i, j] = R_ij, batch last
    dev = np.abs(rotation_residuals(C)).max(0)
    mask: BoolArray | np.bool_ = (dev <= tol).reshape(shape)[()]
    return mask
