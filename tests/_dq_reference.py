"""An independent implementation of cost (8) (+ prior, eq 26) for checking the solvers.

Written from the paper's definitions with its own Hamilton product and quaternion extraction, so
it shares no code with :mod:`handeye_cli.solvers`. Quaternions x-y-z-w; translations in metres.

:func:`cost` evaluates in extended precision (``np.longdouble``): near the noise-free limit the
residuals are ~1e-7 and a float64 evaluation of the cost is only good to ~1e-9 relative, too
coarse to compare two optima at the 1e-12 level the tests demand.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def qmul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product of x-y-z-w quaternions (broadcasting)."""
    px, py, pz, pw = np.moveaxis(p, -1, 0)
    qx, qy, qz, qw = np.moveaxis(q, -1, 0)
    return np.stack([pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw,
                     pw * qw - px * qx - py * qy - pz * qz], axis=-1)


def conj(q: np.ndarray) -> np.ndarray:
    return q * np.array([-1.0, -1.0, -1.0, 1.0])


def _quaternion(R: np.ndarray) -> np.ndarray:
    """Shepperd's method, in the precision of ``R``; x-y-z-w, scalar part ≥ 0."""
    tr = np.trace(R, axis1=-2, axis2=-1)
    diag = np.diagonal(R, axis1=-2, axis2=-1)
    cand = np.stack([1 + 2 * diag[..., 0] - tr, 1 + 2 * diag[..., 1] - tr, 1 + 2 * diag[..., 2] - tr, 1 + tr], -1)
    k = np.argmax(cand, axis=-1)
    q = np.empty(R.shape[:-2] + (4,), dtype=R.dtype)
    for idx in np.ndindex(R.shape[:-2]):
        m, i = R[idx], k[idx]
        s = 2 * np.sqrt(cand[idx][i])
        skew = np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
        if i == 3:
            q[idx] = [*(skew / s), s / 4]
        else:
            j, n = (i + 1) % 3, (i + 2) % 3
            v = np.empty(3, dtype=R.dtype)
            v[i], v[j], v[n] = s / 4, (m[j, i] + m[i, j]) / s, (m[n, i] + m[i, n]) / s
            q[idx] = [*v, skew[i] / s]
    q /= np.sqrt(np.sum(q * q, axis=-1, keepdims=True))
    return np.where(q[..., 3:] < 0, -q, q)


def dual_quaternion(T: np.ndarray, dtype=np.float64) -> tuple[np.ndarray, np.ndarray]:
    """Unit dual quaternion ``q + ε q'`` of transforms, scalar part ≥ 0, ``q' = ½ (t, 0) ⊗ q``."""
    T = np.asarray(T, dtype=dtype)
    q = _quaternion(T[..., :3, :3])
    t = np.concatenate([T[..., :3, 3], np.zeros(T.shape[:-2] + (1,), dtype=dtype)], axis=-1)
    return q, qmul(t, q) / 2


