"""The rig's noise model: how each stream's pose noise reaches every pairwise estimate, jointly.

Pairwise results of a rig are not independent measurements: the pairs (j, k) and (j, l) both see
stream j's noise. Summing the pairs' costs as if they were independent counts stream j twice, and
weighs a pair by how many motion pairs it has rather than by what they are worth (pairs of one
stream at 10 Hz overlap more than pairs of one at 30 Hz). This module propagates the noise of
every pose sample to every pairwise estimate, so that the joint estimate (:mod:`.joint`) can
weigh the pairs by their joint covariance — the generalised least squares of the pairwise
results, which no chain of them beats to first order (every chain is a linear unbiased
combination of the same pairwise results; Gauss–Markov).

Model: stream k's sample m is ``T_wk_k(t_m) Exp(n_km)`` (right perturbation, paper eq 38):
``n_km = (ω [rad], v [m])`` in the sensor's frame, independent across samples and streams, with
per-component variances ``σ²_rot,k`` and ``σ²_trans,k``. A synced sample interpolates the raw
samples around it, so its noise is ``(1 - f) n_lo + f n_hi``; a motion ``A = T(t_i)⁻¹ T(t_j)``
is perturbed by ``ε = n_j - Ad(A⁻¹) n_i``; the residual rows of cost (8) change by ``∂r/∂ε ε``;
and the pair's constrained optimum moves by ``δ = -H⁻¹ Σ_i w_i (K_i D)ᵀ ∂r_i`` (Gauss–Newton
with the Lagrangian's Hessian ``H = Dᵀ(Q - Λ)D``, the notation of
:mod:`handeye_cli.analysis.covariance`). ``δ`` is the left perturbation of ``T_j_k``:
``T̂_j_k = Exp(δ) T_j_k``, rotation [rad] and translation [m] in frame j. Each pair thus gets,
per raw sample of its two streams, the 6x6 map from that sample's noise to its estimate
(:class:`EdgeNoise`), and the covariance of all estimates follows from the streams' variances.

The variances are not known; each pair's residual energy is their sum weighted by known
sensitivities, so with three or more streams they are separable (the "three-cornered hat" of
clock comparisons): :func:`stream_variances` solves the non-negative least squares over all pairs,
rotation first, then translation (the dual rows also carry rotation noise times the lever arm).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import sparse
from scipy.optimize import nnls

from .. import se3
from ..analysis.covariance import constrained_hessian
from ..solvers import dualquat as dq
from ..solvers.problem import pair_blocks
from .pairwise import Edge

__all__ = ["EdgeNoise", "StreamNoise", "edge_noise", "stream_variances", "edge_covariance", "VARIANCE_FLOOR"]

Array = NDArray[np.float64]
VARIANCE_FLOOR = 1e-18      # (1 nrad)², (1 nm)²: below it a stream is noise-free to rounding


@dataclass(frozen=True, eq=False)
class EdgeNoise:
    """How the noise of streams j and k reaches the pairwise estimate of ``T_j_k``.

    maps: per stream (j, k), (M, 6, 6): raw sample m's noise ``(ω, v)`` → the estimate's error ``δ``.
    energy: (2, 3) per stream (j, k): the expected residual energy (ω-weighted as the pair was
        solved) per unit variance — rotation rows from rotation noise, dual rows from rotation
        noise, dual rows from translation noise.
    observed: (2,) the residual energy at the pairwise optimum: rotation rows, dual rows.
    """

    maps: tuple[Array, Array]
    energy: Array
    observed: Array


@dataclass(frozen=True)
class StreamNoise:
    """Per-component pose-noise variances of every stream: ``rotation`` [rad²], ``translation`` [m²] (n,)."""

    rotation: Array
    translation: Array

    def std(self, k: int) -> tuple[float, float]:
        """Stream k's per-sample noise as an angle [rad] and a distance [m] (3-D, root of the sum)."""
        return float(np.sqrt(3 * self.rotation[k])), float(np.sqrt(3 * self.translation[k]))


