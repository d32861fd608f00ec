"""``solvers/problem.py``'s linear algebra, numpy's, against scipy.linalg (its former LAPACK calls and
their drivers) as the reference: the R factor of problem matrices (TSQR and one QR), the triangular
inverse, the SVD of E's factor, the least squares of the dual part (full rank, and rank-deficient
through the rank tolerance), and the symmetric eigensolver, on random and near-degenerate inputs.

R is compared through RᵀR (the rows of R are unique only up to sign) with each entry held to 1e-12 of
``|J e_i| |J e_j|``, its natural scale; where the problem is well conditioned, R itself up to row signs."""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.linalg import lapack

from handeye_cli.geometry import dualquat
from handeye_cli.simulation import motion_pairs, random_transform
from handeye_cli.solvers import problem as P
from handeye_cli.solvers.problem import Problem, build_problem, eigh, pair_blocks, problem_from_blocks

EPS = np.finfo(float).eps
SIGMA_R, SIGMA_T = np.deg2rad(0.57), 0.01


def _scipy_R(J: np.ndarray) -> np.ndarray:
    """The 8x8 R factor of all rows ``J`` at once by scipy (zero rows below the n-th when n < 8)."""
    R = np.zeros((8, 8))
    r = sla.qr(J, mode="r")[0]
    R[:len(r)] = r[:8]
    return R


def _assert_same_gram(R: np.ndarray, R_ref: np.ndarray, rtol: float = 1e-12) -> None:
    """``RᵀR = R_refᵀR_ref``, entry (i, j) to ``rtol |R_ref e_i| |R_ref e_j|``."""
    assert np.array_equal(R, np.triu(R)), "R is not upper triangular"
    G, G_ref = R.T @ R, R_ref.T @ R_ref
    d = np.sqrt(np.diag(G_ref))
    excess = np.abs(G - G_ref) - rtol * np.outer(d, d)
    assert excess.max() <= 0.0, f"RᵀR off by up to {np.abs(G - G_ref).max():.3g} (|R|² {d.max() ** 2:.3g})"


def _assert_same_up_to_signs(X: np.ndarray, X_ref: np.ndarray, axis: int, atol: float) -> None:
    """``X`` equals ``X_ref`` up to the sign of each row (axis 0) or column (axis 1)."""
    X, X_ref = np.moveaxis(X, axis, 0), np.moveaxis(X_ref, axis, 0)
    signs = np.where(np.einsum("ij,ij->i", X, X_ref) < 0, -1.0, 1.0)
    np.testing.assert_allclose(signs[:, None] * X, X_ref, rtol=0, atol=atol)


def _pair_rows(A: np.ndarray, B: np.ndarray, w: np.ndarray, alpha: float) -> np.ndarray:
    """The rows ``√w_i [E_i F_i]`` (4N, 8) of all pairs, signs agreed at α, as :func:`P._motion_factor` reduces them."""
    E, F = pair_blocks(A, B, alpha)
    return (np.sqrt(w)[:, None, None] * np.concatenate((E, F), axis=2)).reshape(-1, 8)


def _motions(n: int, seed: int, noise: float = 1.0, scenario: str = "random") -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return motion_pairs(n, random_transform(rng), rng, scenario, SIGMA_R * noise, SIGMA_T * noise)


def _random_rows(kind: str, n: int, seed: int) -> np.ndarray:
    """Rows (n, 8): Gaussian; columns scaled over 12 decades; rank 5 (the rest rounding); one exact zero column."""
    rng = np.random.default_rng(seed)
    J = rng.standard_normal((n, 8))
    if kind == "graded":
        J *= np.logspace(-6, 6, 8)
    elif kind == "rank5":
        J = rng.standard_normal((n, 5)) @ rng.standard_normal((5, 8))
    elif kind == "zero column":
        J[:, 3] = 0.0
    return J


