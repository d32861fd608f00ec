"""The optimality certificate (solvers/certificate.py): it certifies every optimal solve of the paper's
scenarios, and it rejects true stationary points of cost (8) that are not the global minimum."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from handeye_cli import document
from handeye_cli.geometry import dualquat
from handeye_cli.output.document import result_document
from handeye_cli.simulation import SCENARIOS, motion_pairs, perturb, random_transform
from handeye_cli.solvers import METHODS, Prior, Problem, Solution, build_problem, solve
from handeye_cli.solvers.certificate import RELATIVE_TOLERANCE, certify

SIGMA_R, SIGMA_T = np.deg2rad(0.57), 0.01    # the paper's noise levels (appendix D.2)
# (σr, σt) multiples of the paper's: noise-free, rotations exact with noisy translations (both make M
# singular), the paper's noise, and ten times more
NOISE = ((0.0, 0.0), (0.0, 1.0), (0.1, 0.1), (1.0, 1.0), (10.0, 10.0))


def _case(scenario: str, seed: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """A problem of the paper's scenario generator (appendix D.2): noise, α, translation scale, prior and
    weights varied with the seed; planar motion always has a prior (it cannot fix the extrinsic alone)."""
    rng = np.random.default_rng(seed)
    X = random_transform(rng, (1.0, 20.0)[seed % 2])
    sr, st = NOISE[seed % len(NOISE)]
    A, B = motion_pairs(int(rng.integers(10, 60)), X, rng, scenario, SIGMA_R * sr, SIGMA_T * st)
    kw: dict = {"alpha": float(10 ** rng.uniform(-2, 2))}
    if scenario == "planar" or seed % 3 == 0:
        kw["prior"] = Prior(perturb(X, rng, 0.05, 0.05), float(rng.uniform(0.01, 2)), float(rng.uniform(0.01, 2)))
    if seed % 4 == 1:
        kw["weights"] = rng.uniform(0.05, 3.0, len(A))
    return A, B, kw


@pytest.mark.statistical
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_every_optimal_solve_is_certified(scenario):
    """Noise-free, singular M, prior, weights, α from 0.01 to 100 and 20 m translations: 60 seeds each."""
    singular = 0
    for seed in range(60):
        A, B, kw = _case(scenario, seed)
        sol = solve(A, B, method="dqopt", **kw)
        c = sol.certificate
        assert c is not None and c.certified, (seed, c)
        assert c.stationarity <= 1e-6 * c.tolerance and c.min_eigenvalue >= -1e-6 * c.tolerance, (seed, c)
        assert c.lam == pytest.approx(sol.cost, rel=1e-9, abs=1e-6 * c.tolerance)   # λ is the cost at a KKT point
        assert sol.warnings == ()
        singular += bool(sol.details["singular_m"])
    # exact rotations make M singular (unless a prior adds its b·I, eq 29: planar always has one)
    assert singular >= (0 if scenario == "planar" else 10)


@pytest.mark.statistical
def test_dqitr_is_certified_where_it_converges_and_warned_where_not():
    """DQItr may cycle (§3.2.5); where it ends away from the optimum the certificate says so."""
    certified = warned = 0
    for seed in range(40):
        A, B, kw = _case("line", seed)
        sol = solve(A, B, method="dqitr", **kw)
        assert sol.certificate is not None
        if sol.certificate.certified:
            certified += 1
            assert sol.cost <= solve(A, B, **kw).cost * (1 + 1e-9) + 1e-12
        else:                                        # dqitr cycles: a genuinely worse point, and a warning
            warned += 1
            assert not sol.converged and sol.cost > solve(A, B, **kw).cost * (1 + 1e-6)
            assert len(sol.warnings) == 1 and "⟦method='dqopt'⟧" in sol.warnings[0]
    assert certified >= 30 and warned >= 1


def _secular_kkt_point(problem: Problem, branch: int) -> tuple[np.ndarray, np.ndarray, float]:
    """A true KKT point of cost (8) other than the minimum: the maximum over μ of the ``branch``-th
    eigenvalue λ_a(μ) of Z(μ) (eq 12), i.e. a root of that branch's secular function
    ``f_a(μ) = q_aᵀ(μ Z2 - ½ Z1) q_a`` (eq 18, which dqopt solves for the smallest branch only).

    At such a root ``q = q_a``, ``q' = M⁻¹(μ - Wᵀ) q`` (eq 20) satisfies eq 10 with λ = λ_a and ``q·q' = f_a = 0``.
    Every f_a is negative left of the smallest generalised eigenvalue of (½Z1, Z2) and positive right of the
    largest (appendix C), so bisection between them finds a root."""
    Z0, Z1, Z2 = problem.Z
    theta = np.sort(np.linalg.eigvals(np.linalg.solve(Z2, 0.5 * Z1)).real)
    span = theta[-1] - theta[0] + 1.0

    def f(mu: float) -> tuple[float, np.ndarray, float]:
        lam, V = np.linalg.eigh(Z0 + mu * Z1 - mu * mu * Z2)
        q = V[:, branch]
        return float(q @ (mu * Z2 - 0.5 * Z1) @ q), q, float(lam[branch])

    lo, hi = theta[0] - span, theta[-1] + span
    assert f(lo)[0] < 0 < f(hi)[0]
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        lo, hi = (mid, hi) if f(mid)[0] < 0 else (lo, mid)
    _, q, lam = f(lo)
    qd = Z2 @ (lo * q - problem.W.T @ q)
    return q, qd - (q @ qd) * q, lam


@pytest.mark.parametrize("seed", range(6))
def test_rejects_the_other_stationary_points(seed):
    """The secular equation's other roots are stationary points (KKT residual at rounding) with a higher cost;
    Q - Λ has a clearly negative eigenvalue there, so they are not certified."""
    A, B, kw = _case("random", 10 * seed + 3)            # noisy (M regular), no weights
    problem = build_problem(A, B, alpha=kw["alpha"], prior=kw.get("prior"))
    best = solve(A, B, **kw)
    for branch in (1, 2, 3):
        q, qd, lam = _secular_kkt_point(problem, branch)
        c = certify(problem, q, qd)
        assert c.stationarity <= c.tolerance, (branch, c)        # it is a KKT point …
        assert c.lam == pytest.approx(lam, rel=1e-6)
        assert problem.cost(q, qd) > best.cost * (1 + 1e-6)     # … not the minimum …
        assert c.min_eigenvalue < -1e3 * c.tolerance and not c.certified, (branch, c)   # … and rejected
        wrong = replace(best, matrix=dualquat.to_transform(q, qd), dual_quaternion=(q, qd))
        assert wrong.certificate is not None and not wrong.certificate.certified
        assert len(wrong.warnings) == 1 and "numerical failure of dqopt" in wrong.warnings[0]


@pytest.mark.statistical
def test_rejects_the_optimum_of_another_alpha_and_a_perturbed_optimum():
    for seed in range(10):
        rng = np.random.default_rng(seed)
        A, B = motion_pairs(50, random_transform(rng), rng, sigma_r=SIGMA_R, sigma_t=SIGMA_T)
        right = solve(A, B, alpha=1.0)
        other = solve(A, B, alpha=10.0)
        assert right.certificate is not None and right.certificate.certified
        c = certify(right.problem, *other.dual_quaternion)    # the α = 10 optimum on the α = 1 cost
        assert not c.certified and c.stationarity > 1e3 * c.tolerance
        nudged = perturb(right.matrix, rng, 1e-4, 1e-4)          # 0.006° and 0.1 mm off the optimum
        c = replace(right, matrix=nudged, dual_quaternion=None).certificate
        assert c is not None and not c.certified


def test_tolerance_follows_the_scale_of_the_cost():
    """Weights × 1e6 scale the form, its tolerance and its eigenvalues alike: still certified."""
    rng = np.random.default_rng(5)
    A, B = motion_pairs(40, random_transform(rng), rng, sigma_r=SIGMA_R, sigma_t=SIGMA_T)
    for w in (1e-6, 1.0, 1e6):
        weights = np.full(len(A), w)
        c = solve(A, B, weights=weights).certificate
        assert c is not None and c.certified
        assert c.tolerance == pytest.approx(w * solve(A, B).certificate.tolerance, rel=1e-9)
        form = build_problem(A, B, weights=weights).form
        assert c.tolerance == pytest.approx(RELATIVE_TOLERANCE * np.trace(form), rel=1e-9)


def test_every_method_reports_a_certificate_and_only_the_optimal_ones_warn():
    rng = np.random.default_rng(11)
    A, B = motion_pairs(60, random_transform(rng), rng, sigma_r=SIGMA_R, sigma_t=SIGMA_T)
    for method in METHODS:
        sol = solve(A, B, method=method)
        doc = result_document(sol)["solver"]["certificate"]
        assert set(doc) == {"certified", "min_eigenvalue", "tolerance", "stationarity"}
        assert doc["certified"] is sol.certificate.certified and isinstance(doc["min_eigenvalue"], float)
        assert sol.warnings == ()                                  # the approximations do not warn
    assert result_document(solve(A, B))["solver"]["certificate"]["certified"] is True
    assert result_document(solve(A, B, method="dq2steps"))["solver"]["certificate"]["certified"] is False
    bare = Solution(np.eye(4), 0.0, "dqopt", 1.0, 2)             # built by hand: no problem, no certificate
    assert bare.certificate is None and "certificate" not in result_document(bare)["solver"]


def test_an_uncertified_solve_warns_in_the_calibration(monkeypatch, rig):
    """calibrate carries the solution's warning into the result's warnings."""
    from handeye_cli.calibration import run

    real = run.solve

    def off_by_a_little(*args, **kw):
        sol = real(*args, **kw)
        return replace(sol, matrix=perturb(sol.matrix, np.random.default_rng(0), 1e-3, 1e-3), dual_quaternion=None)

    monkeypatch.setattr(run, "solve", off_by_a_little)
    cal = run.calibrate_files(rig["a"], rig["b"], max_pairs=100)
    assert any("not certified as the global optimum" in w for w in cal.warnings)
    assert document(cal)["solver"]["certificate"]["certified"] is False
