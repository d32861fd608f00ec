"""The command line as a new user meets it: options from files and flags, outputs, writes that fail."""
from __future__ import annotations

import json
import os
import stat

import numpy as np
import pytest
import yaml
from _util import ROOT, pose_error, run

import handeye_cli
from handeye_cli.errors import ConfigError


def _doc(out: str) -> dict:
    return yaml.safe_load(out)


@pytest.mark.parametrize("text", ["max_jump: off\nmax_jump_deg: off\n", "max_jump: false\nmax_jump_deg: null\n"])
def test_off_in_a_config_file_switches_the_gate_off_as_on_the_command_line(capsys, rig, tmp_path, text):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(text)
    code, out, err = run(capsys, "calibrate", rig["a"], rig["b"], "--config", cfg, "-q")
    assert code == 0, err
    doc = _doc(out)
    assert doc["samples"]["dropped_pose_jump"] == 0 and doc["samples"]["synced_kept"] > 1000
    assert doc["settings"]["options"]["max_jump"] is None and doc["settings"]["config_file"] == str(cfg)


@pytest.mark.parametrize("text, message", [
    ("max_dt: fast\n", "c.yaml: max_dt): give a number of seconds > 0"),
    ("bootstrap: lots\n", "bootstrap): give a whole number"),
    ("max_jump: true\n", "max_jump"),
    ("gates:\n  max_translation: off\n", "grouped key 'gates'"),
    ("max_translation: 0.2\n", "it is now max_jump"),
    ("alpah: 2\n", "did you mean alpha"),
    ("name_a: &a [*a, *a]\n", "aliases"),
    ("- 1\n- 2\n", "must hold a mapping"),
    ("method: [unclosed\n", "c.yaml:2"),
])
def test_bad_config_values_are_one_line_exit_2(capsys, rig, tmp_path, text, message):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(text)
    code, out, err = run(capsys, "calibrate", rig["a"], rig["b"], "--config", cfg)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1 and out == "", err
    assert message in err, err


def test_billion_laughs_is_refused_quickly(capsys, rig, tmp_path):
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, 10)]
    cfg = tmp_path / "laughs.yaml"
    cfg.write_text("\n".join(lines) + "\nname_a: *a9\n")
    code, _, err = run(capsys, "calibrate", rig["a"], rig["b"], "--config", cfg)
    assert code == 2 and "aliases" in err


@pytest.mark.parametrize("flag, value, message", [
    ("--time-offset", "nan", "give a finite number"),
    ("--max-dt", "-1", "> 0"),
    ("--max-jump", "fast", "or 'off'"),
    ("--prior-weights", "1", "two non-negative numbers"),
    ("--name-a", "my frame", "bad frame name"),
    ("--pairs", "stride:0", "bad pair strategy"),
])
def test_bad_flags_are_one_line_exit_2(capsys, rig, flag, value, message):
    code, out, err = run(capsys, "calibrate", rig["a"], rig["b"], flag, value)
    assert code == 2 and err.count("\n") == 1 and message in err and out == "", err


def test_preset_is_installed_with_the_package_and_flags_override_it(capsys, rig, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)                                   # not the repository: package data only
    code, out, err = run(capsys, "calibrate", rig["a"], rig["b"], "--preset", "robot-arm", "--max-pairs", "300", "-q")
    assert code == 0, err
    settings = _doc(out)["settings"]
    assert settings["preset"] == "robot-arm" and settings["options"]["pairs"] == "all"
    assert settings["options"]["max_jump"] is None and settings["options"]["max_pairs"] == 300


def test_settings_record_what_produced_the_result(capsys, rig, tmp_path):
    prior = tmp_path / "prior.yaml"
    prior.write_text(yaml.safe_dump({"translation": [0.2, -0.2, 0.05], "quaternion_xyzw": [0.2, 0.4, -0.1, 0.85]}))
    _, plain, _ = run(capsys, "calibrate", rig["a"], rig["b"], "-q")
    _, with_prior, _ = run(capsys, "calibrate", rig["a"], rig["b"], "--prior", prior, "--prior-weights", "2,3", "-q")
    a, b = _doc(plain)["settings"]["options"], _doc(with_prior)["settings"]["options"]
    assert a["prior"] is None and b["prior"] == str(prior) and b["prior_weights"] == [2.0, 3.0]
    assert set(a) == set(handeye_cli.Options().flat())


