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
The energies are those of each pair's shortest motions (up to :data:`SHORT_STRIDE` samples),
where errors that grow with the span (drift, a wrong scale, a mount that slipped) add least: from
the solved pairs' own motions, a stream scaled by 0.8 was charged ~40 times its noise variance,
which hid its bias from the consistency test (:func:`handeye_cli.rig.joint.consistency`).

Drift is not white: an odometry whose world turns and slides at a constant rate ``ξ`` (a twist at
its world's origin [rad/s, m/s]) perturbs every motion by ``ε = Δt Ad(T_end⁻¹) ξ`` — the same
direction in the world for every motion, growing with its span — so its effect on a pairwise
estimate does not average out, and pairs sharing the stream are biased alike (measured on the
simulated rigs: the drift's first-order bias was 68–87 % (RMS) of the drifting pairs' translation error,
their χ² under the white model 11–18 instead of 6; without it, 5.3–6.8). Only the two streams'
*relative* drift ``d`` shows in a pair (a drift common to both keeps ``A X = X B``), and it is
linear in the residuals: ``Log(A⁻¹ X B X⁻¹) ≈ Ad(X) ε_B - ε_A = Δt Ad(T_a,end⁻¹) d``.
:func:`edge_noise` fits ``d`` by least squares on probe motions of every span (a √2 ladder of
strides within the tracking segments), maps every raw sample's noise to ``d̂`` as it does to the
estimate, and gives the estimate's first-order bias ``Ψ d`` (:class:`EdgeDrift`).
:func:`drift_corrections` tests ``d̂`` against its covariance (χ², 6 degrees of freedom) and
removes the bias of the pairs whose drift is significant (p < :data:`DRIFT_P_VALUE`); a
corrected estimate's noise maps are the estimate's minus ``Ψ`` times ``d̂``'s, so
:func:`edge_covariance` stays exact to first order. A drift that is not a constant rate (a random
walk) is modelled only by its mean rate over the log; what a correction may leave is bounded by
the bias it removed (:func:`bias_bound`), which the combination adds to the pair's covariance
(measured on the rig tests' 20 rigs with drifting wheels: cam1's translation 1.11 × its best
pairwise chain without the bound, 0.93 × with it) and the χ² test does not (it keeps its power).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..analysis.covariance import constrained_hessian
from ..analysis.selection import ladder
from ..geometry import dualquat as dq
from ..geometry import se3
from ..geometry.lie import adjoint, log_errors
from ..numeric.chi2 import chi2_sf
from ..numeric.nnls import nnls
from ..solvers.problem import pair_blocks
from ..stages.sync import Synced
from ..streams import bracket
from .pairwise import Edge

__all__ = ["EdgeNoise", "EdgeDrift", "Correction", "StreamNoise", "edge_noise", "stream_variances",
           "drift_corrections", "edge_covariance", "bias_bound", "VARIANCE_FLOOR", "DRIFT_P_VALUE", "DRIFT_PROBE"]

Array = NDArray[np.float64]
VARIANCE_FLOOR = 1e-18      # (1 nrad)², (1 nm)²: below it a stream is noise-free to rounding
DRIFT_P_VALUE = 0.01        # a pair's relative drift is removed when its χ² is this unlikely under "no drift"
DRIFT_PROBE = 200           # probe motions per stride of the drift fit (evenly spread over the segments)
SHORT_STRIDE = 4            # the three-cornered hat's motions span up to this many synced samples
SHORT_MOTIONS = 1000        # ... at most this many per stride (all of a 30-s log's at 30 Hz; 4000 per pair fix its
                            # energies to ~2 %: 2000 cost a 10-min rig 0.2 s more, its 72000 2 s)


@dataclass(frozen=True, eq=False)
class EdgeDrift:
    """The relative constant-rate drift of a pair's streams (module docstring) and its effect.

    rate: (6,) ``d̂``: how stream k's world turns and slides relative to stream j's, as a twist at
        j's world origin in its axes (rotation [rad/s], translation [m/s]).
    maps: per stream (j, k), (M, 6, 6): raw sample m's noise ``(ω, v)`` → the error of ``d̂``.
    bias: (6, 6) ``Ψ``: the pairwise estimate's first-order error ``δ = Ψ d`` (left perturbation,
        rotation [rad], translation [m]) caused by a relative drift ``d``.
    """

    rate: Array
    maps: tuple[Array, Array]
    bias: Array


@dataclass(frozen=True, eq=False)
class EdgeNoise:
    """How the noise of streams j and k reaches the pairwise estimate of ``T_j_k``.

    maps: per stream (j, k), (M, 6, 6): raw sample m's noise ``(ω, v)`` → the estimate's error ``δ``.
    energy: (2, 3) per stream (j, k): the expected residual energy of the pair's short motions
        (:func:`_short_energies`) per unit variance — rotation rows from rotation noise, dual rows
        from rotation noise, dual rows from translation noise.
    observed: (2,) their residual energy at the pairwise optimum: rotation rows, dual rows.
    drift: the fit of the streams' relative drift.
    """

    maps: tuple[Array, Array]
    energy: Array
    observed: Array
    drift: EdgeDrift


@dataclass(frozen=True, eq=False)
class Correction:
    """A pair's relative drift, its test and the bias removed.

    rate: (6,) ``d̂`` (see :class:`EdgeDrift`); statistic: ``d̂ᵀ Cov(d̂)⁻¹ d̂`` (χ² of 6 degrees of
    freedom without drift); p_value; applied: ``p_value < DRIFT_P_VALUE``; bias: (6,) ``Ψ d̂``,
    the estimate's first-order error from that drift (left perturbation, rotation [rad],
    translation [m]), removed when applied.
    """

    rate: Array
    statistic: float
    p_value: float
    applied: bool
    bias: Array

    @property
    def step(self) -> Array:
        """``Exp(-Ψ d̂)`` (4x4; the identity when not applied): the corrected estimate is ``step · T̂_j_k``."""
        step = np.eye(4)
        if self.applied:
            step[:3, :3] = dq.to_matrix(dq.from_rotvec(-self.bias[:3]))
            step[:3, 3] = -self.bias[3:]
        return step

    def as_dict(self) -> dict[str, object]:
        """The document's view: the rate [deg/s, m/s], the test, the bias [deg, m] and whether it was removed."""
        return {"rotation_deg_per_s": float(np.rad2deg(np.linalg.norm(self.rate[:3]))),
                "translation_m_per_s": float(np.linalg.norm(self.rate[3:])),
                "chi2": self.statistic, "dof": 6, "p_value": self.p_value, "corrected": self.applied,
                "bias": {"rotation_deg": float(np.rad2deg(np.linalg.norm(self.bias[:3]))),
                         "translation_m": float(np.linalg.norm(self.bias[3:]))}}


@dataclass(frozen=True)
class StreamNoise:
    """Per-component pose-noise variances of every stream: ``rotation`` [rad²], ``translation`` [m²] (n,)."""

    rotation: Array
    translation: Array

    def std(self, k: int) -> tuple[float, float]:
        """Stream k's per-sample noise as an angle [rad] and a distance [m] (3-D, root of the sum)."""
        return float(np.sqrt(3 * self.rotation[k])), float(np.sqrt(3 * self.translation[k]))



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


@dataclass(frozen=True, eq=False)
class _Spread:
    """How the raw samples' noise enters the right perturbations ``ε = n(end) - Ad(M⁻¹) n(start)`` of
    motions ``M`` (N, 4, 4), each synced sample the interpolation of two raw ones: ``raw`` (4, N) the
    raw samples (end lo, end hi, start lo, start hi) and ``share`` (4, N) their interpolation
    weights, ``back`` (N, 6, 6) ``-Ad(M⁻¹)``, ``samples`` the number of raw samples."""

    raw: NDArray[np.int64]
    share: Array
    back: Array
    samples: int


def _spread(M: Array, raw_ns: NDArray[np.int64], stamps_ns: NDArray[np.int64], start: NDArray[np.int64],
            end: NDArray[np.int64]) -> _Spread:
    """:class:`_Spread` of motions ``M`` from synced sample ``start`` to ``end``."""
    _, lo, hi, frac = bracket(raw_ns, stamps_ns)      # the synced stamps lie within the raw ones
    raw = np.stack((lo[end], hi[end], lo[start], hi[start]))
    share = np.stack((1.0 - frac[end], frac[end], 1.0 - frac[start], frac[start]))
    return _Spread(raw, share, -adjoint(se3.inverse(M)), len(raw_ns))


def _sample_maps(spread: _Spread, blocks: Array) -> Array:
    """(raw samples, 6, 6): Σ over motions of ``blocks`` (N, 6, 6) (∂·/∂ε) times ∂ε/∂n_raw, by one weighted count
    over the raw samples per entry of the 6x6 map (no sparse matrix, whose import would cost ``handeye rig``
    0.15 s; nor one count over all 36 entries at once, whose (4·N·36) index and weights cost more fresh memory
    than the 36 counts do; each entry's terms are added in the same order either way)."""
    n = len(blocks)
    flat, via_start = blocks.reshape(n, 36), (blocks @ spread.back).reshape(n, 36)
    terms = np.empty((36, 4, n))                      # entry × (end lo, end hi, start lo, start hi) × motion
    for r, part in enumerate((flat, flat, via_start, via_start)):
        np.multiply(part.T, spread.share[r], out=terms[:, r])          # in place: no stacked copy
    raw, out = spread.raw.ravel(), np.empty((spread.samples, 36))
    for entry, weights in enumerate(terms):
        out[:, entry] = np.bincount(raw, weights=weights.ravel(), minlength=spread.samples)
    return out.reshape(-1, 6, 6)


def _regressor(synced: Synced, T_a: Array, start: NDArray[np.int64], end: NDArray[np.int64]) -> Array:
    """``Δt Ad(T_a,end⁻¹)`` (N, 6, 6): a relative drift ``d``'s share of the motions' residuals (``T_a``: the
    synced poses of stream a, ``synced.T_a``)."""
    return np.asarray(((synced.stamps_ns[end] - synced.stamps_ns[start]) / 1e9)[:, None, None]
                      * adjoint(se3.inverse(T_a[end])), dtype=np.float64)


def _strided(synced: Synced, strides: NDArray[np.int64], most: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Start and end samples of motions of the given strides within the tracking segments, at most
    ``most`` per stride, evenly spread."""
    seg, n = synced.segment, len(synced.segment)
    i_all, j_all = [], []
    for stride in strides[strides < n]:
        i = np.flatnonzero(seg[:n - stride] == seg[stride:])
        i = i[np.linspace(0, len(i) - 1, min(most, len(i))).astype(np.int64)] if len(i) else i
        i_all.append(i)
        j_all.append(i + stride)
    empty = np.zeros(0, dtype=np.int64)
    return np.concatenate([empty, *i_all]), np.concatenate([empty, *j_all])


def _probe(synced: Synced) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The drift fit's probe motions: every stride of a √2 ladder up to the longest tracking
    segment, :data:`DRIFT_PROBE` per stride."""
    seg = synced.segment
    starts = np.flatnonzero(np.r_[True, seg[1:] != seg[:-1]])
    return _strided(synced, ladder(int(np.diff(np.r_[starts, len(seg)]).max())), DRIFT_PROBE)


def _drift(edge: Edge, raw_ns: tuple[NDArray[np.int64], NDArray[np.int64]], G_b: Array,
           poses: tuple[Array, Array]) -> EdgeDrift:
    """Fit the relative drift of the pair's streams on probe motions (module docstring);
    ``G_b`` (N, 6, 6): ∂δ/∂ε_B of the estimator's motions, for the bias map; ``poses``: the synced poses
    ``T_a``, ``T_b``."""
    cal = edge.calibration
    syn, X, alpha = cal.synced, cal.matrix, cal.solution.alpha
    (T_a, T_b), (i, j) = poses, _probe(syn)
    A, B = se3.relative(T_a[i], T_a[j]), se3.relative(T_b[i], T_b[j])
    H = _regressor(syn, T_a, i, j)
    r = log_errors(se3.inverse(A) @ X @ B @ se3.inverse(X))      # ≈ Ad(X) ε_B - ε_A = H d
    W = np.repeat([1.0, alpha ** 2], 3)                            # rotation vs translation, as the pair's cost
    L = np.linalg.pinv(np.einsum("nai,a,naj->ij", H, W, H, optimize=True), hermitian=True) @ (np.swapaxes(H, 1, 2) * W)
    rate = np.einsum("nab,nb->a", L, r)
    AdX = adjoint(X[None])[0]
    maps = []
    for side, (M, raw) in enumerate(zip((A, B), raw_ns, strict=True)):
        maps.append(_sample_maps(_spread(M, raw, syn.stamps_ns, i, j), -L if side == 0 else L @ AdX))
    bias = np.einsum("nab,bc,ncd->ad", G_b, adjoint(se3.inverse(X)[None])[0],
                     _regressor(syn, T_a, cal.pairs.i, cal.pairs.j), optimize=True)      # ε_B = Ad(X⁻¹) H d
    return EdgeDrift(rate, (maps[0], maps[1]), bias)


def _white_energy(M: Array, S: Array, raw_ns: NDArray[np.int64], stamps_ns: NDArray[np.int64],
                  start: NDArray[np.int64], end: NDArray[np.int64]) -> Array:
    """(3,) expected residual energy per unit variance of one stream's white noise over motions
    ``M`` (sensitivities ``S`` = ∂r/∂ε_M): rotation rows ← rotation, dual ← rotation, dual ←
    translation. A raw sample that both ends of a motion interpolate counts once, its terms added first."""
    spread = _spread(M, raw_ns, stamps_ns, start, end)
    idx, share = spread.raw, spread.share                                   # (4, N): end lo, hi; start lo, hi
    S_back = S @ spread.back                                                # ∂r/∂n of a start term, per unit share
    same = share[:, None] * share[None] * (idx[:, None] == idx[None])      # (4, 4, N): terms on one raw sample
    kinds = (S * S, S * S_back, S_back * S_back)          # products of an end's and a start's terms: 3 kinds
    weight = (same[:2, :2].sum(axis=(0, 1)), 2 * same[:2, 2:].sum(axis=(0, 1)), same[2:, 2:].sum(axis=(0, 1)))
    total = sum(np.einsum("n,nkc->kc", w, P) for w, P in zip(weight, kinds, strict=True))
    return np.array([total[:4, :3].sum(), total[4:, :3].sum(), total[4:, 3:].sum()])


def _short_motions(synced: Synced) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The hat's motions: strides 1 to :data:`SHORT_STRIDE` synced samples, :data:`SHORT_MOTIONS` per stride."""
    return _strided(synced, np.arange(1, SHORT_STRIDE + 1), SHORT_MOTIONS)


def _short_energies(edge: Edge, raw_ns: tuple[NDArray[np.int64], NDArray[np.int64]], poses: tuple[Array, Array]
                    ) -> tuple[Array, Array]:
    """The three-cornered hat's observations of a pair: over its short motions (:func:`_short_motions`,
    where errors that grow with the span — drift, a wrong scale, a slipped mount — add least),
    the expected residual energy per unit variance of each stream (2, 3) and the observed one
    (2,) at the pairwise estimate: rotation rows, dual rows (α-weighted as the pair was solved); ``poses``:
    the synced poses ``T_a``, ``T_b``."""
    cal = edge.calibration
    syn, alpha = cal.synced, cal.solution.alpha
    (T_a, T_b), (i, j) = poses, _short_motions(syn)
    A, B = se3.relative(T_a[i], T_a[j]), se3.relative(T_b[i], T_b[j])
    q, qd = dq.from_transforms(cal.matrix)
    E, F = pair_blocks(A, B, alpha, cal.matrix)
    r = np.concatenate([E @ q, alpha * (F @ q + E @ qd)], axis=1)
    energy = np.stack([_white_energy(M, _residual_sensitivity(M, q, qd, alpha, side), raw, syn.stamps_ns, i, j)
                       for side, (M, raw) in enumerate(zip((A, B), raw_ns, strict=True))])
    return energy, np.array([np.sum(r[:, :4] ** 2), np.sum(r[:, 4:] ** 2)])


def edge_noise(edge: Edge, raw_ns: tuple[NDArray[np.int64], NDArray[np.int64]]) -> EdgeNoise:
    """:class:`EdgeNoise` of a pairwise result; ``raw_ns``: the stamps of streams j and k's raw
    samples in the pair's clock (stream j's: k's shifted by the pair's time offset)."""
    cal = edge.calibration
    A, B = cal.pairs.A, cal.pairs.B
    w = np.ones(len(A)) if cal.weights is None else np.asarray(cal.weights, dtype=float)
    alpha = cal.solution.alpha
    q, qd = dq.from_transforms(cal.matrix)
    E, F = pair_blocks(A, B, alpha, cal.matrix)
    Z = np.zeros_like(E)
    K = np.concatenate([np.concatenate([E, Z], axis=2), alpha * np.concatenate([F, E], axis=2)], axis=1)  # rows on x
    D, H, _ = constrained_hessian(np.einsum("n,nki,nkj->ij", w, K, K), q, qd)
    Hinv = np.linalg.pinv(H, hermitian=True)
    KD = K @ D                                                   # (N, 8, 6) ∂r/∂δ
    maps = []
    for side, (M, raw) in enumerate(zip((A, B), raw_ns, strict=True)):
        S = _residual_sensitivity(M, q, qd, alpha, side)         # ∂r/∂ε_M
        G = -Hinv @ (np.swapaxes(KD, 1, 2) @ (w[:, None, None] * S))   # ∂δ/∂ε_M
        maps.append(_sample_maps(_spread(M, raw, cal.synced.stamps_ns, cal.pairs.i, cal.pairs.j), G))
    poses = cal.synced.T_a, cal.synced.T_b                     # built once per pair, not on each access
    energy, observed = _short_energies(edge, raw_ns, poses)
    return EdgeNoise((maps[0], maps[1]), energy, observed, _drift(edge, raw_ns, G, poses))


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


def _sigma(variances: StreamNoise, s: int) -> Array:
    """Stream s's per-component variances (6,): rotation [rad²] ×3, translation [m²] ×3."""
    return np.repeat([variances.rotation[s], variances.translation[s]], 3)


def _through(L: Array, sigma: Array, M: Array) -> Array:
    """``Σ_m L_m diag(σ) M_mᵀ`` (a, c) of per-sample maps ``L`` (m, a, 6), ``M`` (m, c, 6): the
    covariance of two estimates' errors from one stream's independent samples."""
    return np.asarray(np.einsum("mab,b,mcb->ac", L, sigma, M, optimize=True), dtype=np.float64)


def drift_corrections(pairs: list[tuple[int, int]], noise: list[EdgeNoise], variances: StreamNoise
                      ) -> list[Correction]:
    """Test each pair's relative drift ``d̂`` against its covariance under the streams' noise (χ²,
    6 degrees of freedom) and, where ``p < DRIFT_P_VALUE``, the bias ``Ψ d̂`` to remove."""
    out = []
    for (j, k), nz in zip(pairs, noise, strict=True):
        dr = nz.drift
        cov = sum(_through(L, _sigma(variances, s), L) for L, s in zip(dr.maps, (j, k), strict=True))
        stat = float(dr.rate @ np.linalg.pinv(cov, hermitian=True) @ dr.rate)
        p = chi2_sf(6, stat)
        out.append(Correction(dr.rate, stat, p, p < DRIFT_P_VALUE, dr.bias @ dr.rate))
    return out


def edge_covariance(pairs: list[tuple[int, int]], noise: list[EdgeNoise], variances: StreamNoise,
                    corrections: list[Correction]) -> Array:
    """The joint covariance (6E, 6E) of the pairwise estimates' errors ``δ`` (rotation [rad],
    translation [m]; left perturbations of each ``T_j_k``), from the streams they share; a
    corrected estimate's error is ``δ - Ψ δd̂`` (its maps minus ``Ψ`` times the drift fit's)."""
    E = len(pairs)
    maps = [tuple(m - nz.drift.bias @ dm if c.applied else m for m, dm in zip(nz.maps, nz.drift.maps, strict=True))
            for nz, c in zip(noise, corrections, strict=True)]
    C = np.zeros((6 * E, 6 * E))
    for e in range(E):
        for f in range(e, E):
            block = np.zeros((6, 6))
            for side_e, s in enumerate(pairs[e]):
                if s in pairs[f]:
                    Le, Lf = maps[e][side_e], maps[f][pairs[f].index(s)]
                    block += _through(Le, _sigma(variances, s), Lf)
            C[6 * e:6 * e + 6, 6 * f:6 * f + 6] = block
            C[6 * f:6 * f + 6, 6 * e:6 * e + 6] = block.T
    return C


def bias_bound(corrections: list[Correction]) -> Array:
    """(6E, 6E): each corrected pair's removed bias ``b = Ψ d̂`` as the bound ``b bᵀ`` of what it may
    still carry (a drift that is not a constant rate, its second order), block-diagonal; zero for
    the pairs left as they are. Added to the covariance where the pairs are combined, it down-weighs
    a drifting pair in the directions its drift biased it, by as much as its drift did."""
    E = len(corrections)
    out = np.zeros((6 * E, 6 * E))
    for e, c in enumerate(corrections):
        if c.applied:
            out[6 * e:6 * e + 6, 6 * e:6 * e + 6] = np.outer(c.bias, c.bias)
    return out