# R factor ----------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["gaussian", "graded", "rank5", "zero column"])
@pytest.mark.parametrize("n", [3, 8, 12, 1023, 1024, 1025, 4 * 1024 + 8, 20 * 1024 + 100])
def test_tree_factor_equals_one_qr_of_all_rows(kind: str, n: int) -> None:
    """TSQR over 1024-row blocks (16 to a numpy call, a short last block; short matrices padded with zero rows)
    gives the R factor of all rows that scipy's one QR gives."""
    J = _random_rows(kind, n, seed=n)
    R_ref = _scipy_R(J)
    _assert_same_gram(P._tree_factor(J), R_ref)
    if n <= 1024:
        _assert_same_gram(P._triangular_factors(J), R_ref)
    if kind == "gaussian" and n >= 8:                 # well conditioned: R itself, row by row up to sign
        _assert_same_up_to_signs(P._tree_factor(J), R_ref, 0, 1e-12 * np.abs(R_ref).max())


def test_stacked_factors_are_each_matrix_s_own_and_leave_the_input_as_it_was() -> None:
    """One stacked call: each matrix's R, in any memory layout (the pass hands Fortran-ordered views), of
    scipy's QR (RᵀR to 1e-12 of its scale); the input is not written."""
    rng = np.random.default_rng(5)
    J = rng.standard_normal((7, 8, 300)).swapaxes(1, 2)            # (7, 300, 8), each matrix Fortran-ordered
    J[2] *= 1e-9
    J[4, :, 5] = J[4, :, 1]                                      # rank deficient
    before = J.copy()
    out = np.full((7, 8, 8), np.nan)
    P._stacked_factors(J, out)
    assert np.array_equal(J, before)
    for i in range(7):
        _assert_same_gram(out[i], _scipy_R(J[i]))


def test_a_triangular_factor_is_its_own_factor() -> None:
    """The pass skips the tree for a single block: a QR of an R factor changes nothing, bit for bit."""
    R = P._triangular_factors(_random_rows("graded", 500, 9))
    assert np.array_equal(P._triangular_factors(R), R)
    assert np.array_equal(P._tree_factor(R), R)


@pytest.mark.parametrize(("n", "noise", "scenario"), [(100, 1.0, "random"), (3000, 1.0, "random"),
                                                      (2100, 0.0, "random"), (700, 1e-4, "planar"),
                                                      (900, 1.0, "line")])
def test_the_pass_factor_equals_one_qr_of_the_problem_rows(n: int, noise: float, scenario: str) -> None:
    """The checked pass (chunks of 7 pairs to the default 4096; one block per call to several) gives the R
    factor of all rows ``√w [E F]`` by scipy's one QR, and the problem (pass, or the per-pair blocks' tree,
    then the rows of cost (8)) that of all 8N rows ``[[0, √w E], [α√w E, α√w F]]``, also on noise-free
    motions (M singular) and on planar motions (rank-deficient blocks)."""
    A, B = _motions(n, seed=n, noise=noise, scenario=scenario)
    w = np.random.default_rng(n).uniform(0.1, 3.0, n)
    rows = _pair_rows(A, B, w, 2.0)
    R_ref = _scipy_R(rows)
    whole = _scipy_R(np.vstack([np.hstack([np.zeros((len(rows), 4)), rows[:, :4]]), 2.0 * rows]))
    for chunk in (7, 300, 1000, P.CHUNK):
        _assert_same_gram(P._motion_factor(A, B, w, 2.0, chunk), R_ref)
        _assert_same_gram(build_problem(A, B, alpha=2.0, weights=w, chunk=chunk).R, whole)
    _assert_same_gram(problem_from_blocks(*pair_blocks(A, B, 2.0), w, alpha=2.0).R, whole)


# Triangular inverse and SVD of Re ----------------------------------------------------------------------------

def _problems() -> list[Problem]:
    """Problems over the range of Re's condition: noisy, nearly noise-free (cond ~1e4), graded rows."""
    out = [build_problem(*_motions(50, seed=s, noise=noise), alpha=alpha)
           for s, (noise, alpha) in enumerate([(1.0, 1.0), (1.0, 30.0), (1e-3, 1.0), (0.1, 0.05)])]
    rng = np.random.default_rng(3)
    for scale in (1.0, 1e-6):
        J = rng.standard_normal((40, 8)) * np.r_[np.logspace(0, -4, 4) * scale, np.ones(4)]
        out.append(Problem.from_rows(J))
    return out


