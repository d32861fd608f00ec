"""``handeye batch`` on a generated fleet of 32 inputs (MCAP, ROS 1 bags, ROS 2 bags with sqlite3
and MCAP storage, TUM pairs; sensors moved beyond and below the tolerance; unreadable files):
every record, the order, the exit codes, --output-dir/--skip-done, input lists, the Dask path
(byte-identical records apart from timings), and the fleet-trend report in headless chromium."""
from __future__ import annotations

import io
import json
import os
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from _fleet import NOMINAL, TOPICS, crashed, make_fleet, moved, write_rig
from _html import _images, _run_chromium
from _util import run

from handeye_cli.fleet import engine
from handeye_cli.geometry import se3

TOLERANCE = ["--max-rotation-deg", "0.5", "--max-translation-m", "0.005"]


def _urdf(path: Path) -> Path:
    """A robot whose cameras hang off a mount: the nominal T_cam0_cam1 is a chain of two fixed joints."""
    T_base_cam0 = se3.from_xyz_quat(np.array([0.3, 0.0, 0.5]), np.array([0.0, 0.0, 0.0, 1.0]))
    T_base_cam1 = T_base_cam0 @ NOMINAL

    def joint(child: str, T: np.ndarray) -> str:
        from scipy.spatial.transform import Rotation

        rpy = " ".join(repr(float(v)) for v in Rotation.from_matrix(T[:3, :3]).as_euler("xyz"))
        xyz = " ".join(repr(float(v)) for v in T[:3, 3])
        return (f'<joint name="{child}_joint" type="fixed"><parent link="base_link"/><child link="{child}"/>'
                f'<origin xyz="{xyz}" rpy="{rpy}"/></joint>')

    path.write_text(f'<robot name="robot42"><link name="base_link"/><link name="cam0"/><link name="cam1"/>'
                    f'{joint("cam0", T_base_cam0)}{joint("cam1", T_base_cam1)}</robot>\n')
    return path


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    root = tmp_path_factory.mktemp("fleet")
    expected = make_fleet(root / "logs")
    expected.update(crashed(root / "logs"))          # salvaged by the readers, with a 'truncated' warning
    return root, expected, _urdf(root / "robot42.urdf")


def _args(root: Path, *extra: object) -> list[object]:
    return ["batch", *extra, "--topic-a", TOPICS[0], "--topic-b", TOPICS[1], "--name-a", "cam0", "--name-b", "cam1",
            "--against", root / "robot42.urdf", *TOLERANCE]


def _records(out: str) -> list[dict]:
    return [json.loads(line) for line in out.splitlines()]


def _without_timing(records: list[dict]) -> list[str]:
    return [json.dumps({k: v for k, v in r.items() if k != "seconds"}) for r in records]


def test_fleet_records_order_statuses_and_exit_code(fleet, capsys):
    root, expected, _ = fleet
    code, out, err = run(capsys, *_args(root, root / "logs", "--jobs", "2", "--output-dir", root / "results",
                                        "--report", root / "fleet.html"))
    records = _records(out)
    assert len(expected) >= 30 and len(records) == len(expected)
    assert [r["input"] for r in records] == sorted(expected, key=lambda k: k.split(" "))   # input (path) order
    assert code == 1                                                        # drift beats error
    for r in records:
        exp = expected[r["input"]]
        assert r["status"] == exp.status, (r["input"], r.get("error"), r.get("verdict"))
        assert list(r)[:2] == ["input", "status"] and list(r)[-1] == "seconds"
        if exp.status == "error":
            assert "\n" not in r["error"] and r["input"] in r["error"] and "matrix" not in r
            continue
        if exp.warning:
            assert any(exp.warning in w for w in r["warnings"]), r["warnings"]
        X = np.array(r["matrix"])
        assert np.rad2deg(se3.rotation_angle(X[:3, :3].T @ exp.truth[:3, :3])) < 0.05
        # 12-s logs (7 s left of a crashed one): well inside the 5 mm tolerance the verdicts use
        assert np.linalg.norm(X[:3, 3] - exp.truth[:3, 3]) < 2.5e-3, r["input"]
        v = r["verdict"]
        assert r["frames"] == {"a": "cam0", "b": "cam1"} and v["nominal"]["kind"] == "urdf"
        assert v["drift"] == (exp.status == "drift") and (v["rotation_out_of_tolerance"] or
                                                          v["translation_out_of_tolerance"]) == v["drift"]
        assert len(r["log_span_ns"]) == 2 and r["log_span_ns"][0] < r["log_span_ns"][1]
    counts = {s: sum(e.status == s for e in expected.values()) for s in ("ok", "drift", "error")}
    assert f"{counts['ok']} ok, {counts['drift']} drift, {counts['error']} error" in err
    assert "slowest:" in err and "DRIFT:" in err
    files = sorted(p.name for p in (root / "results").iterdir())
    assert len(files) == counts["ok"] + counts["drift"] and all(f.endswith(".yaml") for f in files)
    (root / "verdicts.jsonl").write_text(out)


