"""Degeneracy detection (handeye_cli.analysis.observability) on motions whose blind spots are known."""
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from _logs import write_tum
from _util import run
from scipy.spatial.transform import Rotation

from handeye_cli._typing import FloatArray
from handeye_cli.analysis import assess_observability, describe_direction
from handeye_cli.calibration import calibrate
from handeye_cli.errors import UnderdeterminedError, as_flags
from handeye_cli.geometry import se3
from handeye_cli.simulation import motion_pairs, random_transform
from handeye_cli.solvers import Prior
from handeye_cli.streams import PoseStream

Z = np.array([0.0, 0.0, 1.0])
X_AXIS = np.array([1.0, 0.0, 0.0])


def _truth(seed):
    rng = np.random.default_rng(seed)
    return rng, random_transform(rng)


def _about(report, code, kind, direction, cos=0.999):
    """The warning with this code whose direction_a is parallel to ``direction`` (fails if none)."""
    hits = [w for w in report.warnings if w.code == code and w.kind == kind
            and abs(np.dot(w.direction_a, direction)) > cos]
    assert hits, [str(w) for w in report.warnings]
    return hits[0]


def test_general_motion_has_no_warnings():
    rng, X = _truth(0)
    A, B = motion_pairs(100, X, rng, "random", np.deg2rad(0.57), 0.01)
    report = assess_observability(A, B)
    assert report.ok and report.codes == []
    assert report.axis_spread_deg > 20 and report.covariance.rotation_rms_deg < 0.2


@pytest.mark.parametrize("noise", [(0.0, 0.0), (np.deg2rad(0.57), 0.01)])
def test_planar_motion_names_translation_along_the_normal(noise):
    rng, X = _truth(1)
    A, B = motion_pairs(300, X, rng, "planar", *noise)
    report = assess_observability(A, B)
    w = _about(report, "planar", "translation", Z)
    assert "translation along the common rotation axis (z of frame a) is unobservable" in w.message
    assert re.search(r"all \d+ motions that rotate \(of 300\) rotate about one axis .*\(spread 0\.\d\d°\)", w.message)
    assert "--prior" in as_flags(w.remedy) and "another axis" in w.remedy
    np.testing.assert_allclose(np.abs(np.dot(w.direction_b, X[:3, :3].T @ Z)), 1.0, atol=1e-3)   # in frame b
    assert not report.ok and "fixed_rotation_line" not in report.codes       # random in-plane paths fix the yaw


def _turntable(n, X, rng, lever):
    """Rotations about z through the fixed point ``lever`` of frame a: t_A = (I - R_A) p."""
    A = np.tile(np.eye(4), (n, 1, 1))
    A[:, :3, :3] = Rotation.from_rotvec(np.c_[np.zeros((n, 2)), rng.uniform(0.2, 1.5, n)]).as_matrix()
    A[:, :3, 3] = (np.eye(3) - A[:, :3, :3]) @ lever
    return A, se3.inverse(X) @ A @ X


def test_rotation_about_one_fixed_line_also_hides_the_yaw():
    rng, X = _truth(2)
    A, B = _turntable(50, X, rng, np.array([0.4, -0.3, 0.2]))
    report = assess_observability(A, B)
    _about(report, "planar", "translation", Z)
    w = _about(report, "fixed_rotation_line", "rotation", Z)
    assert "rotation of the extrinsic about the common rotation axis (z of frame a) is unobservable" in w.message


def test_screw_motion_about_one_axis_is_single_axis():
    rng, X = _truth(3)
    A, B = _turntable(40, X, rng, np.array([0.5, 0.0, 0.0]))
    A[:, 2, 3] = rng.uniform(0.2, 0.5, 40)                      # also move along the axis
    B = se3.inverse(X) @ A @ X
    report = assess_observability(A, B)
    _about(report, "single_axis", "translation", Z)


def test_pure_translation_along_a_line():
    rng, X = _truth(4)
    A = np.tile(np.eye(4), (30, 1, 1))
    A[:, 0, 3] = rng.uniform(0.1, 1.0, 30)
    B = se3.inverse(X) @ A @ X
    report = assess_observability(A, B)
    assert report.codes.count("pure_translation") == 2 and report.rotating_pairs == 0
    assert "unobservable along all axes" in report.warnings[0].message
    w = _about(report, "pure_translation", "rotation", X_AXIS)
    assert "travel direction (x of frame a)" in w.message


def test_noisy_circle_is_flagged_as_ill_conditioned():
    rng, X = _truth(5)
    A, B = motion_pairs(100, X, rng, "circle", np.deg2rad(0.57), 0.01)
    report = assess_observability(A, B)
    _about(report, "ill_conditioned", "rotation", Z, cos=0.98)       # yaw about the circle's axis
    weak_t = [w for w in report.warnings if w.code == "ill_conditioned" and w.kind == "translation"]
    assert weak_t and all("predicted standard deviation" in w.message for w in weak_t)
    assert report.covariance.translation_std_m[2] > 0.05             # along the axis (z of frame a)


