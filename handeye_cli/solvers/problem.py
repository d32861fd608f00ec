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
from scipy.linalg import lapack

from .. import se3
from .._typing import FloatArray
from ..errors import ConfigError, DataError
from . import dualquat as dq
from .dualquat import _L_INDEX, _L_SIGN

__all__ = ["Prior", "Problem", "build_problem", "pair_blocks", "problem_from_blocks", "validate_motions"]

_G = np.diag([1.0, 1.0, 1.0, 0.0])
_UPPER8 = np.triu(np.ones((8, 8)))
_EPS = np.finfo(float).eps
_LWORK, _IWORK = (int(v) for v in lapack.dgelsd_lwork(4, 3, 1, -1)[:2])      # workspace of the 4x3 lstsq


@dataclass(frozen=True)
class Prior:
    """A prior extrinsic ``T_a_b`` and the weights of its rotation (``a``) and translation (``b``) terms (eq 26)."""

    T_a_b: FloatArray
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

    P: FloatArray
    F: FloatArray
    E: FloatArray

    @cached_property
    def _K(self) -> FloatArray:
        """``[E F]`` (L, 8), column-major for LAPACK; zero rows pad it to at least 8."""
        n = len(self.E)
        K: FloatArray = np.zeros((8, max(n, 8))).T
        K[:n, :4] = self.E
        K[:n, 4:] = self.F
        return K

    @cached_property
    def _PtP(self) -> FloatArray:
        PtP: FloatArray = self.P.T @ self.P
        return PtP

    @cached_property
    def form(self) -> FloatArray:
        """The 8x8 matrix ``[[M, Wᵀ], [W, S]]`` of cost (8) (+ prior, eq 29) in ``(q', q)`` order:
        the cost is ``[q'; q]ᵀ form [q'; q]`` plus the prior's constant."""
        K = self._K
        Q: FloatArray = K.T @ K
        Q[4:, 4:] += self._PtP
        return Q

    @property
    def S(self) -> FloatArray:
        return self.form[4:, 4:]

    @property
    def M(self) -> FloatArray:
        return self.form[:4, :4]

    @property
    def W(self) -> FloatArray:
        return self.form[4:, :4]

    def cost(self, q: FloatArray, qd: FloatArray) -> float:
        """Cost (8) plus the prior terms at the dual quaternion ``q + ε q'``, summed from residuals."""
        rot = self.P @ q
        dual = self.F @ q + self.E @ qd
        return float(rot @ rot + dual @ dual)

    @cached_property
    def _R(self) -> FloatArray:
        """The 8x8 R of the thin QR factorisation ``[E F] = Q R = Q [[Re, G], [0, Rf]]``.

        Then ``E = Q₁ Re`` and ``F = Q₁ G + Q₂ Rf`` (``Q = [Q₁ Q₂]``), so ``M = ReᵀRe``,
        ``W = GᵀRe`` and ``|F - Π_E F|² = RfᵀRf``: everything below is 4x4 algebra on R.
        """
        r: FloatArray
        r, _, _, info = lapack.dgeqrf(self._K)
        if info:
            raise np.linalg.LinAlgError(f"QR factorisation failed (info {info})")
        return r[:8] * _UPPER8

    @cached_property
    def _svd(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """SVD ``Re = U Σ Vᵀ`` (Σ: the singular values of E)."""
        u, s, vt, info = lapack.dgesdd(self.R_factor)
        if info:
            raise np.linalg.LinAlgError(f"SVD did not converge (info {info})")
        return u, s, vt

    @cached_property
    def _Rinv(self) -> FloatArray | None:
        """``Re⁻¹``, or None where Re is exactly singular."""
        Rinv, info = lapack.dtrtri(self.R_factor)
        return None if info else Rinv

    @cached_property
    def M_is_regular(self) -> bool:
        """Whether M = EᵀE is safely invertible (the paper's standing assumption below eq 10):
        the singular values of E satisfy ``σ_min > 1e-8 σ_max``.

        ``σ_max ≤ |Re|_F`` and ``1/σ_min = |Re⁻¹|₂ ≤ |Re⁻¹|_F``, so ``|Re|_F |Re⁻¹|_F < 1e8`` settles
        it without an SVD; only otherwise are the singular values computed.
        """
        Rinv = self._Rinv
        if Rinv is not None:
            Re = self.R_factor
            if np.vdot(Re, Re) * np.vdot(Rinv, Rinv) < 1e16:
                return True
        sv = self._svd[1]
        return bool(sv[-1] > _rank_tolerance(sv))

    @property
    def M_smallest_eigenvector(self) -> FloatArray:
        """The eigenvector of M with the smallest eigenvalue (eq 19), from the SVD of E."""
        v: FloatArray = self._svd[2][-1].copy()
        return v

    @property
    def R_factor(self) -> FloatArray:
        """The R of the thin QR factorisation ``E = Qe Re`` (so ``M = ReᵀRe``)."""
        return self._R[:4, :4]

    @cached_property
    def _Zs(self) -> FloatArray:
        """``Z0, Z1, Z2`` stacked (3, 4, 4); see :attr:`Z`."""
        Rinv = self._Rinv
        if Rinv is None:
            raise np.linalg.LinAlgError("M is singular")
        R = self._R
        Zs = np.empty((3, 4, 4))
        Rf = R[4:, 4:]
        np.matmul(Rf.T, Rf, out=Zs[0])
        Zs[0] += self._PtP
        WMinv = R[:4, 4:].T @ Rinv.T
        np.add(WMinv, WMinv.T, out=Zs[1])
        np.matmul(Rinv, Rinv.T, out=Zs[2])
        return Zs

    @cached_property
    def Z(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``Z0 = S - W M⁻¹ Wᵀ``, ``Z1 = W M⁻¹ + M⁻¹ Wᵀ``, ``Z2 = M⁻¹`` (eq 13); needs a regular M.

        From ``[E F] = Q [[Re, G], [0, Rf]]`` (:attr:`_R`): ``Z2 = Re⁻¹ Re⁻ᵀ``, ``W M⁻¹ = Gᵀ Re⁻ᵀ`` and
        ``Z0 = PᵀP + RfᵀRf`` (the paper's ``AᵀA + α² BᵀCB``), which is PSD by construction and
        free of the cancellation in ``S - W M⁻¹ Wᵀ``.
        """
        Zs = self._Zs
        return Zs[0], Zs[1], Zs[2]

    @cached_property
    def Z0_relaxed(self) -> FloatArray:
        """Z0 also for a singular M: the Schur complement with the projector on E's column space.

        With ``E = Q₁ Re`` and ``Re = U Σ Vᵀ``, E's numerical column space is ``Q₁ U_k``, so
        ``F - Π_E F = Q₁ (G - U_k U_kᵀ G) + Q₂ Rf``.
        """
        if self.M_is_regular:
            return self.Z[0]
        U, sv, _ = self._svd
        U = U[:, sv > _rank_tolerance(sv)]
        R = self._R
        G, Rf = R[:4, 4:], R[4:, 4:]
        Gr = G - U @ (U.T @ G)
        Z0: FloatArray = self._PtP + Rf.T @ Rf + Gr.T @ Gr
        return Z0

    def _dual(self, q: FloatArray, basis: FloatArray, full_rank: bool = False
              ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """:meth:`dual_part` in a given orthonormal basis (4, 3) of ``q``'s complement, without μ:
        ``q'`` and, for μ, ``Re B``, ``G q`` and the coefficients ``y``.

        ``full_rank`` (M regular, so ``Re B`` has full column rank with ``cond ≤ cond(Re) < 1e8``)
        lets the least squares be solved by QR (``dgels``) instead of the rank-revealing SVD."""
        R = self._R
        gq = R[:4, 4:] @ q
        CB = R[:4, :4] @ basis
        info = 1
        if full_rank:
            _, y, info = lapack.dgels(CB, -gq)
        if info:
            y, _, _, info = lapack.dgelsd(CB, -gq, _LWORK, _IWORK, _EPS * max(len(self.E), 3))
            if info:
                raise np.linalg.LinAlgError(f"least squares did not converge (info {info})")
        y = y[:3]
        return basis @ y, CB, gq, y

    def dual_part(self, q: FloatArray) -> tuple[FloatArray, float]:
        """The optimal ``q'`` for a given unit ``q`` under ``q·q' = 0``, and its multiplier μ.

        Solves ``min |F q + E q'|²`` over ``q' = B y ⊥ q`` by least squares, with the orthonormal
        basis ``B`` of ``q``'s complement formed by the first three columns of ``L(q)`` (orthogonal,
        with ``L(q) e_w = q``). With ``[E F] = Q [[Re, G], [0, Rf]]`` (:attr:`_R`) that is the 4x3
        problem ``min |Re B y + G q|`` (the rows ``Rf q`` do not depend on y), the same as the
        (L x 3) one on E and F.
        With a regular M this is exactly eq 20, ``q' = M⁻¹ (μ - Wᵀ) q`` with μ from eq 14, but it
        needs no inverse of M and stays defined when M is singular along ``q`` (noise-free data).
        Where the translation is truly unobservable the least-norm ``q'`` is returned.
        """
        q = np.asarray(q, dtype=np.float64)
        qd, CB, gq, y = self._dual(q, (q[_L_INDEX] * _L_SIGN)[:, :3])
        # M q' + Wᵀ q = μ q (eq 10), with M = ReᵀRe and Wᵀ = ReᵀG: μ = (Re q)·(Re q' + G q)
        return qd, float((self.R_factor @ q) @ (CB @ y + gq))


def eigh(A: FloatArray, vectors: bool = True) -> tuple[FloatArray, FloatArray]:
    """Eigenvalues (ascending) and eigenvectors (columns) of a small symmetric matrix: LAPACK
    ``dsyev`` called directly, without the per-call overhead of ``np.linalg.eigh`` (several times
    the work at 4x4). With ``vectors=False`` the second item is meaningless."""
    lam, V, info = lapack.dsyev(A, compute_v=int(vectors))
    if info:
        raise np.linalg.LinAlgError(f"eigenvalue computation did not converge (info {info})")
    return lam, V


def _rank_tolerance(sv: FloatArray) -> float:
    """Singular values of E below this count as zero (M singular)."""
    return 1e-8 * max(float(sv[0]), 1e-300)


def _all_rigid(T: FloatArray) -> bool:
    """Whether every transform of a (N, 4, 4) stack is finite with a rotation block (both sensors at once)."""
    return bool(np.isfinite(T).all() and se3.is_rotation(T[:, :3, :3], 1e-6).all())


def _raise_first_bad(A: FloatArray, B: FloatArray) -> None:
    """Raise the error for the first bad motion array: wrong shape, non-finite, or not a rotation."""
    for name, T in (("motions_a", A), ("motions_b", B)):
        if T.ndim != 3 or T.shape[1:] != (4, 4):
            raise DataError(f"{name} has shape {T.shape}", name, "pass an array of shape (N, 4, 4)")
        if not np.isfinite(T).all():
            bad = int(np.flatnonzero(~np.isfinite(T).all(axis=(1, 2)))[0])
            raise DataError(f"{name}[{bad}] contains NaN or inf", name, "remove or repair that motion")
        ok = se3.is_rotation(T[:, :3, :3], 1e-6)
        if not ok.all():
            bad = int(np.flatnonzero(~ok)[0])
            raise DataError(f"{name}[{bad}] has a rotation block that is not a rotation", name,
                               "pass rigid transforms (orthonormal rotation, det +1)")


def validate_motions(motions_a: FloatArray, motions_b: FloatArray,
                     weights: FloatArray | None = None) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Check shapes, finiteness and rotation blocks; return float arrays (N,4,4), (N,4,4), (N,)."""
    A = np.asarray(motions_a, dtype=np.float64)
    B = np.asarray(motions_b, dtype=np.float64)
    shapes_ok = A.ndim == B.ndim == 3 and A.shape[1:] == B.shape[1:] == (4, 4)
    if not (shapes_ok and _all_rigid(np.concatenate((A, B)))):
        _raise_first_bad(A, B)
    if len(A) != len(B):
        raise DataError(f"motions_a has {len(A)} motions, motions_b {len(B)}", "motions",
                           "pass the same number of motions for both sensors")
    if len(A) < 2:
        raise DataError(f"{len(A)} motion pair(s)", "motions", "at least 2 motion pairs are needed")
    if weights is None:
        w = np.ones(len(A))
    else:
        w = np.asarray(weights, dtype=np.float64).reshape(-1)
        if w.shape != (len(A),) or not np.isfinite(w).all() or (w < 0).any() or not (w > 0).any():
            raise DataError(f"weights must be {len(A)} finite non-negative numbers, not all zero",
                               "weights", "pass one weight per motion pair")
    return A, B, w


def pair_blocks(motions_a: FloatArray, motions_b: FloatArray, alpha: float = 1.0) -> tuple[FloatArray, FloatArray]:
    """The per-pair blocks ``E_i = L(q_C) - R(q_H)`` and ``F_i = L(q'_C) - R(q'_H)`` (eqs 6–7), (N,4,4) each;
    the sign of ``Q_H`` agrees with ``Q_C``'s dual scalar part weighed by α [1/m]
    (:func:`~handeye_cli.solvers.dualquat.pair_difference_blocks`)."""
    return dq.pair_difference_blocks(motions_a, motions_b, alpha)


def build_problem(motions_a: FloatArray, motions_b: FloatArray, alpha: float = 1.0,
                  prior: Prior | None = None, weights: FloatArray | None = None) -> Problem:
    """Stack the residual rows of cost (8) (weighted) and of the prior (eqs 26–27).

    ``alpha`` [1/m] weighs the translational residuals against the rotational ones.
    """
    A, B, w = validate_motions(motions_a, motions_b, weights)
    return problem_from_blocks(*pair_blocks(A, B, alpha), w, alpha=alpha, prior=prior)


def problem_from_blocks(E: FloatArray, F: FloatArray, w: FloatArray, alpha: float = 1.0,
                        prior: Prior | None = None) -> Problem:
    """:func:`build_problem` from the per-pair blocks of :func:`pair_blocks` and validated weights."""
    if not (np.isfinite(alpha) and alpha > 0):
        raise ConfigError(f"alpha must be a positive number, got {alpha}", "alpha",
                           "pass e.g. alpha=1.0 (units 1/m)")
    sw = np.sqrt(w)[:, None, None]
    P = (E * sw).reshape(-1, 4)
    Fd = (alpha * F * sw).reshape(-1, 4)
    Ed = alpha * P
    if prior is not None:
        if not (prior.a >= 0 and prior.b >= 0):
            raise ConfigError("prior weights must be non-negative", "prior", "pass a, b ≥ 0")
        qp, qpd = dq.from_transforms(np.asarray(prior.T_a_b, dtype=np.float64))
        Lc = dq.left(dq.conjugate(qp))                       # δq = L(q̂*) q            (eq 27)
        Lcd = dq.left(dq.conjugate(qpd))                     # δq' = L(q̂'*) q + L(q̂*) q'
        P = np.vstack([P, np.sqrt(prior.a) * (_G @ Lc)])
        Fd = np.vstack([Fd, np.sqrt(prior.b) * Lcd])
        Ed = np.vstack([Ed, np.sqrt(prior.b) * Lc])
    return Problem(P, Fd, Ed)
