"""Choice of α (handeye_cli.analysis.alpha) against an α sweep with known truth (paper's scenarios, app. D.2)."""
import numpy as np
import pytest

from handeye_cli.analysis import auto_alpha, extrinsic_error, residual_ratio_alpha
from handeye_cli.analysis.alpha import DEFAULT_GRID, noise_model_alpha
from handeye_cli.simulation import motion_pairs, random_transform
from handeye_cli.solvers import solve

SIGMA_R, SIGMA_T = np.deg2rad(0.57), 0.01
SWEEP = np.logspace(-2.0, 1.7, 12)


@pytest.mark.statistical
@pytest.mark.parametrize("scenario", ["random", "line", "circle"])
def test_auto_alpha_within_20_percent_of_the_sweep_best(scenario):
    trials = 8
    sweep = np.zeros((len(SWEEP), 2))
    auto = np.zeros(2)
    for seed in range(trials):
        rng = np.random.default_rng(100 + seed)
        X = random_transform(rng)
        A, B = motion_pairs(100, X, rng, scenario, SIGMA_R, SIGMA_T)
        sweep += [extrinsic_error(solve(A, B, alpha=a).matrix, X) for a in SWEEP]
        auto += extrinsic_error(solve(A, B, alpha=auto_alpha(A, B).alpha).matrix, X)
    best = sweep.min(axis=0)          # mean error at the best α, separately for rotation and translation
    assert (auto <= 1.2 * best).all(), (auto / trials, best / trials)


def test_choice_reports_the_evidence():
    rng = np.random.default_rng(1)
    X = random_transform(rng)
    A, B = motion_pairs(80, X, rng, "random", SIGMA_R, SIGMA_T)
    choice = auto_alpha(A, B)
    assert choice.method == "sandwich" and choice.alpha in DEFAULT_GRID
    d = choice.as_dict()
    assert d["alpha"] == choice.alpha
    # The predicted RMS errors at the chosen α against the real errors over fresh noise (Monte Carlo).
    errors = np.array([extrinsic_error(solve(*motion_pairs(80, X, rng, "random", SIGMA_R, SIGMA_T),
                                             alpha=choice.alpha).matrix, X) for _ in range(40)])
    rms_rot, rms_trans = np.sqrt(np.mean(errors ** 2, axis=0))
    assert 0.5 < d["predicted_rotation_rms_deg"] / rms_rot < 2.0, (d, rms_rot)
    assert 0.5 < d["predicted_translation_rms_m"] / rms_trans < 2.0, (d, rms_trans)


def test_residual_ratio_follows_the_noise_ratio():
    """Pure rotation noise vs pure translation noise: quadrupling σ_t divides α by about four."""
    rng = np.random.default_rng(2)
    X = random_transform(rng, 0.05)                      # small lever arm: residuals ≈ the injected noise
    A, B = motion_pairs(400, X, np.random.default_rng(3), "random", np.deg2rad(0.5), 0.005)
    A4, B4 = motion_pairs(400, X, np.random.default_rng(3), "random", np.deg2rad(0.5), 0.02)
    a1, a4 = residual_ratio_alpha(A, B).alpha, residual_ratio_alpha(A4, B4).alpha
    assert 3.0 < a1 / a4 < 4.5


def test_noise_free_data_falls_back():
    rng = np.random.default_rng(4)
    A, B = motion_pairs(30, random_transform(rng), rng, "random")
    choice = auto_alpha(A, B)
    assert choice.method == "residual-ratio" and choice.alpha == 1.0


@pytest.mark.statistical
@pytest.mark.parametrize("scenario", ["random", "line", "circle"])
def test_noise_model_alpha_is_never_worse_than_alpha_one(scenario):
    """The default rule (ML α under the noise model) on the paper's scenarios: mean errors over the
    trials no worse than α = 1 by more than 5 %, rotation and translation alike."""
    trials = 10
    ml, one = np.zeros(2), np.zeros(2)
    for seed in range(trials):
        rng = np.random.default_rng(300 + seed)
        X = random_transform(rng)
        A, B = motion_pairs(100, X, rng, scenario, SIGMA_R, SIGMA_T)
        choice = noise_model_alpha(A, B)
        assert choice.method == "noise-model" and 0.05 < choice.alpha < 5
        ml += extrinsic_error(solve(A, B, alpha=choice.alpha).matrix, X)
        one += extrinsic_error(solve(A, B, alpha=1.0).matrix, X)
    assert (ml <= 1.05 * one).all(), (ml / trials, one / trials)


def test_noise_model_alpha_on_noise_free_motions_keeps_the_start():
    rng = np.random.default_rng(4)
    X = random_transform(rng)
    A, B = motion_pairs(30, X, rng, "random")
    assert noise_model_alpha(A, B, start=2.5).alpha == 2.5
