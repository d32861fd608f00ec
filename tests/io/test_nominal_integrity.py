"""Nominals, results and priors that are not a transform — NaN/inf, aliases, deep nesting, huge
expressions, unbalanced quotes, URDF joints with two parents or in a loop — are refused in one
line (exit 2, never a traceback); and every output format reads back as a nominal (issue 23: a
JSON result too), with or without its file suffix."""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest
from _util import run

from handeye_cli.errors import ReadError
from handeye_cli.geometry import se3
from handeye_cli.io.nominal import read_nominal
from handeye_cli.output.document import render, static_transform_command
from handeye_cli.output.formats import ALL_FORMATS, render_format
from handeye_cli.rig.result import transform_entry
from handeye_cli.simulation import random_transform

IDENTITY = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
RESULT = {"matrix": IDENTITY, "translation": [0, 0, 0], "quaternion_xyzw": [0, 0, 0, 1],
          "frames": {"a": "cam0", "b": "cam1"}}
STP = "ros2 run tf2_ros static_transform_publisher"
FLAGS = "--x 0 --y 0 --z 0 --qx 0 --qy 0 --qz 0 --qw 1 --frame-id cam0 --child-frame-id cam1"


@pytest.fixture
def result(tmp_path) -> Path:
    path = tmp_path / "r.yaml"
    path.write_text(render(RESULT))
    return path


def _one_line_error(capsys, *args) -> str:
    code, out, err = run(capsys, *args)
    assert code == 2 and out == "" and err.count("\n") == 1 and err.startswith("error: "), (code, err)
    assert "Traceback" not in err
    return err


def _urdf(joints: str) -> str:
    return f'<?xml version="1.0"?>\n<robot name="r">{joints}</robot>\n'


def _joint(name: str, parent: str, child: str, xyz: str = "0 0 0", kind: str = "fixed") -> str:
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="0 0 0"/></joint>')


def _launch1(args: str) -> str:
    return f'<launch><node pkg="tf2_ros" type="static_transform_publisher" name="n" args="{args}"/></launch>\n'


def _launch_py(args: str) -> str:
    return ("from launch import LaunchDescription\nfrom launch_ros.actions import Node\n\n\n"
            "def generate_launch_description():\n    return LaunchDescription([Node(package='tf2_ros', "
            f"executable='static_transform_publisher', arguments={args})])\n")


NON_FINITE = {                         # nominal text (or command line), what the message names
    "rpy.cmdline": (None, "static_transform_publisher 0 0 0 nan nan nan cam0 cam1", "x y z yaw pitch roll"),
    "quat.cmdline": (None, "static_transform_publisher 0 0 0 0 0 nan 1 cam0 cam1", "x y z qx qy qz qw"),
    "flag.cmdline": (None, f"{STP} {FLAGS.replace('--x 0', '--x inf')}", "--x"),
    "ros1.launch": ("n.launch", _launch1("0 0 0 nan nan nan cam0 cam1"), "x y z yaw pitch roll"),
    "ros2.launch.py": ("n.launch.py", _launch_py("['inf', '0', '0', '0', '0', '0', 'cam0', 'cam1']"), "x y z yaw"),
    "urdf": ("n.urdf", _urdf(_joint("j", "cam0", "cam1", "inf 0 0")), "origin xyz"),
    "result.yaml": ("n.yaml", render({**RESULT, "matrix": [[float("nan")] * 4] + IDENTITY[1:]}).replace("null", ".nan"),
                    "'matrix'"),
    "result.json": ("n.json", json.dumps({**RESULT, "translation": [float("nan"), 0, 0]}), "'translation'"),
    "inf.json": ("i.json", json.dumps({"translation": [0, float("inf"), 0], "quaternion_xyzw": [0, 0, 0, 1]}),
                 "'translation'"),
}


@pytest.mark.parametrize("case", NON_FINITE)
def test_non_finite_nominals_are_refused_naming_the_file_and_field(case, result, tmp_path, capsys):
    name, text, field = NON_FINITE[case]
    nominal = text
    if name:
        nominal = tmp_path / name
        nominal.write_text(text)
    err = _one_line_error(capsys, "check", result, "--against", nominal)
    assert field in err and (str(nominal) if name else "--against") in err
    assert "finite" in err


