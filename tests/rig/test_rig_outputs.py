"""``handeye rig`` outputs (URDF, launch files, tf-static lines, Kalibr) and ``--against`` verdicts, through the CLI
on sample_data/rig4.mcap. The rig is calibrated once; later runs reuse that result (the CLI path is the same)."""
from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from _util import ROOT, run

from handeye_cli import rig as rig_module
from handeye_cli.cli import main
from handeye_cli.geometry import se3
from handeye_cli.io.nominal import read_nominal
from handeye_cli.output.formats import render_format
from handeye_cli.rig.verdicts import rig_verdicts

RIG4 = ROOT / "sample_data" / "rig4.mcap"
TRUTH = yaml.safe_load((ROOT / "sample_data" / "rig4_truth.yaml").read_text())
STREAMS = ["--stream", "cam0=/cam0/pose", "--stream", "cam1=/cam1/pose", "--stream", "lidar=/lidar/odom",
           "--stream", "imu=tf:odom,imu_link"]
SENSORS = ["cam1", "lidar", "imu"]
SUFFIX = {"urdf": ".urdf", "ros1-launch": ".launch", "ros2-launch": ".launch.py", "tf-static": ".sh",
          "kalibr": ".kalibr.yaml"}


@pytest.fixture(scope="module")
def calibrated():
    """The rig4 calibration, computed once (through the CLI) and returned by every later run."""
    results = []
    real = rig_module.calibrate_rig_files

    def once(*args, **kwargs):
        if not results:
            results.append(real(*args, **kwargs))
        return results[0]

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rig_module, "calibrate_rig_files", once)
        yield results