def test_small_rotations_and_too_few_pairs():
    rng, X = _truth(6)
    A, B = motion_pairs(100, X, rng, "line", np.deg2rad(0.57), 0.01)
    assert "small_rotations" in assess_observability(A, B).codes
    A, B = motion_pairs(6, X, rng, "random", np.deg2rad(0.57), 0.01)
    report = assess_observability(A, B)
    assert report.codes[0] == "too_few_pairs" and "only 6 motion pairs" in report.warnings[0].message


def test_with_a_prior_the_remedy_says_the_prior_decides():
    rng, X = _truth(7)
    A, B = motion_pairs(100, X, rng, "planar", np.deg2rad(0.57), 0.01)
    report = assess_observability(A, B, prior=Prior(X, 1.0, 1.0))
    assert "planar" in report.codes and all("--prior FILE" not in w.remedy for w in report.warnings)
    assert "given prior" in report.warnings[0].remedy
    d = report.as_dict()
    assert d["warnings"][0]["code"] == "planar" and len(d["warnings"][0]["direction_a"]) == 3


def test_describe_direction():
    assert describe_direction(np.array([0.01, -0.02, -1.0]), "a") == "z of frame a"
    assert describe_direction(np.array([1.0, 1.0, 0.0]), "b") == "direction [0.71, 0.71, 0.00] of frame b"


def _arm_about_one_joint(seed: int = 0, noise_deg: float = 0.01) -> tuple[PoseStream, PoseStream, FloatArray,
                                                                          FloatArray]:
    """A flange turned about one oblique joint axis ``n`` while it moves across it (10 Hz, 60 s), and a
    camera ``T_flange_cam`` on it, both seen from fixed worlds, with 0.2 mm / ``noise_deg`` noise."""
    rng = np.random.default_rng(seed)
    n = np.array([1.0, 1.0, 2.0]) / np.sqrt(6.0)
    X = se3.from_xyz_quat(np.array([0.04, -0.05, 0.07]), Rotation.from_rotvec([0.3, -0.2, 2.5]).as_quat())
    t = np.arange(600) / 10.0
    angle = 1.0 * np.sin(0.21 * t) + 0.4 * np.sin(0.53 * t)
    across = np.cross(n, [1.0, 0.0, 0.0])
    across /= np.linalg.norm(across)
    move = 0.3 * np.sin(0.17 * t)[:, None] * across + 0.2 * np.cos(0.29 * t)[:, None] * np.cross(n, across)
    P = np.tile(np.eye(4), (len(t), 1, 1))
    P[:, :3, :3] = Rotation.from_rotvec(angle[:, None] * n).as_matrix()
    P[:, :3, 3] = move
    Q = P @ X

    def stream(T: FloatArray, name: str) -> PoseStream:
        T = T @ se3.from_xyz_quat(rng.normal(0, 2e-4, (len(t), 3)),
                                  Rotation.from_rotvec(rng.normal(0, np.deg2rad(noise_deg), (len(t), 3))).as_quat())
        return PoseStream((t * 1e9).astype(np.int64), T[:, :3, 3], Rotation.from_matrix(T[:, :3, :3]).as_quat(),
                          "world", name)
    return stream(P, "flange"), stream(Q, "cam"), X, n


def test_one_oblique_axis_is_refused_without_a_prior_and_takes_only_that_direction_from_one(tmp_path, capsys):
    """An arm turned about one joint leaves the translation along it open, in every coordinate of the result
    (the axis is oblique): without a nominal that is refused naming the direction and --prior; with one, only
    the translation along the axis is the nominal's (kinhec's motion-000002: 30 mm along it from a nominal
    6 cm off, 0.6 mm across, where the full solve is 212 mm off)."""
    a, b, X, n = _arm_about_one_joint()
    with pytest.raises(UnderdeterminedError, match=r"translation along the common rotation axis .* is not "
                       r"determined by the motion.*prior=FILE"):
        calibrate(a, b)
    code, out, err = run(capsys, "calibrate", write_tum(tmp_path / "a.tum", a), write_tum(tmp_path / "b.tum", b),
                         "-o", tmp_path / "r.yaml")
    assert code == 2 and err.count("\n") == 1 and "is not determined by the motion" in err, err
    assert not (tmp_path / "r.yaml").exists()
    N = X.copy()
    N[:3, 3] += 0.05 * n + 0.02 * np.cross(n, [0.0, 0.0, 1.0])         # 5 cm along the axis, 2 cm across
    N[:3, :3] = Rotation.from_rotvec(np.deg2rad([0.0, 1.0, 0.0])).as_matrix() @ N[:3, :3]
    prior = tmp_path / "nominal.yaml"
    prior.write_text(yaml.safe_dump({"matrix": N.tolist(), "frames": {"a": "flange", "b": "cam"}}))
    c = calibrate(a, b, prior=str(prior))
    d = c.matrix[:3, 3] - X[:3, 3]
    assert d @ n == pytest.approx((N[:3, 3] - X[:3, 3]) @ n, abs=1e-5)     # along (estimated axis): the nominal's
    assert np.linalg.norm(d - (d @ n) * n) < 1e-3                                   # across: the data's
    assert np.rad2deg(np.linalg.norm(Rotation.from_matrix(X[:3, :3].T @ c.matrix[:3, :3]).as_rotvec())) < 0.05
    dofs = c.diagnostics["degrees_of_freedom"]
    assert [dofs[k]["status"] for k in ("x", "y", "z")] == ["from_prior"] * 3
    assert all(dofs[k]["status"] == "estimated" and dofs[k]["std"] < 0.02 for k in ("roll", "pitch", "yaw"))


