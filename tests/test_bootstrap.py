"""Bootstrap uncertainty (handeye_cli.analysis.bootstrap) and the sandwich covariance it is checked against."""
import time

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from handeye_cli.analysis import bootstrap, linear_covariance
from handeye_cli.analysis.bootstrap import replicate_problems
from handeye_cli.errors import HandEyeError
from handeye_cli.solvers import Prior, build_problem, solve
from handeye_cli.solvers import dualquat as dq
from handeye_cli.solvers.optimal import dqopt
from handeye_cli.synthetic import motion_pairs, random_transform

SIGMA_R, SIGMA_T = np.deg2rad(0.57), 0.01


def _data(seed, n, scenario="random"):
    rng = np.random.default_rng(seed)
    X = random_transform(rng)
    A, B = motion_pairs(n, X, rng, scenario, SIGMA_R, SIGMA_T)
    return X, A, B


@pytest.mark.parametrize("prior", [None, "prior"])
def test_replicate_with_unit_counts_is_the_full_solve(prior):
    X, A, B = _data(0, 80)
    p = Prior(X @ np.diag([1, 1, 1, 1.0]), 2.0, 3.0) if prior else None
    counts = np.vstack([np.ones(80), np.r_[np.full(40, 2.0), np.zeros(40)]])
    probs = replicate_problems(A, B, counts, alpha=0.7, prior=p)
    for problem, w in zip(probs, counts):
        r = dqopt(problem)
        want = solve(A, B, alpha=0.7, prior=p, weights=w).matrix
        np.testing.assert_allclose(dq.to_transform(r.q, r.qd), want, atol=1e-9)


def test_95_percent_intervals_cover_the_truth_about_95_percent_of_the_time():
    hits = np.zeros(6)
    for trial in range(100):
        X, A, B = _data(1000 + trial, 40)
        r_in, t_in = bootstrap(A, B, 400, seed=trial).contains(X)
        hits += np.r_[r_in, t_in]
    assert ((85 <= hits) & (hits <= 100)).all(), hits


def test_thousand_replicates_on_thousand_pairs_takes_seconds():
    X, A, B = _data(2, 1000)
    t0 = time.perf_counter()
    result = bootstrap(A, B, 1000, seed=1)
    assert time.perf_counter() - t0 < 5.0
    assert result.rotation_deltas_deg.shape == (1000, 3) and result.replicates == 1000
    assert (result.rotation_interval_deg[0] < result.rotation_interval_deg[1]).all()


def test_spread_agrees_with_the_sandwich_covariance_and_with_the_truth_scale():
    X, A, B = _data(3, 300)
    boot = bootstrap(A, B, 400, alpha=0.7, seed=2)
    cov = linear_covariance(A, B, boot.matrix, alpha=0.7)
    np.testing.assert_allclose(boot.rotation_std_deg, cov.rotation_std_deg, rtol=0.25)
    np.testing.assert_allclose(boot.translation_std_m, cov.translation_std_m, rtol=0.25)


def test_sandwich_hessian_matches_finite_differences_of_cost_8():
    X, A, B = _data(4, 100)
    sol = solve(A, B, alpha=0.7)
    problem = build_problem(A, B, alpha=0.7)

    def cost(rot, trans):          # left perturbation in frame a: R' = exp(ω) R, t' = t + δt
        Y = sol.matrix.copy()
        Y[:3, :3] = Rotation.from_rotvec(rot).as_matrix() @ Y[:3, :3]
        Y[:3, 3] += trans
        return problem.cost(*dq.from_transforms(Y))

    cov = linear_covariance(A, B, sol.matrix, alpha=0.7)
    h, E = 1e-4, np.eye(6)
    f = lambda d: cost(d[:3], d[3:])                                          # noqa: E731
    H = np.array([[(f(h * (E[i] + E[j])) - f(h * (E[i] - E[j])) - f(h * (E[j] - E[i])) + f(-h * (E[i] + E[j])))
                   / (4 * h * h) for j in range(6)] for i in range(6)])
    np.testing.assert_allclose(2 * cov.hessian, H, atol=1e-6 * np.abs(H).max())


def test_zero_weight_pairs_are_not_resampled_and_seed_reproduces():
    X, A, B = _data(5, 60)
    A2, B2 = np.concatenate([A, A[:5] @ random_transform(np.random.default_rng(0))]), np.concatenate([B, B[:5]])
    mask = np.r_[np.ones(60), np.zeros(5)]
    masked = bootstrap(A2, B2, 50, weights=mask, seed=4)
    plain = bootstrap(A, B, 50, seed=4)
    np.testing.assert_allclose(masked.translations_m, plain.translations_m, atol=1e-12)
    assert masked.as_dict()["replicates"] == 50
    with pytest.raises(HandEyeError):
        bootstrap(A, B, 1)


@pytest.mark.parametrize("scenario", ["random", "circle", "line"])
def test_vectorised_dqopt_matches_the_project_dqopt(scenario):
    from handeye_cli.analysis.bootstrap import _solve_replicates, replicate_grams
    X, A, B = _data(6, 200, scenario)
    counts = np.random.default_rng(1).multinomial(200, np.full(200, 1 / 200), size=50)
    Q = replicate_grams(A, B, counts, alpha=0.5)
    want = np.array([dq.to_transform(r.q, r.qd) for r in map(dqopt, replicate_problems(A, B, counts, alpha=0.5))])
    np.testing.assert_allclose(_solve_replicates(Q), want, atol=1e-9)
