"""The optimal solvers: DQOpt (Algorithm 1, §3.2.1) and the fixed-point iteration DQItr (Algorithm 5, §3.2.5).

Both search the Lagrange multiplier μ of the constraint ``q·q' = 0``. For a given μ the
smallest eigenpair ``(λ₀(μ), q₀(μ))`` of ``Z(μ) = Z0 + μ Z1 - μ² Z2`` (eq 12) is the best
unit ``q``; λ₀ is concave in μ (§3.1.2, footnote 4) and the optimum is its maximum, the unique
root of the increasing function ``f(μ) = q₀ᵀ (μ Z2 - ½ Z1) q₀ = -½ dλ₀/dμ`` (eq 18).

DQOpt runs Newton steps on the analytic derivative
``f'(μ) = q₀ᵀZ2q₀ + Σₐ (qₐᵀ(Z1 - 2μZ2)q₀)² / (λₐ - λ₀) > 0`` (second-order perturbation of λ₀),
safeguarded by bisection inside the bounds of appendix C — μ = ½ qᵀZ1q / qᵀZ2q (eq 14) is a
generalised Rayleigh quotient, so every root lies between the extreme generalised eigenvalues
of (½ Z1, Z2), where f changes sign.

M singular (noise-free data, or rotations that are exact while translations are not) breaks
eq 11. There the solvers start from the relaxed solution — the solution itself on noise-free
data, where μ* = 0 — and polish it by Newton's method on the exact KKT system of cost (8)
(eq 10 plus both constraints), which converges quadratically and never inverts M.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray
from .problem import Problem, eigh

__all__ = ["LineSearchResult", "dqopt", "dqitr", "kkt_polish"]

_EPS = np.finfo(float).eps


@dataclass(frozen=True)
class LineSearchResult:
    """Solution ``q + ε q'`` with its multipliers and how the search went."""

    q: FloatArray
    qd: FloatArray
    lam: float
    mu: float
    iterations: int
    converged: bool
    singular_m: bool = False


def _smallest(Zs: FloatArray, mu: float) -> tuple[FloatArray, FloatArray]:
    """All eigenpairs of Z(μ) = Z0 + μ Z1 - μ² Z2 (eq 12), ascending; column 0 is the smallest.
    ``Zs`` is ``(Z0, Z1, Z2)`` stacked and flattened, (3, 16)."""
    return eigh(np.dot((1.0, mu, -mu * mu), Zs).reshape(4, 4))


def _f_and_slope(Z12: FloatArray, mu: float, lam: list[float], V: FloatArray
                 ) -> tuple[float, float, list[float], float]:
    """``f(μ)`` of eq 18, its derivative from second-order eigenvalue perturbation, the first-order
    change of the eigenvector q₀ per unit μ in the eigenbasis, and the (floored) gap λ₁ - λ₀.

    ``Z12`` stacks Z1 and Z2; with ``c_a = qₐᵀ(Z1 - 2μZ2)q₀`` (``dZ(μ)/dμ = Z1 - 2μZ2``):
    ``f = -½ c₀``, ``f' = q₀ᵀZ2q₀ + Σ_{a>0} c_a² / (λ_a - λ₀)`` and ``dq₀/dμ = Σ_{a>0} c_a/(λ₀ - λ_a) qₐ``.
    The arithmetic on the four numbers is done in Python floats, cheaper than numpy calls at this size.
    """
    z1, z2 = (V[:, 0] @ Z12 @ V).tolist()          # q₀ᵀZ1qₐ, q₀ᵀZ2qₐ
    l0, l1, l2, l3 = lam
    floor = _EPS * max(abs(l3), 1.0)
    tm = 2.0 * mu
    c1, c2, c3 = z1[1] - tm * z2[1], z1[2] - tm * z2[2], z1[3] - tm * z2[3]
    g1, g2, g3 = max(l1 - l0, floor), max(l2 - l0, floor), max(l3 - l0, floor)
    r1, r2, r3 = c1 / g1, c2 / g2, c3 / g3
    f = 0.5 * (tm * z2[0] - z1[0])
    return f, z2[0] + c1 * r1 + c2 * r2 + c3 * r3, [0.0, -r1, -r2, -r3], g1


