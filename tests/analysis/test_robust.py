"""Outlier rejection (handeye_cli.analysis.robust) on synthetic pairs with injected gross outliers."""
import numpy as np
import pytest

from handeye_cli.analysis import extrinsic_error, robust_solve
from handeye_cli.errors import HandEyeError
from handeye_cli.simulation import motion_pairs, random_transform
from handeye_cli.solvers import solve

SIGMA_R, SIGMA_T = np.deg2rad(0.57), 0.01


def contaminate(A, B, fraction, rng):
    """Replace ``fraction`` of the pairs by gross outliers: A_i or B_i becomes a random motion."""
    A, B = A.copy(), B.copy()
    bad = np.sort(rng.choice(len(A), int(round(fraction * len(A))), replace=False))
    for i in bad:
        target = A if rng.random() < 0.5 else B
        target[i] = random_transform(rng)
    return A, B, bad


def _trial(seed, n=100, fraction=0.1):
    rng = np.random.default_rng(seed)
    X = random_transform(rng)
    A, B = motion_pairs(n, X, rng, "random", SIGMA_R, SIGMA_T)
    clean = extrinsic_error(solve(A, B).matrix, X)
    A2, B2, bad = contaminate(A, B, fraction, rng)
    plain = extrinsic_error(solve(A2, B2).matrix, X)
    result = robust_solve(A2, B2, seed=seed)
    return clean, plain, extrinsic_error(result.solution.matrix, X), bad, result


@pytest.mark.statistical
def test_ten_percent_outliers_within_1_5x_of_outlier_free_error():
    trials = [_trial(s) for s in range(12)]
    clean = np.median([t[0] for t in trials], axis=0)
    plain = np.median([t[1] for t in trials], axis=0)
    robust = np.median([t[2] for t in trials], axis=0)
    assert robust[0] <= 1.5 * clean[0] and robust[1] <= 1.5 * clean[1], (clean, robust)
    assert plain[0] > 5 * clean[0] and plain[1] > 5 * clean[1], "outliers must matter for the test to mean anything"
    for _, _, _, bad, result in trials:
        assert set(bad) <= set(result.rejected.tolist())          # every outlier rejected
        assert len(result.rejected) <= len(bad) + 6               # few good pairs lost
        assert not result.inliers[bad].any() and result.inliers.sum() == 100 - len(result.rejected)


def test_thirty_percent_outliers_still_recovered():
    clean, _, robust, bad, result = _trial(5, n=150, fraction=0.3)
    assert set(bad) <= set(result.rejected.tolist())
    assert robust[0] <= 2 * clean[0] and robust[1] <= 2 * clean[1]


def test_clean_data_keeps_almost_everything_and_matches_dqopt():
    rng = np.random.default_rng(7)
    X = random_transform(rng)
    A, B = motion_pairs(200, X, rng, "random", SIGMA_R, SIGMA_T)
    result = robust_solve(A, B)
    assert len(result.rejected) <= 6
    rot, trans = extrinsic_error(result.solution.matrix, solve(A, B).matrix)
    assert rot < 0.02 and trans < 1e-3
    assert result.threshold_rotation_deg > 0 and result.threshold_translation_m > 0


def test_seeded_and_reported():
    rng = np.random.default_rng(8)
    X = random_transform(rng)
    A, B = motion_pairs(60, X, rng, "random", SIGMA_R, SIGMA_T)
    A, B, _ = contaminate(A, B, 0.1, rng)
    r1, r2 = robust_solve(A, B, seed=3), robust_solve(A, B, seed=3)
    np.testing.assert_array_equal(r1.solution.matrix, r2.solution.matrix)
    d = r1.as_dict()
    assert d["inliers"] + len(d["rejected"]) == 60 and d["hypotheses"] == 256


def test_too_few_pairs_is_a_handeye_error():
    rng = np.random.default_rng(9)
    A, B = motion_pairs(5, random_transform(rng), rng, "random")
    with pytest.raises(HandEyeError, match="too few"):
        robust_solve(A, B)


def test_refinement_cap_still_runs_one_round():
    """``max_refinements`` caps the solve / re-threshold rounds, and one round always runs (a result needs a solve)."""
    rng = np.random.default_rng(10)
    X = random_transform(rng)
    A, B = motion_pairs(60, X, rng, "random", SIGMA_R, SIGMA_T)
    A, B, bad = contaminate(A, B, 0.1, rng)
    none, one, many = (robust_solve(A, B, max_refinements=m) for m in (0, 1, 10))
    assert none.refinements == one.refinements == 1 and many.refinements >= 1
    np.testing.assert_array_equal(none.solution.matrix, one.solution.matrix)
    assert not one.inliers[bad].any()
    rot, trans = extrinsic_error(one.solution.matrix, X)
    assert rot < 1.0 and trans < 0.02
