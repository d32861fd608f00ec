"""The optimality certificate of a solution: the Lagrangian condition that proves it the global minimum.

Cost (8) with the prior (eqs 26–29) is the quadratic form ``xᵀ Q x`` of ``x = [q'; q]`` (8 numbers, in
:attr:`~handeye_cli.solvers.problem.Problem.form`'s ``(q', q)`` order, the prior's constant included),
minimised under ``|q|² = 1`` and ``q·q' = 0``. With the Lagrangian
``xᵀQx - λ(|q|² - 1) - 2μ q·q'`` the KKT conditions (eq 10) are ``H x = 0`` for

    H = Q - Λ(λ, μ) = Q - λ C1 - μ C2,    C1 = [[0, 0], [0, I4]],    C2 = [[0, I4], [I4, 0]]

(``C1 x = [0; q]``, ``C2 x = [q; q']``). If moreover ``H ⪰ 0``, then for every feasible ``y``
``yᵀQy = yᵀHy + λ ≥ λ = xᵀQx``: ``x`` is a global minimum (strong duality: the Lagrangian dual's bound
equals the cost). This needs no assumption on ``M``: it is a statement about the full 8x8 form, so it
applies where ``M`` is singular (noise-free data) as well. Conversely, for the minimiser with a regular
``M`` the condition always holds (``H``'s Schur complement on q is ``Z(μ) - λ₀ I``, eq 12), so a failed
certificate of DQOpt means a numerical failure.

:func:`certify` takes the multipliers by least squares on the stationarity equations
``Q x = λ C1 x + μ C2 x`` (8 equations, 2 unknowns), whose residual ``|H x| / |x|`` is the
``stationarity``, and the smallest eigenvalue of ``H``. Both are compared with a tolerance
``1e-9 · trace(Q)`` (``trace Q = |R|²_F`` lies between ``|Q|₂`` and ``8 |Q|₂``): the solution is certified when
it is stationary to that tolerance and ``λ_min(H) ≥ -tolerance``. A point that is not stationary is not
certified, however positive its ``H``: the methods that approximate the optimum (the paper's DQ2Steps,
DQConvRlx, Daniilidis' method, the classical ones) are certified only where they happen to reach it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray
from .problem import Problem

__all__ = ["Certificate", "RELATIVE_TOLERANCE", "certify"]

RELATIVE_TOLERANCE = 1e-9
"""The certificate's tolerance over ``trace(Q)``. Solves of the paper's scenarios reach ~1e-16 (rounding);
the wrong stationary points of the relaxation miss by ~1e-2 or more (tests/solvers/test_certificate.py)."""

# C1 and C2 flattened, so that one product forms λ C1 + μ C2
_C12 = np.stack((np.diag([0.0] * 4 + [1.0] * 4),
                 np.block([[np.zeros((4, 4)), np.eye(4)], [np.eye(4), np.zeros((4, 4))]]))).reshape(2, 64)


@dataclass(frozen=True)
class Certificate:
    """Whether a solution ``q + ε q'`` is proven the global minimum of its cost (8) (+ prior).

    Attributes
    ----------
    certified:
        ``stationarity ≤ tolerance`` and ``min_eigenvalue ≥ -tolerance``.
    min_eigenvalue:
        Smallest eigenvalue of ``H = Q - λ C1 - μ C2`` (units of the cost per ``|x|²``; ≈ 0 at the optimum,
        where ``x`` is its null vector).
    tolerance:
        ``1e-9 · trace(Q)``, same units.
    stationarity:
        ``|H x| / |x|``: how far ``x`` is from a KKT point (0 for an exact one), same units.
    lam, mu:
        The least-squares multipliers λ (of ``|q|² = 1``; equal to the cost at a KKT point) and μ (of ``q·q' = 0``).
    """

    certified: bool
    min_eigenvalue: float
    tolerance: float
    stationarity: float
    lam: float
    mu: float

    def as_dict(self) -> dict[str, float | bool]:
        """The result document's ``solver.certificate``."""
        return {"certified": self.certified, "min_eigenvalue": self.min_eigenvalue, "tolerance": self.tolerance,
                "stationarity": self.stationarity}


def certify(problem: Problem, q: FloatArray, qd: FloatArray) -> Certificate:
    """The :class:`Certificate` of the dual quaternion ``q + ε q'`` (x-y-z-w parts; feasible: ``|q| = 1``,
    ``q·q' = 0``, as every solver returns) for ``problem``'s cost. A few µs: one 8x8 symmetric eigenvalue
    problem, the rest in Python floats."""
    Q = problem.form
    g = Q.dot(np.concatenate((qd, q))).tolist()           # Q x; the rest in Python floats (8 numbers)
    d0, d1, d2, d3 = d = qd.tolist()
    q0, q1, q2, q3 = p = q.tolist()
    g0, g1, g2, g3, g4, g5, g6, g7 = g
    # normal equations of [C1x C2x] [λ; μ] = Qx (C1x = [0; q], C2x = [q; q']), whose Gram matrix
    # [[|q|², q·q'], [q·q', |x|²]] is diagonal at a feasible x
    qq, qqd = _dot(p, p), _dot(p, d)
    xx = qq + _dot(d, d)
    b1 = _dot(p, g[4:])
    b2 = _dot(p, g[:4]) + _dot(d, g[4:])
    det = qq * xx - qqd * qqd
    lam, mu = (xx * b1 - qqd * b2) / det, (qq * b2 - qqd * b1) / det
    r2 = ((g0 - mu * q0) ** 2 + (g1 - mu * q1) ** 2 + (g2 - mu * q2) ** 2 + (g3 - mu * q3) ** 2     # |H x|²
          + (g4 - lam * q0 - mu * d0) ** 2 + (g5 - lam * q1 - mu * d1) ** 2
          + (g6 - lam * q2 - mu * d2) ** 2 + (g7 - lam * q3 - mu * d3) ** 2)
    ev = np.linalg.eigvalsh(Q - np.dot((lam, mu), _C12).reshape(8, 8)).tolist()
    stationarity, min_eig = math.sqrt(r2 / xx), ev[0]
    tol = RELATIVE_TOLERANCE * (sum(ev) + 4.0 * lam)                # trace Q = trace H + 4λ (trace C2 = 0)
    return Certificate(stationarity <= tol and min_eig >= -tol, min_eig, tol, stationarity, lam, mu)


def _dot(u: list[float], v: list[float]) -> float:
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2] + u[3] * v[3]