def _rotated(V: FloatArray, step: float, dq: list[float]) -> FloatArray:
    """The orthonormal basis ``V (I + δK)`` with ``K`` antisymmetric, ``K[a, 0] = dq[a]``: its first
    column is the perturbed eigenvector ``q₀ + δ Σ dq[a] qₐ`` and the others stay orthogonal to it,
    up to ``δ² |dq|²`` (below rounding where it is used). Columns are normalised exactly."""
    _, d1, d2, d3 = (step * d for d in dq)
    s0 = (1.0 + d1 * d1 + d2 * d2 + d3 * d3) ** -0.5
    s1, s2, s3 = (1.0 + d1 * d1) ** -0.5, (1.0 + d2 * d2) ** -0.5, (1.0 + d3 * d3) ** -0.5
    rotated: FloatArray = V @ np.array([[s0, -d1 * s1, -d2 * s2, -d3 * s3],
                                        [d1 * s0, s1, 0.0, 0.0],
                                        [d2 * s0, 0.0, s2, 0.0],
                                        [d3 * s0, 0.0, 0.0, s3]])
    return rotated


def _mu_bracket(Z1: FloatArray, Re: FloatArray) -> tuple[float, float]:
    """Appendix C: every solution μ lies between the extreme generalised eigenvalues of (½Z1, Z2).

    With ``Z2 = M⁻¹ = Re⁻¹ Re⁻ᵀ`` (``E = Qe Re``) they are the eigenvalues of ``Re (½Z1) Reᵀ``.
    """
    theta, _ = eigh(Re @ (0.5 * Z1) @ Re.T, vectors=False)
    lo, hi = theta[0], theta[-1]
    pad = 1e-12 * max(abs(lo), abs(hi), 1e-300)
    return float(lo - pad), float(hi + pad)


def kkt_polish(problem: Problem, q: FloatArray, qd: FloatArray, lam: float, mu: float,
               iterations: int = 8) -> tuple[FloatArray, FloatArray, float, float]:
    """Newton's method on the stationarity conditions of cost (8) with both constraints.

    Unknowns ``(q, q', λ, μ)``; equations ``Sq + Wq' - λq - μq' = 0``, ``Wᵀq + Mq' - μq = 0``
    (eq 10), ``|q|² = 1`` and ``q·q' = 0``. A step is kept only if it does not raise the cost.
    """
    S, M, W = problem.S, problem.M, problem.W
    I4 = np.eye(4)
    best = problem.cost(q, qd)
    for _ in range(iterations):
        r = np.concatenate([S @ q + W @ qd - lam * q - mu * qd, W.T @ q + M @ qd - mu * q,
                            [0.5 * (1.0 - q @ q), -(q @ qd)]])
        J = np.zeros((10, 10))
        J[:4, :4] = S - lam * I4
        J[:4, 4:8] = W - mu * I4
        J[4:8, :4] = W.T - mu * I4
        J[4:8, 4:8] = M
        J[:4, 8], J[:4, 9], J[4:8, 9] = -q, -qd, -q
        J[8, :4], J[9, :4], J[9, 4:8] = -q, -qd, -q
        try:
            step = np.linalg.solve(J, -r)
        except np.linalg.LinAlgError:
            step = np.linalg.lstsq(J, -r, rcond=None)[0]
        q_new, qd_new = q + step[:4], qd + step[4:8]
        n = np.linalg.norm(q_new)
        q_new, qd_new = q_new / n, qd_new / n
        qd_new = qd_new - (q_new @ qd_new) * q_new        # stay exactly on the constraint set
        cost = problem.cost(q_new, qd_new)
        if not cost <= best:
            break
        converged = np.abs(step[:8]).max() <= 4 * _EPS
        q, qd, lam, mu, best = q_new, qd_new, lam + step[8], mu + step[9], cost
        if converged:
            break
    return q, qd, float(lam), float(mu)


def _result(problem: Problem, V: FloatArray, mu: float, lam: list[float], iterations: int,
            converged: bool) -> LineSearchResult:
    """Complete the smallest eigenvector ``q`` of Z(μ) (M regular) with its optimal dual part (eq 20,
    by least squares: ``M⁻¹`` amplifies rounding when the cost is tiny). The eigenvector's error is
    about eps·|Z(μ)|/gap; where that is not negligible (ill-conditioned problems), polish the pair
    on the KKT system. ``lam``: the eigenvalues as a list."""
    q = V[:, 0]
    qd = problem._dual(q, V[:, 1:], full_rank=True)[0]     # the other eigenvectors: a basis of q's complement
    l0, l1, _, l3 = lam
    if _EPS * max(abs(l0), abs(l3)) > 1e-10 * (l1 - l0):
        q, qd, l0, mu = kkt_polish(problem, q, qd, l0, mu)
    return LineSearchResult(q, qd, l0, float(mu), iterations, converged)


