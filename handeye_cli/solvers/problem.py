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

The residual rows of all pairs are never held: the motions are read in chunks, each checked
(finite, rigid) and reduced at once to the 8x8 R factor of its rows ``√w_i [E_i F_i]``; the
chunks' factors, stacked, are factorised again (TSQR), which gives the R factor of all rows to
rounding. Quaternions are x-y-z-w (see :mod:`.dualquat`).

The linear algebra is numpy's (``numpy.linalg``, LAPACK underneath), not scipy's: importing ``scipy.linalg``
costs a process 0.27 s of start-up on top of numpy's 0.1 s, which every ``handeye calibrate`` would pay.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import ConfigError, DataError
from ..geometry import dualquat as dq
from ..geometry import se3
from ..geometry.dualquat import _L_INDEX, _L_SIGN

__all__ = ["Prior", "Problem", "build_problem", "checked_arrays", "motion_problem", "pair_blocks",
           "pair_forms", "problem_from_blocks", "split_forms", "validate_motions"]

_G = np.diag([1.0, 1.0, 1.0, 0.0])
_UPPER8 = np.triu(np.ones((8, 8)))
_EPS = np.finfo(float).eps
_NO_VECTORS = np.empty((0, 0))
_NO_VECTORS.flags.writeable = False
_ROTATION_TOL = 1e-6        # a motion's rotation block: |RᵀR - I| and |det R - 1| at most this
CHUNK = 4096
"""Motion pairs read, checked and converted at once (their rows of scratch fit a cache of a few MB)."""
# Pairs factorised per QR (one LAPACK dgeqrf each, however many one numpy call stacks): their 1024 x 8 rows
# stay below the size from which OpenBLAS runs its level-2 BLAS on several threads; on a busy 2-core machine
# a call that waits for a second thread was measured 100 times slower.
_QR_PAIRS = 256
_QR_ROWS = 4 * _QR_PAIRS
# Blocks factorised by one numpy call: a chunk's (1 MB, which numpy copies). With 4 per call a 10^6-motion solve
# took ~5 % longer (each call costs ~20 µs of its own); with 16, a fresh process's first solve of ~10^4 motions
# faults in ~470 more pages than the in-place LAPACK calls did (1-4 ms), where 4 per call faulted ~30.
_QR_STACK = CHUNK // _QR_PAIRS


@dataclass(frozen=True)
class Prior:
    """A prior extrinsic ``T_a_b`` and the weights of its rotation (``a``) and translation (``b``) terms (eq 26)."""

    T_a_b: FloatArray
    a: float = 1.0
    b: float = 1.0


def _triangular_factors(J: FloatArray, out: FloatArray | None = None) -> FloatArray:
    """The 8x8 R factors of the thin QR factorisations of the matrices ``J`` (..., n, 8), (..., 8, 8) (zero rows
    below the n-th when n < 8), written into ``out`` if given.

    One call of numpy's QR, a gufunc that runs LAPACK's dgeqrf on each matrix; R is the upper triangle of what
    dgeqrf leaves (``mode="raw"`` returns it transposed, beside the Householder vectors), so R's rows have
    dgeqrf's signs. ``J`` is left as it is: numpy copies it, and each matrix into LAPACK's layout and back,
    three passes over the rows that an in-place dgeqrf does not make (~5 % of a 10⁶-motion solve)."""
    h = np.linalg.qr(J, mode="raw")[0]
    R = np.empty(J.shape[:-2] + (8, 8)) if out is None else out
    k = min(J.shape[-2], 8)
    np.multiply(h.swapaxes(-1, -2)[..., :k, :], _UPPER8[:k], out=R[..., :k, :])
    if k < 8:
        R[..., k:, :] = 0.0
    return R


def _stacked_factors(J: FloatArray, out: FloatArray) -> FloatArray:
    """The 8x8 R factors of the matrices ``J`` (k, n, 8) written into ``out`` (k, 8, 8), by numpy calls of
    ``_QR_STACK`` matrices each (:func:`_triangular_factors`)."""
    for s in range(0, len(J), _QR_STACK):
        _triangular_factors(J[s:s + _QR_STACK], out[s:s + _QR_STACK])
    return out