def test_exit_codes_without_drift(fleet, capsys):
    root, _, _ = fleet
    logs = root / "logs"
    code, out, _ = run(capsys, *_args(root, logs / "robot00", logs / "robot04", logs / "broken" / "garbage.mcap"))
    assert code == 2 and [r["status"] for r in _records(out)] == ["ok", "ok", "error"]
    code, out, _ = run(capsys, *_args(root, logs / "robot00", logs / "robot26", "-q"))      # moved below tolerance
    assert code == 0 and [r["status"] for r in _records(out)] == ["ok", "ok"]
    wrong = ["batch", logs / "robot00", "--topic-a", TOPICS[0], "--topic-b", TOPICS[1], "--invert-b", "-q"]
    code, out, _ = run(capsys, *wrong)                     # a flag the data contradict: that input's error
    assert code == 2 and _records(out)[0]["status"] == "error" and "contradict the data" in _records(out)[0]["error"]
    strict = ["batch", logs / "crashed0", "--topic-a", TOPICS[0], "--topic-b", TOPICS[1], "-q"]
    code, out, _ = run(capsys, *strict)
    assert code == 0 and "truncated" in " ".join(_records(out)[0]["warnings"])
    wrong.append("--accept-poor-fit")                      # kept on request
    code, out, _ = run(capsys, *wrong)
    assert code == 0 and "looks inverted" in _records(out)[0]["warnings"][1]
    code, out, _ = run(capsys, *strict, "--strict")                            # warnings fail under --strict
    assert code == 3 and _records(out)[0]["status"] == "ok"


def test_skip_done_reuses_results_of_the_same_content_options_and_version(fleet, capsys, monkeypatch, tmp_path):
    root, expected, _ = fleet
    logs = root / "logs"
    inputs = [logs / "robot00", logs / "robot01", logs / "robot02", logs / "broken" / "empty.bag"]
    base = _args(root, *inputs, "--jobs", "1", "--output-dir", tmp_path / "out", "--skip-done", "-q")
    _, first, _ = run(capsys, *base)
    calls: list[str] = []
    real = engine.run_job
    monkeypatch.setattr(engine, "run_job", lambda job: calls.append(job.input.label) or real(job))
    _, again, _ = run(capsys, *base)
    assert calls == [str(logs / "broken" / "empty.bag")]                       # only the failed input ran again
    assert _without_timing(_records(again)) == _without_timing(_records(first))
    (logs / "robot01" / "rig1.bag").unlink()
    write_rig(logs / "robot01", "bag1", moved(0.0, 0.02, 9), seed=1)             # the log changed on disk
    calls.clear()
    _, changed, _ = run(capsys, *base)
    assert sorted(calls) == sorted([str(logs / "robot01" / "rig1.bag"), str(logs / "broken" / "empty.bag")])
    assert _records(changed)[1]["status"] == "drift"
    calls.clear()
    run(capsys, *base, "--method", "dq2ndord")                                  # other options: everything runs
    assert len(calls) == 4
    (logs / "robot01" / "rig1.bag").unlink()
    write_rig(logs / "robot01", "bag1", NOMINAL, seed=1)                         # restore the fleet for other tests
    assert expected[str(logs / "robot01" / "rig1.bag")].status == "ok"


def test_inputs_from_lists_stdin_and_globs(fleet, capsys, monkeypatch, tmp_path):
    root, _, _ = fleet
    logs = root / "logs"
    listing = tmp_path / "list.txt"
    listing.write_text(f"# fleet of the day\n{logs / 'robot00' / 'rig0.mcap'}\n\n"
                       f"'{logs / 'robot04' / 'cam0.tum'}' {logs / 'robot04' / 'cam1.tum'}\n{logs / 'nope.bag'}\n")
    monkeypatch.setattr(sys, "stdin", io.StringIO(f"{logs / 'robot01' / 'rig1.bag'}\n"))
    (tmp_path / "three").mkdir()
    for name in ("a.tum", "b.tum", "c.tum"):
        (tmp_path / "three" / name).write_text((logs / "robot04" / "cam0.tum").read_text())
    code, out, _ = run(capsys, *_args(root, f"@{listing}", "-", str(logs / "robot0[23]"), tmp_path / "three",
                                      str(tmp_path / "*.none"), "--jobs", "1", "-q"))
    records = _records(out)
    assert [r["status"] for r in records] == ["ok", "ok", "error", "ok", "ok", "ok", "error", "error"]
    assert records[1]["input"] == f"{logs / 'robot04' / 'cam0.tum'} {logs / 'robot04' / 'cam1.tum'}"
    assert "file not found" in records[2]["error"] and records[3]["input"].endswith("rig1.bag")
    assert "3 TUM file(s)" in records[6]["error"] and "matches no file" in records[7]["error"]
    assert code == 2