def _singular(problem: Problem) -> LineSearchResult:
    """M singular: start from the relaxed solution (exact at μ = 0 on noise-free data, §3.1.2) and
    polish on the KKT system, which needs no inverse of M."""
    lam, V = eigh(problem.Z0_relaxed)
    q = V[:, 0]
    qd, mu = problem.dual_part(q)
    q, qd, lam0, mu = kkt_polish(problem, q, qd, float(lam[0]), mu)
    return LineSearchResult(q, qd, lam0, mu, 0, True, singular_m=True)


def dqopt(problem: Problem, max_iterations: int = 100) -> LineSearchResult:
    """Algorithm 1 (DQOpt): the global minimiser of cost (8), to machine precision.

    Newton's method on the increasing function f (eq 18) from μ = 0, safeguarded by bisection:
    every evaluation narrows a sign bracket, and once a step would leave it, or the second step is
    not already negligible, the bracket is also cut to the bounds of appendix C. A step δ so small that
    the second-order change of the eigenvector, about ``δ² (|Z1 - 2μZ2|²/gap² + |Z2|/gap)``, is
    below rounding is not taken with another eigendecomposition but by first-order perturbation,
    ``q₀ + δ Σ c_a/(λ₀ - λ_a) qₐ``. On noisy data that is the second step: the first, from μ = 0,
    is the second-order estimate of DQ2ndOrd (§3.2.4) and typically lands within a relative 1e-8 of μ*.
    """
    if not problem.M_is_regular:
        return _singular(problem)
    Zs = problem._Zs
    Z12 = Zs[1:]
    n1, n2 = float(np.vdot(Zs[1], Zs[1])) ** 0.5, float(np.vdot(Zs[2], Zs[2])) ** 0.5      # Frobenius
    ev, V = eigh(Zs[0])
    lam: list[float] = ev.tolist()
    Zs = Zs.reshape(3, 16)
    lo, hi = -np.inf, np.inf
    bracketed = False
    mu = 0.0
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):
        f, slope, dq, gap = _f_and_slope(Z12, mu, lam, V)
        if f == 0.0:
            converged = True
            break
        if f < 0.0:
            lo = mu
        else:
            hi = mu
        # a step whose second-order effect on the eigenvector is below rounding
        negligible = _EPS / (((n1 + 2.0 * abs(mu) * n2) / gap) ** 2 + n2 / gap)
        new = mu - f / slope
        if not (lo < new < hi and (it == 1 or bracketed or (new - mu) ** 2 <= negligible)):
            if not bracketed:
                blo, bhi = _mu_bracket(Z12[0], problem.R_factor)
                lo, hi, bracketed = max(lo, blo), min(hi, bhi), True
            if not lo < new < hi:
                new = 0.5 * (lo + hi)
        step = new - mu
        if step * step <= negligible:
            V = _rotated(V, step, dq)
            lam[0] += step * (-2.0 * f - step * slope)             # λ₀ to second order
            mu = new
            converged = True
            break
        if bracketed and hi - lo <= 4.0 * _EPS * max(abs(lo), abs(hi)):
            converged = True
            break
        mu = new
        ev, V = _smallest(Zs, mu)
        lam = ev.tolist()
    return _result(problem, V, mu, lam, it, converged)


def dqitr(problem: Problem, tolerance: float = 1e-12, max_iterations: int = 100) -> LineSearchResult:
    """Algorithm 5 (DQItr): iterate μ ← ½ q(μ)ᵀZ1q(μ) / q(μ)ᵀZ2q(μ) (eq 24) from μ = 0.

    Converges quickly on noisy data; the paper notes it is unstable on noise-free data, and
    it may cycle. ``converged`` says whether ``|Δμ| ≤ tolerance·max(1, |μ|)`` was reached.
    """
    if not problem.M_is_regular:
        return _singular(problem)
    Zs = problem._Zs
    Z12 = Zs[1:]
    Zs = Zs.reshape(3, 16)
    mu = 0.0
    converged = False
    it = 0
    lam, V = _smallest(Zs, mu)
    while it < max_iterations:
        it += 1
        q = V[:, 0]
        z1, z2 = (Z12 @ q @ q).tolist()
        new = 0.5 * z1 / z2
        done = abs(new - mu) <= tolerance * max(1.0, abs(mu))
        mu = new
        lam, V = _smallest(Zs, mu)
        if done:
            converged = True
            break
    return _result(problem, V, mu, lam.tolist(), it, converged)