def test_non_finite_results_and_priors_are_refused(result, tmp_path, capsys, rig):
    bad = tmp_path / "nan.json"
    bad.write_text(json.dumps({**RESULT, "matrix": [[0, 0, 0, float("nan")]] + IDENTITY[1:]}))
    assert "'matrix'" in _one_line_error(capsys, "check", bad, "--against", result)
    err = _one_line_error(capsys, "calibrate", rig["a"], rig["b"], "--prior", bad, "-o", tmp_path / "x.yaml")
    assert "'matrix'" in err and "--prior" in err and not (tmp_path / "x.yaml").exists()


def test_urdf_joints_with_two_parents_or_in_a_loop_are_refused(result, tmp_path, capsys):
    first = _joint("j1", "cam0", "cam1")
    cases = {"two_parents": _urdf(first + _joint("j2", "base", "cam1", "1 0 0")),
             "moving_second_parent": _urdf(first + _joint("j2", "base", "cam1", kind="revolute")),
             "loop": _urdf(first + _joint("j2", "cam1", "mount") + _joint("j3", "mount", "cam0")),
             "self": _urdf(_joint("j1", "cam0", "cam0") + _joint("j2", "cam0", "cam1"))}
    for name, text in cases.items():
        path = tmp_path / f"{name}.urdf"
        path.write_text(text)
        err = _one_line_error(capsys, "check", result, "--against", path)
        assert ("two transforms" in err) if "parent" in name else ("loop" in err), err
    launch = tmp_path / "two.launch"
    launch.write_text(_launch1("0 0 0 0 0 0 cam0 cam1").replace("</launch>", "")
                      + '<node pkg="tf2_ros" type="static_transform_publisher" name="m" args="1 0 0 0 0 0 base cam1"/>'
                      "</launch>")
    assert "two transforms" in _one_line_error(capsys, "check", result, "--against", launch)


def _laughs() -> str:
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, 9)]
    return "\n".join(lines) + "\nT_cam_imu: *a8\n"


def test_yaml_aliases_and_deep_nesting_are_refused_everywhere(result, tmp_path, capsys, rig):
    laughs, deep, alias = tmp_path / "laughs.yaml", tmp_path / "deep.json", tmp_path / "alias.yaml"
    laughs.write_text(_laughs())
    deep.write_text("[" * 50_000 + "]" * 50_000)
    alias.write_text(render(RESULT).replace("frames:", "extra: &x [1]\nagain: *x\nframes:"))
    start = time.perf_counter()
    assert "aliases" in _one_line_error(capsys, "check", result, "--against", laughs)
    assert "aliases" in _one_line_error(capsys, "check", alias, "--against", result)
    assert "aliases" in _one_line_error(capsys, "check", result, "--against", alias)
    out = ("-o", tmp_path / "x.yaml")
    for args in (("check", result, "--against", deep), ("check", deep, "--against", result),
                 ("calibrate", rig["a"], rig["b"], "--config", deep, *out),
                 ("calibrate", rig["a"], rig["b"], "--prior", deep, *out)):
        assert "nested deeper than 100 levels" in _one_line_error(capsys, *args)
    assert time.perf_counter() - start < 10
    assert not (tmp_path / "x.yaml").exists()


def test_huge_python_and_unbalanced_quotes_are_one_line(result, tmp_path, capsys):
    big = tmp_path / "big.launch.py"
    big.write_text(_launch_py("['0', '0', '0', '0', '0', '0', 'cam0', 'cam1']") + "x = " + "+".join(["1"] * 200_000))
    assert "nested too deeply" in _one_line_error(capsys, "check", result, "--against", big)
    quotes = tmp_path / "q.launch"
    quotes.write_text(_launch1("0 0 0 0 0 0 'cam0 cam1"))
    assert "quotation" in _one_line_error(capsys, "check", result, "--against", quotes)
    assert "quotation" in _one_line_error(capsys, "check", result, "--against",
                                          "static_transform_publisher 0 0 0 0 0 0 'cam0 cam1")
    script = tmp_path / "tf.sh"
    script.write_text(f"{STP} {FLAGS}\n{STP} --x 0 --frame-id 'cam1 --child-frame-id x\n")
    assert f"{script}:2" in _one_line_error(capsys, "check", result, "--against", script)