@pytest.fixture(scope="module")
def rig_doc(calibrated, tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("rig4") / "rig.json"
    with pytest.raises(SystemExit) as e:
        main(["rig", str(RIG4), *STREAMS, "-o", str(out), "-q"])
    assert e.value.code == 0 and len(calibrated) == 1
    return json.loads(out.read_text())


def _joint(doc: dict) -> dict[str, np.ndarray]:
    return {t["child"]: se3.from_xyz_quat(np.array(t["translation"]), np.array(t["quaternion_xyzw"]))
            for t in doc["transforms"]}


def _truth() -> dict[str, np.ndarray]:
    return {s["name"]: se3.from_xyz_quat(np.array(s["translation"]), np.array(s["quaternion_xyzw"]))
            for s in TRUTH["sensors"]}


# Kalibr YAML is chosen by --format only (a .yaml name means the rig document).
CASES = [(fmt, by_name) for fmt in SUFFIX for by_name in (False, True) if not (by_name and fmt == "kalibr")]


@pytest.mark.parametrize(("fmt", "by_name"), CASES)
def test_every_rig_format_reads_back_to_1e9(rig_doc, tmp_path, capsys, fmt: str, by_name: bool) -> None:
    """Each format, chosen by --format or by the -o name, holds every T_ref_k (read back as a nominal)."""
    path = tmp_path / f"rig{SUFFIX[fmt]}"
    code, out, err = run(capsys, "rig", RIG4, *STREAMS, "-o", path, "-q", *([] if by_name else ["--format", fmt]))
    assert code == 0 and out == "", err
    nominal = read_nominal(path)
    assert nominal.kind == fmt
    joint = _joint(rig_doc)
    for i, name in enumerate(SENSORS):
        N = nominal.transform("imu0", f"cam{i}") if fmt == "kalibr" else nominal.transform("cam0", name)
        assert np.abs(N - joint[name]).max() < 1e-9, (fmt, name)
    if fmt == "urdf":       # one fixed joint per sensor, the reference the root link
        assert {(e.parent, e.child) for e in nominal.edges} == {("cam0", name) for name in SENSORS}
    if fmt != "kalibr":     # the sensors' chains compose through the reference
        assert np.abs(nominal.transform("cam1", "imu") - se3.inverse(joint["cam1"]) @ joint["imu"]).max() < 1e-9


def _nominal_urdf(path, moved: str | None = None) -> str:
    """The truth as a URDF hanging every sensor from a base_link (so cam0 → k is a chain of two joints);
    sensor ``moved`` shifted 2 cm along its x axis."""
    T_base_cam0 = se3.from_xyz_quat(np.array([0.3, -0.1, 0.8]), np.array([0.1, 0.2, -0.3, 0.9]))
    transforms = []
    for name, T in _truth().items():
        if name == moved:
            T = T @ se3.from_xyz_quat(np.array([0.02, 0.0, 0.0]), np.array([0.0, 0.0, 0.0, 1.0]))
        t, q = se3.to_xyz_quat(T_base_cam0 @ T)
        transforms.append({"parent": "base_link", "child": name, "translation": t.tolist(),
                           "quaternion_xyzw": q.tolist()})
    path.write_text(render_format({"transforms": transforms, "reference": "base_link"}, "urdf"))
    return str(path)


TOLERANCE = ["--max-rotation-deg", "0.5", "--max-translation-m", "0.01"]


def test_against_the_true_rig_exits_0(rig_doc, tmp_path, capsys) -> None:
    nominal = _nominal_urdf(tmp_path / "robot.urdf")
    code, out, err = run(capsys, "rig", RIG4, *STREAMS, "--against", nominal, *TOLERANCE, "--format", "json")
    assert code == 0, err
    verdicts = json.loads(out)["verdicts"]
    assert set(verdicts) == set(SENSORS)
    for name, v in verdicts.items():
        assert not v["drift"] and v["translation_m"] < 0.01 and v["rotation_deg"] < 0.5, (name, v)
        assert v["nominal"]["kind"] == "urdf" and v["max_translation_m"] == 0.01
    assert "within tolerance" in err


def test_a_sensor_moved_2cm_exits_1_and_is_named(rig_doc, tmp_path, capsys) -> None:
    nominal = _nominal_urdf(tmp_path / "robot.urdf", moved="lidar")
    result = tmp_path / "rig.yaml"
    code, out, err = run(capsys, "rig", RIG4, *STREAMS, "--against", nominal, *TOLERANCE, "-o", result, "-q")
    assert code == 1 and out == ""
    assert err.startswith("drift: sensor lidar DRIFT") and "cam1" not in err and "sensor imu" not in err
    verdicts = yaml.safe_load(result.read_text())["verdicts"]       # the result is still written
    assert [name for name, v in verdicts.items() if v["drift"]] == ["lidar"]
    assert 0.015 < verdicts["lidar"]["translation_m"] < 0.025 and verdicts["lidar"]["translation_out_of_tolerance"]


def test_against_a_nominal_without_the_sensors_is_refused_before_the_work(calibrated, tmp_path, capsys) -> None:
    path = tmp_path / "other.urdf"
    path.write_text(render_format({"matrix": np.eye(4).tolist(), "frames": {"a": "base", "b": "cam0"}}, "urdf"))
    n_before = len(calibrated)
    code, out, err = run(capsys, "rig", RIG4, *STREAMS, "--against", path)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert "cam1, lidar, imu not in the nominal" in err and "--stream FRAME=SOURCE" in err
    assert len(calibrated) == n_before


def test_rig_verdict_judges_significance_from_the_bootstrap_intervals(rig_doc, calibrated, tmp_path) -> None:
    """A nominal 2 cm away is drift when outside the sensor's interval, and only out of tolerance inside a wide one.
    The verdicts read the typed result (its bootstrap intervals), not its document."""
    from dataclasses import replace

    from handeye_cli.rig.joint import RigUncertainty

    nominal = read_nominal(_nominal_urdf(tmp_path / "robot.urdf", moved="lidar"))
    result = calibrated[0]
    plain = rig_verdicts(result, nominal, 0.5, 0.01)
    assert plain["cam1"].rotation_significant is None and not plain["cam1"].drift     # no bootstrap: not known
    t = {f.child: f.matrix for f in result.stated()}["lidar"][:3, 3]
    n = len(result.names)
    for half_width, drift in ((0.001, True), (0.05, False)):
        rotation = np.tile([[-10 * half_width] * 3, [10 * half_width] * 3], (n, 1, 1))
        u = RigUncertainty(np.zeros((n, 3)), np.zeros((n, 3)), rotation,
                           np.tile([t - half_width, t + half_width], (n, 1, 1)), 10, 2.0, 0)
        verdicts = rig_verdicts(replace(result, uncertainty=u), nominal, 0.5, 0.01)
        assert verdicts["lidar"].drift is drift and verdicts["lidar"].translation_out
        assert verdicts["lidar"].translation_significant is drift


def test_rig_report_shows_the_joint_extrinsics_clock_offsets_and_each_pairs_fit(calibrated, rig_doc, capsys,
                                                                                 tmp_path) -> None:
    """``handeye rig --report FILE`` (issue 21: refused before) writes the rig's page with calibrate's report module:
    the numbers it shows are the result document's, read from the typed result."""
    import base64
    import html
    import re
    import xml.etree.ElementTree as ET

    report = tmp_path / "rig.html"
    code, out, err = run(capsys, "rig", RIG4, *STREAMS, "--report", report, "-q", "--format", "json")
    assert code == 0 and json.loads(out)["transforms"] == rig_doc["transforms"], err
    text = report.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>") and "No warnings." in text and not re.search(r"https?:", text)
    cells = [html.unescape(c) for c in re.findall(r"<td class='num'>([^<]*)</td>", text)]
    for t in rig_doc["transforms"]:                                       # the joint extrinsics
        row = cells.index(f"T_cam0_{t['child']}")
        assert cells[row + 1] == ", ".join(f"{v:.6f}" for v in t["translation"])
        assert cells[row + 2] == ", ".join(f"{v:.6f}" for v in t["quaternion_xyzw"])
    for s in rig_doc["streams"]:                                          # the clock offsets
        row = cells.index(s["name"], cells.index("cam0"))
        assert cells[row + 1] == f"{s['time_offset']['seconds'] * 1e3:.3f}"
    for p in rig_doc["pairwise"]:                                         # each pair: residuals and its fit test
        row = cells.index(f"{p['parent']}–{p['child']}")
        joint = p["residuals"]["joint"]
        assert cells[row + 1] == str(p["pairs_used"])
        assert cells[row + 2] == f"{joint['rotation_median_deg']:.4f} / {1e3 * joint['translation_median_m']:.3f}"
        assert cells[row + 4].startswith("passed: ")
    (src,) = re.findall(r"src='data:image/svg\+xml;base64,([^']*)'", text)  # one figure, well-formed SVG
    svg = ET.fromstring(base64.b64decode(src))
    assert svg.tag == "{http://www.w3.org/2000/svg}svg"
    assert len(calibrated) == 1                                           # the cached calibration: no solve here


def test_rig_report_to_a_missing_folder_fails_before_the_work(calibrated, capsys, tmp_path) -> None:
    n_before = len(calibrated)
    out_file = tmp_path / "rig.yaml"
    code, out, err = run(capsys, "rig", RIG4, *STREAMS, "--report", tmp_path / "missing" / "r.html", "-o", out_file)
    assert code == 2 and out == "" and err.count("\n") == 1 and "--report" in err and not out_file.exists()
    assert len(calibrated) == n_before


def test_a_failed_rig_report_keeps_the_result(calibrated, capsys, tmp_path, monkeypatch) -> None:
    from handeye_cli.errors import WriteError
    from handeye_cli.rig import report

    def broken(path, result):
        raise WriteError("cannot write (Read-only file system)", str(path), "choose another --report path")

    monkeypatch.setattr(report, "write_rig_report", broken)
    out_file = tmp_path / "rig.yaml"
    code, _, err = run(capsys, "rig", RIG4, *STREAMS, "--report", tmp_path / "r.html", "-o", out_file, "-q")
    assert code == 2 and "the result was written, but not the report: cannot write" in err
    assert yaml.safe_load(out_file.read_text())["reference"] == "cam0"


def test_rig_report_escapes_sensor_names(calibrated, rig_doc) -> None:
    """Sensor names (a rig's NAME=, or frames read from a log) reach the page only escaped: a name holding markup
    or a quote shows as text, in the heading, the tables and the figure."""
    import base64
    import re
    import xml.etree.ElementTree as ET
    from dataclasses import replace

    from handeye_cli.rig.report import render_rig_report

    result = calibrated[0]
    hostile = [f"<script>alert({k})</script>'\"&{name}" for k, name in enumerate(result.names)]
    text = render_rig_report(replace(result, names=hostile))
    assert "<script>alert" not in text and "&lt;script&gt;alert(0)&lt;/script&gt;" in text
    (src,) = re.findall(r"src='data:image/svg\+xml;base64,([^']*)'", text)
    svg = base64.b64decode(src).decode()
    assert "<script>alert" not in svg and ET.fromstring(svg).tag == "{http://www.w3.org/2000/svg}svg"
