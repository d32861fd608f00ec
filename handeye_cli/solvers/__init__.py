"""Solvers of ``A_i X = X B_i`` for ``X = T_a_b`` (Dekel, Härenstam-Nielsen, Caccamo).

``solve()`` is the entry point; ``METHODS`` lists the algorithms. The optimal one, ``dqopt``,
is the default. Motions follow the project convention: ``A_i = T_wa(t_i)⁻¹ T_wa(t_j)``,
``B_i = T_wb(t_i)⁻¹ T_wb(t_j)``; the extrinsic maps points from b to a.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cached_property, partial

import numpy as np

from .._typing import FloatArray
from ..errors import ConfigError, UnderdeterminedError
from ..geometry import dualquat
from .approximate import dq2ndord, dq2steps, dqconvrlx
from .certificate import Certificate, certify
from .classical import CLASSICAL
from .daniilidis import daniilidis
from .optimal import dqitr, dqopt
from .problem import (
    Prior,
    Problem,
    build_problem,
    checked_arrays,
    disagreeing_signs,
    eigh,
    motion_problem,
    near_half_turns,
    pair_blocks,
    problem_from_blocks,
    validate_motions,
)

__all__ = ["Certificate", "METHODS", "OPTIMAL", "Prior", "Problem", "Solution", "build_problem", "solve"]

METHODS = ("dqopt", "dq2steps", "dqconvrlx", "dq2ndord", "dqitr", "daniilidis", *CLASSICAL)
OPTIMAL = ("dqopt", "dqitr")
"""The methods that claim the global minimum of cost (8): a failed certificate of theirs is a warning."""
_SIGN_ROUNDS = 3         # re-solves with the signs of the estimate (one suffices but for a chain of half-turns)


@dataclass(frozen=True, eq=False)
class Solution:
    """The result of one solve.

    Attributes
    ----------
    matrix:
        (4, 4) ``T_a_b``: pose of frame b in frame a, maps points from b to a.
    cost:
        Cost (8) at the solution, plus the prior terms of eq 26 when a prior is given.
    method, alpha:
        The algorithm and the weight α [1/m] used.
    lam, mu:
        Lagrange multipliers λ (= the cost without the prior's constant, eq 10) and μ where
        the method defines them (``None`` otherwise).
    iterations, converged:
        For the iterative methods (dqopt, dqitr).
    details:
        Method-specific figures, e.g. DQConvRlx's ``gap_bound`` (eq 22).
    problem, dual_quaternion:
        The cost the solution was measured on and, where the method computed it, the solution's unit dual
        quaternion ``(q, q')`` (x-y-z-w parts; else taken from ``matrix``), for :attr:`certificate`.
    optimum:
        For an estimate that is not the minimum of a cost (8) (``problem`` None: the reduced in-plane solve of
        planar motion, or the maximum-likelihood refinement): the optimum of cost (8) it was made from, whose
        certificate the result document keeps, marked ``of: optimum``, beside its cost and pose
        (:func:`~handeye_cli.output.document.solver_section`).
    """

    matrix: FloatArray
    cost: float
    method: str
    alpha: float
    pairs: int
    lam: float | None = None
    mu: float | None = None
    iterations: int | None = None
    converged: bool | None = None
    details: Mapping[str, float | bool] = field(default_factory=dict)
    problem: Problem | None = field(default=None, repr=False)
    dual_quaternion: tuple[FloatArray, FloatArray] | None = field(default=None, repr=False)
    optimum: Solution | None = field(default=None, repr=False)

    @cached_property
    def certificate(self) -> Certificate | None:
        """The Lagrangian proof that the solution is the global minimum of its cost (8) (+ prior), or not
        (:mod:`.certificate`); computed on first use (10–25 µs), for every method: dqopt passes it on every problem
        (a failure is a numerical one), the approximations only where they reach the optimum. None without a
        :attr:`problem`."""
        if self.problem is None:
            return None
        return certify(self.problem, *(self.dual_quaternion or dualquat.from_transforms(self.matrix)))

    @property
    def warnings(self) -> tuple[str, ...]:
        """One line when a method of :data:`OPTIMAL` failed its certificate (a numerical failure), else none."""
        c = self.certificate
        if self.method not in OPTIMAL or c is None or c.certified:
            return ()
        fix = ("dqitr did not reach the optimum: use ⟦method='dqopt'⟧" if self.method == "dqitr" else
               "a numerical failure of dqopt: compare with ⟦method='dqitr'⟧ and report the data")
        return (f"the {self.method} solution is not certified as the global optimum (solver.certificate: smallest "
                f"eigenvalue {c.min_eigenvalue:.3g}, stationarity {c.stationarity:.3g}, tolerance {c.tolerance:.3g}): "
                f"{fix}",)

    @property
    def translation(self) -> FloatArray:
        """Translation of ``T_a_b`` [m]."""
        t: FloatArray = self.matrix[:3, 3].copy()
        return t

    @property
    def quaternion_xyzw(self) -> FloatArray:
        """Rotation of ``T_a_b`` as a unit quaternion x, y, z, w with w ≥ 0."""
        q, _ = dualquat.from_transforms(self.matrix)
        return q


def _check_determined(problem: Problem) -> None:
    """Refuse a truly under-determined problem: cost (8) has a null space beyond the solution's own.

    Noise-free data leaves two null directions of the 8x8 form (the solution and ``(0, q)``);
    a third means a whole family of extrinsics fits exactly (e.g. planar motion: translation
    along the normal; a single rotation axis: rotation about it).
    """
    ev, _ = eigh(problem.form, vectors=False)
    null = int(np.count_nonzero(ev <= 1e-13 * max(ev[-1], 1e-300)))
    if null >= 3:
        raise UnderdeterminedError("the motions cannot determine the extrinsic: a family of solutions fits "
                           "them exactly (all motions about one axis, or planar, or too few)",
                           "motions", "add motion about a second rotation axis, or pass a prior "
                           "(⟦prior=FILE⟧) to fix the unobservable directions")


def solve(motions_a: FloatArray, motions_b: FloatArray, method: str = "dqopt", alpha: float = 1.0,
          prior: Prior | None = None, weights: FloatArray | None = None) -> Solution:
    """Solve ``A_i X = X B_i`` for ``X = T_a_b`` in the least-squares sense of the paper's cost (8).

    Parameters
    ----------
    motions_a, motions_b:
        (N, 4, 4) relative motions of sensors a and b over the same time intervals.
    method:
        One of :data:`METHODS`; ``dqopt`` (Algorithm 1) is the global optimum.
    alpha:
        Weight of the translational residuals [1/m] (eq 8).
    prior:
        Optional :class:`Prior` (eqs 26–29): pulls the solution toward ``prior.T_a_b``.
    weights:
        Optional (N,) non-negative per-pair weights (default 1).

    Raises
    ------
    HandEyeError
        Bad shapes, non-finite values, non-rotation blocks, unknown method, or a problem whose
        motions cannot determine the extrinsic.

    Examples
    --------
    Noise-free motions of the paper's "random" scenario (appendix D.2) give back the true
    extrinsic; with noise, dqopt has the lowest cost (8) of all methods.

    >>> import numpy as np
    >>> from handeye_cli.solvers import METHODS, solve
    >>> from handeye_cli.simulation import motion_pairs, random_transform
    >>> rng = np.random.default_rng(0)
    >>> X = random_transform(rng)                      # the true T_a_b
    >>> A, B = motion_pairs(50, X, rng)                 # (50, 4, 4) each, A_i X = X B_i
    >>> sol = solve(A, B, method="dqopt", alpha=1.0)
    >>> bool(np.allclose(sol.matrix, X, atol=1e-9)), sol.pairs, sol.method
    (True, 50, 'dqopt')
    >>> A, B = motion_pairs(50, X, rng, sigma_r=0.01, sigma_t=0.01)
    >>> costs = {m: solve(A, B, method=m).cost for m in METHODS}
    >>> all(costs["dqopt"] <= cost * (1 + 1e-12) for cost in costs.values())   # ties to rounding allowed
    True
    """
    if method not in METHODS:
        raise ConfigError(f"unknown method {method!r}", "method", f"choose one of {', '.join(METHODS)}")
    if method == "daniilidis":                                 # needs the per-pair blocks: few pairs
        A, B, w = validate_motions(motions_a, motions_b, weights)
    else:
        A, B, w = checked_arrays(motions_a, motions_b, weights)
    near = near_half_turns(A, B)
    build = _builder(A, B, w, method, alpha, prior)
    solution = _solution(A, B, w, method, alpha, *build(None))
    # A half-turn's pair whose signs the invariants told wrong costs as much as a 180° error: agree them by the
    # estimate and solve again, until the estimate's signs stand (each round lowers cost (8) at the estimate).
    before = None
    for _ in range(_SIGN_ROUNDS if len(near) else 0):
        reference = solution.matrix
        if not disagreeing_signs(A[near], B[near], alpha, reference, before):
            break
        solution, before = _solution(A, B, w, method, alpha, *build(reference)), reference
    return solution


_Built = tuple[Problem, tuple[FloatArray, FloatArray] | None]


def _builder(A: FloatArray, B: FloatArray, w: FloatArray, method: str, alpha: float, prior: Prior | None
             ) -> Callable[[FloatArray | None], _Built]:
    """The problem of checked motions as a function of ``reference`` (an estimate of X, 4×4, that agrees the signs
    of the pairs near a half-turn: :func:`~handeye_cli.geometry.dualquat.sign_flips`; None: the invariants),
    with Daniilidis' per-pair blocks. Built again whole when the signs change (it is one pass over the motions,
    and it happens only where a pair is near a half-turn and the invariants told it wrong)."""
    if method == "daniilidis":
        def blocks(reference: FloatArray | None) -> _Built:
            E, F = pair_blocks(A, B, alpha, reference)
            return _checked(problem_from_blocks(E, F, w, alpha=alpha, prior=prior), prior), (E, F)
        return blocks
    return lambda reference: (_checked(motion_problem(A, B, w, alpha=alpha, prior=prior, reference=reference),
                                       prior), None)


def _checked(problem: Problem, prior: Prior | None) -> Problem:
    """``problem``, refused when its motions cannot determine X without a prior (:func:`_check_determined`)."""
    if prior is None:
        _check_determined(problem)
    return problem


def _solution(A: FloatArray, B: FloatArray, w: FloatArray, method: str, alpha: float, problem: Problem,
              blocks: tuple[FloatArray, FloatArray] | None) -> Solution:
    """:func:`solve`'s method on checked motions and their ``problem`` (Daniilidis': and per-pair ``blocks``)."""
    common = partial(Solution, method=method, alpha=float(alpha), pairs=len(A), problem=problem)
    if method in ("dqopt", "dqitr"):
        r = (dqopt if method == "dqopt" else dqitr)(problem)
        return common(dualquat.to_transform(r.q, r.qd), problem.cost(r.q, r.qd), lam=r.lam, mu=r.mu,
                      iterations=r.iterations, converged=r.converged, details={"singular_m": r.singular_m},
                      dual_quaternion=(r.q, r.qd))
    if method in CLASSICAL:
        X = CLASSICAL[method](A, B, w)
        return common(X, problem.cost(*dualquat.from_transforms(X)))
    if method == "daniilidis":
        assert blocks is not None
        q, qd = daniilidis(*blocks, alpha=alpha, weights=w)
        return common(dualquat.to_transform(q, qd), problem.cost(q, qd), dual_quaternion=(q, qd))
    approx = {"dq2steps": dq2steps, "dqconvrlx": dqconvrlx, "dq2ndord": dq2ndord}[method](problem)
    return common(dualquat.to_transform(approx.q, approx.qd), problem.cost(approx.q, approx.qd), mu=approx.mu,
                  details=approx.details, dual_quaternion=(approx.q, approx.qd))