@pytest.mark.parametrize("problem", _problems())
def test_triangular_inverse_equals_lapack_s(problem: Problem) -> None:
    """``Re⁻¹`` (numpy's solve against the identity) equals LAPACK's dtrtri and scipy's triangular solve to
    1e-12 of each column's scale, with ``Re Re⁻¹ = I``; Z and M_is_regular follow."""
    Re = problem.R_factor
    Rinv = problem._Rinv
    assert Rinv is not None
    ref, info = lapack.dtrtri(Re)
    assert info == 0
    scale = np.abs(ref).max(axis=0)                          # per column: Re⁻¹ e_j
    assert (np.abs(Rinv - ref) <= 1e-12 * scale).all()
    assert (np.abs(Rinv - sla.solve_triangular(Re, np.eye(4))) <= 1e-12 * scale).all()
    assert np.array_equal(Rinv, np.triu(Rinv))
    Z2 = problem.Z[2]
    np.testing.assert_allclose(Z2, ref @ ref.T, rtol=0, atol=1e-12 * np.abs(Z2).max())


def test_an_exactly_singular_re_has_no_inverse_as_with_dtrtri() -> None:
    """A zero on Re's diagonal: no inverse (dtrtri's info > 0), M is not regular, Z refuses; a tiny but
    nonzero one still inverts, as with dtrtri."""
    R = P._triangular_factors(_random_rows("gaussian", 30, 4))
    R[2, 2] = 0.0
    singular = Problem(R, 30)
    assert lapack.dtrtri(R[:4, :4])[1] > 0
    assert singular._Rinv is None and not singular.M_is_regular
    with pytest.raises(np.linalg.LinAlgError):
        singular.Z  # noqa: B018
    R[2, 2] = 1e-200
    tiny = Problem(R, 30)
    assert tiny._Rinv is not None and not tiny.M_is_regular
    np.testing.assert_allclose(tiny._Rinv, lapack.dtrtri(R[:4, :4])[0], rtol=1e-12)


@pytest.mark.parametrize("problem", _problems() + [build_problem(*_motions(40, seed=8, noise=0.0))])
def test_svd_of_re_equals_scipy_s(problem: Problem) -> None:
    """Singular values of Re to 1e-13 of the largest, U and V up to signs (distinct singular values), and
    M's smallest eigenvector, also for noise-free motions, where σ_min is rounding (M singular)."""
    Re = problem.R_factor
    U, s, Vt = problem._svd
    U_ref, s_ref, Vt_ref = sla.svd(Re)
    np.testing.assert_allclose(s, s_ref, rtol=0, atol=1e-13 * s_ref[0])
    np.testing.assert_allclose(U * s @ Vt, Re, rtol=0, atol=1e-14 * s_ref[0])
    gap = np.min(np.abs(np.diff(s_ref))) / s_ref[0]
    if gap > 1e-3:
        _assert_same_up_to_signs(U, U_ref, 1, 1e-12 / gap)
        _assert_same_up_to_signs(Vt, Vt_ref, 0, 1e-12 / gap)
    v = problem.M_smallest_eigenvector
    assert abs(abs(v @ Vt_ref[-1]) - 1.0) < 1e-12 / min(gap, 1.0) ** 2
    assert problem.M_is_regular == (s_ref[-1] > 1e-8 * s_ref[0])


# Least squares of the dual part ------------------------------------------------------------------------------

def _designed(singular_values: tuple[float, float, float], rows: int, seed: int) -> tuple[Problem, np.ndarray,
                                                                                      np.ndarray]:
    """A problem whose ``Re B`` has the given singular values for the returned basis B (4, 3), and a unit q."""
    rng = np.random.default_rng(seed)
    U, V = np.linalg.qr(rng.standard_normal((4, 4)))[0], np.linalg.qr(rng.standard_normal((4, 4)))[0]
    R = np.zeros((8, 8))
    R[:4, :4] = U @ np.diag([*singular_values, 1.0]) @ V.T        # Re V[:, :3] = U[:, :3] diag(σ)
    R[:4, 4:] = rng.standard_normal((4, 4))
    R[4:, 4:] = np.triu(rng.standard_normal((4, 4)))
    q = rng.standard_normal(4)
    return Problem(R, rows), V[:, :3], q / np.linalg.norm(q)


