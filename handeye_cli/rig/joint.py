"""Joint refinement of a rig: minimise the summed pairwise dual-quaternion costs over all ``T_ref_k``.

Each calibrated pair (j, k) contributes its cost (8) — exactly quadratic in the dual quaternion
``[q'; q]`` of ``T_j_k`` — as two 8x8 matrices (eq 9 split by its rows, with the pair's α and
per-pair weights): ``Q_jk,rot`` of the rotational rows ``E_i q`` and ``Q_jk,dual`` of the dual rows
``α (F_i q + E_i q')``, each scaled by its own weight::

    J(T_ref_1 … T_ref_n) = Σ_jk Σ_p ω_jk,p [q'; q]ᵀ Q_jk,p [q'; q],   (q, q') of T_ref_j⁻¹ T_ref_k

so the result is consistent by construction and every pair's data count, not only the
reference's. The noise model: ``ω_jk,p = 1 / σ²_jk,p`` (rescaled so the largest is 1) with
``σ²_jk,p`` the part's cost per degree of freedom at the pair's own optimum, so a noisy pair (or
one with a bad stream) counts less, and each pair's rotation and translation are weighed by
their own noise levels rather than by one α. The unknowns are right
perturbations ``T_ref_k Exp(δ_k)`` (rotation vector [rad], translation [m]) of every non-reference
sensor, solved by Levenberg–Marquardt from the graph synchronisation's estimate.

:func:`bootstrap_rig` resamples time blocks shared by all pairs (a block's count multiplies
every motion pair that starts in it), re-forms each pair's matrices and re-solves.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from .. import se3
from ..solvers import dualquat as dq
from ..solvers.problem import pair_blocks

__all__ = ["Motions", "JointProblem", "refine", "bootstrap_rig", "RigUncertainty", "split_forms", "part_costs"]

Array = NDArray[np.float64]
Motions = tuple[Array, Array, Array, Array]   # motions A, B (N, 4, 4); start stamps [ns] (N,); pair weights (N,)
_SIGMA2_FLOOR = 1e-18     # (1e-9 rad)², (α · 1 nm)²: below it residuals are rounding, not noise


def split_forms(A: Array, B: Array, counts: Array, alpha: float) -> Array:
    """The rotational and dual 8x8 cost matrices (``[q'; q]`` order) of motion pairs ``A_i X = X B_i``
    (N, 4, 4) weighted by each row of ``counts`` (R, N): (R, 2, 8, 8), the dual part scaled by α²."""
    E, F = pair_blocks(A, B, alpha)
    rot = np.zeros((len(E), 8, 8))
    rot[:, 4:, 4:] = np.einsum("nki,nkj->nij", E, E)
    EF = np.concatenate((E, F), axis=2)                       # rows E q' + F q on [q'; q]
    grams = np.stack((rot, alpha ** 2 * np.einsum("nki,nkj->nij", EF, EF)), axis=1).reshape(len(E), -1)
    return np.asarray((np.asarray(counts, dtype=float) @ grams).reshape(-1, 2, 8, 8), dtype=np.float64)


def part_costs(forms: Array, T: Array) -> Array:
    """``[q'; q]ᵀ Q_p [q'; q]`` of transforms T (E, 4, 4) for forms (E, 2, 8, 8): (E, 2)."""
    q, qd = dq.from_transforms(T)
    v = np.concatenate((qd, q), axis=1)
    return np.asarray(np.einsum("ei,epij,ej->ep", v, forms, v), dtype=np.float64)


@dataclass(frozen=True, eq=False)
class JointProblem:
    """The summed pairwise costs: ``pairs`` (E edges (j, k)), ``forms`` (E, 2, 8, 8) (rotational,
    dual; ``[q'; q]`` order), ``weights`` ω (E, 2), ``reference`` index and ``n`` sensors."""

    n: int
    reference: int
    pairs: list[tuple[int, int]]
    forms: Array
    weights: Array

    @staticmethod
    def pair_weights(sigma2: Array) -> Array:
        """``ω = σ²_min / σ²`` (E, 2) (largest weight 1), with σ² floored for noise-free pairs."""
        s = np.maximum(np.asarray(sigma2, dtype=float), _SIGMA2_FLOOR)
        return np.asarray(s.min() / s, dtype=np.float64)

    def relative(self, T: Array) -> Array:
        """``T_j_k = T_ref_j⁻¹ T_ref_k`` (E, 4, 4) of every edge."""
        j, k = (np.array([p[i] for p in self.pairs]) for i in (0, 1))
        return np.asarray(se3.inverse(T[j]) @ T[k], dtype=np.float64)

    def edge_costs(self, T: Array) -> Array:
        """Each pair's cost (8) at its α (unweighted by ω) at the rig ``T`` (n, 4, 4)."""
        return np.asarray(part_costs(self.forms, self.relative(T)).sum(axis=1), dtype=np.float64)

    def cost(self, T: Array) -> float:
        """J: the ω-weighted sum of the pairs' rotational and dual costs."""
        return float(np.sum(self.weights * part_costs(self.forms, self.relative(T))))


def _factors(forms: Array, weights: Array) -> Array:
    """``K`` with ``KᵀK = Σ_p ω_p Q_p`` per edge (E, 8, 8), so that J is a sum of squares."""
    lam, V = np.linalg.eigh(np.einsum("ep,epij->eij", weights, forms))
    return np.asarray(np.sqrt(np.clip(lam, 0.0, None))[:, :, None] * np.swapaxes(V, 1, 2), dtype=np.float64)


def _perturbed(T0: Array, free: Array, p: Array) -> Array:
    T = T0.copy()
    d = p.reshape(-1, 6)
    T[free, :3, :3] = T0[free, :3, :3] @ Rotation.from_rotvec(d[:, :3]).as_matrix()
    T[free, :3, 3] = T0[free, :3, 3] + d[:, 3:]
    return np.asarray(T, dtype=np.float64)


def refine(problem: JointProblem, T0: Array) -> Array:
    """Minimise J from the rig estimate ``T0`` (n, 4, 4) (``T0[reference] = I``); returns the rig."""
    free = np.arange(problem.n) != problem.reference
    K = _factors(problem.forms, problem.weights)
    q0, _ = dq.from_transforms(problem.relative(T0))

    def residuals(p: Array) -> Array:
        q, qd = dq.from_transforms(problem.relative(_perturbed(T0, free, p)))
        sign = np.where(np.sum(q * q0, axis=1) < 0, -1.0, 1.0)[:, None]      # follow one sheet of q ~ -q
        return np.asarray(np.einsum("eij,ej->ei", K, sign * np.concatenate((qd, q), axis=1)).ravel(), dtype=np.float64)

    r = least_squares(residuals, np.zeros(6 * int(free.sum())), method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return _perturbed(T0, free, r.x)


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


def bootstrap_rig(problem: JointProblem, T_hat: Array, motions: list[Motions],
                  alpha: float, replicates: int, *, block_s: float = 2.0, seed: int = 0) -> RigUncertainty:
    """Block bootstrap of the joint estimate ``T_hat`` (n, 4, 4).

    ``motions[e] = (A, B, start_ns, pair_weights)`` of edge e: its motion pairs, their start
    stamps in the reference's clock [ns] and weights (1, or the robust inlier mask). Time is cut
    into blocks of ``block_s`` seconds shared by every edge; a replicate draws block counts
    (multinomial) and re-solves from ``T_hat``.
    """
    t0 = min(int(m[2].min()) for m in motions)
    blocks = [((m[2] - t0) // int(block_s * 1e9)).astype(np.int64) for m in motions]
    n_blocks = int(max(b.max() for b in blocks)) + 1
    rng = np.random.default_rng(seed)
    counts = rng.multinomial(n_blocks, np.full(n_blocks, 1.0 / n_blocks), size=replicates).astype(float)
    forms = [split_forms(A, B, counts[:, b] * w, alpha) for (A, B, _, w), b in zip(motions, blocks, strict=True)]
    rot, trans = np.zeros((replicates, problem.n, 3)), np.zeros((replicates, problem.n, 3))
    for r in range(replicates):
        rep = JointProblem(problem.n, problem.reference, problem.pairs, np.stack([f[r] for f in forms]),
                           problem.weights)
        T = refine(rep, T_hat)
        rot[r] = Rotation.from_matrix(T[:, :3, :3] @ np.swapaxes(T_hat[:, :3, :3], 1, 2)).as_rotvec(degrees=True)
        trans[r] = T[:, :3, 3] - T_hat[:, :3, 3]
    pct = [2.5, 97.5]
    return RigUncertainty(rot.std(axis=0, ddof=1), trans.std(axis=0, ddof=1),
                          np.swapaxes(np.percentile(rot, pct, axis=0), 0, 1),
                          np.swapaxes(np.percentile(trans + T_hat[:, :3, 3], pct, axis=0), 0, 1),
                          replicates, block_s, seed)