def interpolation(raw_ns: NDArray[np.int64], query_ns: NDArray[np.int64]
                  ) -> tuple[NDArray[np.int64], NDArray[np.int64], Array]:
    """Raw samples ``lo``, ``hi`` and fraction ``f`` with ``value(query) = (1 - f) raw[lo] + f raw[hi]``
    (the interpolation of :mod:`handeye_cli.stages.sync`; an exact stamp has ``f = 0``)."""
    n = len(raw_ns)
    after = np.searchsorted(raw_ns, query_ns, side="right")
    lo = np.clip(after - 1, 0, n - 1)
    hi = np.where(raw_ns[lo] == query_ns, lo, np.clip(after, 0, n - 1))
    span = np.maximum(raw_ns[hi] - raw_ns[lo], 1)
    frac = np.where(hi == lo, 0.0, np.clip((query_ns - raw_ns[lo]) / span, 0.0, 1.0))
    return lo, hi, frac


def adjoint(T: Array) -> Array:
    """``Ad_T`` (N, 6, 6) on twists ``(ω, v)``: ``T Exp(ξ) T⁻¹ = Exp(Ad_T ξ)``."""
    R, t = T[:, :3, :3], T[:, :3, 3]
    tx = np.zeros_like(R)
    tx[:, 0, 1], tx[:, 0, 2], tx[:, 1, 2] = -t[:, 2], t[:, 1], -t[:, 0]
    tx -= np.swapaxes(tx, 1, 2)
    Ad = np.zeros((len(T), 6, 6))
    Ad[:, :3, :3] = Ad[:, 3:, 3:] = R
    Ad[:, 3:, :3] = tx @ R
    return Ad


def _residual_sensitivity(M: Array, q: Array, qd: Array, alpha: float, side: int) -> Array:
    """``∂r/∂ε`` (N, 8, 6) of the rows ``r = [E q; α(E q' + F q)]`` for ``M → M Exp(ε)``, M the
    motions of side 0 (a: ``E = L(q_A) - R(q_B)``) or 1 (b). ``Q_M Exp(ε) ≈ Q_M ⊗ ((ω/2, 1) + ε(v/2, 0))``."""
    qm, qdm = dq.from_transforms(M)
    d_q = 0.5 * dq.left(qm)[:, :, :3]           # ∂q_M/∂ω
    d_qd_w = 0.5 * dq.left(qdm)[:, :, :3]       # ∂q'_M/∂ω
    d_qd_v = d_q                                # ∂q'_M/∂v
    if side == 0:       # dE q = L(dq_A) q = R(q) dq_A
        P, Pd, sign = dq.right(q), dq.right(qd), 1.0
    else:               # dE q = -R(dq_B) q = -L(q) dq_B
        P, Pd, sign = dq.left(q), dq.left(qd), -1.0
    out = np.zeros((len(M), 8, 6))
    out[:, :4, :3] = P @ d_q
    out[:, 4:, :3] = alpha * (Pd @ d_q + P @ d_qd_w)
    out[:, 4:, 3:] = alpha * (P @ d_qd_v)
    return sign * out