@pytest.mark.parametrize("problem", _problems())
def test_full_rank_least_squares_equals_dgels(problem: Problem) -> None:
    """With M regular, the dual part in the eigenbasis (as dqopt asks it) is dgels' QR solution and scipy's
    lstsq, to 1e-12 relative (times cond(Re B))."""
    lam, V = sla.eigh(problem.Z[0])
    q, basis = V[:, 0], V[:, 1:]
    qd, CB, gq, y = problem._dual(q, basis, full_rank=True)
    ref = lapack.dgels(CB, -gq)[1][:3]
    cond = np.linalg.cond(CB)
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-12 * cond * np.abs(ref).max())
    np.testing.assert_allclose(y, sla.lstsq(CB, -gq)[0], rtol=0, atol=1e-12 * cond * np.abs(ref).max())
    np.testing.assert_allclose(qd, basis @ ref, rtol=0, atol=1e-12 * cond * np.abs(ref).max())


@pytest.mark.parametrize("side", [0.5, 2.0])
@pytest.mark.parametrize("rows", [40, 4_000_000])
def test_rank_tolerance_of_the_least_squares_is_dgelsd_s(side: float, rows: int) -> None:
    """Singular values of ``Re B`` below ``eps max(rows, 3)`` of the largest count as zero (the least-norm
    solution), just above they count: as scipy's gelsd with that ``cond``. With ``full_rank`` none is dropped,
    as dgels drops none."""
    tol = EPS * max(rows, 3)
    problem, basis, q = _designed((1.0, 1e-3, side * tol), rows, seed=rows)
    _, CB, gq, y = problem._dual(q, basis)
    ref = sla.lstsq(CB, -gq, cond=tol, lapack_driver="gelsd")
    assert ref[2] == (2 if side < 1 else 3)                      # the rank scipy found
    np.testing.assert_allclose(y, ref[0], rtol=0, atol=1e-12 * np.abs(ref[0]).max())
    full = problem._dual(q, basis, full_rank=True)[3]
    dgels = lapack.dgels(CB, -gq)[1][:3]
    np.testing.assert_allclose(full, dgels, rtol=0, atol=1e-12 * np.linalg.cond(CB) * np.abs(dgels).max())
    if side < 1:
        assert np.abs(full).max() > 1e3 * np.abs(y).max()         # the two paths do differ there


def test_dual_part_on_noise_free_motions_is_scipy_s_least_norm_solution() -> None:
    """Noise-free motions: M singular, the true q's dual part by the rank-revealing least squares, as scipy's
    gelsd with the same tolerance, and the translation exact."""
    rng = np.random.default_rng(11)
    X = random_transform(rng)
    A, B = motion_pairs(60, X, rng)
    problem = build_problem(A, B)
    assert not problem.M_is_regular
    q, qd_true = dualquat.from_transforms(X)
    qd, mu = problem.dual_part(q)
    basis = (q[dualquat._L_INDEX] * dualquat._L_SIGN)[:, :3]
    _, CB, gq, y = problem._dual(q, basis)
    ref = sla.lstsq(CB, -gq, cond=EPS * max(problem.rows, 3), lapack_driver="gelsd")[0]
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(qd, qd_true, atol=1e-12)
    assert abs(mu) < 1e-12


# Symmetric eigenproblems -------------------------------------------------------------------------------------

def _symmetric(kind: str, n: int, seed: int) -> np.ndarray:
    """Random; a double eigenvalue; a cluster split by 1e-10; eigenvalues over 16 decades (near singular)."""
    rng = np.random.default_rng(seed)
    Q = np.linalg.qr(rng.standard_normal((n, n)))[0]
    lam = {"random": rng.standard_normal(n),
           "double": np.r_[1.0, 1.0, np.arange(2, n)],
           "cluster": np.r_[1.0, 1.0 + 1e-10, np.arange(2, n) + 0.5],
           "graded": np.logspace(-16, 0, n)}[kind]
    A = (Q * lam) @ Q.T
    return 0.5 * (A + A.T)


def _problem_matrices() -> list[np.ndarray]:
    """What the solvers decompose: the cost form (8x8), Z0, Z(μ), and ``Re (½Z1) Reᵀ`` (4x4)."""
    out = []
    for p in _problems()[:4]:
        Z0, Z1, Z2 = p.Z
        out += [p.form, Z0, Z0 + 0.3 * Z1 - 0.09 * Z2, p.R_factor @ (0.5 * Z1) @ p.R_factor.T]
    return out


