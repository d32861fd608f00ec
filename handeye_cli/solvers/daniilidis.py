"""Daniilidis (1999), "Hand-eye calibration using dual quaternions": the paper's baseline "Dan".

Each pair contributes the vector parts of eq 6 (six rows: ``E_i q = 0`` and ``F_i q + E_i q' = 0``
with the scalar rows dropped, as Daniilidis does); the translational rows are scaled by α as in
the paper's §4.3 comparison. The solution lies in the span of the two right singular vectors of
the stacked matrix with the smallest singular values; the unit and orthogonality constraints fix
the combination (Daniilidis' quadratic in s = λ1/λ2).

Faithful to the original, the root is chosen by the largest ``|s u1 + u2|²``. That rule is
exact on noise-free data but can pick the wrong root under noise: on 1 of 200 problems with
the paper's noise (benchmarks/solvers.py) it returns a rotation 180° off, where the other root
is within 0.6 % of the optimal cost. dqopt has no such failure mode.
"""
from __future__ import annotations

import numpy as np

from .._typing import FloatArray
from ..errors import DataError

__all__ = ["daniilidis"]


def daniilidis(E: FloatArray, F: FloatArray, alpha: float = 1.0,
               weights: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
    """The dual quaternion ``(q, q')`` (x-y-z-w) of ``X = T_a_b`` by Daniilidis' SVD method, from
    the per-pair blocks ``E_i``, ``F_i`` (N, 4, 4) of :func:`~handeye_cli.solvers.problem.pair_blocks`."""
    n = len(E)
    T = np.zeros((n, 6, 8))
    T[:, :3, :4] = E[:, :3]
    T[:, 3:, :4] = alpha * F[:, :3]
    T[:, 3:, 4:] = alpha * E[:, :3]
    if weights is not None:
        T *= np.sqrt(np.asarray(weights, dtype=np.float64))[:, None, None]
    _, _, Vt = np.linalg.svd(T.reshape(-1, 8), full_matrices=False)
    u1, v1 = Vt[-2, :4], Vt[-2, 4:]
    u2, v2 = Vt[-1, :4], Vt[-1, 4:]
    # (s u1 + u2)·(s v1 + v2) = 0  →  a s² + b s + c = 0
    a, b, c = u1 @ v1, u1 @ v2 + u2 @ v1, u2 @ v2
    if abs(a) > 1e-300:
        disc = b * b - 4 * a * c
        if disc < 0:
            raise DataError("Daniilidis' method found no real solution (noisy or degenerate motions)",
                               "daniilidis", "use ⟦method='dqopt'⟧, which always has one")
        roots = (-b + np.array([1.0, -1.0]) * np.sqrt(disc)) / (2 * a)
        # pick the root maximising |s u1 + u2|², then scale to |q| = 1
        norms = [(s * u1 + u2) @ (s * u1 + u2) for s in roots]
        s = roots[int(np.argmax(norms))]
        q, qd = s * u1 + u2, s * v1 + v2
    else:                       # a = 0: s → ∞ is a root, i.e. the first singular vector alone
        q, qd = u1, v1
    n_q = np.linalg.norm(q)
    if not np.isfinite(n_q) or n_q < 1e-12:     # e.g. every translation 0: the root picked has no rotation part
        raise DataError("Daniilidis' method degenerates on these motions (its chosen root has no rotation part; "
                        "every translation zero?)", "daniilidis", "use ⟦method='dqopt'⟧, which always has a solution")
    return q / n_q, qd / n_q