def _nominal(path: Path, T: FloatArray) -> str:
    path.write_text(yaml.safe_dump({"matrix": T.tolist(), "frames": {"a": "flange", "b": "cam"}}))
    return str(path)


def test_one_axis_paired_sample_by_sample_is_still_one_axis(tmp_path):
    """Consecutive samples of an arm turned about one joint rotate by about a degree, and 0.2° of noise tilts each
    one's axis: they spread 7–14° about the joint, beyond the 2° that marks one axis, though the motion determines
    no more than before. The spread is judged against the rotation residuals (the noise): the translation along
    the joint is refused, as on pairs further apart. It was left unnamed, 45 mm off, with exit 0."""
    a, b, X, n = _arm_about_one_joint(noise_deg=0.2)
    with pytest.raises(UnderdeterminedError, match=r"translation along the common rotation axis"):
        calibrate(a, b, pairs="consecutive")
    c = calibrate(a, b, pairs="consecutive", prior=_nominal(tmp_path / "n.yaml", X))
    obs = c.diagnostics["observability"]
    assert obs["axis_spread_deg"] > 2.0 and "single_axis" in [w["code"] for w in obs["warnings"]]
    assert abs(np.dot(obs["axis_a"], n)) > 0.99


def _barely_rotating(seed: int = 0) -> tuple[PoseStream, PoseStream, FloatArray]:
    """A rig that translates in 3-D and turns by at most 0.15° between its 10 Hz samples (60 s); 0.2 mm / 0.01°
    noise."""
    rng = np.random.default_rng(seed)
    X = se3.from_xyz_quat(np.array([0.04, -0.05, 0.07]), Rotation.from_rotvec([0.3, -0.2, 2.5]).as_quat())
    t = np.arange(600) / 10.0
    P = np.tile(np.eye(4), (len(t), 1, 1))
    P[:, :3, :3] = Rotation.from_rotvec(0.05 * np.c_[np.sin(0.5 * t), np.sin(0.4 * t + 1), np.sin(0.3 * t + 2)]
                                        ).as_matrix()
    P[:, :3, 3] = np.c_[0.3 * np.sin(0.17 * t), 0.2 * np.cos(0.29 * t), 0.25 * np.sin(0.23 * t + 1)]

    def stream(T: FloatArray, name: str) -> PoseStream:
        T = T @ se3.from_xyz_quat(rng.normal(0, 2e-4, (len(t), 3)),
                                  Rotation.from_rotvec(rng.normal(0, np.deg2rad(0.01), (len(t), 3))).as_quat())
        return PoseStream((t * 1e9).astype(np.int64), T[:, :3, 3], Rotation.from_matrix(T[:, :3, :3]).as_quat(),
                          "world", name)
    return stream(P, "flange"), stream(P @ X, "cam"), X


def test_motions_that_do_not_rotate_are_refused_unless_a_prior_fixes_the_translation(tmp_path, capsys):
    """No pair rotates (1° is the least that counts): the translation is open along every axis. That was a warning
    and exit 0 (kinhec's motion-000004 paired sample by sample: 0.73 m, σ 14° about y); now it is refused in one
    line, exit 2, naming --prior, and no result file is left (--accept-poor-fit keeps it, exit 3). A prior
    determines it: then the result leaves."""
    a, b, X = _barely_rotating()
    with pytest.raises(UnderdeterminedError, match="translation of the extrinsic is not determined by the motion"):
        calibrate(a, b, pairs="consecutive")
    fa, fb = write_tum(tmp_path / "a.tum", a), write_tum(tmp_path / "b.tum", b)
    code, out, err = run(capsys, "calibrate", fa, fb, "--pairs", "consecutive", "-o", tmp_path / "r.yaml")
    assert code == 2 and err.count("\n") == 1 and "none of the" in err and "--prior FILE" in err, err
    assert not (tmp_path / "r.yaml").exists()
    code, out, err = run(capsys, "calibrate", fa, fb, "--pairs", "consecutive", "--accept-poor-fit", "-q")
    assert code == 3 and "poor fit accepted with --accept-poor-fit: translation of the extrinsic" in out + err
    assert err.count("unobservable along all axes") == 1                              # said once, as accepted
    c = calibrate(a, b, pairs="consecutive", prior=_nominal(tmp_path / "n.yaml", X))
    assert "pure_translation" in [w["code"] for w in c.diagnostics["observability"]["warnings"]]
    assert np.abs(c.matrix[:3, 3] - X[:3, 3]).max() < 0.01
