"""Non-negative least squares for the few-column fits of the noise models.

``min ‖A x − b‖₂ subject to x ≥ 0`` by the active-set method of Lawson and Hanson ("Solving Least
Squares Problems", SIAM 1995, ch. 23), the algorithm of :func:`scipy.optimize.nnls`. It is here
because importing ``scipy.optimize`` costs 0.07 s of every command's start-up (a tenth of
``handeye calibrate`` on an image-heavy log), for fits of 3 and 5 columns whose every step is one
small least-squares solve. Where it does not converge within its iterations, scipy's does the fit;
tests check that the two agree.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["nnls"]


def _lstsq(A: NDArray[np.float64], b: NDArray[np.float64], cols: NDArray[np.bool_]) -> NDArray[np.float64]:
    """The least-squares solution on the columns ``cols``, zero elsewhere."""
    z = np.zeros(A.shape[1])
    z[cols] = np.linalg.lstsq(A[:, cols], b, rcond=None)[0]
    return z


def _active_set(A: NDArray[np.float64], b: NDArray[np.float64], tol: float) -> NDArray[np.float64] | None:
    """Lawson and Hanson's iteration on ``(A, b)``; None where it would cycle."""
    n = A.shape[1]
    x = np.zeros(n)
    free = np.zeros(n, dtype=bool)                   # the passive set: columns off their bound
    for _ in range(3 * n + 1):                        # each pass frees a column (at most n) or drops some
        if free.all():
            return x
        grad = A.T @ (b - A @ x)                      # minus half the gradient of the squared residual
        grad[free] = -np.inf
        j = int(np.argmax(grad))
        if grad[j] <= tol:
            return x                                  # Kuhn-Tucker conditions hold
        free[j] = True
        z = _lstsq(A, b, free)
        for _ in range(n):                            # step back to the boundary, drop the columns it meets
            if (z[free] > 0).all():
                break
            hit = np.flatnonzero(free & (z <= 0))
            step = x[hit] / (x[hit] - z[hit])
            x += float(step.min()) * (z - x)
            x[hit[np.argmin(step)]] = 0.0             # the column that meets the bound first leaves, exactly
            free &= x > 0.0                           # (a tolerance on x would be in b's units over A's)
            x[~free] = 0.0
            z = _lstsq(A, b, free)
        else:
            return None
        x = z
    return None


def nnls(A: NDArray[np.float64], b: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """``(x, ‖A x − b‖₂)`` with ``x ≥ 0`` minimising the residual, as :func:`scipy.optimize.nnls`
    (A: (m, n), b: (m,); any units: x has b's over A's).

    With more rows than columns the iteration runs on the n x n triangle of A's QR factorisation:
    ``‖A x − b‖² = ‖R x − Qᵀb‖² + const``, the same fit (and conditioning) at the cost of n rows."""
    A, b = np.asarray(A, dtype=np.float64), np.asarray(b, dtype=np.float64)
    tol = 10 * np.finfo(float).eps * max(A.shape) * max(float(np.abs(A).sum(axis=0).max(initial=0.0)), 1.0)
    n = A.shape[1]
    if A.shape[0] > n:
        Rb = np.asarray(np.linalg.qr(np.column_stack([A, b]), mode="r"))  # [R, Qᵀb], no Q formed
        x = _active_set(Rb[:n, :n], Rb[:n, n], tol)
    else:
        x = _active_set(A, b, tol)
    if x is None:                                     # cycling on a degenerate fit: scipy's
        from scipy.optimize import nnls as scipy_nnls

        x = scipy_nnls(A, b)[0]
    return x, float(np.linalg.norm(A @ x - b))
