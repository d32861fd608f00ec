"""Linearised (sandwich) covariance of the DQOpt estimate ``X = T_a_b`` under cost (8).

Conventions: ``X = T_a_b`` (maps frame b to frame a), ``A_i X = X B_i``; dual quaternions
``x = [q; q']`` with q in x-y-z-w order (:mod:`handeye_cli.geometry.dualquat`).

The estimate is perturbed on the left in frame a, ``X(δ) = Δ(ω, v) X``, i.e.
``Q_X(δ) = Q_Δ ⊗ Q_X`` with ``Q_Δ ≈ (ω/2, 1) + ε (v/2, 0)``. This map stays on the unit dual
quaternions, so ``dx/dδ = D`` (8x6) spans the constraint set's tangent space. With the per-pair
rows ``K_i = [E_i, 0; αF_i, αE_i]`` (eqs 6–8) and the Lagrangian of §3.1,
``L = xᵀQx - λ(|q|² - 1) - 2μ q·q'``:

* Hessian along the constraint set: ``H = Dᵀ (Q - Λ) D``, ``Λ = [λI, μI; μI, 0]`` (λ, μ from eq 10);
* per-pair score: ``g_i = Dᵀ K_iᵀ K_i x``;
* covariance of δ: ``H⁻¹ (Σ g_i g_iᵀ) H⁻¹ · n/(n-6)`` (or the dyadic-robust sum over shared
  pose samples) — the sandwich form (with the HC1
  degrees-of-freedom factor), valid whatever α is, because it measures the noise from the
  residuals instead of assuming that α weighs it correctly.

Finally δ is mapped to the error of X itself: rotation ``ω`` [rad] and translation
``δt = ω × t + v`` [m], both in frame a.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..geometry import dualquat as dq
from ..solvers import Prior
from ..solvers.problem import pair_blocks, problem_from_blocks, validate_motions

__all__ = ["LinearCovariance", "linear_covariance", "tangent_basis", "constrained_hessian", "DriftCheck", "drift_check",
           "DRIFT_INFLATION_LIMIT"]


@dataclass(frozen=True, eq=False)
class LinearCovariance:
    """First-order uncertainty of ``T_a_b`` as a 6x6 covariance over ``(ω [rad], δt [m])`` in frame a.

    ``hessian`` is the cost's curvature in the same coordinates (for conditioning checks);
    ``singular`` says whether it had a null space (some direction is not determined at all).
    """

    covariance: FloatArray
    hessian: FloatArray
    singular: bool

    @property
    def rotation_std_deg(self) -> FloatArray:
        """(3,) standard deviations of the rotation error about x, y, z of frame a [deg]."""
        return np.rad2deg(np.sqrt(np.clip(np.diag(self.covariance)[:3], 0.0, None)))

    @property
    def translation_std_m(self) -> FloatArray:
        """(3,) standard deviations of the translation error along x, y, z of frame a [m]."""
        return np.sqrt(np.clip(np.diag(self.covariance)[3:], 0.0, None))

    @property
    def rotation_rms_deg(self) -> float:
        """Expected geodesic rotation error (root of the trace) [deg]."""
        return float(np.rad2deg(np.sqrt(max(np.trace(self.covariance[:3, :3]), 0.0))))

    @property
    def translation_rms_m(self) -> float:
        """Expected Euclidean translation error (root of the trace) [m]."""
        return float(np.sqrt(max(np.trace(self.covariance[3:, 3:]), 0.0)))


def tangent_basis(q: FloatArray, qd: FloatArray) -> FloatArray:
    """``D = dx/dδ`` (8x6) for ``Q_X(δ) = Q_Δ(ω, v) ⊗ Q_X``, x = [q; q'], δ = (ω [rad], v [m]) in frame a."""
    Rq, Rqd = dq.right(q)[:, :3], dq.right(qd)[:, :3]
    D = np.zeros((8, 6))
    D[:4, :3] = 0.5 * Rq
    D[4:, :3] = 0.5 * Rqd
    D[4:, 3:] = 0.5 * Rq
    return D


def constrained_hessian(Q: FloatArray, q: FloatArray, qd: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The curvature of the cost ``xᵀQx`` (Q 8x8 in ``x = [q; q']`` order) over unit dual quaternions at
    ``q + ε q'``: ``(D, H, Qx)`` with ``D`` the :func:`tangent_basis`, ``H = Dᵀ(Q - Λ)D`` the Lagrangian's
    Hessian in δ = (ω [rad], v [m]) (Λ from the multipliers ``λ = qᵀ(Qx)_q``, ``μ = qᵀ(Qx)_q'`` of the
    unit and orthogonality constraints) and ``Qx`` (half the cost's gradient)."""
    x = np.concatenate([q, qd])
    Qx = Q @ x
    lam, mu = float(q @ Qx[:4]), float(q @ Qx[4:])
    Lam = np.block([[lam * np.eye(4), mu * np.eye(4)], [mu * np.eye(4), np.zeros((4, 4))]])
    D = tangent_basis(q, qd)
    H: FloatArray = D.T @ (Q - Lam) @ D
    return D, H, Qx


def _error_map(t: FloatArray) -> FloatArray:
    """6x6 map from δ = (ω, v) to the error (ω, δt = ω × t + v) of ``X = [R | t]``."""
    T = np.eye(6)
    T[3:, :3] = -np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    return T


def _meat(G: FloatArray, samples: tuple[IntArray, IntArray] | None) -> tuple[FloatArray, int]:
    """``Σ g gᵀ`` over independent units and their number: pairs, or — when pairs share pose
    samples ``(i, j)`` — the dyadic-robust sum ``Σ_n s_n s_nᵀ - Σ_k g_k g_kᵀ`` with ``s_n`` the
    summed scores of the pairs touching sample n (clipped to PSD)."""
    if samples is None:
        return G.T @ G, len(G)
    i, j = (np.asarray(v).reshape(-1) for v in samples)
    nodes, inv = np.unique(np.concatenate([i, j]), return_inverse=True)
    S = np.zeros((len(nodes), G.shape[1]))
    np.add.at(S, inv[: len(G)], G)
    np.add.at(S, inv[len(G):], G)
    lam, V = np.linalg.eigh(S.T @ S - G.T @ G)
    return (V * np.clip(lam, 0.0, None)) @ V.T, len(nodes)


def _block_meat(G: FloatArray, blocks: IntArray) -> tuple[FloatArray, int]:
    """``Σ_b s_b s_bᵀ`` with ``s_b`` the summed scores of the pairs in block b (cluster-robust: errors
    correlated inside a block, e.g. drift shared by pairs of one stretch of time), and the number of blocks."""
    labels, inv = np.unique(np.asarray(blocks).reshape(-1), return_inverse=True)
    S = np.zeros((len(labels), G.shape[1]))
    np.add.at(S, inv, G)
    return S.T @ S, len(labels)


def select_samples(samples: tuple[IntArray, IntArray] | None, keep: BoolArray) -> tuple[IntArray, IntArray] | None:
    """The pose-sample indices ``(i, j)`` (flattened) of the pairs selected by the mask ``keep``; ``None`` stays."""
    if samples is None:
        return None
    i, j = (np.asarray(v).reshape(-1)[keep] for v in samples)
    return i, j


def linear_covariance(motions_a: FloatArray, motions_b: FloatArray, T_a_b: FloatArray, *,
                      alpha: float = 1.0, prior: Prior | None = None, weights: FloatArray | None = None,
                      samples: tuple[IntArray, IntArray] | None = None,
                      blocks: IntArray | None = None) -> LinearCovariance:
    """Sandwich covariance of the cost-(8) minimiser at ``T_a_b`` (which should be that minimiser).

    Parameters are those of :func:`handeye_cli.solvers.solve`; α in 1/m. The prior adds
    curvature (eq 29) but no noise. ``samples = (i, j)`` (the pose samples each pair was formed
    from) switches to the dyadic-robust form for pairs that share samples (see
    :func:`handeye_cli.analysis.bootstrap`). ``blocks`` (N,) labels each pair with a block (e.g. of time)
    and switches to the cluster-robust form instead: pairs of one block may share errors (drift), pairs
    of different blocks do not. Returns a :class:`LinearCovariance`; for a singular
    Hessian the pseudo-inverse is used and ``singular`` is set.
    """
    A, B, w = validate_motions(motions_a, motions_b, weights)
    q, qd = dq.from_transforms(np.asarray(T_a_b, dtype=np.float64))
    E, F = pair_blocks(A, B, alpha, T_a_b)                # signs agreed by T_a_b, as the solver agrees them
    problem = problem_from_blocks(E, F, w, alpha=alpha, prior=prior)   # the blocks serve both
    D, H, _ = constrained_hessian(np.block([[problem.S, problem.W], [problem.W.T, problem.M]]), q, qd)
    r_rot = E @ q                                                   # (N, 4)
    r_dual = alpha * (F @ q + E @ qd)
    Kx = np.concatenate([np.einsum("nki,nk->ni", E, r_rot) + alpha * np.einsum("nki,nk->ni", F, r_dual),
                         alpha * np.einsum("nki,nk->ni", E, r_dual)], axis=1)   # K_iᵀ K_i x
    G = (w[:, None] * Kx) @ D                                       # (N, 6) scores
    ev = np.linalg.eigvalsh(H)
    singular = bool(ev[0] <= 1e-12 * max(abs(ev[-1]), 1e-300))
    Hinv = np.linalg.pinv(H, hermitian=True)
    keep = w > 0
    meat, n = (_meat(G[keep], select_samples(samples, keep)) if blocks is None
               else _block_meat(G[keep], np.asarray(blocks)[keep]))
    cov = Hinv @ meat @ Hinv * (n / (n - 6) if n > 12 else 2.0)              # HC1 correction
    Tm = _error_map(np.asarray(T_a_b, dtype=np.float64)[:3, 3])
    Tinv = np.linalg.inv(Tm)
    return LinearCovariance(Tm @ cov @ Tm.T, Tinv.T @ H @ Tinv, singular)


#: The blocked σ this many times the independent one: the residuals share errors across time.
DRIFT_INFLATION_LIMIT = 2.0


@dataclass(frozen=True, eq=False)
class DriftCheck:
    """The sandwich σ of ``T_a_b`` with pairs (or their pose samples) independent, beside the
    cluster-robust σ with ``blocks`` stretches of time as the independent units. ``ratio`` (rotation,
    translation) is blocked σ ÷ independent σ (root of the traces); above :data:`DRIFT_INFLATION_LIMIT`
    the errors are correlated across time (drift) and the independent σ is overconfident."""

    independent: LinearCovariance
    blocked: LinearCovariance
    blocks: int

    @property
    def ratio(self) -> tuple[float, float]:
        """Blocked ÷ independent RMS error (rotation, translation)."""
        tiny = 1e-300
        return (self.blocked.rotation_rms_deg / max(self.independent.rotation_rms_deg, tiny),
                self.blocked.translation_rms_m / max(self.independent.translation_rms_m, tiny))

    @property
    def overconfident(self) -> bool:
        """Whether either ratio exceeds :data:`DRIFT_INFLATION_LIMIT`."""
        return max(self.ratio) > DRIFT_INFLATION_LIMIT

    def warning(self) -> str:
        """The warning text for an overconfident σ (frames: rotation [deg], translation [m], frame a)."""
        r = self.ratio
        return (f"the residuals are correlated across time (drift): blocks of time give a {max(r):.3g}× larger "
                f"uncertainty than independent pairs — σ {self.blocked.rotation_rms_deg:.3g}° / "
                f"{self.blocked.translation_rms_m:.3g} m (uncertainty_check.blocked); "
                "record longer or more varied motion, or check the streams for drift")

    def as_dict(self) -> dict[str, Any]:
        """The result's ``uncertainty_check``: both σ per axis of frame a [deg], [m], the ratios, the verdict."""
        return {"blocks": self.blocks, "ratio": list(self.ratio), "limit": DRIFT_INFLATION_LIMIT,
                "overconfident": self.overconfident,
                "independent": {"rotation_std_deg": self.independent.rotation_std_deg.tolist(),
                                "translation_std_m": self.independent.translation_std_m.tolist()},
                "blocked": {"rotation_std_deg": self.blocked.rotation_std_deg.tolist(),
                            "translation_std_m": self.blocked.translation_std_m.tolist()}}


def drift_check(motions_a: FloatArray, motions_b: FloatArray, T_a_b: FloatArray, blocks: IntArray, *,
                alpha: float = 1.0, prior: Prior | None = None, weights: FloatArray | None = None,
                samples: tuple[IntArray, IntArray] | None = None) -> DriftCheck:
    """:class:`DriftCheck` of the solution ``T_a_b``: :func:`linear_covariance` with ``samples``
    (independent pose samples) and with ``blocks`` (N,) (independent stretches of time)."""
    kw: dict[str, Any] = {"alpha": alpha, "prior": prior, "weights": weights}
    return DriftCheck(linear_covariance(motions_a, motions_b, T_a_b, samples=samples, **kw),
                      linear_covariance(motions_a, motions_b, T_a_b, blocks=blocks, **kw),
                      int(len(np.unique(blocks))))
