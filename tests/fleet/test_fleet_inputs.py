"""What a fleet engineer hit in ``handeye batch`` and the fleet report (issue 21): per-input
streams, patterns that match as users expect, the summary, every format in --output-dir, and a
report with one line per robot, its legend off the data, that reads a records file with a cut
last line."""
from __future__ import annotations

import base64
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from _fleet import NOMINAL, _rig_streams
from _logs import POSE, pose_channel, records, write_mcap
from _util import ROOT, run

from handeye_cli.fleet import engine
from handeye_cli.io.nominal import read_nominal

LOG = ROOT / "sample_data" / "rig.mcap"
TOPICS = ["--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose"]


def _records(out: str) -> list[dict]:
    return [json.loads(line) for line in out.splitlines()]


@pytest.fixture
def mixed(tmp_path) -> Path:
    """robot01 logs /cam0/pose and /cam1/pose; robot07 names its second sensor /imu/pose."""
    (tmp_path / "logs" / "robot01").mkdir(parents=True)
    shutil.copyfile(LOG, tmp_path / "logs" / "robot01" / "rig.mcap")
    a, b = _rig_streams(NOMINAL, seed=7, duration_s=8.0)
    (tmp_path / "logs" / "robot07").mkdir()
    write_mcap(tmp_path / "logs" / "robot07" / "rig.mcap", [pose_channel("/cam0/pose", POSE, records(a)),
                                                           pose_channel("/imu/pose", POSE, records(b))])
    return tmp_path


def test_per_input_sets_the_streams_of_a_mixed_fleet_by_folder_name(capsys, monkeypatch, mixed):
    monkeypatch.chdir(mixed)
    code, out, _ = run(capsys, "batch", "logs", *TOPICS, "--jobs", "1", "-q")
    assert code == 2 and [r["status"] for r in _records(out)] == ["ok", "error"]      # one run could not do both
    Path("per-input.yaml").write_text('"robot07*": {topic_b: /imu/pose}\n"robot99*": {method: dq2ndord}\n')
    code, out, err = run(capsys, "batch", "logs", *TOPICS, "--per-input", "per-input.yaml", "--jobs", "1", "-q")
    records_ = _records(out)
    assert code == 0 and [r["status"] for r in records_] == ["ok", "ok"], records_
    assert np.allclose(np.array(records_[1]["matrix"]), NOMINAL, atol=5e-3)
    assert "robot99*" in err and "matches none of the 2 input(s)" in err and "robot07*" not in err


@pytest.mark.parametrize("value", ["[odom]", "3", "''"])
def test_bad_per_input_streams_are_one_line_errors(capsys, tmp_path, value):
    (tmp_path / "p.yaml").write_text(f'"*": {{frames_a: {value}}}\n')
    code, out, err = run(capsys, "batch", LOG, *TOPICS, "--per-input", tmp_path / "p.yaml")
    assert code == 2 and out == "" and "frames_a" in err and "p.yaml" in err and len(err.strip().splitlines()) == 1


def test_the_summary_names_error_inputs_counts_the_rest_and_what_skip_done_reused(capsys, tmp_path):
    missing = [tmp_path / f"gone{k}.mcap" for k in range(7)]
    code, _, err = run(capsys, "batch", LOG, *missing, *TOPICS, "--jobs", "1")
    assert code == 2 and "1 ok, 0 drift, 7 error" in err
    assert f"error: file not found: {missing[0]}" in err and "… and 2 more error(s)" in err
    assert f"error: file not found: {missing[4]}" in err and f"error: file not found: {missing[5]}" not in err
    args = ["batch", LOG, *TOPICS, "--jobs", "1", "--output-dir", tmp_path / "out", "--skip-done"]
    run(capsys, *args)
    code, _, err = run(capsys, *args)
    assert code == 0 and "1 input(s) (1 reused by --skip-done)" in err


