"""Bootstrap uncertainty (handeye_cli.analysis.bootstrap) and the sandwich covariance it is checked against."""
import time

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from handeye_cli.analysis import bootstrap, linear_covariance
from handeye_cli.analysis.bootstrap import replicate_problems
from handeye_cli.errors import HandEyeError
from handeye_cli.geometry import dualquat as dq
from handeye_cli.simulation import motion_pairs, random_transform
from handeye_cli.solvers import Prior, build_problem, solve
from handeye_cli.solvers.optimal import dqopt

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
    for problem, w in zip(probs, counts, strict=True):
        r = dqopt(problem)
        want = solve(A, B, alpha=0.7, prior=p, weights=w).matrix
        np.testing.assert_allclose(dq.to_transform(r.q, r.qd), want, atol=1e-9)


@pytest.mark.statistical
def test_95_percent_intervals_cover_the_truth_about_95_percent_of_the_time():
    hits = np.zeros(6)
    for trial in range(100):
        X, A, B = _data(1000 + trial, 40)
        r_in, t_in = bootstrap(A, B, 400, seed=trial).contains(X)
        hits += np.r_[r_in, t_in]
    assert ((hits >= 85) & (hits <= 100)).all(), hits


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


def test_the_callers_estimate_stands_for_the_solve_it_saves():
    """The pipeline passes its own solve (all pairs, zero weights on the outliers) as the estimate."""
    X, A, B = _data(8, 60)
    w = np.r_[np.zeros(5), np.full(55, 2.0)]
    est = solve(A, B, alpha=0.7, weights=w).matrix
    own, given = (bootstrap(A, B, 30, alpha=0.7, weights=w, seed=1, estimate=e) for e in (None, est))
    np.testing.assert_allclose(given.matrix, own.matrix, atol=1e-12)
    np.testing.assert_allclose(given.rotation_deltas_deg, own.rotation_deltas_deg, atol=1e-9)
    np.testing.assert_allclose(given.translations_m, own.translations_m, atol=1e-12)


@pytest.mark.parametrize("scenario", ["random", "circle", "line"])
def test_vectorised_dqopt_matches_the_project_dqopt(scenario):
    from handeye_cli.analysis.bootstrap import _solve_replicates, replicate_grams
    X, A, B = _data(6, 200, scenario)
    counts = np.random.default_rng(1).multinomial(200, np.full(200, 1 / 200), size=50)
    Q = replicate_grams(A, B, counts, alpha=0.5)
    want = np.array([dq.to_transform(r.q, r.qd) for r in map(dqopt, replicate_problems(A, B, counts, alpha=0.5))])
    np.testing.assert_allclose(_solve_replicates(Q), want, atol=1e-9)


@pytest.mark.statistical
def test_samples_bootstrap_accounts_for_pairs_sharing_poses():
    """Keyframe pairs reuse each pose in many pairs: resampling poses (vertex bootstrap) must
    spread wider than resampling pairs, and its intervals must contain the truth."""
    from handeye_cli.simulation import Rig, simulate_rig
    from handeye_cli.stages.pairs import make_pairs
    from handeye_cli.stages.sync import associate
    hits, ratio = np.zeros(6), []
    for seed in range(6):
        X = random_transform(np.random.default_rng(seed), 0.3)
        a, b = simulate_rig(Rig(X), duration_s=40, rate_a=30, rate_b=12, sigma_r=np.deg2rad(0.2),
                            sigma_t=0.002, seed=seed)
        pairs, _ = make_pairs(associate(a, b)[0], "keyframes", max_pairs=1000)
        by_pairs = bootstrap(pairs.A, pairs.B, 200, seed=seed)
        by_samples = bootstrap(pairs.A, pairs.B, 200, seed=seed, samples=(pairs.i, pairs.j))
        ratio.append(np.r_[by_samples.rotation_std_deg / by_pairs.rotation_std_deg,
                           by_samples.translation_std_m / by_pairs.translation_std_m])
        hits += np.concatenate(by_samples.contains(X))
    assert np.median(ratio) > 1.5, np.median(ratio, axis=0)
    assert (hits >= 5).all(), hits


def test_samples_weights_are_products_of_sample_counts():
    from handeye_cli.analysis.bootstrap import _sample_counts
    i, j = np.array([0, 0, 1, 5]), np.array([1, 2, 2, 7])
    k, w = _sample_counts((i, j), np.arange(4), 3, np.random.default_rng(0))
    assert k == 5 and w.shape == (3, 4)
    k, w2 = _sample_counts((i, j), np.array([0, 2]), 3, np.random.default_rng(0))
    assert k == 3 and w2.shape == (3, 2)
    rng = np.random.default_rng(0)
    c = rng.multinomial(5, np.full(5, 0.2), size=3).astype(float)       # nodes 0, 1, 2, 5, 7
    np.testing.assert_array_equal(w, np.c_[c[:, 0] * c[:, 1], c[:, 0] * c[:, 2], c[:, 1] * c[:, 2], c[:, 3] * c[:, 4]])


def test_dyadic_sandwich_reduces_to_the_plain_one_when_no_sample_is_shared():
    X, A, B = _data(7, 60)
    sol = solve(A, B)
    plain = linear_covariance(A, B, sol.matrix)
    distinct = linear_covariance(A, B, sol.matrix, samples=(np.arange(0, 120, 2), np.arange(1, 120, 2)))
    np.testing.assert_allclose(distinct.covariance, plain.covariance * (120 / 114) * (54 / 60), rtol=1e-9)
    chained = linear_covariance(A, B, sol.matrix, samples=(np.arange(60), np.arange(1, 61)))
    assert not np.allclose(chained.covariance, plain.covariance)
