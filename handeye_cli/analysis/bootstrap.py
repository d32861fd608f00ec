"""Bootstrap uncertainty of ``X = T_a_b``: resample the motion pairs, re-solve, report the spread.

Conventions: ``X = T_a_b`` (maps frame b to frame a), ``A_i X = X B_i``; quaternions x-y-z-w.
A replicate ``X*`` is compared with the full-data estimate ``X̂`` as a perturbation in frame a:
rotation vector ``δθ = Log(R* R̂ᵀ)`` [rad, reported in deg] and translation ``t*`` [m].

Speed: a replicate with multinomial counts ``c_i`` has the weighted normal matrices of eq 9,
``S = Σ c_i (E_iᵀE_i + α² F_iᵀF_i)``, ``M = α² Σ c_i E_iᵀE_i``, ``W = α² Σ c_i F_iᵀE_i``. The
per-pair 8x8 blocks ``Q_i`` of ``[q'; q]`` are built once (eqs 6–7, :func:`pair_blocks`); all
replicates' sums are one matrix product ``C Q`` of the (R, N) count matrix. Each sum is turned
solved by DQOpt (Algorithm 1) vectorised over the replicates (:func:`_batched_dqopt`, checked
against the project's :func:`dqopt`, which takes over for any replicate with a singular M).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..errors import ConfigError, DataError
from ..geometry import dualquat as dq
from ..solvers import Prior, solve
from ..solvers.optimal import dqopt
from ..solvers.problem import Problem, build_problem, pair_blocks, validate_motions

__all__ = ["BootstrapResult", "bootstrap", "replicate_grams", "replicate_problems"]


@dataclass(frozen=True, eq=False)
class BootstrapResult:
    """Spread of ``T_a_b`` over bootstrap replicates.

    Attributes
    ----------
    matrix:
        (4, 4) full-data estimate ``X̂ = T_a_b``.
    rotation_std_deg, translation_std_m:
        (3,) per-axis standard deviations of ``δθ`` [deg] (rotation vector of ``R* R̂ᵀ``, frame a)
        and of the translation [m] (frame a).
    rotation_interval_deg:
        (2, 3) lower/upper 95 % percentile bounds of ``δθ`` [deg]: the truth ``R`` lies in it
        when ``Log(R R̂ᵀ)`` does.
    translation_interval_m:
        (2, 3) lower/upper 95 % percentile bounds of the translation [m].
    rotation_deltas_deg, translations_m:
        (R, 3) the replicates themselves.
    replicates, seed, level:
        Number of replicates, the seed and the interval's coverage (0.95).
    """

    matrix: FloatArray
    rotation_std_deg: FloatArray
    translation_std_m: FloatArray
    rotation_interval_deg: FloatArray
    translation_interval_m: FloatArray
    rotation_deltas_deg: FloatArray
    translations_m: FloatArray
    replicates: int
    seed: int
    level: float

    def contains(self, T_a_b: FloatArray) -> tuple[BoolArray, BoolArray]:
        """Per-axis booleans (3,), (3,): whether a transform's rotation and translation lie in the intervals."""
        d, t = _deltas(self.matrix, np.asarray(T_a_b, dtype=np.float64)[None])
        r_in = (self.rotation_interval_deg[0] <= d[0]) & (d[0] <= self.rotation_interval_deg[1])
        t_in = (self.translation_interval_m[0] <= t[0]) & (t[0] <= self.translation_interval_m[1])
        return r_in, t_in

    def as_dict(self) -> dict[str, Any]:
        """Plain summary for the result file (no replicate arrays)."""
        return {"replicates": self.replicates, "seed": self.seed, "level": self.level,
                "rotation_std_deg": self.rotation_std_deg.tolist(),
                "translation_std_m": self.translation_std_m.tolist(),
                "rotation_interval_deg": self.rotation_interval_deg.tolist(),
                "translation_interval_m": self.translation_interval_m.tolist()}


def _pair_gram(E: FloatArray, F: FloatArray, alpha: float) -> FloatArray:
    """Per-pair 8x8 ``K_iᵀK_i`` of the rows ``[0, E_i; αE_i, αF_i]`` acting on ``[q'; q]``, as (N, 64)."""
    n = len(E)
    K = np.zeros((n, 8, 8))
    K[:, :4, 4:] = E
    K[:, 4:, :4] = alpha * E
    K[:, 4:, 4:] = alpha * F
    gram: FloatArray = np.einsum("nki,nkj->nij", K, K)
    return gram.reshape(n, 64)


