"""Monocular scale: ``--scale auto`` estimates the scale of b's translations with T_a_b."""
from __future__ import annotations

import numpy as np
import pytest
import yaml
from _util import pose_error, run, write_tum

from handeye_cli import calibrate
from handeye_cli.analysis.fit_test import sample_noise
from handeye_cli.errors import DataError
from handeye_cli.geometry import se3
from handeye_cli.simulation import Rig, motion_pairs, random_transform, simulate_rig
from handeye_cli.simulation.arm import monocular, simulate_arm
from handeye_cli.solvers.scale import scale_translations, solve_with_scale
from handeye_cli.stages.pairs import make_pairs
from handeye_cli.stages.stations import detect_stations
from handeye_cli.stages.sync import associate
from handeye_cli.streams import PoseStream

SCALE = 0.37          # metres per unit of the monocular stream


def test_noise_free_pairs_give_the_exact_scale():
    rng = np.random.default_rng(0)
    X = random_transform(rng, 0.3)
    A, B = motion_pairs(30, X, rng)
    est = solve_with_scale(A, scale_translations(B, 1 / SCALE))
    assert est.scale == pytest.approx(SCALE, rel=1e-9) and est.linear_scale == pytest.approx(SCALE, rel=1e-9)
    assert pose_error(est.matrix, X)[1] < 1e-9


def _arm_scale(seed: int, dh_error: float):
    c = simulate_arm(15, seed=seed, dh_error=dh_error)   # dwelling stations, 1 mm / 0.1° camera noise
    b = monocular(c.camera.inverted(), SCALE)
    st = detect_stations(c.robot, b)
    pairs, _ = make_pairs(st.synced, "all")
    return c, solve_with_scale(pairs.A, pairs.B, samples=(pairs.i, pairs.j))


def test_scale_of_an_arm_capture_within_0_1_percent_and_its_std():
    c, est = _arm_scale(4, 1.0)                    # with the simulation's kinematic (DH) errors
    assert abs(est.scale / SCALE - 1) < 1e-3
    assert abs(est.scale - SCALE) < 4 * est.scale_std and est.scale_std < 1e-3 * SCALE   # honest and small
    rot, trans = pose_error(est.matrix, c.truth)
    assert rot < 0.05 and trans < 0.002


@pytest.mark.statistical
def test_scale_std_matches_the_spread_over_captures():
    """Exact kinematics: every capture's scale within 0.1 % and within 3 of its own std; the errors'
    RMS in stds near 1 (the jackknife over stations, not the pairs-as-independent figure)."""
    z = []
    for seed in range(5):
        _, est = _arm_scale(seed, 0.0)
        assert abs(est.scale / SCALE - 1) < 1e-3
        z.append((est.scale - SCALE) / est.std_of_data)     # exact kinematics: the data are all there is
    assert np.all(np.abs(z) < 3) and 0.3 < np.sqrt(np.mean(np.square(z))) < 1.7, z


@pytest.mark.statistical
def test_scale_of_a_noisy_camera_is_not_attenuated():
    """Errors in variables: the camera's translations multiply the scale, so least squares on the plain
    residuals pulls it low by more than its σ at 8 mm / 0.8° camera noise. Weighed by the streams' jitter
    (what ``--scale auto`` does), the error is within its σ on every capture and unbiased on average."""
    z_weighted, z_plain = [], []
    for seed in range(3):
        c = simulate_arm(6, dwell_s=0.0, move_s=2.0, camera_sigma_r=np.deg2rad(0.8), camera_sigma_t=0.008,
                         dh_error=0.0, seed=seed)
        b = monocular(c.camera.inverted(), SCALE)
        synced, _ = associate(c.robot, b)
        pairs, _ = make_pairs(synced, "random:80")
        noise = sample_noise(c.robot, b, synced, None, "auto").translation_variances(pairs.i, pairs.j)
        est = solve_with_scale(pairs.A, pairs.B, samples=(pairs.i, pairs.j), translation_noise=noise)
        plain = solve_with_scale(pairs.A, pairs.B)
        z_weighted.append((est.scale - SCALE) / est.scale_std)
        z_plain.append((plain.scale - SCALE) / est.scale_std)
    assert np.all(np.abs(z_weighted) < 2) and abs(np.mean(z_weighted)) < 0.6, z_weighted
    assert np.mean(z_plain) < -1.2, z_plain                     # what the plain residuals gave


