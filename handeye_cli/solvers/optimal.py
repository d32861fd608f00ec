"""The optimal solvers: DQOpt (Algorithm 1, §3.2.1) and the fixed-point iteration DQItr (Algorithm 5, §3.2.5).

Both search the Lagrange multiplier μ of the constraint ``q·q' = 0``. For a given μ the
smallest eigenpair ``(λ₀(μ), q₀(μ))`` of ``Z(μ) = Z0 + μ Z1 - μ² Z2`` (eq 12) is the best
unit ``q``; λ₀ is concave in μ (§3.1.2, footnote 4) and the optimum is its maximum, the unique
root of the increasing function ``f(μ) = q₀ᵀ (μ Z2 - ½ Z1) q₀ = -½ dλ₀/dμ`` (eq 18).

DQOpt brackets the root with the bounds of appendix C — μ = ½ qᵀZ1q / qᵀZ2q (eq 14) is a
generalised Rayleigh quotient, so every root lies between the extreme generalised eigenvalues
of (½ Z1, Z2), where f changes sign — and runs safeguarded Newton steps on the analytic
derivative ``f'(μ) = q₀ᵀZ2q₀ + Σₐ (qₐᵀ(Z1 - 2μZ2)q₀)² / (λₐ - λ₀) > 0`` (second-order
perturbation of λ₀), falling back to bisection whenever a step leaves the bracket.

M singular (noise-free data, or rotations that are exact while translations are not) breaks
eq 11. There the solvers start from the relaxed solution — the solution itself on noise-free
data, where μ* = 0 — and polish it by Newton's method on the exact KKT system of cost (8)
(eq 10 plus both constraints), which converges quadratically and never inverts M.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .problem import Problem

__all__ = ["LineSearchResult", "dqopt", "dqitr", "kkt_polish"]

_EPS = np.finfo(float).eps


@dataclass(frozen=True)
class LineSearchResult:
    """Solution ``q + ε q'`` with its multipliers and how the search went."""

    q: np.ndarray
    qd: np.ndarray
    lam: float
    mu: float
    iterations: int
    converged: bool
    singular_m: bool = False


def _smallest(Z0: np.ndarray, Z1: np.ndarray, Z2: np.ndarray, mu: float) -> tuple[np.ndarray, np.ndarray]:
    """All eigenpairs of Z(μ) (eq 12), ascending; column 0 is the smallest."""
    return np.linalg.eigh(Z0 + mu * Z1 - (mu * mu) * Z2)


def _f_and_slope(Z1: np.ndarray, Z2: np.ndarray, mu: float, lam: np.ndarray, V: np.ndarray) -> tuple[float, float]:
    """``f(μ)`` of eq 18 and its derivative from second-order eigenvalue perturbation."""
    q = V[:, 0]
    z2q = Z2 @ q
    f = mu * (q @ z2q) - 0.5 * (q @ Z1 @ q)
    coupling = V[:, 1:].T @ ((Z1 - 2.0 * mu * Z2) @ q)
    gaps = np.maximum(lam[1:] - lam[0], _EPS * max(abs(lam[-1]), 1.0))
    return float(f), float(q @ z2q + np.sum(coupling * coupling / gaps))


def _mu_bracket(Z1: np.ndarray, Re: np.ndarray) -> tuple[float, float]:
    """Appendix C: every solution μ lies between the extreme generalised eigenvalues of (½Z1, Z2).

    With ``Z2 = M⁻¹ = Re⁻¹ Re⁻ᵀ`` (``E = Qe Re``) they are the eigenvalues of ``Re (½Z1) Reᵀ``.
    """
    theta = np.linalg.eigvalsh(Re @ (0.5 * Z1) @ Re.T)
    pad = 1e-12 * max(abs(theta[0]), abs(theta[-1]), 1e-300)
    return float(theta[0] - pad), float(theta[-1] + pad)


def kkt_polish(problem: Problem, q: np.ndarray, qd: np.ndarray, lam: float, mu: float,
               iterations: int = 8) -> tuple[np.ndarray, np.ndarray, float, float]:
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