@pytest.mark.parametrize("fmt, suffix", [("urdf", ".urdf"), ("ros1-launch", ".launch"), ("kalibr", ".kalibr.yaml")])
def test_output_dir_writes_every_format_and_skip_done_reuses_it(capsys, monkeypatch, tmp_path, fmt, suffix):
    monkeypatch.chdir(tmp_path)
    shutil.copyfile(LOG, tmp_path / "rig.mcap")
    args = ["batch", "rig.mcap", *TOPICS, "--jobs", "1", "--output-dir", "out", "--format", fmt, "--skip-done", "-q"]
    code, out, _ = run(capsys, *args)
    assert code == 0, out
    written = tmp_path / "out" / f"rig.mcap{suffix}"
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [written.name, written.name + ".handeye.json"]
    if fmt != "kalibr":
        assert np.allclose(read_nominal(written).transform(), _records(out)[0]["matrix"], atol=1e-9)
    calls: list[str] = []
    monkeypatch.setattr(engine, "run_job", lambda job: calls.append(job.input.label))
    code, again, _ = run(capsys, *args)
    assert code == 0 and calls == [] and _records(again)[0]["matrix"] == _records(out)[0]["matrix"]


def _fleet_records(path: Path) -> None:
    """Records of two robots over three nights each: robot 01 steady, robot 02 moving 1 mm a night."""
    lines = []
    for night in range(3):
        for robot, shift in (("01", 0.0), ("02", 0.001 * night)):
            X = NOMINAL.copy()
            X[0, 3] += shift
            start = 1_790_000_000 * 10**9 + night * 86_400 * 10**9
            lines.append(json.dumps({"input": f"logs/2026-11-0{night + 1}/robot{robot}.mcap", "status": "ok",
                                     "matrix": X.tolist(), "frames": {"a": "cam0", "b": "cam1"},
                                     "log_span_ns": [start, start + 10**10], "seconds": 0.1}))
    path.write_text("\n".join(lines) + "\n")


def _svg(html: str) -> str:
    (data,) = re.findall(r"src='data:image/svg\+xml;base64,([^']*)'", html)
    return base64.b64decode(data).decode()


def test_the_fleet_report_draws_one_line_per_robot_with_the_legend_off_the_data(capsys, tmp_path):
    _fleet_records(tmp_path / "records.jsonl")
    code, out, err = run(capsys, "report", tmp_path / "records.jsonl", "-o", tmp_path / "fleet.html", "-q")
    assert code == 0 and out == err == ""
    html = (tmp_path / "fleet.html").read_text()
    svg = _svg(html)
    first, second = "#1f77b4", "#ff7f0e"                      # the colours of robot 01 and robot 02
    assert svg.count(f"stroke='{first}'") == svg.count(f"stroke='{second}'") > 0
    assert "fill-opacity='0.8'" not in svg                     # no legend box over the panels
    caption = html.split("<figcaption>", 1)[1].split("</figcaption>", 1)[0]
    assert "6 log(s) of 2 robot(s)" in caption and "logs/robot01.mcap" in caption and "robot02" in caption
    assert "matplotlib" not in html and "image/png" not in html


def test_the_fleet_report_draws_each_sensor_pair_apart_one_line_per_robot(capsys, tmp_path):
    """Two sensor pairs of the same two robots: one chart per pair, in each one line per robot (not all
    robots' logs of every pair joined into one line)."""
    _fleet_records(tmp_path / "records.jsonl")
    cam = (tmp_path / "records.jsonl").read_text().splitlines()
    lidar = [json.dumps({**json.loads(line), "frames": {"a": "base", "b": "lidar"}}) for line in cam[:4]]
    (tmp_path / "records.jsonl").write_text("\n".join(cam + lidar) + "\n")
    code, _, err = run(capsys, "report", tmp_path / "records.jsonl", "-o", tmp_path / "fleet.html", "-q")
    assert code == 0 and err == ""
    html = (tmp_path / "fleet.html").read_text()
    svgs = [base64.b64decode(d).decode() for d in re.findall(r"src='data:image/svg\+xml;base64,([^']*)'", html)]
    captions = re.findall(r"<figcaption>(.*?)</figcaption>", html)
    assert len(svgs) == 2 and captions[0].startswith("T_base_lidar: 4 log(s) of 2 robot(s)")
    assert captions[1].startswith("T_cam0_cam1: 6 log(s) of 2 robot(s)")
    for svg, per_robot in zip(svgs, (2, 3), strict=True):     # logs per robot: lidar 2 nights, cameras 3
        for color in ("#1f77b4", "#ff7f0e"):          # robot 01, robot 02: one line in each of the six panels
            lines = re.findall(rf"<path fill='none' stroke='{color}' stroke-width='[^']*' d='M[^ ]+ [^ ]+l([^']*)'/>",
                               svg)
            assert len(lines) == 6 and all(len(d.split()) == 2 * (per_robot - 1) for d in lines), lines


