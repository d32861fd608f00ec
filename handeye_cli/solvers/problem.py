"""The least-squares problem of the paper: the matrices S, M, W (eqs 6–9) and the prior (eqs 26–29).

Given motion pairs ``A_i X = X B_i`` (``X = T_a_b``; the paper's ``C_i = A_i``, ``H_i = B_i``)
with dual quaternions ``Q_C = q_C + ε q'_C`` and ``Q_H = q_H + ε q'_H``, eq 6 gives per pair
the 4x4 blocks (the paper's ``A_i``, ``B_i`` of eq 7, named ``E_i``, ``F_i`` here so they do not
clash with the motions)::

    E_i = L(q_C) - R(q_H),    F_i = L(q'_C) - R(q'_H)

and the cost (8), with per-pair weights w_i::

    Σ w_i (|E_i q|² + α² |F_i q + E_i q'|²) = qᵀ S q + q'ᵀ M q' + 2 qᵀ W q'
    S = Σ w EᵀE + α² Σ w FᵀF,   M = α² Σ w EᵀE,   W = α² Σ w FᵀE            (eq 9)

The prior (eq 26) adds ``a δqᵀ G δq + b |δq'|²`` with ``δQ = Q̂* ⊗ Q`` (eq 27): rows
``√a G L(q̂*)`` acting on q, and ``√b (L(q̂'*) q + L(q̂*) q')``, which give eq 29
(``S += a L*ᵀGL*``, ``W += b L'*ᵀL*``, ``M += b I``) plus the constant ``b |q̂'|²`` that the
paper drops and that is kept here so that costs are the true values.
Quaternions are x-y-z-w (see :mod:`.dualquat`).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .. import se3
from ..errors import HandEyeError
from . import dualquat as dq

__all__ = ["Prior", "Problem", "build_problem", "pair_blocks", "problem_from_blocks", "validate_motions"]

_G = np.diag([1.0, 1.0, 1.0, 0.0])


@dataclass(frozen=True)
class Prior:
    """A prior extrinsic ``T_a_b`` and the weights of its rotation (``a``) and translation (``b``) terms (eq 26)."""

    T_a_b: np.ndarray
    a: float = 1.0
    b: float = 1.0


@dataclass(frozen=True, eq=False)
class Problem:
    """Cost (8) (+ prior) as stacked residual rows: ``|P q|² + |F q + E q'|²``.

    ``P`` (K, 4) holds the rotational residual rows (``√w_i E_i``, and ``√a G L(q̂*)`` for a prior);
    ``F``, ``E`` (L, 4) the dual ones (``α√w_i F_i``, ``α√w_i E_i``, and ``√b L(q̂'*)``, ``√b L(q̂*)``).
    Then ``S = PᵀP + FᵀF``, ``M = EᵀE``, ``W = FᵀE`` (eq 9, eq 29) and the prior's constant is
    included, so :meth:`cost` is the true value. Keeping the rows lets Z0 be formed without
    the cancellation in ``S - W M⁻¹ Wᵀ`` and costs be summed from residuals.
    """

    P: np.ndarray
    F: np.ndarray
    E: np.ndarray

    @cached_property
    def S(self) -> np.ndarray:
        return self.P.T @ self.P + self.F.T @ self.F

    @cached_property
    def M(self) -> np.ndarray:
        return self.E.T @ self.E

    @cached_property
    def W(self) -> np.ndarray:
        return self.F.T @ self.E

    def cost(self, q: np.ndarray, qd: np.ndarray) -> float:
        """Cost (8) plus the prior terms at the dual quaternion ``q + ε q'``, summed from residuals."""
        rot = self.P @ q
        dual = self.F @ q + self.E @ qd
        return float(rot @ rot + dual @ dual)

    @cached_property
    def _qr(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Thin QR of E, and the SVD (singular values, right vectors) of its R factor."""
        Qe, Re = np.linalg.qr(self.E)
        _, sv, Vt = np.linalg.svd(Re)
        return Qe, Re, sv, Vt

    @property
    def M_is_regular(self) -> bool:
        """Whether M = EᵀE is safely invertible (the paper's standing assumption below eq 10)."""
        sv = self._qr[2]
        return bool(sv[-1] > 1e-8 * max(sv[0], 1e-300))

    @property
    def M_smallest_eigenvector(self) -> np.ndarray:
        """The eigenvector of M with the smallest eigenvalue (eq 19), from the SVD of E."""
        return self._qr[3][-1].copy()

    @property
    def R_factor(self) -> np.ndarray:
        """The R of the thin QR factorisation ``E = Qe Re`` (so ``M = ReᵀRe``)."""
        return self._qr[1]

    @cached_property
    def Z(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``Z0 = S - W M⁻¹ Wᵀ``, ``Z1 = W M⁻¹ + M⁻¹ Wᵀ``, ``Z2 = M⁻¹`` (eq 13); needs a regular M.

        With ``E = Qe Re``: ``Z2 = Re⁻¹ Re⁻ᵀ``, ``W M⁻¹ = (Qeᵀ F)ᵀ Re⁻ᵀ`` and
        ``Z0 = PᵀP + |F - Qe Qeᵀ F|²`` (the paper's ``AᵀA + α² BᵀCB``), which is PSD by construction.
        """
        Qe, Re, _, _ = self._qr
        G = Qe.T @ self.F
        Rinv = np.linalg.inv(Re)
        Fr = self.F - Qe @ G
        WMinv = G.T @ Rinv.T
        return self.P.T @ self.P + Fr.T @ Fr, WMinv + WMinv.T, Rinv @ Rinv.T

    @cached_property
    def Z0_relaxed(self) -> np.ndarray:
        """Z0 also for a singular M: the Schur complement with the projector on E's column space."""
        if self.M_is_regular:
            return self.Z[0]
        U, sv, _ = np.linalg.svd(self.E, full_matrices=False)
        U = U[:, sv > 1e-8 * max(sv[0], 1e-300)]
        Fr = self.F - U @ (U.T @ self.F)
        return self.P.T @ self.P + Fr.T @ Fr

    def dual_part(self, q: np.ndarray) -> tuple[np.ndarray, float]:
        """The optimal ``q'`` for a given unit ``q`` under ``q·q' = 0``, and its multiplier μ.

        Solves ``min |F q + E q'|²`` over ``q' ⊥ q`` by least squares in an orthonormal basis of
        ``q``'s complement. With a regular M this is exactly eq 20, ``q' = M⁻¹ (μ - Wᵀ) q`` with μ
        from eq 14, but it needs no inverse of M and stays defined when M is singular along ``q``
        (noise-free data). Where the translation is truly unobservable the least-norm ``q'`` is returned.
        """
        basis = np.linalg.svd(q[None, :])[2][1:].T          # (4, 3), orthonormal, ⊥ q
        y = np.linalg.lstsq(self.E @ basis, -(self.F @ q), rcond=None)[0]
        qd = basis @ y
        mu = float(q @ (self.W.T @ q + self.M @ qd))         # from M q' + Wᵀ q = μ q (eq 10)
        return qd, mu


def validate_motions(motions_a: np.ndarray, motions_b: np.ndarray,
                     weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Check shapes, finiteness and rotation blocks; return float arrays (N,4,4), (N,4,4), (N,)."""
    A = np.asarray(motions_a, dtype=float)
    B = np.asarray(motions_b, dtype=float)
    for name, T in (("motions_a", A), ("motions_b", B)):
        if T.ndim != 3 or T.shape[1:] != (4, 4):
            raise HandEyeError(f"{name} has shape {T.shape}", name, "pass an array of shape (N, 4, 4)")
        if not np.isfinite(T).all():
            bad = int(np.flatnonzero(~np.isfinite(T).all(axis=(1, 2)))[0])
            raise HandEyeError(f"{name}[{bad}] contains NaN or inf", name, "remove or repair that motion")
        ok = se3.is_rotation(T[:, :3, :3], 1e-6)
        if not ok.all():
            bad = int(np.flatnonzero(~ok)[0])
            raise HandEyeError(f"{name}[{bad}] has a rotation block that is not a rotation", name,
                               "pass rigid transforms (orthonormal rotation, det +1)")
    if len(A) != len(B):
        raise HandEyeError(f"motions_a has {len(A)} motions, motions_b {len(B)}", "motions",
                           "pass the same number of motions for both sensors")
    if len(A) < 2:
        raise HandEyeError(f"{len(A)} motion pair(s)", "motions", "at least 2 motion pairs are needed")
    if weights is None:
        w = np.ones(len(A))
    else:
        w = np.asarray(weights, dtype=float).reshape(-1)
        if w.shape != (len(A),) or not np.isfinite(w).all() or (w < 0).any() or not (w > 0).any():
            raise HandEyeError(f"weights must be {len(A)} finite non-negative numbers, not all zero",
                               "weights", "pass one weight per motion pair")
    return A, B, w


def pair_blocks(motions_a: np.ndarray, motions_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The per-pair blocks ``E_i = L(q_C) - R(q_H)`` and ``F_i = L(q'_C) - R(q'_H)`` (eqs 6–7), (N,4,4) each."""
    qc, qcd = dq.from_transforms(motions_a)
    qh, qhd = dq.from_transforms(motions_b)
    return dq.left(qc) - dq.right(qh), dq.left(qcd) - dq.right(qhd)


def build_problem(motions_a: np.ndarray, motions_b: np.ndarray, alpha: float = 1.0,
                  prior: Prior | None = None, weights: np.ndarray | None = None) -> Problem:
    """Stack the residual rows of cost (8) (weighted) and of the prior (eqs 26–27).

    ``alpha`` [1/m] weighs the translational residuals against the rotational ones.
    """
    A, B, w = validate_motions(motions_a, motions_b, weights)
    return problem_from_blocks(*pair_blocks(A, B), w, alpha=alpha, prior=prior)


def problem_from_blocks(E: np.ndarray, F: np.ndarray, w: np.ndarray, alpha: float = 1.0,
                        prior: Prior | None = None) -> Problem:
    """:func:`build_problem` from the per-pair blocks of :func:`pair_blocks` and validated weights."""
    if not (np.isfinite(alpha) and alpha > 0):
        raise HandEyeError(f"alpha must be a positive number, got {alpha}", "alpha",
                           "pass e.g. alpha=1.0 (units 1/m)")
    sw = np.sqrt(w)[:, None, None]
    P = (E * sw).reshape(-1, 4)
    Fd = (alpha * F * sw).reshape(-1, 4)
    Ed = alpha * P
    if prior is not None:
        if not (prior.a >= 0 and prior.b >= 0):
            raise HandEyeError("prior weights must be non-negative", "prior", "pass a, b ≥ 0")
        qp, qpd = dq.from_transforms(np.asarray(prior.T_a_b, dtype=float))
        Lc = dq.left(dq.conjugate(qp))                       # δq = L(q̂*) q            (eq 27)
        Lcd = dq.left(dq.conjugate(qpd))                     # δq' = L(q̂'*) q + L(q̂*) q'
        P = np.vstack([P, np.sqrt(prior.a) * (_G @ Lc)])
        Fd = np.vstack([Fd, np.sqrt(prior.b) * Lcd])
        Ed = np.vstack([Ed, np.sqrt(prior.b) * Lc])
    return Problem(P, Fd, Ed)
