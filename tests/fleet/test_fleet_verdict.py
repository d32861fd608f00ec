"""Drift verdicts: angle and distance to the nominal, tolerances, bootstrap significance, and
``handeye check`` end to end (exit 0 within tolerance, 1 drift, 2 bad input)."""
from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from _logs import write_tum
from _util import run
from scipy.spatial.transform import Rotation

from handeye_cli.analysis.verdict import compare, intervals_of
from handeye_cli.geometry import se3
from handeye_cli.output.formats import render_format
from handeye_cli.simulation import Rig, simulate_rig

X = se3.from_xyz_quat(np.array([0.2, 0.05, -0.1]), Rotation.from_euler("xyz", [10, 20, 30], degrees=True).as_quat())


def _moved(T: np.ndarray, degrees: float, metres: float) -> np.ndarray:
    D = se3.from_xyz_quat(np.array([metres, 0, 0]), Rotation.from_rotvec([0, 0, np.deg2rad(degrees)]).as_quat())
    return D @ T


def test_angle_distance_and_tolerances():
    v = compare(_moved(X, 1.0, 0.003), X, 0.5, 0.005)
    assert v.rotation_deg == pytest.approx(1.0, abs=1e-9)
    assert v.translation_m == pytest.approx(np.linalg.norm(_moved(X, 1.0, 0.003)[:3, 3] - X[:3, 3]), abs=1e-12)
    assert v.rotation_out and not v.translation_out and v.drift
    assert v.rotation_significant is None and "rotation_significant" not in v.as_dict()
    ok = compare(_moved(X, 0.2, 0.001), X, 0.5, 0.005)
    assert not ok.drift and ok.as_dict()["drift"] is False and "within tolerance" in ok.summary()
    assert np.allclose(ok.nominal["translation"], X[:3, 3])


def test_significance_from_the_bootstrap_interval():
    result = _moved(X, 1.0, 0.0)                                   # 1° beyond a 0.5° tolerance
    d = Rotation.from_matrix(X[:3, :3] @ result[:3, :3].T).as_rotvec(degrees=True)   # δθ of the nominal: −1° about z
    t = result[:3, 3]
    wide = {"rotation_interval_deg": [[-2, -2, -2], [2, 2, 2]], "translation_interval_m": [t - 0.01, t + 0.01]}
    narrow = {"rotation_interval_deg": [[-0.1] * 3, [0.1] * 3], "translation_interval_m": [t - 0.01, t + 0.01]}
    assert d[2] == pytest.approx(-1.0, abs=1e-9)
    not_significant = compare(result, X, 0.5, 0.005, intervals=intervals_of(wide))
    assert not_significant.rotation_out and not not_significant.rotation_significant and not not_significant.drift
    assert "not significant" in not_significant.summary()
    significant = compare(result, X, 0.5, 0.005, intervals=intervals_of(narrow))
    assert significant.rotation_significant and not significant.translation_significant and significant.drift
    assert significant.as_dict()["rotation_significant"] is True and significant.as_dict()["significant"] is True
    assert not_significant.as_dict()["significant"] is False


@pytest.fixture(scope="module")
def result_file(tmp_path_factory):
    """A real result with a bootstrap interval, from two TUM files of a rig with extrinsic X."""
    d = tmp_path_factory.mktemp("check")
    a, b = simulate_rig(Rig(X), duration_s=15, sigma_r=1e-3, sigma_t=5e-4, seed=4)
    code = None
    with pytest.raises(SystemExit) as info:
        from handeye_cli.cli import main
        main(["calibrate", str(write_tum(d / "a.tum", a)), str(write_tum(d / "b.tum", b)), "--bootstrap", "200",
              "--name-a", "cam", "--name-b", "imu", "-q", "-o", str(d / "result.yaml")])
    code = info.value.code
    assert code == 0
    return d / "result.yaml"


def test_check_exit_codes_against_urdf_and_command_line(result_file, capsys, tmp_path):
    (tmp_path / "nominal.urdf").write_text(render_format({"matrix": X.tolist(), "frames": {"a": "cam", "b": "imu"}},
                                                         "urdf"))
    code, out, _ = run(capsys, "check", result_file, "--against", tmp_path / "nominal.urdf")
    assert code == 0 and out.startswith("within tolerance")
    moved = _moved(X, 1.0, 0.01)
    line = render_format({"matrix": moved.tolist(), "frames": {"a": "cam", "b": "imu"}}, "tf-static").splitlines()[1]
    code, out, _ = run(capsys, "check", result_file, "--against", line, "--format", "json")
    verdict = json.loads(out)
    assert code == 1 and verdict["drift"] and verdict["rotation_significant"] and verdict["translation_significant"]
    assert verdict["rotation_deg"] == pytest.approx(1.0, abs=0.05) and verdict["nominal"]["kind"] == "tf-static"
    code, out, _ = run(capsys, "check", result_file, "--against", line, "--max-rotation-deg", "2",
                       "--max-translation-m", "0.02", "--format", "yaml")
    assert code == 0 and yaml.safe_load(out)["drift"] is False


def test_check_refuses_what_is_not_a_result(capsys, tmp_path):
    (tmp_path / "n.urdf").write_text(render_format({"matrix": X.tolist(), "frames": {"a": "a", "b": "b"}}, "urdf"))
    (tmp_path / "r.yaml").write_text("translation: [0, 0, 0]\n")
    for args in (["check", tmp_path / "r.yaml", "--against", tmp_path / "n.urdf"],
                 ["check", tmp_path / "n.urdf", "--against", tmp_path / "n.urdf"],
                 ["check", tmp_path / "missing.yaml", "--against", tmp_path / "n.urdf"],
                 ["check", tmp_path / "r.yaml"]):
        code, out, err = run(capsys, *args)
        assert code == 2 and out == "" and err.startswith("error: ") and len(err.strip().splitlines()) == 1


def test_records_are_strict_json():
    from handeye_cli.fleet.batch import record_line

    line = record_line({"input": "x", "status": "ok", "cost": float("nan"), "r": [1.0, float("inf")], "seconds": 0.1})
    assert json.loads(line) == {"input": "x", "status": "ok", "cost": None, "r": [1.0, None], "seconds": 0.1}