def test_the_fleet_report_reads_a_records_file_with_a_cut_last_line(capsys, tmp_path):
    _fleet_records(tmp_path / "records.jsonl")
    text = (tmp_path / "records.jsonl").read_text()
    (tmp_path / "records.jsonl").write_text(text[:-40])       # the batch was killed writing its last record
    code, out, err = run(capsys, "report", tmp_path / "records.jsonl", "-o", tmp_path / "fleet.html", "-q")
    assert code == 0 and out == "" and "records.jsonl:6: the last line is cut" in err      # warnings stay
    assert "5 log(s) of 2 robot(s)" in (tmp_path / "fleet.html").read_text()
    (tmp_path / "records.jsonl").write_text(text.rstrip("\n"))  # whole, with no final newline: kept
    code, _, err = run(capsys, "report", tmp_path / "records.jsonl", "-o", tmp_path / "fleet.html", "-q")
    assert code == 0 and err == "" and "6 log(s)" in (tmp_path / "fleet.html").read_text()


def test_the_summary_and_the_fleet_report_read_typed_records(capsys, tmp_path):
    """Issue 21: 'the report and the verdicts read typed objects, not the dict parsed back'. A record (batch's
    output format, from a worker or a records file) is parsed once into a BatchRecord; the summary and the fleet
    report read its fields, and a record whose field has the wrong shape is one line naming its input (the report
    crashed on such a matrix)."""
    from handeye_cli.analysis.verdict import Verdict
    from handeye_cli.fleet import BatchSummary
    from handeye_cli.output.records import BatchRecord

    verdict = {"drift": True, "rotation_deg": 0.1, "translation_m": 0.02, "max_rotation_deg": 0.5,
               "max_translation_m": 0.005, "nominal": {"translation": [0, 0, 0], "quaternion_xyzw": [0, 0, 0, 1]}}
    typed = BatchRecord.from_record({"input": "robot01.mcap", "status": "drift", "matrix": NOMINAL.tolist(),
                                     "frames": {"a": "cam0", "b": "cam1"}, "log_span_ns": [1, 2], "verdict": verdict,
                                     "warnings": ["w"], "seconds": 1.5})
    assert isinstance(typed.verdict, Verdict) and typed.drifted and typed.warned
    assert typed.matrix is not None and typed.matrix.shape == (4, 4) and typed.frames == ("cam0", "cam1")
    assert typed.log_span_ns == (1, 2) and typed.seconds == 1.5
    summary = BatchSummary(strict=True)
    summary.add(typed)
    summary.add(BatchRecord.from_record({"input": "robot02.mcap", "status": "error", "error": "bad log"}), True)
    assert summary.exit_code == 1 and summary.reused == 1
    text = summary.text()
    assert "DRIFT: robot01.mcap: 0.100° (max 0.5°), 20.00 mm (max 5 mm)" in text
    assert "robot01.mcap 1.50 s" in text and "error: robot02.mcap: bad log" in text

    _fleet_records(tmp_path / "records.jsonl")
    lines = (tmp_path / "records.jsonl").read_text().splitlines()
    bad = json.loads(lines[2])
    bad["matrix"] = bad["matrix"][:3]                        # 3 rows: not a T_a_b
    (tmp_path / "records.jsonl").write_text("\n".join([*lines[:2], json.dumps(bad), *lines[3:]]) + "\n")
    code, _, err = run(capsys, "report", tmp_path / "records.jsonl", "-o", tmp_path / "fleet.html", "-q")
    line = err.strip().splitlines()
    assert code == 2 and len(line) == 1 and "bad batch record" in line[0] and f"({bad['input']})" in line[0]
    assert not (tmp_path / "fleet.html").exists()
