"""Joint refinement of a rig: every ``T_ref_k`` from all pairwise results, weighed by their joint covariance.

Each calibrated pair (j, k) gives an estimate ``X̂_jk`` of ``T_j_k`` — the optimum of its cost (8).
The pairwise estimates are not independent: pairs (j, k) and (j, l) share stream j's noise, so
summing their costs as if they were counts stream j twice. :mod:`.noise` propagates every pose
sample's noise to every pairwise estimate and gives their joint covariance ``C`` (6E x 6E). The
rig is then the generalised least squares of the pairwise estimates::

    J(T_ref_1 … T_ref_n) = zᵀ C⁻¹ z,   z_jk = Log(T_ref_j⁻¹ T_ref_k X̂_jk⁻¹)   (rotation [rad], translation [m])

consistent by construction (every ``T_j_k`` is ``T_ref_j⁻¹ T_ref_k``), and, to first order, at
least as accurate as any chain of pairwise results for every sensor, in rotation and in
translation: a chain is a linear unbiased combination of the same estimates (Gauss–Markov). Each
pair's rotation and translation, and their correlations with the other pairs', are weighed by
the noise the data show, not by one α or by how many motion pairs each pair has.

Before that, each pairwise estimate may carry a correction: the first-order bias of its streams'
relative drift, removed where that drift is significant (:mod:`.noise`); ``estimates`` are the
corrected ones and ``steps`` the corrections, so the bootstrap can apply them to its re-solves.

:func:`consistency` tests the pairwise estimates against each other: at the joint optimum J is a
χ² of ``6(E - n + 1)`` degrees of freedom when the noise model holds; removing sensor s's pairs
lowers it by a χ² of ``6(deg s - 1)`` (the innovation of its pairs given the others', linear
Gaussian least squares). When the whole rig's J is improbable (p < :data:`CONSISTENCY_P_VALUE`),
the sensor whose removal lowers it most improbably — and itself improbably — is the suspect.

The unknowns are perturbations ``T_ref_k Exp(δ_k)`` (rotation vector [rad], right; translation
[m], added in the reference frame) of every non-reference sensor, solved by Gauss–Newton
(first-order Jacobian) from the graph synchronisation's estimate. :func:`bootstrap_rig` resamples time blocks shared by
all pairs (a block's count multiplies every motion pair that starts in it), re-solves each pair on
its re-weighted cost (8) and the rig from those estimates.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from ..analysis.covariance import constrained_hessian
from ..geometry import dualquat as dq
from ..geometry import se3
from ..geometry.lie import log_errors, skew
from ..numeric.chi2 import chi2_log_sf, chi2_sf
from ..solvers.problem import split_forms
from .graph import connected

__all__ = ["Motions", "JointProblem", "refine", "bootstrap_rig", "RigUncertainty", "part_costs",
           "resolve_pairs", "whitening", "Consistency", "consistency", "CONSISTENCY_P_VALUE"]

Array = NDArray[np.float64]
Motions = tuple[Array, Array, Array, Array, float]   # A, B (N, 4, 4); start stamps [ns] (N,); pair weights (N,); α
_EIGEN_FLOOR = 1e-12      # the smallest eigenvalue of C kept, relative to the largest
# The rig is called inconsistent, and a stream named, when the χ² is this improbable under the noise
# model. Measured on 20 clean simulated rigs of each kind (seeds 0–19): with tracking gaps and drift
# 1 is called inconsistent (2 at 0.01), with gaps 0, with neither 0, with drift 0; the noise model's
# residual errors make the tail heavier than a χ²'s. tests/rig/test_rig.py checks the rest of its rigs
# (gaps, drifting wheels) without their bad stream: 2 of 20 below it.
CONSISTENCY_P_VALUE = 1e-3


def part_costs(forms: Array, T: Array) -> Array:
    """``[q'; q]ᵀ Q_p [q'; q]`` of transforms T (E, 4, 4) for forms (E, 2, 8, 8): (E, 2)."""
    q, qd = dq.from_transforms(T)
    v = np.concatenate((qd, q), axis=1)
    return np.asarray(np.einsum("ei,epij,ej->ep", v, forms, v), dtype=np.float64)



def whitening(C: Array) -> Array:
    """``W`` with ``WᵀW = C⁻¹`` for a covariance C, its eigenvalues floored at ``_EIGEN_FLOOR`` of the
    largest (combinations of the pairwise estimates that the noise model calls exact stay finite)."""
    lam, V = np.linalg.eigh(C)
    lam = np.maximum(lam, _EIGEN_FLOOR * max(float(lam.max()), np.finfo(float).tiny))
    return np.asarray((V / np.sqrt(lam)).T, dtype=np.float64)


@dataclass(frozen=True, eq=False)
class JointProblem:
    """The rig's generalised least squares: ``pairs`` (E edges (j, k)), their pairwise estimates
    ``estimates`` (E, 4, 4) ``X̂_jk``, the joint ``covariance`` (6E, 6E) of their errors (left
    perturbations, rotation [rad] and translation [m] per edge), each pair's cost (8) as
    ``forms`` (E, 2, 8, 8) (rotational, dual; ``[q'; q]`` order), the ``reference`` and ``n`` sensors.
    ``steps`` (E, 4, 4): the drift corrections applied, ``estimates = steps · pairwise-only``
    (identity where none). ``bias`` (6E, 6E): the bound of the bias left in the corrected estimates
    (:func:`~handeye_cli.rig.noise.bias_bound`), added to the covariance where the pairs are combined
    (:func:`refine`), not where they are tested against each other (:func:`consistency`, :meth:`cost`).
    ``excluded``: a sensor whose pairs do not inform the others' extrinsics (a named bad stream)."""

    n: int
    reference: int
    pairs: list[tuple[int, int]]
    estimates: Array
    covariance: Array
    forms: Array
    steps: Array
    bias: Array
    excluded: int | None = None

    @cached_property
    def whitening(self) -> Array:
        """``W`` with ``WᵀW = C⁻¹`` (see :func:`whitening`)."""
        return whitening(self.covariance)

    @cached_property
    def combining(self) -> Array:
        """``W`` with ``WᵀW = (C + bias)⁻¹``: how the pairs are weighed in the combination."""
        return whitening(self.covariance + self.bias)

    def edge_std(self) -> Array:
        """(E, 2) predicted RMS error of each pairwise-only estimate: rotation [rad], translation [m]."""
        d = np.diag(self.covariance).reshape(-1, 2, 3)
        return np.asarray(np.sqrt(np.clip(d, 0.0, None).sum(axis=2)), dtype=np.float64)

    def relative(self, T: Array) -> Array:
        """``T_j_k = T_ref_j⁻¹ T_ref_k`` (E, 4, 4) of every edge."""
        j, k = (np.array([p[i] for p in self.pairs]) for i in (0, 1))
        return np.asarray(se3.inverse(T[j]) @ T[k], dtype=np.float64)

    def errors(self, T: Array, estimates: Array | None = None) -> Array:
        """``z`` (E, 6): ``Log(T_j_k X̂_jk⁻¹)`` of the rig ``T`` against the pairwise estimates."""
        X = self.estimates if estimates is None else estimates
        return np.asarray(log_errors(self.relative(T) @ se3.inverse(X)), dtype=np.float64)

    def edge_costs(self, T: Array) -> Array:
        """Each pair's own cost (8) at its α and pair weights at the rig ``T`` (n, 4, 4)."""
        return np.asarray(part_costs(self.forms, self.relative(T)).sum(axis=1), dtype=np.float64)

    def cost(self, T: Array, edges: NDArray[np.bool_] | None = None) -> float:
        """J = zᵀ C⁻¹ z (a χ² with 6(E - n + 1) degrees of freedom when the noise model holds), over
        the ``edges`` kept (default all)."""
        if edges is None or edges.all():
            return float(np.sum(np.square(self.whitening @ self.errors(T).ravel())))
        keep = np.repeat(edges, 6)
        return float(np.sum(np.square(whitening(self.covariance[np.ix_(keep, keep)]) @ self.errors(T)[edges].ravel())))


def _perturbed(T0: Array, free: NDArray[np.bool_], p: Array) -> Array:
    T = T0.copy()
    d = p.reshape(-1, 6)
    T[free, :3, :3] = T0[free, :3, :3] @ dq.to_matrix(dq.from_rotvec(d[:, :3]))
    T[free, :3, 3] = T0[free, :3, 3] + d[:, 3:]
    return np.asarray(T, dtype=np.float64)


def _jacobian(problem: JointProblem, T: Array, free: NDArray[np.bool_], edges: NDArray[np.bool_],
              X: Array) -> Array:
    """``∂z/∂p`` (6E', 6F) of the kept edges' errors at the rig ``T`` for the free sensors' perturbations
    ``p`` (:func:`_perturbed`), to first order in z: with ``G = R_jᵀ R_k``, ``s = R̂ᵀ t̂`` and ``u`` the
    translation of ``T_j⁻¹ T_k X̂⁻¹``, the rotation moves by ``-ω_j + R̂ ω_k`` and the translation by
    ``[u]× ω_j - R_jᵀ v_j + G [s]× ω_k + R_jᵀ v_k``."""
    column = np.cumsum(free) - 1
    kept = [(p, Xe) for p, Xe, e in zip(problem.pairs, X, edges, strict=True) if e]
    out = np.zeros((len(kept), 6, 6 * int(free.sum())))
    eye = np.eye(3)
    for r, ((j, k), Xe) in enumerate(kept):
        Rj_t, G = T[j, :3, :3].T, T[j, :3, :3].T @ T[k, :3, :3]
        s = Xe[:3, :3].T @ Xe[:3, 3]
        u = Rj_t @ (T[k, :3, 3] - T[j, :3, 3]) - G @ s
        if free[j]:
            c = 6 * column[j]
            out[r, :3, c:c + 3], out[r, 3:, c:c + 3], out[r, 3:, c + 3:c + 6] = -eye, skew(u), -Rj_t
        if free[k]:
            c = 6 * column[k]
            out[r, :3, c:c + 3], out[r, 3:, c:c + 3], out[r, 3:, c + 3:c + 6] = Xe[:3, :3], G @ skew(s), Rj_t
    return out.reshape(6 * len(kept), -1)


_ITERATIONS = 30        # Gauss–Newton steps at most (from the graph synchronisation: 2–4 suffice)


def _solve(problem: JointProblem, T0: Array, free: NDArray[np.bool_], edges: NDArray[np.bool_],
           estimates: Array | None, combine: bool = False) -> tuple[Array, Array]:
    """Minimise J over the ``free`` sensors using the ``edges`` kept — weighed by the noise only, or
    with ``combine`` by the noise and the bias bound — and return the rig and the covariance (6F, 6F)
    of the free sensors' perturbations. Gauss–Newton on the whitened errors with the first-order
    Jacobian (:func:`_jacobian`), a step halved while it raises the cost."""
    keep = np.repeat(edges, 6)
    if edges.all():
        W = problem.combining if combine else problem.whitening
    else:
        C = problem.covariance + problem.bias if combine else problem.covariance
        W = whitening(C[np.ix_(keep, keep)])
    X = problem.estimates if estimates is None else estimates

    def residuals(T: Array) -> Array:
        return np.asarray(W @ problem.errors(T, X)[edges].ravel(), dtype=np.float64)

    T, r = T0, residuals(T0)
    J = W @ _jacobian(problem, T, free, edges, X)
    for _ in range(_ITERATIONS):
        step = np.asarray(np.linalg.lstsq(J, -r, rcond=None)[0], dtype=np.float64)
        cost = float(r @ r)
        for _ in range(30):
            T_new = _perturbed(T, free, step)
            r_new = residuals(T_new)
            if float(r_new @ r_new) <= cost or not step.any():
                break
            step = 0.5 * step
        else:
            break
        T, r = T_new, r_new
        J = W @ _jacobian(problem, T, free, edges, X)
        if np.abs(step).max() < 1e-13:
            break
    return T, np.asarray(np.linalg.pinv(J.T @ J, hermitian=True), dtype=np.float64)


def refine(problem: JointProblem, T0: Array, estimates: Array | None = None) -> tuple[Array, Array]:
    """Minimise J from the rig estimate ``T0`` (n, 4, 4) (``T0[reference] = I``), optionally on other
    pairwise ``estimates`` (a bootstrap replicate's). Returns the rig and the covariance (n, 6, 6)
    of each ``T_ref_k``'s perturbation (rotation vector [rad], translation [m]; zero for the reference).

    With an ``excluded`` sensor, the others come from the pairs without it, then the excluded one
    from its own pairs with the others held: a stream known to be inconsistent moves nobody else.
    An excluded reference (or one whose removal disconnects the others) cannot be set apart: every
    ``T_ref_k`` is then solved from all pairs, as without exclusion."""
    n, ref = problem.n, problem.reference
    free = np.arange(n) != ref
    edges = np.ones(len(problem.pairs), dtype=bool)
    cov = np.zeros((n, 6, 6))
    bad = problem.excluded
    if bad is not None:
        edges = np.array([bad not in p for p in problem.pairs])
        others = free & (np.arange(n) != bad)
        kept = [p for p, e in zip(problem.pairs, edges, strict=True) if e]
        if edges.any() and connected(n, kept, ref)[others].all():
            T0, c = _solve(problem, T0, others, edges, estimates, combine=True)
            cov[others] = _blocks(c)
            free, edges = np.arange(n) == bad, ~edges
    T, c = _solve(problem, T0, free, edges, estimates, combine=True)
    cov[free] = _blocks(c)
    return T, cov


@dataclass(frozen=True)
class Consistency:
    """The χ² test of the pairwise estimates against each other (module docstring).

    statistic: J at the joint optimum of all pairs; dof: ``6(E - n + 1)``; p_value: of J;
    reductions, reduction_dof, reduction_p: per sensor, J minus J without its pairs, its degrees
    of freedom ``6(deg - 1)`` and p-value (NaN, 0 and NaN where it cannot be tested: a sensor in
    fewer than two pairs, or whose removal disconnects the others); suspect: the sensor whose
    removal has the smallest p-value, when both it and the rig's are below
    :data:`CONSISTENCY_P_VALUE` and no other sensor ties with it; else None.
    """

    statistic: float
    dof: int
    p_value: float
    reductions: tuple[float, ...]
    reduction_dof: tuple[int, ...]
    reduction_p: tuple[float, ...]
    suspect: int | None

    @property
    def inconsistent(self) -> bool:
        """The rig's pairwise estimates disagree more than their noise model allows."""
        return self.p_value < CONSISTENCY_P_VALUE


def consistency(problem: JointProblem, T0: Array) -> Consistency:
    """The χ² test of ``problem`` (without exclusion) from the rig estimate ``T0`` (see :class:`Consistency`)."""
    n, E = problem.n, len(problem.pairs)
    everything = np.ones(E, dtype=bool)
    free = np.arange(n) != problem.reference
    J = problem.cost(_solve(problem, T0, free, everything, None)[0])
    dof = 6 * (E - n + 1)
    red, red_dof, log_p = [], [], []
    for s in range(n):
        edges = np.array([s not in p for p in problem.pairs])
        others = np.arange(n) != s
        gauge = problem.reference if s != problem.reference else int(np.flatnonzero(others)[0])
        kept = [p for p, e in zip(problem.pairs, edges, strict=True) if e]
        d = dof - 6 * (int(edges.sum()) - n + 2)
        if d <= 0 or not connected(n, kept, gauge)[others].all():
            red.append(float("nan"))
            red_dof.append(0)
            log_p.append(float("nan"))
            continue
        T, _ = _solve(problem, T0, others & (np.arange(n) != gauge), edges, None)
        red.append(J - problem.cost(T, edges))
        red_dof.append(d)
        log_p.append(chi2_log_sf(d, red[-1]))      # finite far into the tail: improbable reductions still rank
    suspect = None
    ranked = np.argsort(np.where(np.isnan(log_p), np.inf, log_p))
    best = log_p[ranked[0]] if n else float("nan")
    tie = n > 1 and np.isclose(log_p[ranked[1]], best, rtol=1e-9, atol=0.0)
    p_value = chi2_sf(dof, J) if dof > 0 else float("nan")     # no degrees of freedom: nothing to test
    if p_value < CONSISTENCY_P_VALUE and best < np.log(CONSISTENCY_P_VALUE) and not tie:
        suspect = int(ranked[0])
    return Consistency(J, dof, p_value, tuple(red), tuple(red_dof),
                       tuple(float(np.exp(v)) for v in log_p), suspect)


def _blocks(c: Array) -> Array:
    return np.asarray([c[6 * i:6 * i + 6, 6 * i:6 * i + 6] for i in range(len(c) // 6)], dtype=np.float64)


def resolve_pairs(forms: Array, X: Array) -> Array:
    """Each pair's optimum of the cost (8) given by ``forms`` (E, 2, 8, 8) near ``X`` (E, 4, 4): one
    constrained Newton step, ``δ = -(Dᵀ(Q - Λ)D)⁻¹ Dᵀ Q x`` (left perturbation; see
    :mod:`handeye_cli.analysis.covariance`)."""
    order = np.r_[4:8, 0:4]                                   # [q'; q] → [q; q']
    q, qd = dq.from_transforms(X)
    out = np.empty_like(X)
    for e, Qe in enumerate(forms.sum(axis=1)):
        D, H, Qx = constrained_hessian(Qe[np.ix_(order, order)], q[e], qd[e])
        delta = -np.linalg.lstsq(H, D.T @ Qx, rcond=None)[0]
        step = np.eye(4)
        step[:3, :3] = dq.to_matrix(dq.from_rotvec(delta[:3]))
        step[:3, 3] = delta[3:]
        out[e] = step @ X[e]
    return out


@dataclass(frozen=True, eq=False)
class RigUncertainty:
    """Bootstrap spread of every ``T_ref_k``: ``rotation_std_deg`` (n, 3) per axis of
    ``Log(R* R̂ᵀ)`` (frame ref) and ``translation_std_m`` (n, 3); ``rotation_interval_deg`` (n, 2, 3)
    lower/upper 95 % percentile bounds of ``Log(R* R̂ᵀ)`` [deg] and ``translation_interval_m`` (n, 2, 3)
    those of the translation [m] (as :class:`handeye_cli.analysis.bootstrap.Bootstrap` has them for one
    extrinsic); ``replicates``, ``block_s`` [s], ``seed``."""

    rotation_std_deg: Array
    translation_std_m: Array
    rotation_interval_deg: Array
    translation_interval_m: Array
    replicates: int
    block_s: float
    seed: int


def bootstrap_rig(problem: JointProblem, T_hat: Array, motions: list[Motions], replicates: int, *,
                  block_s: float = 2.0, seed: int = 0) -> RigUncertainty:
    """Block bootstrap of the joint estimate ``T_hat`` (n, 4, 4).

    ``motions[e] = (A, B, start_ns, pair_weights, alpha)`` of edge e: its motion pairs, their start
    stamps in the reference's clock [ns], weights (the noise model's, times the robust inlier mask)
    and α. Time is cut into blocks of ``block_s`` seconds shared by every edge; a replicate draws
    block counts (multinomial), re-solves every pair on its re-weighted cost and the rig from those
    estimates (with the same joint covariance and drift corrections), from ``T_hat``.
    """
    t0 = min(int(m[2].min()) for m in motions)
    blocks = [((m[2] - t0) // int(block_s * 1e9)).astype(np.int64) for m in motions]
    n_blocks = int(max(b.max() for b in blocks)) + 1
    rng = np.random.default_rng(seed)
    counts = rng.multinomial(n_blocks, np.full(n_blocks, 1.0 / n_blocks), size=replicates).astype(float)
    forms = [split_forms(A, B, counts[:, b] * w, alpha) for (A, B, _, w, alpha), b in zip(motions, blocks, strict=True)]
    rot, trans = np.zeros((replicates, problem.n, 3)), np.zeros((replicates, problem.n, 3))
    start = se3.inverse(problem.steps) @ problem.estimates                  # the pairwise-only optima
    for r in range(replicates):
        X = problem.steps @ resolve_pairs(np.stack([f[r] for f in forms]), start)
        T, _ = refine(problem, T_hat, X)
        rot[r] = np.rad2deg(dq.to_rotvec(dq.from_matrix(T[:, :3, :3] @ np.swapaxes(T_hat[:, :3, :3], 1, 2))))
        trans[r] = T[:, :3, 3] - T_hat[:, :3, 3]
    pct = [2.5, 97.5]
    return RigUncertainty(rot.std(axis=0, ddof=1), trans.std(axis=0, ddof=1),
                          np.swapaxes(np.percentile(rot, pct, axis=0), 0, 1),
                          np.swapaxes(np.percentile(trans + T_hat[:, :3, 3], pct, axis=0), 0, 1),
                          replicates, block_s, seed)
