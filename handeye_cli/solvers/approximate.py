"""The analytic approximations of §3.2: DQ2Steps (Alg. 2), DQConvRlx (Alg. 3), DQ2ndOrd (Alg. 4).

Each picks a unit ``q`` in closed form and then the optimal ``q'`` for it (eq 20, computed by
:meth:`Problem.dual_part`, which also covers a singular M). Quaternions are x-y-z-w.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray
from .problem import Problem, eigh

__all__ = ["Approximation", "dq2steps", "dqconvrlx", "dq2ndord"]


@dataclass(frozen=True)
class Approximation:
    """An approximate solution ``q + ε q'``, its μ and method-specific figures (e.g. the gap bound of eq 22)."""

    q: FloatArray
    qd: FloatArray
    mu: float
    details: Mapping[str, float]


def _with_dual(problem: Problem, q: FloatArray, details: Mapping[str, float]) -> Approximation:
    q = q / np.sqrt(q @ q)
    qd, mu = problem.dual_part(q)
    return Approximation(q, qd, mu, details)


def dq2steps(problem: Problem) -> Approximation:
    """Algorithm 2: rotation first (smallest eigenvector of M, eq 19), then translation (eq 20)."""
    return _with_dual(problem, problem.M_smallest_eigenvector, {})


def _z0_eigen(problem: Problem) -> tuple[FloatArray, FloatArray]:
    """Eigenpairs of Z0 (eq 21), ascending; defined for a singular M too."""
    return eigh(problem.Z0_relaxed)


def dqconvrlx(problem: Problem) -> Approximation:
    """Algorithm 3: relax ``q·q' = 0`` (smallest eigenvector of Z0, eq 21), then project with eq 20.

    ``details["lower_bound"]`` is λ₀ (the relaxed cost, ≤ the optimum) and ``details["gap_bound"]``
    is Δλ of eq 22, so that ``λ₀ ≤ optimal cost ≤ λ₀ + Δλ``.
    """
    lam, V = _z0_eigen(problem)
    q = V[:, 0]
    details = {"lower_bound": float(lam[0])}
    if problem.M_is_regular:
        z1, z2 = (problem._Zs[1:] @ q @ q).tolist()       # qᵀZ1q, qᵀZ2q
        details["gap_bound"] = 0.25 * z1 * z1 / z2
    return _with_dual(problem, q, details)


def dq2ndord(problem: Problem) -> Approximation:
    """Algorithm 4: second-order expansion in μ around the relaxed solution (eq 23 / appendix A, eq 34).

    With ``Z_i^{ab} = q_aᵀ Z_i q_b`` and ``λ_{0a} = λ₀ - λ_a`` over the eigenpairs of Z0:
    ``μ* = ½ Z1^{00} / (Z2^{00} - Σ_a (Z1^{a0})² / λ_{0a})`` and
    ``q₍₂₎ = q₀ + μ* Σ_a (Z1^{a0}/λ_{0a}) q_a + μ*² (−½ q₀ Σ_a (Z1^{a0}/λ_{0a})²
    + Σ_a (Σ_b Z1^{b0} Z1^{ab}/λ_{0b} − Z2^{a0} − Z1^{00} Z1^{a0}/λ_{0a}) / λ_{0a} q_a)``,
    then normalised (the paper's "q₍₂₎/q₍₂₎²" is a slip for q₍₂₎/|q₍₂₎|) and completed with eq 20.
    Needs a regular M; with a singular M (noise-free data) μ* = 0 and the relaxed solution is exact.
    """
    lam, V = _z0_eigen(problem)
    if not problem.M_is_regular:
        return _with_dual(problem, V[:, 0], {"mu_2nd_order": 0.0})
    # Z1^{ab}, Z2^{ab} as nested lists: the arithmetic on 4x4 numbers is cheaper in Python floats
    Z1e, Z2e = (V.T @ problem._Zs[1:] @ V).tolist()
    l0, *la = lam.tolist()
    gaps = [l0 - lam_a for lam_a in la]                     # λ_{0a}, a = 1..3 (negative)
    z10 = [Z1e[a][0] for a in (1, 2, 3)]                    # Z1^{a0}
    c1 = [z / g for z, g in zip(z10, gaps, strict=True)]                 # Z1^{a0} / λ_{0a}
    mu = 0.5 * Z1e[0][0] / (Z2e[0][0] - sum(z * c for z, c in zip(z10, c1, strict=True)))
    inner = [sum(Z1e[a][b] * c1[b - 1] for b in (1, 2, 3)) - Z2e[a][0] - Z1e[0][0] * c1[a - 1] for a in (1, 2, 3)]
    coeff = [1.0 - 0.5 * mu * mu * sum(c * c for c in c1)] + [mu * c + mu * mu * i / g
                                                             for c, i, g in zip(c1, inner, gaps, strict=True)]
    return _with_dual(problem, V @ coeff, {"mu_2nd_order": float(mu)})