def test_a_drifting_scale_is_found_and_its_std_covers_the_drift():
    """b's scale drifts 0.2 %/s for 40 s (monocular odometry): the halves of the recording fit scales many of
    their σ apart, which is a warning, and the std covers the scale at the middle of the recording and at
    either end (without the halves' term it was 4 times smaller)."""
    X = random_transform(np.random.default_rng(3), 0.3)
    a, b = simulate_rig(Rig(X, 0), duration_s=40, rate_a=30, rate_b=30, sigma_r=np.deg2rad(0.1), sigma_t=0.001,
                        seed=3)
    cal = calibrate(a, monocular(b, SCALE, drift_per_s=0.002), scale="auto", time_offset=0.0)
    block = cal.diagnostics["scale"]
    first, second = block["drift"]["halves"]
    assert first > SCALE / 1.04 > second                     # metres per unit fall as the units shrink
    assert block["drift"]["drift_std"] > 2 * np.hypot(*block["drift"]["halves_std"])
    assert block["std"] > block["drift"]["drift_std"]
    assert sum("scale of stream b drifts" in w for w in cal.warnings) == 1
    for t in (0.0, 20.0, 40.0):                              # start, middle, end of the recording
        assert abs(block["value"] - SCALE / (1 + 0.002 * t)) < 2 * block["std"], t


def test_no_translation_cannot_determine_a_scale():
    rng = np.random.default_rng(1)
    X = random_transform(rng, 0.3)
    A, B = motion_pairs(20, X, rng)
    B = B.copy()
    B[:, :3, 3] = 0.0
    with pytest.raises(DataError, match="does not translate"):
        solve_with_scale(A, B)


@pytest.fixture(scope="module")
def mono_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("mono")
    X = se3.from_xyz_quat(np.array([0.12, -0.05, 0.08]), np.array([0.1, -0.2, 0.3, 0.93]))
    a, b = simulate_rig(Rig(X, 0), duration_s=60, rate_a=30, rate_b=30, sigma_r=np.deg2rad(0.1), sigma_t=0.001,
                        seed=7)
    return X, write_tum(d / "a.tum", a), write_tum(d / "mono.tum", monocular(b, SCALE))


def test_cli_scale_auto_recovers_the_scale(capsys, mono_files):
    X, fa, fb = mono_files
    code, out, err = run(capsys, "calibrate", fa, fb, "--scale", "auto", "-q")
    assert code == 0, err
    doc = yaml.safe_load(out)
    assert abs(doc["scale"]["value"] / SCALE - 1) < 1e-3 and 0 < doc["scale"]["std"] < 1e-3 * SCALE
    rot, trans = pose_error(np.array(doc["matrix"]), X)
    assert rot < 0.05 and trans < 0.003
    assert doc["scale"]["drift"]["drift_std"] == 0 and not any("drifts" in w for w in doc["warnings"])
    code, out, err = run(capsys, "calibrate", fa, fb, "-q")         # by default the fit finds the other units
    assert code == 0, err
    doc = yaml.safe_load(out)
    assert doc["interpretation"]["scale"]["applied"] and "--scale" in doc["warnings"][0]
    assert abs(doc["scale"]["value"] / SCALE - 1) < 1e-3
    assert pose_error(np.array(doc["matrix"]), X)[1] < 0.003


def test_fit_test_reads_b_noise_in_metres_with_scale_auto(capsys, mono_files):
    """With ``--scale auto`` the fit test judges b's samples in metres, so b's jitter is read in metres too:
    the same σ as with the scale given as a number (it was read in b's own units, 1/0.37 too large)."""
    _, fa, fb = mono_files
    sigmas = []
    for scale in ("auto", str(SCALE)):
        code, out, err = run(capsys, "calibrate", fa, fb, "--scale", scale, "-q")
        assert code == 0, err
        sigmas.append(yaml.safe_load(out)["fit_test"]["noise"]["b"]["sigma_translation_m"])
    assert sigmas[0] == pytest.approx(sigmas[1], rel=0.01)


def test_cli_fixed_scale_number(capsys, mono_files):
    X, fa, fb = mono_files
    code, out, err = run(capsys, "calibrate", fa, fb, "--scale", str(SCALE), "-q")
    assert code == 0, err
    assert pose_error(np.array(yaml.safe_load(out)["matrix"]), X)[1] < 0.003


def test_cli_scale_auto_refuses_data_without_translation(capsys, tmp_path):
    t = np.arange(300) / 30.0
    rot = np.c_[0.6 * np.sin(0.7 * t), 0.5 * np.sin(1.1 * t + 1), 0.8 * np.sin(0.5 * t + 2)]
    T_a = np.tile(np.eye(4), (300, 1, 1))
    T_a[:, :3, :3] = se3.from_xyz_quat(np.zeros((300, 3)),
                                       np.roll(np.c_[np.ones(300), 0.5 * rot], -1, axis=1))[:, :3, :3]
    stamps = 1_700_000_000_000_000_000 + np.round(t * 1e9).astype(np.int64)
    a = PoseStream.from_matrices(stamps, T_a)
    b = PoseStream.from_matrices(stamps, T_a)              # X = identity: b rotates in place, never translates
    fa, fb = write_tum(tmp_path / "a.tum", a), write_tum(tmp_path / "b.tum", b)
    code, out, err = run(capsys, "calibrate", fa, fb, "--scale", "auto", "-q")
    assert code == 2 and not out and "scale of stream b cannot be determined" in err and "--scale" in err
