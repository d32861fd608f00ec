"""``handeye rig`` and ``handeye compare`` through the CLI, on the shipped samples."""
from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from _util import ROOT, pose_error, run, write_tum

import handeye_cli.io as handeye_io
from handeye_cli.cli import main
from handeye_cli.geometry import se3
from handeye_cli.io import read_stream
from handeye_cli.solvers import METHODS

RIG4 = ROOT / "sample_data" / "rig4.mcap"
TRUTH = yaml.safe_load((ROOT / "sample_data" / "rig4_truth.yaml").read_text())
STREAMS = ["--stream", "cam0=/cam0/pose", "--stream", "cam1=/cam1/pose", "--stream", "lidar=/lidar/odom",
           "--stream", "imu=tf:odom,imu_link"]


def _truth(name: str) -> np.ndarray:
    s = next(s for s in TRUTH["sensors"] if s["name"] == name)
    return se3.from_xyz_quat(np.array(s["translation"]), np.array(s["quaternion_xyzw"]))


@pytest.fixture(scope="module")
def rig4_doc(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("rig4") / "rig.json"
    with pytest.raises(SystemExit) as e:
        main(["rig", str(RIG4), *STREAMS, "-o", str(out), "-q"])
    assert e.value.code == 0
    return json.loads(out.read_text())


def test_sample_size_budget() -> None:
    assert RIG4.stat().st_size < 300_000


def test_rig4_every_extrinsic_recovered(rig4_doc: dict) -> None:
    """Within 0.25° / 5 mm (the imu stream drifts 1°/min, which biases its long motion pairs)."""
    assert rig4_doc["reference"] == "cam0"
    assert [t["child"] for t in rig4_doc["transforms"]] == ["cam1", "lidar", "imu"]
    for t in rig4_doc["transforms"]:
        assert set(t) == {"parent", "child", "translation", "quaternion_xyzw"}
        X = se3.from_xyz_quat(np.array(t["translation"]), np.array(t["quaternion_xyzw"]))
        rot, trans = pose_error(X, _truth(t["child"]))
        assert rot < 0.25 and trans < 0.005, (t["child"], rot, trans)
    offsets = {s["name"]: s["time_offset"]["seconds"] for s in rig4_doc["streams"]}
    for s in TRUTH["sensors"]:
        assert abs(offsets[s["name"]] - s["time_offset_s"]) < 0.002


def test_rig4_document_sections(rig4_doc: dict) -> None:
    pairs = rig4_doc["pairwise"]
    assert len(pairs) == 6 and {(p["parent"], p["child"]) for p in pairs} >= {("cam0", "imu"), ("lidar", "imu")}
    for p in pairs:
        assert {"joint", "pairwise_only"} == set(p["residuals"]) and p["pairs_used"] >= 3
        assert p["pairwise_only"]["parent"] == p["parent"]
    closures = rig4_doc["loop_closures"]
    assert len(closures["pairwise_only"]) == 4
    assert closures["joint_max"]["rotation_deg"] < 1e-9 and closures["joint_max"]["translation_m"] < 1e-9
    assert rig4_doc["consistency"]["suspect"] is None
    assert rig4_doc["settings"]["reference"] == "cam0" and rig4_doc["warnings"] == []


def test_rig_reads_the_log_once(monkeypatch, capsys) -> None:
    """One pass over the log for all four streams, and the log detected once (the read path of calibrate)."""
    calls, detected = [], []
    real, real_detect = handeye_io._read_log, handeye_io.detect_format

    def counting(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    def detecting(*args, **kwargs):
        detected.append(args)
        return real_detect(*args, **kwargs)

    monkeypatch.setattr(handeye_io, "_read_log", counting)
    monkeypatch.setattr(handeye_io, "detect_format", detecting)
    code, out, _ = run(capsys, "rig", RIG4, *STREAMS, "--time-offset", "cam1=0.015", "--time-offset", "lidar=-0.04",
                       "--time-offset", "imu=0.025", "--format", "json", "-q")
    assert code == 0 and len(calls) == 1 and len(calls[0][2]) == 4 and len(detected) == 1
    doc = json.loads(out)
    assert {s["name"]: s["time_offset"]["method"] for s in doc["streams"]} == {
        "cam0": "reference", "cam1": "fixed", "lidar": "fixed", "imu": "fixed"}


def test_rig_mixes_a_log_and_a_file(tmp_path, capsys) -> None:
    """A stream from a separate TUM file beside the log's topics; --reference picks another sensor."""
    imu = read_stream(RIG4, frames=("odom", "imu_link"))
    path = write_tum(tmp_path / "imu.tum", imu)
    code, out, err = run(capsys, "rig", RIG4, "--stream", "cam0=/cam0/pose", "--stream", "lidar=/lidar/odom",
                         "--stream", f"imu={path}", "--reference", "lidar", "--bootstrap", "20", "--format", "json")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["reference"] == "lidar" and "T_lidar_imu" in err
    X = {t["child"]: se3.from_xyz_quat(np.array(t["translation"]), np.array(t["quaternion_xyzw"]))
         for t in doc["transforms"]}
    rot, trans = pose_error(X["imu"], se3.inverse(_truth("lidar")) @ _truth("imu"))
    assert rot < 0.3 and trans < 0.005          # three sensors, the drifting imu against the 10 Hz lidar
    assert set(doc["uncertainty"]["sensors"]) == {"cam0", "imu"}
    assert doc["inputs"]["streams"]["imu"] == {"file": str(path)}


@pytest.mark.parametrize(("args", "message"), [
    (["--stream", "cam0=/cam0/pose"], "1 stream(s) given"),
    (["--stream", "cam0=/cam0/pose", "--stream", "cam1"], "bad stream"),
    (["--stream", "cam0=/cam0/pose", "--stream", "cam1=/cam1/pose", "--reference", "radar"], "unknown reference"),
    (["--stream", "cam0=/cam0/pose", "--stream", "cam1=/cam1/pose", "--time-offset", "cam1"], "bad value"),
    (["--stream", "cam0=/cam0/pose", "--stream", "cam1=/nope"], "/nope"),
    (["--stream", "cam0=/cam0/pose", "--stream", "cam1=tf:odom"], "bad TF chain"),
    (["--stream", "a=/cam0/pose", "--stream", "a=/cam1/pose"], "repeat"),
])
def test_rig_user_errors(capsys, args: list[str], message: str) -> None:
    code, out, err = run(capsys, "rig", RIG4, *args)
    assert code == 2 and out == ""
    assert err.startswith("error: ") and message in err and err.count("\n") == 1 and "Traceback" not in err


def test_rig_without_log_for_a_topic(capsys) -> None:
    code, _, err = run(capsys, "rig", "--stream", "cam0=/cam0/pose", "--stream", "cam1=/cam1/pose")
    assert code == 2 and "no log is given" in err


def test_compare_table_and_json(capsys) -> None:
    args = ["compare", ROOT / "sample_data" / "rig.mcap", "--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose", "-q"]
    code, out, _ = run(capsys, *args)
    assert code == 0
    lines = out.splitlines()
    assert lines[0].split()[0] == "method" and len(lines) == 1 + len(METHODS) + 2
    assert {line.split()[0] for line in lines[1:]} >= {"dqopt", "tsai", "park", "horaud", "andreff", "shah", "li"}
    code, out, _ = run(capsys, *args, "--format", "json")
    rows = json.loads(out)["methods"]
    cost = {r["method"]: r["cost"] for r in rows}
    assert all(cost["dqopt"] <= c * (1 + 1e-9) for c in cost.values())      # the optimum is the optimum
    best = next(r for r in rows if r["method"] == "dqopt")
    assert best["vs_dqopt_deg"] == 0.0 and all(r["vs_dqopt_deg"] < 0.5 for r in rows)


def test_rig_applies_every_read_option_to_its_files(tmp_path) -> None:
    """Issue 21: ``handeye rig --time-unit`` was accepted and ignored for file streams. The rig reads through
    calibrate's read path: a TUM file written in milliseconds reads back in seconds only with ``time_unit``."""
    from handeye_cli.errors import ReadError
    from handeye_cli.options import Options
    from handeye_cli.rig import parse_stream, read_rig

    imu = read_stream(RIG4, frames=("odom", "imu_link"))
    path = tmp_path / "imu_ms.tum"
    np.savetxt(path, np.c_[imu.stamps_ns / 1e6, imu.xyz, imu.quat_xyzw], fmt="%.6f")
    specs = [parse_stream("cam0=/cam0/pose"), parse_stream(f"imu={path}")]
    as_ms = read_rig(str(RIG4), specs, Options.from_flat(None, time_unit="ms"))
    np.testing.assert_allclose(as_ms["imu"].stamps_ns, imu.stamps_ns, atol=1_000)
    with pytest.raises(ReadError, match="time_unit='s"):       # epoch milliseconds read as seconds: out of range
        read_rig(str(RIG4), specs, Options.from_flat(None, time_unit="s"))


def test_the_package_docstrings_rig_example_runs() -> None:
    """Issue 21: ``calibrate_rig_files("log.mcap", ["cam0=/cam0/pose", …], RigOptions())``, as the package
    docstring writes it, raised AttributeError (a str is not a StreamSpec): the command-line form is accepted."""
    import handeye_cli
    from handeye_cli import RigOptions, calibrate_rig_files, calibration, rig
    from handeye_cli.io import spec

    assert handeye_cli.StreamSpec is rig.StreamSpec is calibration.StreamSpec is spec.StreamSpec     # one class
    assert 'calibrate_rig_files("log.mcap", ["cam0=/cam0/pose", "imu=tf:odom,imu_link"], RigOptions())' in \
        (handeye_cli.__doc__ or "")
    result = calibrate_rig_files(str(RIG4), ["cam0=/cam0/pose", "imu=tf:odom,imu_link"], RigOptions())
    assert result.names == ["cam0", "imu"]
    rot, trans = pose_error(result.matrices[1], _truth("imu"))
    assert rot < 0.5 and trans < 0.02