def test_per_input_options(fleet, capsys, tmp_path):
    root, _, _ = fleet
    logs = root / "logs"
    (tmp_path / "per-input.yaml").write_text('"*/robot01/*": {method: dq2ndord}\n"*rig*": {max_pairs: 40}\n')
    code, out, _ = run(capsys, *_args(root, logs / "robot00", logs / "robot01", logs / "robot04", "--per-input",
                                      tmp_path / "per-input.yaml", "--jobs", "1", "-q"))
    records = _records(out)
    assert code == 0 and [r["method"] for r in records] == ["dqopt", "dq2ndord", "dqopt"]
    assert [r["pairs_used"] for r in records][:2] == [40, 40] and records[2]["pairs_used"] > 40   # TUM: no "rig"
    (tmp_path / "bad.yaml").write_text('"*": {max_jump: fast}\n')
    code, out, err = run(capsys, *_args(root, logs / "robot00", "--per-input", tmp_path / "bad.yaml"))
    assert code == 2 and out == "" and "max_jump" in err and "bad.yaml" in err


def test_dask_cluster_gives_byte_identical_records(fleet, capsys):
    try:
        from distributed import LocalCluster
    except ImportError:
        if os.environ.get("CI"):
            raise
        pytest.skip("dask.distributed is not installed (pip install 'dask[distributed]'); CI installs it")
    root, _, _ = fleet
    inputs = [str(root / "logs" / "robot0[0-4]"), root / "logs" / "broken", root / "logs" / "robot22"]
    code_local, local, _ = run(capsys, *_args(root, *inputs, "--jobs", "2", "-q"))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        code_dask, remote, _ = run(capsys, *_args(root, *inputs, "--scheduler", cluster.scheduler_address, "-q"))
    assert code_local == code_dask == 1 and len(_records(local)) == 9
    strip = re.compile(r',"seconds":[0-9.e+-]+\}$')
    assert [strip.sub("}", line) for line in remote.splitlines()] == \
        [strip.sub("}", line) for line in local.splitlines()]


def test_fleet_report_renders_in_headless_chromium(fleet, capsys, tmp_path):
    root, expected, _ = fleet
    if not (root / "verdicts.jsonl").exists():
        pytest.fail("test_fleet_records_order_statuses_and_exit_code must run first (it writes the records)")
    code, out, err = run(capsys, "report", root / "verdicts.jsonl", "-o", tmp_path / "fleet.html")
    statuses = [json.loads(line)["status"] for line in (root / "verdicts.jsonl").read_text().splitlines()]
    assert code == 0 and out == "" and err == (f"{tmp_path / 'fleet.html'}: {len(statuses)} records ("
                                               f"{statuses.count('ok')} ok, {statuses.count('drift')} drift, "
                                               f"{statuses.count('error')} error)\n")
    code, out, err = run(capsys, "report", root / "verdicts.jsonl", "-o", tmp_path / "fleet.html", "-q")
    assert code == 0 and out == "" and err == ""
    text = (tmp_path / "fleet.html").read_text(encoding="utf-8")
    stamp = re.compile(r"Generated [^<]* by")
    assert stamp.sub("", text) == stamp.sub("", (root / "fleet.html").read_text(encoding="utf-8"))  # = batch --report
    drifted = [k for k, e in expected.items() if e.status == "drift"]
    failed = [k for k, e in expected.items() if e.status == "error"]
    table = text.split("id='drifted'", 1)[1].split("</table>", 1)[0]
    assert sorted(re.findall(r"<tr><td>([^<]*)</td>", table)) == sorted(drifted)
    assert all(f in text.split("id='failed'", 1)[1] for f in failed)
    assert "T_cam0_cam1" in text and len(_images(text)) == 1 and not re.search(r"https?:", text)
    dom = _run_chromium(tmp_path, "--dump-dom", (tmp_path / "fleet.html").resolve().as_uri()).stdout
    body = re.search(r"<body\b[^>]*>", dom).group(0)
    assert 'data-images="1"' in body and 'data-loaded="1"' in body


def test_bad_batch_options_are_one_line_errors(fleet, capsys, tmp_path):
    root, _, _ = fleet
    for args, message in ((["batch", root / "logs" / "robot00", "--skip-done"], "--skip-done needs --output-dir"),
                          (["batch", root / "logs" / "robot00", "--against", tmp_path / "none.urdf"], "not found"),
                          (["report", tmp_path / "none.jsonl", "-o", tmp_path / "r.html"], "cannot read")):
        code, out, err = run(capsys, *args)
        assert code == 2 and out == "" and message in err and len(err.strip().splitlines()) == 1