def _problems_from_grams(Q: FloatArray) -> list[Problem]:
    """Residual-row problems with ``M, Wᵀ, S`` equal to the blocks of each 8x8 ``Q`` (in ``[q'; q]`` order)."""
    lam, V = np.linalg.eigh(Q)
    K = np.sqrt(np.clip(lam, 0.0, None))[:, :, None] * np.swapaxes(V, 1, 2)     # KᵀK = Q
    return [Problem.from_rows(k) for k in K]


def _prior_gram(A: FloatArray, B: FloatArray, alpha: float, prior: Prior | None) -> FloatArray:
    """The prior's 8x8 contribution (eq 29) in ``[q'; q]`` order; zero without a prior."""
    if prior is None:
        return np.zeros((8, 8))
    with_p, without = (build_problem(A, B, alpha, p) for p in (prior, None))
    return with_p.form - without.form


def replicate_grams(motions_a: FloatArray, motions_b: FloatArray, counts: FloatArray,
                    alpha: float = 1.0, prior: Prior | None = None) -> FloatArray:
    """``[[M, Wᵀ], [W, S]]`` (eq 9, + prior eq 29) per row of ``counts`` (R, N) as (R, 8, 8), via one matrix product."""
    A, B, _ = validate_motions(motions_a, motions_b)
    E, F = pair_blocks(A, B, alpha)
    Q = (np.asarray(counts, dtype=np.float64) @ _pair_gram(E, F, alpha)).reshape(-1, 8, 8)
    return Q + _prior_gram(A, B, alpha, prior)


def replicate_problems(motions_a: FloatArray, motions_b: FloatArray, counts: FloatArray,
                       alpha: float = 1.0, prior: Prior | None = None) -> list[Problem]:
    """One weighted :class:`Problem` per row of ``counts`` (R, N), e.g. for the project's solvers."""
    return _problems_from_grams(replicate_grams(motions_a, motions_b, counts, alpha, prior))


def _batched_z(Q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, BoolArray]:
    """Z0, Z1, Z2 of eq 13 for a stack of 8x8 ``Q`` in ``[q'; q]`` order, the Cholesky factor of M,
    and a mask of the stack entries whose M is regular (the others get a placeholder M).

    With ``M = L Lᵀ`` and ``H = L⁻¹``, ``G = H Wᵀ``: ``Z2 = M⁻¹ = HᵀH``, ``W M⁻¹ = Gᵀ H``,
    ``Z0 = S - GᵀG``.
    """
    M, Wt, S = Q[:, :4, :4], Q[:, :4, 4:], Q[:, 4:, 4:]
    ev = np.linalg.eigvalsh(M)
    regular = ev[:, 0] > 1e-8 * ev[:, -1]
    L = np.linalg.cholesky(np.where(regular[:, None, None], M, np.eye(4)))
    H = np.linalg.inv(L)
    Gt = np.swapaxes(H @ Wt, 1, 2)
    WMinv = Gt @ H
    return S - Gt @ np.swapaxes(Gt, 1, 2), WMinv + np.swapaxes(WMinv, 1, 2), np.swapaxes(H, 1, 2) @ H, L, regular