def test_dash_output_is_stdout_and_report_dash_is_stdout(capsys, rig, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, "calibrate", rig["a"], rig["b"], "-o", "-", "-q")
    assert code == 0 and "matrix:" in out and not (tmp_path / "-").exists()
    code, out, _ = run(capsys, "calibrate", rig["a"], rig["b"], "-o", "r.json", "--report", "-", "-q")
    assert code == 0 and out.startswith("<!DOCTYPE html>") and not (tmp_path / "-").exists()
    assert json.loads((tmp_path / "r.json").read_text())["method"] == "dqopt"


@pytest.mark.parametrize("name, message", [("r.xml", "cannot tell the output format"), ("noext", "--format")])
def test_unknown_output_extension_is_refused_before_computing(capsys, rig, tmp_path, name, message):
    code, out, err = run(capsys, "calibrate", rig["a"], rig["b"], "-o", tmp_path / name)
    assert code == 2 and message in err and not (tmp_path / name).exists()


def test_format_flag_wins_over_the_extension(capsys, rig, tmp_path):
    code, _, err = run(capsys, "calibrate", rig["a"], rig["b"], "-o", tmp_path / "r.txt", "--format", "json", "-q")
    assert code == 0, err
    assert json.loads((tmp_path / "r.txt").read_text())["method"] == "dqopt"


def test_fifo_and_devices_are_written_through_not_replaced(capsys, rig, tmp_path):
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    reader = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)             # a reader keeps the FIFO open
    try:
        code, _, err = run(capsys, "calibrate", rig["a"], rig["b"], "-o", fifo, "-q")
        data = os.read(reader, 1 << 20)
    finally:
        os.close(reader)
    assert code == 0, err
    assert stat.S_ISFIFO(os.stat(fifo).st_mode) and b"matrix:" in data
    code, _, err = run(capsys, "calibrate", rig["a"], rig["b"], "-o", "/dev/null", "--format", "yaml", "-q")
    assert code == 0 and stat.S_ISCHR(os.stat("/dev/null").st_mode), err
    code, _, err = run(capsys, "calibrate", rig["a"], rig["b"], "-o", "/dev/null", "-q")    # a device: YAML
    assert code == 0 and stat.S_ISCHR(os.stat("/dev/null").st_mode), err


@pytest.mark.parametrize("where, message", [("file/r.yaml", "not a folder"), ("dir", "is a folder"),
                                            ("missing/r.yaml", "does not exist")])
def test_unwritable_outputs_are_one_line_exit_2(capsys, rig, tmp_path, where, message):
    (tmp_path / "file").write_text("x")
    (tmp_path / "dir").mkdir()
    code, out, err = run(capsys, "calibrate", rig["a"], rig["b"], "-o", tmp_path / where)
    assert code == 2 and message in err and err.count("\n") == 1, err


@pytest.mark.parametrize("path", ["/sys/handeye-r.yaml", "/proc/handeye-r.yaml"])
def test_a_folder_that_refuses_writes_is_one_line_exit_2(capsys, rig, path):
    """Even root cannot create files in /sys or /proc: the OSError becomes one line, not a traceback."""
    code, out, err = run(capsys, "calibrate", rig["a"], rig["b"], "-o", path, "-q")
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1 and path in err, err
    assert not os.path.exists(path)