def _result(problem: Problem, V: np.ndarray, mu: float, lam: np.ndarray, iterations: int,
            converged: bool) -> LineSearchResult:
    """Complete the smallest eigenvector ``q`` of Z(μ) with its optimal dual part (eq 20, by least
    squares: ``M⁻¹`` amplifies rounding when the cost is tiny). The eigenvector's error is about
    eps·|Z(μ)|/gap; where that is not negligible (ill-conditioned problems), polish the pair on
    the KKT system."""
    q = V[:, 0]
    qd, _ = problem.dual_part(q)
    if _EPS * max(abs(lam[0]), abs(lam[-1])) > 1e-10 * (lam[1] - lam[0]):
        q, qd, lam0, mu = kkt_polish(problem, q, qd, float(lam[0]), mu)
        return LineSearchResult(q, qd, lam0, mu, iterations, converged)
    return LineSearchResult(q, qd, float(lam[0]), float(mu), iterations, converged)


def _singular(problem: Problem) -> LineSearchResult:
    """M singular: start from the relaxed solution (exact at μ = 0 on noise-free data, §3.1.2) and
    polish on the KKT system, which needs no inverse of M."""
    lam, V = np.linalg.eigh(problem.Z0_relaxed)
    q = V[:, 0]
    qd, mu = problem.dual_part(q)
    q, qd, lam0, mu = kkt_polish(problem, q, qd, float(lam[0]), mu)
    return LineSearchResult(q, qd, lam0, mu, 0, True, singular_m=True)


def dqopt(problem: Problem, max_iterations: int = 100) -> LineSearchResult:
    """Algorithm 1 (DQOpt): the global minimiser of cost (8), to machine precision."""
    if not problem.M_is_regular:
        return _singular(problem)
    Z0, Z1, Z2 = problem.Z
    lo, hi = _mu_bracket(Z1, problem.R_factor)
    mu = min(max(0.0, lo), hi)
    lam, V = _smallest(Z0, Z1, Z2, mu)
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):
        f, slope = _f_and_slope(Z1, Z2, mu, lam, V)
        if f == 0.0:
            converged = True
            break
        if f < 0.0:
            lo = mu
        else:
            hi = mu
        step = -f / slope if slope > 0 else np.inf
        new = mu + step
        if not (lo < new < hi):
            new = 0.5 * (lo + hi)
        tol = 2.0 * _EPS * max(abs(mu), abs(new), _EPS)
        if abs(new - mu) <= tol or hi - lo <= tol:
            converged = True
            mu = new
            lam, V = _smallest(Z0, Z1, Z2, mu)
            break
        mu = new
        lam, V = _smallest(Z0, Z1, Z2, mu)
    return _result(problem, V, mu, lam, it, converged)


def dqitr(problem: Problem, tolerance: float = 1e-12, max_iterations: int = 100) -> LineSearchResult:
    """Algorithm 5 (DQItr): iterate μ ← ½ q(μ)ᵀZ1q(μ) / q(μ)ᵀZ2q(μ) (eq 24) from μ = 0.

    Converges quickly on noisy data; the paper notes it is unstable on noise-free data, and
    it may cycle. ``converged`` says whether ``|Δμ| ≤ tolerance·max(1, |μ|)`` was reached.
    """
    if not problem.M_is_regular:
        return _singular(problem)
    Z0, Z1, Z2 = problem.Z
    mu = 0.0
    converged = False
    it = 0
    lam, V = _smallest(Z0, Z1, Z2, mu)
    for it in range(1, max_iterations + 1):
        q = V[:, 0]
        new = 0.5 * (q @ Z1 @ q) / (q @ Z2 @ q)
        done = abs(new - mu) <= tolerance * max(1.0, abs(mu))
        mu = new
        lam, V = _smallest(Z0, Z1, Z2, mu)
        if done:
            converged = True
            break
    return _result(problem, V, mu, lam, it, converged)