def _eig_z(Z0: FloatArray, Z1: FloatArray, Z2: FloatArray, mu: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Eigenpairs (ascending) of ``Z(μ) = Z0 + μZ1 - μ²Z2`` (eq 12) for a stack."""
    m = mu[:, None, None]
    return np.linalg.eigh(Z0 + m * Z1 - (m * m) * Z2)


def _f_slope(Z1: FloatArray, Z2: FloatArray, mu: FloatArray, lam: FloatArray,
             V: FloatArray) -> tuple[FloatArray, FloatArray]:
    """f(μ) of eq 18 and its derivative (second-order eigenvalue perturbation), for a stack."""
    q = V[:, :, 0]
    z2q = np.einsum("rij,rj->ri", Z2, q)
    qz2q = np.einsum("ri,ri->r", q, z2q)
    f = mu * qz2q - 0.5 * np.einsum("ri,rij,rj->r", q, Z1, q)
    coupling = np.einsum("rja,rj->ra", V[:, :, 1:], np.einsum("rij,rj->ri", Z1 - 2 * mu[:, None, None] * Z2, q))
    gaps = np.maximum(lam[:, 1:] - lam[:, :1], 1e-300)
    return f, qz2q + np.sum(coupling ** 2 / gaps, axis=1)


def _batched_dqopt(Q: FloatArray, iterations: int = 60) -> tuple[FloatArray, FloatArray, BoolArray]:
    """DQOpt (Algorithm 1) on a stack of problems at once: bisection-safeguarded Newton on f(μ) (eq 18).

    f(μ) = q₀ᵀ(μZ2 - ½Z1)q₀ is increasing; its root lies between the extreme generalised
    eigenvalues of (½Z1, Z2), i.e. the eigenvalues of ``Lᵀ(½Z1)L`` with ``Z2⁻¹ = M = LLᵀ``
    (appendix C). Returns q, q' (x-y-z-w, (R, 4) each; q' from eq 20, projected onto q⊥) and a
    mask of the problems solved here (M regular and converged); the caller re-solves the rest.
    """
    Z0, Z1, Z2, L, ok = _batched_z(Q)
    theta = np.linalg.eigvalsh(np.swapaxes(L, 1, 2) @ (0.5 * Z1) @ L)
    pad = 1e-12 * np.abs(theta).max(axis=1)
    lo, hi = theta[:, 0] - pad, theta[:, -1] + pad
    mu = np.clip(0.0, lo, hi)
    done = ~ok
    for _ in range(iterations):
        f, slope = _f_slope(Z1, Z2, mu, *_eig_z(Z0, Z1, Z2, mu))
        lo, hi = np.where(f < 0, mu, lo), np.where(f < 0, hi, mu)
        with np.errstate(divide="ignore", invalid="ignore"):
            new = mu - f / slope
        new = np.where((lo < new) & (new < hi), new, 0.5 * (lo + hi))
        converged = np.abs(new - mu) <= 4 * np.finfo(float).eps * np.maximum(np.abs(mu), 1.0)
        mu = np.where(done, mu, new)
        done |= converged
        if done.all():
            break
    q = _eig_z(Z0, Z1, Z2, mu)[1][:, :, 0]
    Wt_q = np.einsum("rij,rj->ri", Q[:, :4, 4:], q)
    qd = np.einsum("rij,rj->ri", Z2, mu[:, None] * q - Wt_q)                   # eq 20
    qd -= np.einsum("ri,ri->r", q, qd)[:, None] * q
    return q, qd, ok & done


def _to_transforms(q: FloatArray, qd: FloatArray) -> FloatArray:
    """Transforms (R, 4, 4) of unit dual quaternions (R, 4) x-y-z-w: ``t = 2 q' ⊗ q*`` (eq 2)."""
    X = np.tile(np.eye(4), (len(q), 1, 1))
    X[:, :3, :3] = dq.to_matrix(q)
    X[:, :3, 3] = 2.0 * dq.multiply(qd, dq.conjugate(q))[:, :3]
    return X


def _solve_replicates(Q: FloatArray) -> FloatArray:
    """``T_a_b`` (R, 4, 4) minimising each replicate's cost; the project's DQOpt where batching gives up."""
    q, qd, ok = _batched_dqopt(Q)
    X = _to_transforms(q, qd)
    for i in np.flatnonzero(~ok):
        r = dqopt(_problems_from_grams(Q[i:i + 1])[0])
        X[i] = dq.to_transform(r.q, r.qd)
    return X