def edge_noise(edge: Edge, raw_ns: tuple[NDArray[np.int64], NDArray[np.int64]]) -> EdgeNoise:
    """:class:`EdgeNoise` of a pairwise result; ``raw_ns``: the stamps of streams j and k's raw
    samples in the pair's clock (stream j's: k's shifted by the pair's time offset)."""
    cal = edge.calibration
    A, B = cal.pairs.A, cal.pairs.B
    w = np.ones(len(A)) if cal.weights is None else np.asarray(cal.weights, dtype=float)
    alpha = cal.solution.alpha
    q, qd = dq.from_transforms(cal.matrix)
    x = np.concatenate([q, qd])
    E, F = pair_blocks(A, B, alpha)
    Z = np.zeros_like(E)
    K = np.concatenate([np.concatenate([E, Z], axis=2), alpha * np.concatenate([F, E], axis=2)], axis=1)  # rows on x
    D, H, _ = constrained_hessian(np.einsum("n,nki,nkj->ij", w, K, K), q, qd)
    Hinv = np.linalg.pinv(H, hermitian=True)
    KD = K @ D                                                   # (N, 8, 6) ∂r/∂δ
    r = K @ x
    stamps = cal.synced.stamps_ns
    maps, energy = [], np.zeros((2, 3))
    for side, (M, raw) in enumerate(zip((A, B), raw_ns, strict=True)):
        S = _residual_sensitivity(M, q, qd, alpha, side)         # ∂r/∂ε_M
        G = -Hinv @ (np.swapaxes(KD, 1, 2) @ (w[:, None, None] * S))   # ∂δ/∂ε_M
        back = -adjoint(se3.inverse(M))                          # ε_M = n(t_j) - Ad(M⁻¹) n(t_i)
        lo, hi, frac = interpolation(raw, stamps)
        ends = (cal.pairs.j, cal.pairs.i)                        # a motion's end and start samples
        blocks = (G, G @ back)
        n_pairs = len(G)
        rows, cols, vals = [], [], []
        for e, (sample, S_end) in enumerate(zip(ends, (S, S @ back), strict=True)):
            S2 = np.square(S_end)
            parts = np.stack([S2[:, :4, :3].sum(axis=(1, 2)), S2[:, 4:, :3].sum(axis=(1, 2)),
                              S2[:, 4:, 3:].sum(axis=(1, 2))], axis=1)          # (N, 3) per unit share²
            for idx, share in ((lo, 1.0 - frac), (hi, frac)):
                rows.append(idx[sample])
                cols.append(e * n_pairs + np.arange(n_pairs))
                vals.append(share[sample])
                energy[side] += (w * share[sample] ** 2) @ parts
        spread = sparse.csr_array((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                                  shape=(len(raw), 2 * n_pairs))               # raw sample ← (pair, end)
        L = spread @ np.concatenate(blocks).reshape(-1, 36)
        maps.append(L.reshape(-1, 6, 6))
    observed = np.array([np.sum(w * np.sum(r[:, :4] ** 2, axis=1)), np.sum(w * np.sum(r[:, 4:] ** 2, axis=1))])
    return EdgeNoise((maps[0], maps[1]), energy, observed)


def stream_variances(n: int, pairs: list[tuple[int, int]], noise: list[EdgeNoise]) -> StreamNoise:
    """Every stream's per-component rotation and translation variance from the pairs' residual
    energies (non-negative least squares in relative terms, rotation first; module docstring).
    With two streams (one pair) the split between them is not determined: NNLS picks one, which
    does not matter to a joint estimate of one pair."""
    design = np.zeros((len(pairs), 3, n))
    for e, ((j, k), nz) in enumerate(zip(pairs, noise, strict=True)):
        design[e, :, j] += nz.energy[0]
        design[e, :, k] += nz.energy[1]
    observed = np.array([nz.observed for nz in noise])
    scale = np.maximum(observed, np.finfo(float).tiny)
    rot = nnls(design[:, 0] / scale[:, :1], observed[:, 0] / scale[:, 0])[0]
    rest = observed[:, 1] - design[:, 1] @ rot
    trans = nnls(design[:, 2] / scale[:, 1:], rest / scale[:, 1])[0]
    return StreamNoise(np.maximum(rot, VARIANCE_FLOOR), np.maximum(trans, VARIANCE_FLOOR))


def edge_covariance(pairs: list[tuple[int, int]], noise: list[EdgeNoise], variances: StreamNoise) -> Array:
    """The joint covariance (6E, 6E) of the pairwise estimates' errors ``δ`` (rotation [rad],
    translation [m]; left perturbations of each ``T_j_k``), from the streams they share."""
    E = len(pairs)
    C = np.zeros((6 * E, 6 * E))
    sigma = [np.repeat([variances.rotation[s], variances.translation[s]], 3) for s in range(len(variances.rotation))]
    for e in range(E):
        for f in range(e, E):
            block = np.zeros((6, 6))
            for side_e, s in enumerate(pairs[e]):
                if s in pairs[f]:
                    Le, Lf = noise[e].maps[side_e], noise[f].maps[pairs[f].index(s)]
                    block += np.einsum("mab,b,mcb->ac", Le, sigma[s], Lf)
            C[6 * e:6 * e + 6, 6 * f:6 * f + 6] = block
            C[6 * f:6 * f + 6, 6 * e:6 * e + 6] = block.T
    return C