def _agree(qa: np.ndarray, qad: np.ndarray, qb: np.ndarray, qbd: np.ndarray, alpha: float,
           signs_by: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``Q_B ~ -Q_B``: the sign whose dual scalar ``(w, α w')`` agrees with ``Q_A``'s (conjugation keeps it),
    or with ``signs_by`` (an estimate of X, 4x4) the sign whose term of cost (8) is the smaller there."""
    if signs_by is None:
        dot = qa[:, 3] * qb[:, 3] + alpha ** 2 * qad[:, 3] * qbd[:, 3]
    else:
        qx, qxd = dual_quaternion(signs_by, qa.dtype)
        real_a, real_b = qmul(qa, qx), qmul(qx, qb)
        dual_a, dual_b = qmul(qad, qx) + qmul(qa, qxd), qmul(qxd, qb) + qmul(qx, qbd)
        dot = np.sum(real_a * real_b, -1) + alpha ** 2 * np.sum(dual_a * dual_b, -1)
    agree = np.where(dot < 0, -1, 1).astype(qb.dtype)[:, None]
    return agree * qb, agree * qbd


def cost(A: np.ndarray, B: np.ndarray, X: np.ndarray, alpha: float, weights: np.ndarray | None = None,
         prior: tuple[np.ndarray, float, float] | None = None, signs_by: np.ndarray | None = None) -> float:
    """``Σ w_i |Q_A ⊗ Q_X − Q_X ⊗ Q_B|²_α`` (cost 8), plus ``a |vec δq|² + b |δq'|²`` (eq 26); the sign of
    each ``Q_B`` agrees with ``Q_A``'s dual scalar part ``w + ε w'`` (weighed by α), or is the one of smaller
    cost at ``signs_by`` (:func:`_agree`)."""
    ld = np.longdouble
    qa, qad = dual_quaternion(A, ld)
    qb, qbd = dual_quaternion(B, ld)
    qx, qxd = dual_quaternion(X, ld)
    alpha = ld(alpha)
    qb, qbd = _agree(qa, qad, qb, qbd, alpha, None if signs_by is None else np.asarray(signs_by, dtype=ld))
    real = qmul(qa, qx) - qmul(qx, qb)
    dual = qmul(qad, qx) + qmul(qa, qxd) - qmul(qxd, qb) - qmul(qx, qbd)
    w = np.ones(len(A), dtype=ld) if weights is None else np.asarray(weights, dtype=ld)
    total = (np.sum(w * (np.sum(real ** 2, -1) + alpha ** 2 * np.sum(dual ** 2, -1))))
    if prior is not None:
        T_p, a, b = prior
        qp, qpd = dual_quaternion(T_p, ld)
        dq = qmul(conj(qp), qx)
        dqd = qmul(conj(qpd), qx) + qmul(conj(qp), qxd)
        total += ld(a) * np.sum(dq[:3] ** 2) + ld(b) * np.sum(dqd ** 2)
    return float(total)


def transform(params: np.ndarray) -> np.ndarray:
    """4x4 transform from a rotation vector [rad] and a translation [m] (6 parameters)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(params[:3]).as_matrix()
    T[:3, 3] = params[3:]
    return T


def residuals(params: np.ndarray, A: np.ndarray, B: np.ndarray, alpha: float,
              prior: tuple[np.ndarray, float, float] | None = None) -> np.ndarray:
    """The residual vector whose squared norm is :func:`cost` at ``transform(params)``."""
    return Residuals(A, B, alpha, prior)(params)


class Residuals:
    """:func:`residuals` of one problem as a function of the 6 parameters, for a least-squares solver that
    calls it hundreds of times. The residual is linear in X's dual quaternion ``(q_X, q'_X)``: its matrix is
    formed once by applying the same expressions as :func:`cost` (in float64) to the 8 unit vectors, so each
    call is one product with the dual quaternion of ``transform(params)``."""

    def __init__(self, A: np.ndarray, B: np.ndarray, alpha: float,
                 prior: tuple[np.ndarray, float, float] | None = None, signs_by: np.ndarray | None = None) -> None:
        qa, qad = dual_quaternion(A)
        qb, qbd = _agree(qa, qad, *dual_quaternion(B), alpha, signs_by)
        cp = None
        if prior is not None:
            T_p, a, b = prior
            qp, qpd = dual_quaternion(T_p)
            cp = (conj(qp), conj(qpd), np.sqrt(a), np.sqrt(b))

        def rows(qx: np.ndarray, qxd: np.ndarray) -> np.ndarray:
            real = qmul(qa, qx) - qmul(qx, qb)
            dual = qmul(qad, qx) + qmul(qa, qxd) - qmul(qxd, qb) - qmul(qx, qbd)
            parts = [real.ravel(), alpha * dual.ravel()]
            if cp is not None:
                parts += [cp[2] * qmul(cp[0], qx)[:3], cp[3] * (qmul(cp[1], qx) + qmul(cp[0], qxd))]
            return np.concatenate(parts)

        basis = np.eye(8)
        self.matrix = np.stack([rows(e[:4], e[4:]) for e in basis], axis=1)

    def __call__(self, params: np.ndarray) -> np.ndarray:
        qx, qxd = dual_quaternion(transform(params))
        return np.asarray(self.matrix @ np.r_[qx, qxd])


def params_of(X: np.ndarray) -> np.ndarray:
    return np.concatenate([Rotation.from_matrix(X[:3, :3]).as_rotvec(), X[:3, 3]])