def _deltas(X_hat: FloatArray, Xs: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Rotation vectors ``Log(R R̂ᵀ)`` [deg] (frame a) and translations [m] of transforms (R, 4, 4)."""
    dR = Xs[:, :3, :3] @ X_hat[:3, :3].T
    return np.rad2deg(dq.to_rotvec(dq.from_matrix(dR))), Xs[:, :3, 3].copy()


def _dof_correction(n: int) -> float:
    """``√(n / (n - 6))``: the pairs bootstrap, like the HC0 sandwich, under-spreads by the 6 fitted
    degrees of freedom; scaling the replicates' deviations by this is the HC1 correction."""
    return float(np.sqrt(n / (n - 6))) if n > 12 else float(np.sqrt(2.0))


def _sample_counts(samples: tuple[IntArray, IntArray], use: IntArray, replicates: int,
                   rng: np.random.Generator) -> tuple[int, FloatArray]:
    """Vertex bootstrap: multinomial counts over the K samples the pairs ``use`` touch, and each
    pair's weight ``c[i]·c[j]`` as (R, len(use)). Returns K and the weights."""
    i, j = (np.asarray(v).reshape(-1) for v in samples)
    if i.shape != j.shape or len(i) < use.max(initial=-1) + 1:
        raise DataError(f"samples must be two index arrays of one entry per pair ({len(i)}, {len(j)})",
                           "bootstrap", "pass (pairs.i, pairs.j)")
    nodes, inv = np.unique(np.concatenate([i[use], j[use]]), return_inverse=True)
    k = len(nodes)
    c = rng.multinomial(k, np.full(k, 1.0 / k), size=replicates).astype(float)
    return k, c[:, inv[: len(use)]] * c[:, inv[len(use):]]


def bootstrap(motions_a: FloatArray, motions_b: FloatArray, replicates: int = 1000, *,
              alpha: float = 1.0, prior: Prior | None = None, weights: FloatArray | None = None,
              samples: tuple[IntArray, IntArray] | None = None, seed: int = 0,
              level: float = 0.95, estimate: FloatArray | None = None) -> BootstrapResult:
    """Pairs bootstrap (or samples bootstrap) of the DQOpt estimate of ``T_a_b``.

    Parameters
    ----------
    motions_a, motions_b:
        (N, 4, 4) relative motions, ``A_i X = X B_i``.
    replicates:
        Number of resamples R (≥ 2); each draws N pairs with replacement (multinomial counts).
    alpha, prior:
        As for :func:`handeye_cli.solvers.solve` (α in 1/m).
    weights:
        Optional (N,) non-negative pair weights, e.g. an inlier mask from :func:`robust_solve`:
        only pairs with weight > 0 are resampled, and counts are multiplied by the weights.
    samples:
        Optional ``(i, j)``, (N,) int each: the pose samples each pair was formed from
        (``Pairs.i``, ``Pairs.j``). Then the *samples* are resampled (multinomial counts ``c``)
        and pair k gets weight ``c[i_k] · c[j_k]`` — the vertex bootstrap for dyadic data. Use it
        whenever pairs share samples (keyframe or all-pairs strategies): a pose's noise then
        enters many pairs, and resampling pairs as if independent under-states the spread
        (several-fold on the simulated rig of ``sample_data``).
    seed:
        Seed of the resampling (results are reproducible).
    level:
        Coverage of the percentile intervals.
    estimate:
        Optional (4, 4) full-data DQOpt estimate ``X̂ = T_a_b`` of these motions, weights, α and
        prior, when the caller has solved it already (default: solved here).

    Returns
    -------
    :class:`BootstrapResult`. The replicates' deviations from ``X̂`` are scaled by ``√(n/(n-6))``
    (HC1 degrees-of-freedom correction; n = resampled pairs, or samples).
    """
    A, B, w = validate_motions(motions_a, motions_b, weights)
    if replicates < 2:
        raise ConfigError(f"{replicates} bootstrap replicates", "bootstrap", "ask for at least 2 (e.g. 1000)")
    use = np.flatnonzero(w > 0)
    A, B, w = A[use], B[use], w[use]
    X_hat = (solve(A, B, alpha=alpha, prior=prior, weights=w).matrix if estimate is None
             else np.asarray(estimate, dtype=np.float64))
    rng = np.random.default_rng(seed)
    if samples is None:
        units = len(A)
        counts = rng.multinomial(units, np.full(units, 1.0 / units), size=replicates) * w
    else:
        units, counts = _sample_counts(samples, use, replicates, rng)
        counts = counts * w
    Xs = _solve_replicates(replicate_grams(A, B, counts, alpha, prior))
    d, t = _deltas(X_hat, Xs)
    c = _dof_correction(units)
    d, t = c * d, X_hat[:3, 3] + c * (t - X_hat[:3, 3])
    pct = 100.0 * np.array([(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return BootstrapResult(X_hat, d.std(axis=0, ddof=1), t.std(axis=0, ddof=1),
                           np.percentile(d, pct, axis=0), np.percentile(t, pct, axis=0),
                           d, t, int(replicates), int(seed), float(level))