def _check_eigh(A: np.ndarray) -> None:
    lam, V = eigh(A)
    lam_ref, V_ref, info = lapack.dsyev(A)                    # upper triangle, as before
    assert info == 0
    size = np.abs(lam_ref).max()
    np.testing.assert_allclose(lam, lam_ref, rtol=0, atol=1e-13 * size)
    np.testing.assert_allclose(lam, sla.eigh(A, lower=False, eigvals_only=True), rtol=0, atol=1e-13 * size)
    np.testing.assert_allclose(V.T @ V, np.eye(len(A)), rtol=0, atol=1e-13)
    Au = np.triu(A) + np.triu(A, 1).T
    np.testing.assert_allclose(Au @ V, V * lam, rtol=0, atol=1e-13 * size)
    # eigenvectors up to sign where the eigenvalue is isolated; the spanned space of a cluster
    edges = np.flatnonzero(np.diff(lam_ref) > 1e-6 * size) + 1
    for group in np.split(np.arange(len(A)), edges):
        lo, hi = group[0], group[-1]
        gap = min(lam_ref[lo] - lam_ref[lo - 1] if lo > 0 else np.inf,
                  lam_ref[hi + 1] - lam_ref[hi] if hi + 1 < len(A) else np.inf) / size
        Pj, Pj_ref = V[:, group] @ V[:, group].T, V_ref[:, group] @ V_ref[:, group].T
        np.testing.assert_allclose(Pj, Pj_ref, rtol=0, atol=1e-13 / gap)
        if len(group) == 1:
            _assert_same_up_to_signs(V[:, group], V_ref[:, group], 1, 1e-13 / gap)
    lam_only, none = eigh(A, vectors=False)
    np.testing.assert_allclose(lam_only, lapack.dsyev(A, compute_v=0)[0], rtol=0, atol=1e-13 * size)
    assert none.size == 0


@pytest.mark.parametrize("kind", ["random", "double", "cluster", "graded"])
@pytest.mark.parametrize("n", [4, 8])
def test_eigh_equals_dsyev(kind: str, n: int) -> None:
    """Eigenvalues to 1e-13 of the largest, vectors up to sign (isolated) or as a space (clusters)."""
    for seed in range(5):
        _check_eigh(_symmetric(kind, n, seed))


@pytest.mark.parametrize("index", range(16))
def test_eigh_equals_dsyev_on_the_solvers_matrices(index: int) -> None:
    _check_eigh(_problem_matrices()[index])


def test_eigh_reads_the_upper_triangle_as_dsyev_did() -> None:
    """A product such as ``Re (½Z1) Reᵀ`` is symmetric only to rounding: the upper triangle is the matrix."""
    A = _symmetric("random", 4, 1)
    A[np.tril_indices(4, -1)] += np.random.default_rng(2).standard_normal(6)
    _check_eigh(A)
    np.testing.assert_allclose(eigh(A)[0], np.linalg.eigvalsh(np.triu(A) + np.triu(A, 1).T), atol=1e-13)


# What problem.py imports -------------------------------------------------------------------------------------

def test_problem_module_imports_no_scipy() -> None:
    """Neither at its top nor in a function: scipy.linalg alone costs every process 0.3 s of start-up."""
    tree = ast.parse(Path(P.__file__).read_text(encoding="utf-8"))
    imported = [alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names]
    imported += [node.module or "" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)]
    assert not [m for m in imported if m.split(".")[0] == "scipy"]


def test_a_solve_loads_no_scipy_module_once_problem_py_is_imported() -> None:
    """In a fresh process: building problems and solving them by the problem-based methods loads no scipy
    module beyond those that importing the solvers brought in."""
    code = """
import sys, numpy as np
from handeye_cli.solvers import solve
from handeye_cli.simulation import motion_pairs, random_transform
rng = np.random.default_rng(0)
data = [motion_pairs(n, random_transform(rng), rng, sigma_r=s, sigma_t=s)
        for n, s in ((50, 0.01), (5000, 0.01), (30, 0.0))]
before = {m for m in sys.modules if m.startswith("scipy")}
for A, B in data:
    for method in ("dqopt", "dqitr", "dq2steps", "dqconvrlx", "dq2ndord", "daniilidis"):
        solve(A, B, method=method)
print(sorted({m for m in sys.modules if m.startswith("scipy")} - before))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