def test_a_failed_report_keeps_the_result(capsys, rig, tmp_path, monkeypatch):
    from handeye_cli.errors import WriteError
    from handeye_cli.output import report

    def broken(path, calibration):
        raise WriteError("cannot write (Read-only file system)", str(path), "choose another --report path")

    monkeypatch.setattr(report, "write_report", broken)
    out_file = tmp_path / "ok.yaml"
    code, _, err = run(capsys, "calibrate", rig["a"], rig["b"], "-o", out_file, "--report", tmp_path / "r.html", "-q")
    assert code == 2 and "the result was written, but not the report" in err
    assert _doc(out_file.read_text())["method"] == "dqopt"


def test_frame_names_are_valid_tf2_ids(capsys, rig):
    code, out, err = run(capsys, "calibrate", rig["a"], rig["b"], "--name-a", "/base_link", "--name-b", "cam/optical",
                         "-q")
    assert code == 0, err
    doc = _doc(out)
    assert doc["frames"] == {"a": "base_link", "b": "cam/optical"}
    assert "--frame-id base_link --child-frame-id cam/optical" in doc["ros2_static_transform"]


def test_python_api_takes_paths_and_keyword_options(rig):
    cal = handeye_cli.calibrate_files(str(rig["a"]), rig["b"], method="dq2steps", gate="paper", max_jump="off",
                                      pairs="stride:10")
    assert cal.options.solver.method == "dq2steps" and cal.options.gates.max_jump is None
    rot, trans = pose_error(cal.matrix, rig["X"])
    assert rot < 0.2 and trans < 0.01
    same = handeye_cli.calibrate_files(*rig["streams"], method="dq2steps", gate="paper", max_jump="off",
                                       pairs="stride:10")
    np.testing.assert_allclose(same.matrix, cal.matrix, atol=1e-6)
    with pytest.raises(ConfigError, match="did you mean max_jump"):
        handeye_cli.calibrate_files(rig["a"], rig["b"], max_jmp=0.2)


def test_readme_python_example_runs(monkeypatch):
    monkeypatch.chdir(ROOT)
    cal = handeye_cli.calibrate_files("sample_data/rig_a.tum", "sample_data/rig_b.tum", method="dqopt")
    truth = yaml.safe_load((ROOT / "sample_data" / "truth.yaml").read_text())
    assert pose_error(cal.matrix, np.array(truth["matrix"]))[1] < 0.001


def test_calibrate_against_a_nominal_exits_1_on_drift_and_0_within_tolerance(capsys, rig, tmp_path):
    truth = yaml.safe_dump({"translation": rig["X"][:3, 3].tolist(),
                            "quaternion_xyzw": handeye_cli.geometry.se3.to_xyz_quat(rig["X"])[1].tolist()})
    (tmp_path / "nominal.yaml").write_text(truth)
    code, out, err = run(capsys, "calibrate", rig["a"], rig["b"], "--against", tmp_path / "nominal.yaml",
                         "--max-rotation-deg", "1", "--max-translation-m", "0.01")
    assert code == 0 and _doc(out)["verdict"]["drift"] is False and "within tolerance" in err, err
    moved = rig["X"].copy()
    moved[0, 3] += 0.05
    (tmp_path / "moved.yaml").write_text(yaml.safe_dump({"matrix": moved.tolist()}))
    code, out, err = run(capsys, "calibrate", rig["a"], rig["b"], "--against", tmp_path / "moved.yaml", "-q")
    assert code == 1 and _doc(out)["verdict"]["drift"] is True and "DRIFT" in err


def test_format_from_the_output_name_round_trips_as_a_nominal(capsys, rig, tmp_path):
    from handeye_cli.io.nominal import read_nominal

    for name in ("x.urdf", "x.launch", "x.launch.py", "x.sh"):
        code, _, err = run(capsys, "calibrate", rig["a"], rig["b"], "-o", tmp_path / name, "--name-a", "a",
                           "--name-b", "b", "-q")
        assert code == 0, err
        T = read_nominal(str(tmp_path / name)).transform("a", "b")
        code, out, _ = run(capsys, "calibrate", rig["a"], rig["b"], "-q")
        np.testing.assert_allclose(T, np.array(_doc(out)["matrix"]), atol=1e-9)