def test_a_nominal_is_parsed_never_run(result, tmp_path, capsys):
    marker = tmp_path / "ran"
    text = (f"import pathlib\npathlib.Path({str(marker)!r}).touch()\n"
            + _launch_py("['0', '0', '0', '0', '0', '0', 'cam0', 'cam1']"))
    (tmp_path / "n.launch.py").write_text(text)
    code, out, _ = run(capsys, "check", result, "--against", tmp_path / "n.launch.py")
    assert code == 0 and "within tolerance" in out and not marker.exists()


# --- issue 23: every output format is a nominal -----------------------------------------------------
def _document(X: np.ndarray) -> dict:
    """A result as calibrate writes it, ``ros2_static_transform`` line included."""
    t, q = se3.to_xyz_quat(X)
    frames = {"a": "cam0_link", "b": "imu"}
    return {"matrix": X.tolist(), "translation": t.tolist(), "quaternion_xyzw": q.tolist(), "frames": frames,
            "method": "dqopt", "pairs_used": 10, "version": "0.2.0", "warnings": [],
            "ros2_static_transform": static_transform_command(t, q, frames)}


SUFFIX = {"yaml": ".yaml", "json": ".json", "urdf": ".urdf", "urdf-joint": ".urdf", "ros1-launch": ".launch",
          "ros2-launch": ".launch.py",
          "tf-static": ".sh", "kalibr": ".yaml"}


@pytest.mark.parametrize("suffix", [True, False], ids=["suffix", "no-suffix"])
@pytest.mark.parametrize("fmt", ALL_FORMATS)
def test_every_format_reads_back_as_a_nominal(fmt, suffix, tmp_path):
    rng = np.random.default_rng(23)
    for k in range(5):
        X = random_transform(rng, 2.0)
        path = tmp_path / (f"x{k}{SUFFIX[fmt]}" if suffix else f"x{k}")
        path.write_text(render_format(_document(X), fmt))
        nominal = read_nominal(path)
        assert nominal.kind == {"yaml": "result", "json": "result"}.get(fmt, fmt)
        assert np.abs(nominal.transform("cam0_link", "imu") - X).max() < 1e-9


def test_check_a_result_against_its_json_twin(result, tmp_path, capsys, rig):
    out = tmp_path / "r.json"
    code, _, _ = run(capsys, "calibrate", rig["a"], rig["b"], "-o", out, "-q")
    assert code == 0
    doc = json.loads(out.read_text(), parse_constant=lambda c: pytest.fail(f"invalid JSON constant {c}"))
    (tmp_path / "r.yaml").write_text(render(doc))
    code, text, err = run(capsys, "check", tmp_path / "r.yaml", "--against", out)
    assert code == 0 and "rotation 0.000°" in text, err


def test_a_nominal_with_a_hostile_frame_name_is_refused(tmp_path):
    path = tmp_path / "n.sh"
    path.write_text(f"{STP} {FLAGS.replace('cam1', chr(39) + 'cam1; rm -rf x' + chr(39))}\n")
    with pytest.raises(ReadError, match="not a valid frame id"):
        read_nominal(path)


def test_deeply_nested_fleet_records_are_one_line(tmp_path, capsys):
    records = tmp_path / "v.jsonl"
    records.write_text("[" * 50_000 + "]" * 50_000 + "\n")
    assert "nested too deeply" in _one_line_error(capsys, "report", records, "-o", tmp_path / "f.html")
    assert not (tmp_path / "f.html").exists()


@pytest.mark.parametrize("suffix", [True, False], ids=["suffix", "no-suffix"])
@pytest.mark.parametrize("fmt", ALL_FORMATS)
def test_every_format_of_a_rig_result_reads_back_as_a_nominal(fmt, suffix, tmp_path):
    rng = np.random.default_rng(24)
    T = {name: random_transform(rng, 2.0) for name in ("cam0", "lidar")}
    doc = {"reference": "imu", "version": "0.2.0", "transforms": [transform_entry("imu", k, v) for k, v in T.items()]}
    path = tmp_path / ("rig" + SUFFIX[fmt] if suffix else "rig")
    path.write_text(render_format(doc, fmt))
    nominal = read_nominal(path)
    names = {"imu": "imu0", "cam0": "cam0", "lidar": "cam1"} if fmt == "kalibr" else {n: n for n in ("imu", *T)}
    for name, X in T.items():
        assert np.abs(nominal.transform(names["imu"], names[name]) - X).max() < 1e-9