def _tree_factor(J: FloatArray) -> FloatArray:
    """The 8x8 R factor of ``J`` (n, 8) by a tree (TSQR): blocks of at most ``_QR_ROWS`` rows are factorised
    and their R factors stacked, and again, until one is left."""
    while True:
        full = len(J) // _QR_ROWS                                   # full blocks, then one shorter
        R = np.empty((-(-len(J) // _QR_ROWS), 8, 8))
        _stacked_factors(J[:full * _QR_ROWS].reshape(full, _QR_ROWS, 8), R[:full])
        if len(R) > full:
            _triangular_factors(J[full * _QR_ROWS:], R[full])
        J = R.reshape(-1, 8)
        if len(J) == 8:
            return J


@dataclass(frozen=True, eq=False)
class Problem:
    """Cost (8) (+ prior) as the R factor of its stacked residual rows, ``|P q|² + |F q + E q'|²``.

    ``P`` holds the rotational residual rows (``√w_i E_i``, and ``√a G L(q̂*)`` for a prior);
    ``F``, ``E`` the dual ones (``α√w_i F_i``, ``α√w_i E_i``, and ``√b L(q̂'*)``, ``√b L(q̂*)``).
    ``R`` (8, 8) is the upper-triangular factor of the thin QR factorisation of the rows
    ``[[0, P], [E, F]]`` acting on ``[q'; q]``, and the cost is ``|R [q'; q]|²``: the prior's constant
    is included, so :meth:`cost` is the true value. In blocks ``R = [[Re, G], [0, Rz]]``: ``Re`` is the R
    factor of ``E`` (``M = ReᵀRe``), ``W = GᵀRe``, and ``RzᵀRz = PᵀP + |F - Π_E F|²`` is Z0, so Z0 is
    formed without the cancellation in ``S - W M⁻¹ Wᵀ``. ``rows`` is the number of dual residual rows
    (4 per pair, 4 for a prior); it sets the rank tolerance of the least squares in :meth:`dual_part`.
    """

    R: FloatArray
    rows: int

    @classmethod
    def from_rows(cls, J: FloatArray, rows: int | None = None) -> Problem:
        """The problem whose cost is ``|J [q'; q]|²`` for residual rows ``J`` (n, 8) in ``(q', q)`` order;
        ``rows`` defaults to n."""
        J = np.asarray(J, dtype=np.float64)
        return cls(_triangular_factors(J), len(J) if rows is None else rows)

    @cached_property
    def form(self) -> FloatArray:
        """The 8x8 matrix ``[[M, Wᵀ], [W, S]]`` of cost (8) (+ prior, eq 29) in ``(q', q)`` order:
        the cost is ``[q'; q]ᵀ form [q'; q]``, the prior's constant included."""
        Q: FloatArray = self.R.T @ self.R
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
        """Cost (8) plus the prior terms at the dual quaternion ``q + ε q'``: ``|R [q'; q]|²``."""
        r = self.R[:, :4] @ qd + self.R[:, 4:] @ q
        return float(r @ r)

    @cached_property
    def _svd(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """SVD ``Re = U Σ Vᵀ`` (Σ: the singular values of E, descending), by numpy (LAPACK's dgesdd)."""
        u, s, vt = np.linalg.svd(self.R_factor)
        return u, s, vt

    @cached_property
    def _Rinv(self) -> FloatArray | None:
        """``Re⁻¹``, or None where Re is exactly singular (a zero on its diagonal).

        Solved against the identity by numpy (LAPACK's dgesv): the LU factorisation with partial pivoting of
        the upper-triangular Re is Re itself, with no row exchanged and no rounding (nothing below the
        diagonal to eliminate), so this is the back substitution of a triangular inverse."""
        try:
            return np.asarray(np.linalg.inv(self.R_factor), dtype=np.float64)
        except np.linalg.LinAlgError:
            return None

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
        """``Re``, the R of the thin QR factorisation ``E = Qe Re`` (so ``M = ReᵀRe``)."""
        return self.R[:4, :4]

    @cached_property
    def _Zs(self) -> FloatArray:
        """``Z0, Z1, Z2`` stacked (3, 4, 4); see :attr:`Z`."""
        Rinv = self._Rinv
        if Rinv is None:
            raise np.linalg.LinAlgError("M is singular")
        R = self.R
        Zs = np.empty((3, 4, 4))
        Rz = R[4:, 4:]
        np.matmul(Rz.T, Rz, out=Zs[0])
        WMinv = R[:4, 4:].T @ Rinv.T
        np.add(WMinv, WMinv.T, out=Zs[1])
        np.matmul(Rinv, Rinv.T, out=Zs[2])
        return Zs

    @cached_property
    def Z(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``Z0 = S - W M⁻¹ Wᵀ``, ``Z1 = W M⁻¹ + M⁻¹ Wᵀ``, ``Z2 = M⁻¹`` (eq 13); needs a regular M.

        From ``R = [[Re, G], [0, Rz]]`` (:attr:`R`): ``Z2 = Re⁻¹ Re⁻ᵀ``, ``W M⁻¹ = Gᵀ Re⁻ᵀ`` and
        ``Z0 = RzᵀRz`` (the paper's ``AᵀA + α² BᵀCB``), which is PSD by construction and
        free of the cancellation in ``S - W M⁻¹ Wᵀ``.
        """
        Zs = self._Zs
        return Zs[0], Zs[1], Zs[2]

    @cached_property
    def Z0_relaxed(self) -> FloatArray:
        """Z0 also for a singular M: the Schur complement with the projector on E's column space.

        With ``E = Q₁ Re`` and ``Re = U Σ Vᵀ``, E's numerical column space is ``Q₁ U_k``, so the rows
        ``[G; Rz]`` of q lose ``U_k U_kᵀ G``.
        """
        if self.M_is_regular:
            return self.Z[0]
        U, sv, _ = self._svd
        U = U[:, sv > _rank_tolerance(sv)]
        R = self.R
        G, Rz = R[:4, 4:], R[4:, 4:]
        Gr = G - U @ (U.T @ G)
        Z0: FloatArray = Rz.T @ Rz + Gr.T @ Gr
        return Z0

    def _dual(self, q: FloatArray, basis: FloatArray, full_rank: bool = False
              ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """:meth:`dual_part` in a given orthonormal basis (4, 3) of ``q``'s complement, without μ:
        ``q'`` and, for μ, ``Re B``, ``G q`` and the coefficients ``y``.

        The least squares is numpy's (LAPACK's dgelsd, by the SVD): singular values of ``Re B`` below
        ``eps · max(rows, 3)`` times the largest count as zero, which gives the least-norm ``y`` where the
        translation is unobservable. ``full_rank`` (M regular, so ``Re B`` has full column rank with
        ``cond ≤ cond(Re) < 1e8``) drops that tolerance, which with ~10⁷ pairs would reach 1e-8: the
        full-rank solution is taken, as a QR solve would."""
        R = self.R
        gq = R[:4, 4:] @ q
        CB = R[:4, :4] @ basis
        y = np.asarray(np.linalg.lstsq(CB, -gq, rcond=0.0 if full_rank else _EPS * max(self.rows, 3))[0],
                       dtype=np.float64)
        return basis @ y, CB, gq, y

    def dual_part(self, q: FloatArray) -> tuple[FloatArray, float]:
        """The optimal ``q'`` for a given unit ``q`` under ``q·q' = 0``, and its multiplier μ.

        Solves ``min |F q + E q'|²`` over ``q' = B y ⊥ q`` by least squares, with the orthonormal
        basis ``B`` of ``q``'s complement formed by the first three columns of ``L(q)`` (orthogonal,
        with ``L(q) e_w = q``). With ``R = [[Re, G], [0, Rz]]`` (:attr:`R`) that is the 4x3
        problem ``min |Re B y + G q|`` (the rows ``Rz q`` do not depend on y), the same as the
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
    """Eigenvalues (ascending) and eigenvectors (columns) of a small symmetric matrix, from its upper
    triangle: numpy's ``eigh`` (LAPACK's dsyevd, which up to 25 rows runs the implicit QL/QR iteration of
    dsyev, dsteqr), or ``eigvalsh`` with ``vectors=False``, when the second item is empty."""
    if not vectors:
        return np.asarray(np.linalg.eigvalsh(A, UPLO="U"), dtype=np.float64), _NO_VECTORS
    lam, V = np.linalg.eigh(A, UPLO="U")
    return np.asarray(lam, dtype=np.float64), np.asarray(V, dtype=np.float64)


def _rank_tolerance(sv: FloatArray) -> float:
    """Singular values of E below this count as zero (M singular)."""
    return 1e-8 * max(float(sv[0]), 1e-300)


def _raise_first_bad(A: FloatArray, B: FloatArray) -> None:
    """Raise the error for the first bad motion array: wrong shape, non-finite, or not a rotation."""
    for name, T in (("motions_a", A), ("motions_b", B)):
        if T.ndim != 3 or T.shape[1:] != (4, 4):
            raise DataError(f"{name} has shape {T.shape}", name, "pass an array of shape (N, 4, 4)")
        if not np.isfinite(T).all():
            bad = int(np.flatnonzero(~np.isfinite(T).all(axis=(1, 2)))[0])
            raise DataError(f"{name}[{bad}] contains NaN or inf", name, "remove or repair that motion")
        ok = se3.is_rotation(T[:, :3, :3], _ROTATION_TOL)
        if not ok.all():
            bad = int(np.flatnonzero(~ok)[0])
            raise DataError(f"{name}[{bad}] has a rotation block that is not a rotation", name,
                               "pass rigid transforms (orthonormal rotation, det +1)")


def checked_arrays(motions_a: FloatArray, motions_b: FloatArray,
                   weights: FloatArray | None = None) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Check shapes, counts and weights, not the motions themselves (:func:`motion_problem` and
    :func:`validate_motions` check those in the one pass that reads them); return float arrays
    (N,4,4), (N,4,4), (N,).

    Where a check fails, a bad motion is still reported first, as :func:`validate_motions` does."""
    A = np.asarray(motions_a, dtype=np.float64)
    B = np.asarray(motions_b, dtype=np.float64)
    if not (A.ndim == B.ndim == 3 and A.shape[1:] == B.shape[1:] == (4, 4)):
        _raise_first_bad(A, B)
    if len(A) != len(B):
        _raise_first_bad(A, B)
        raise DataError(f"motions_a has {len(A)} motions, motions_b {len(B)}", "motions",
                           "pass the same number of motions for both sensors")
    if len(A) < 2:
        _raise_first_bad(A, B)
        raise DataError(f"{len(A)} motion pair(s)", "motions", "at least 2 motion pairs are needed")
    if weights is None:
        return A, B, np.ones(len(A))
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    if w.shape != (len(A),) or not np.isfinite(w).all() or (w < 0).any() or not (w > 0).any():
        _raise_first_bad(A, B)
        raise DataError(f"weights must be {len(A)} finite non-negative numbers, not all zero",
                           "weights", "pass one weight per motion pair")
    return A, B, w


def _checked_chunks(A: FloatArray, B: FloatArray, chunk: int, block: int = 1,
                    work: FloatArray | None = None) -> Iterator[tuple[int, int, FloatArray]]:
    """The motions in chunks of ``chunk`` pairs, each checked as it is read: ``(start, stop, X)`` with
    ``X`` (12, 2p) batch-last (``X[4i + j]`` holds ``T_ij``; reused between chunks): the transforms of
    ``A[start:stop]``, identities up to p (``stop - start`` rounded up to a multiple of ``block``), then
    those of ``B[start:stop]`` and identities again. A chunk with a non-finite entry or a rotation block
    off by more than 1e-6 (:func:`~handeye_cli.geometry.se3.rotation_residuals`, as ``se3.is_rotation``) raises
    the error for the first bad motion of all (:func:`_raise_first_bad`). ``work`` (16, 2p) is
    scratch; with it nothing is allocated per chunk."""
    n = len(A)
    Af, Bf = A.reshape(n, 16), B.reshape(n, 16)
    buffer = np.empty((12, 2 * -(-min(chunk, n) // block) * block))
    work = np.empty((16, buffer.shape[1])) if work is None else work
    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        m = stop - start
        p = -(-m // block) * block
        a, b = Af[start:stop], Bf[start:stop]
        X = buffer[:, :2 * p]
        np.copyto(X[:, :m], a[:, :12].T)
        np.copyto(X[:, p:p + m], b[:, :12].T)
        if p > m:
            for pad in (X[:, m:p], X[:, p + m:]):
                pad[...] = 0.0
                pad[0:11:5] = 1.0
        residuals = se3.rotation_residuals(X.reshape(3, 4, 2 * p)[:, :3], work[:, :2 * p])
        np.abs(residuals, out=residuals)
        # a sum is finite only if every term is (a false alarm from overflow is cleared by the full check)
        if not (np.isfinite(a.sum() + b.sum()) and residuals.max() <= _ROTATION_TOL):
            _raise_first_bad(A, B)
        yield start, stop, X


def validate_motions(motions_a: FloatArray, motions_b: FloatArray,
                     weights: FloatArray | None = None) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Check shapes, finiteness and rotation blocks, in one pass of :data:`CHUNK` pairs at a time (the
    arrays are not copied); return float arrays (N,4,4), (N,4,4), (N,)."""
    A, B, w = checked_arrays(motions_a, motions_b, weights)
    for _ in _checked_chunks(A, B, CHUNK):
        pass
    return A, B, w


def pair_blocks(motions_a: FloatArray, motions_b: FloatArray, alpha: float = 1.0,
                reference: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
    """The per-pair blocks ``E_i = L(q_C) - R(q_H)`` and ``F_i = L(q'_C) - R(q'_H)`` (eqs 6–7), (N,4,4) each;
    the sign of ``Q_H`` agrees with ``Q_C``'s dual scalar part weighed by α [1/m], or is the one that costs
    less at ``reference``, an estimate of X (4, 4): :func:`~handeye_cli.geometry.dualquat.sign_flips`."""
    return dq.pair_difference_blocks(motions_a, motions_b, alpha, reference)


def pair_forms(A: FloatArray, B: FloatArray, alpha: float, reference: FloatArray | None = None) -> FloatArray:
    """Each motion pair's rotational and dual 8x8 cost matrix (``[q'; q]`` order) of ``A_i X = X B_i``
    (N, 4, 4): (N, 2, 8, 8), the dual part scaled by α²; signs as :func:`pair_blocks` agrees them."""
    E, F = pair_blocks(A, B, alpha, reference)
    rot = np.zeros((len(E), 8, 8))
    rot[:, 4:, 4:] = np.einsum("nki,nkj->nij", E, E)
    EF = np.concatenate((E, F), axis=2)                       # rows E q' + F q on [q'; q]
    return np.stack((rot, alpha ** 2 * np.einsum("nki,nkj->nij", EF, EF)), axis=1)


def split_forms(A: FloatArray, B: FloatArray, counts: FloatArray, alpha: float) -> FloatArray:
    """The rotational and dual 8x8 cost matrices (``[q'; q]`` order) of motion pairs ``A_i X = X B_i``
    (N, 4, 4) weighted by each row of ``counts`` (R, N): (R, 2, 8, 8), the dual part scaled by α²."""
    grams = pair_forms(A, B, alpha).reshape(len(A), -1)
    return np.asarray((np.asarray(counts, dtype=float) @ grams).reshape(-1, 2, 8, 8), dtype=np.float64)


def _motion_factor(A: FloatArray, B: FloatArray, w: FloatArray, alpha: float, chunk: int,
                   reference: FloatArray | None = None) -> FloatArray:
    """The 8x8 R factor of the rows ``√w_i [E_i F_i]`` of all pairs (signs agreed at α [1/m] or by ``reference``:
    see :func:`~handeye_cli.geometry.dualquat.sign_flips`), in one checked pass (TSQR).

    Per chunk, the pairs' dual quaternions give the blocks by one product
    (:func:`~handeye_cli.geometry.dualquat.difference_blocks`), laid out as the columns of Fortran-ordered
    (4b, 8) matrices of b pairs each (rows in any order: R does not depend on it; the identity pairs
    that pad the last matrix give zero rows), factorised a few per QR call; their R factors,
    stacked, are factorised again (:func:`_tree_factor`), unless there is only one."""
    sw = None if (w == 1.0).all() else np.sqrt(w)
    size = min(chunk, len(A))
    block = min(_QR_PAIRS, size)
    blocks = -(-size // block)                                      # QR blocks per chunk
    factors = np.empty((8 * blocks * -(-len(A) // chunk), 8))
    work, both = np.empty((16, 2 * blocks * block)), np.empty((2, 4, 2 * blocks * block))
    pairs, columns = np.empty((blocks, 2, 8, block)), np.empty((blocks, 2, 16, block))
    k = 0
    for start, stop, X in _checked_chunks(A, B, chunk, block, work):
        m, p = stop - start, X.shape[1] // 2
        qq = dq.align_signs(dq._from_rows(X, both[:, :, :2 * p], work[:, :2 * p]), alpha, reference)   # a, then b
        if sw is not None:
            qq[:, :, :m] *= sw[start:stop]
            qq[:, :, p:p + m] *= sw[start:stop]
        nb = p // block
        for s, half in ((0, slice(0, 4)), (p, slice(4, 8))):        # per QR block and part: [q_a; q_b]
            pairs[:nb, :, half] = qq[:, :, s:s + p].reshape(2, 4, nb, block).transpose(2, 0, 1, 3)
        dq.difference_blocks(pairs[:nb], columns[:nb])              # (nb, 2, 16, b): the columns of [E F]
        _stacked_factors(columns[:nb].reshape(nb, 8, 4 * block).swapaxes(1, 2), factors[k:k + 8 * nb].reshape(nb, 8, 8))
        k += 8 * nb
    # one block's R is already triangular (a QR of it would change nothing: its reflections are identities)
    return factors[:8] if k == 8 else _tree_factor(factors[:k])


def _reduced_problem(Rm: FloatArray, pairs: int, alpha: float, prior: Prior | None) -> Problem:
    """The problem of ``pairs`` pairs from the R factor ``Rm`` of their rows ``√w_i [E_i F_i]``, after the
    checks of α and the prior, with the prior's rows (eqs 26–27) added."""
    if not (np.isfinite(alpha) and alpha > 0):
        raise ConfigError(f"alpha must be a positive number, got {alpha}", "alpha",
                           "pass e.g. alpha=1.0 (units 1/m)")
    # [[0, P], [E, F]] with P = √w E_i and [E F] = α √w [E_i F_i] = Q α Rm: the same R as
    # [[0, Re], [α Re, α G], [0, α Rf]] for Rm = [[Re, G], [0, Rf]]
    J = np.zeros((12, 8))
    J[:4, 4:] = Rm[:4, :4]
    J[4:, :] = alpha * Rm
    rows = 4 * pairs
    if prior is not None:
        if not (prior.a >= 0 and prior.b >= 0):
            raise ConfigError("prior weights must be non-negative", "prior", "pass a, b ≥ 0")
        qp, qpd = dq.from_transforms(np.asarray(prior.T_a_b, dtype=np.float64))
        Lc = dq.left(dq.conjugate(qp))                       # δq = L(q̂*) q            (eq 27)
        Lcd = dq.left(dq.conjugate(qpd))                     # δq' = L(q̂'*) q + L(q̂*) q'
        J = np.vstack([J, np.hstack([np.zeros((4, 4)), np.sqrt(prior.a) * (_G @ Lc)]),
                       np.sqrt(prior.b) * np.hstack([Lc, Lcd])])
        rows += 4
    return Problem.from_rows(J, rows)


def motion_problem(A: FloatArray, B: FloatArray, w: FloatArray, alpha: float = 1.0,
                   prior: Prior | None = None, chunk: int = CHUNK, reference: FloatArray | None = None) -> Problem:
    """:func:`build_problem` from the arrays of :func:`checked_arrays`: reads, checks and reduces the
    motions in one pass of ``chunk`` pairs at a time; each pair's signs agreed at α or by ``reference`` (an
    estimate of X, 4×4: :func:`~handeye_cli.geometry.dualquat.sign_flips`)."""
    return _reduced_problem(_motion_factor(A, B, w, alpha, chunk, reference), len(A), alpha, prior)


def near_half_turns(A: FloatArray, B: FloatArray) -> IntArray:
    """Indices of the motion pairs (N, 4, 4) whose relative sign the invariants may tell wrong: either rotation
    within :data:`~handeye_cli.geometry.dualquat.HALF_TURN_W` of a half-turn, found from the traces
    (``w² = (1 + tr R) / 4``)."""
    limit = 4.0 * dq.HALF_TURN_W ** 2 - 1.0                 # tr R below this: w below HALF_TURN_W
    near: IntArray = np.flatnonzero((np.trace(A[:, :3, :3], axis1=1, axis2=2) < limit)
                                             | (np.trace(B[:, :3, :3], axis1=1, axis2=2) < limit))
    return near


def disagreeing_signs(A: FloatArray, B: FloatArray, alpha: float, reference: FloatArray,
                      before: FloatArray | None = None) -> bool:
    """Whether some pair's signs, agreed at α [1/m] (or by the earlier estimate ``before``), are not those
    that cost less at the estimate ``reference`` of X (4×4; checked motions (N, 4, 4), those of
    :func:`near_half_turns`: no other pair can disagree): then that pair costs as much as a half-turn's error
    at the estimate, and the problem is built again with ``reference``'s signs (:func:`~handeye_cli.solvers.solve`)."""
    both = dq.pair_quaternions(A, B)
    return bool((dq.sign_flips(both, alpha, before) != dq.sign_flips(both, alpha, reference)).any())


def problem_from_blocks(E: FloatArray, F: FloatArray, w: FloatArray, alpha: float = 1.0,
                        prior: Prior | None = None) -> Problem:
    """:func:`build_problem` from the per-pair blocks of :func:`pair_blocks` (N, 4, 4) of checked motions
    and their weights, for a caller that needs the blocks anyway (Daniilidis' method): the rows
    ``√w_i [E_i F_i]`` are stacked whole (4N x 8) and factorised by :func:`_tree_factor`."""
    K = (np.sqrt(w)[:, None, None] * np.concatenate((E, F), axis=2)).reshape(-1, 8)
    return _reduced_problem(_tree_factor(K), len(E), alpha, prior)


def build_problem(motions_a: FloatArray, motions_b: FloatArray, alpha: float = 1.0,
                  prior: Prior | None = None, weights: FloatArray | None = None, chunk: int = CHUNK) -> Problem:
    """Stack the residual rows of cost (8) (weighted) and of the prior (eqs 26–27), as their R factor.

    ``alpha`` [1/m] weighs the translational residuals against the rotational ones; ``chunk``: the
    motions read at once (the result does not depend on it beyond rounding).
    """
    A, B, w = checked_arrays(motions_a, motions_b, weights)
    return motion_problem(A, B, w, alpha=alpha, prior=prior, chunk=chunk)
