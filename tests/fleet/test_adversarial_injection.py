"""Frame names are untrusted (they come from logs): every generated artefact is parsed or run here
with hostile names — the ROS 2 launch file exec'd with stub ``launch`` modules, the tf-static
script and the document's ``ros2_static_transform`` line run by ``sh`` with a stub ``ros2`` —
and must carry the names intact as data, run no payload, and parse to exactly the expected
structure; a format that cannot carry a name refuses it. Logs with a hostile frame id are refused
at read time (one line, exit 2, no output)."""
from __future__ import annotations

import ast
import html.parser
import json
import os
import re
import subprocess
import sys
import types
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from _logs import ODOM, TF, Channel, pose_channel, records, write_mcap
from _util import run

from handeye_cli import document
from handeye_cli.calibration import Inputs
from handeye_cli.errors import ConfigError, HandEyeError
from handeye_cli.geometry import se3
from handeye_cli.output.document import render, static_transform_command
from handeye_cli.output.formats import ALL_FORMATS, render_format
from handeye_cli.rig.result import transform_entry
from handeye_cli.simulation import Rig, random_transform, simulate_rig

# issue 36: run under -W error, every warning a failure (an unclosed file or pipe: its ResourceWarning,
# reported at garbage collection as PytestUnraisableExceptionWarning); not a filter to hide one
pytestmark = pytest.mark.filterwarnings("error")

MARK = "PWNED_MARKER"     # replaced by a path in the test's folder: the payloads create that file


def hostile_names(marker: Path) -> list[str]:
    """Names that break out of a Python docstring or string, a shell comment or word, an XML
    comment or attribute, a YAML comment — each payload would create ``marker``."""
    m = str(marker)
    py = f"import pathlib; pathlib.Path({m!r}).touch()"
    return [
        f'cam"""\n{py}\n"""', f"cam'''\n{py}\n'''", f"cam'\n{py}\n'", f'cam"\n{py}\n"',
        f"cam\ntouch {m}\n", f"cam;touch {m}", f"cam$(touch {m})", f"cam`touch {m}`", f"cam' ; touch {m} ; '",
        f'cam" ; touch {m} ; "', f"cam\\\ntouch {m}", f"cam\r\ntouch {m}",
        "cam--><evil/><!--", "cam]]><evil/>", "cam--", "cam-", "<!--", "cam&amp;<x>",
        f"cam\u2028{py}", f"cam\u2029{py}", f"cam\x85{py}", "cam\x00evil", "cam\x1b[2Jevil",
        "cam\ncam1:\n  T_cam_imu: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]",
        "cam ${evil}", "a" * 300,
    ]


def _doc(a: str, b: str) -> dict:
    X = random_transform(np.random.default_rng(1), 1.0)
    t, q = se3.to_xyz_quat(X)
    return {"matrix": X.tolist(), "translation": t.tolist(), "quaternion_xyzw": q.tolist(), "frames": {"a": a, "b": b},
            "method": "dqopt", "pairs_used": 10, "version": "0.2.0", "warnings": [a],
            "ros2_static_transform": static_transform_command(t, q, {"a": a, "b": b})}


def _rig_doc(ref: str, child: str) -> dict:
    rng = np.random.default_rng(2)
    return {"reference": ref, "version": "0.2.0",
            "transforms": [transform_entry(ref, child, random_transform(rng, 1.0)),
                           transform_entry(ref, "lidar", random_transform(rng, 1.0))]}


def _pairs(doc: dict) -> list[tuple[str, str]]:
    if "transforms" in doc:
        return [(t["parent"], t["child"]) for t in doc["transforms"]]
    return [(doc["frames"]["a"], doc["frames"]["b"])]


# --- what each format cannot carry (the test's own statement of the rules) ------------------------
def _xml_cannot(name: str) -> bool:
    return bool(re.search("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]", name)) or "$(" in name \
        or "${" in name


def _refused(fmt: str, names: list[str]) -> bool:
    if fmt in ("urdf", "urdf-joint"):
        return any(_xml_cannot(n) for n in names)
    if fmt == "ros1-launch":        # args are split at whitespace: only names tf2 accepts
        return any(_xml_cannot(n) or re.search(r"[\s'\"`\\]", n) or not n.isprintable() or len(n) > 256
                   for n in names)
    if fmt == "tf-static":
        return any("\0" in n for n in names)
    return False


# --- the checks, one per format ---------------------------------------------------------------------
def _check_yaml(text: str, doc: dict) -> None:
    _check_parsed(yaml.safe_load(text), doc)


def _check_json(text: str, doc: dict) -> None:
    _check_parsed(json.loads(text), doc)


def _check_parsed(parsed: dict, doc: dict) -> None:
    assert list(parsed) == list(doc)
    assert _pairs(parsed) == _pairs(doc)
    if "warnings" in doc:
        assert parsed["warnings"] == doc["warnings"]


def _check_kalibr(text: str, doc: dict) -> None:
    parsed = yaml.safe_load(text)
    assert list(parsed) == [f"cam{i}" for i in range(len(_pairs(doc)))]
    assert all(set(v) == {"T_cam_imu", "T_imu_cam"} for v in parsed.values())
    comments = [line for line in text.splitlines() if line.startswith("#")]
    assert len(comments) == 2 and all(not line.startswith("#") for line in text.splitlines()[2:])


def _xml(text: str) -> tuple[ET.Element, list[str]]:
    """The root element and the text of every comment (the prolog's too)."""
    parser = ET.XMLPullParser(events=("comment",))
    parser.feed(text)
    parser.close()
    return ET.fromstring(text), [str(e.text) for _, e in parser.read_events()]


def _check_urdf(text: str, doc: dict) -> None:
    pairs = _pairs(doc)
    root, comments = _xml(text)
    assert len(comments) == 1 and "\n" not in comments[0]
    assert {e.tag for e in root.iter()} == {"robot", "link", "joint", "parent", "child",
                                                                        "origin"}
    joints = root.findall("joint")
    assert [(j.find("parent").get("link"), j.find("child").get("link")) for j in joints] == pairs
    assert [link.get("name") for link in root.findall("link")] == list(dict.fromkeys(n for p in pairs for n in p))


def _check_urdf_joint(text: str, doc: dict) -> None:
    """The joints alone: pasted into a <robot>, the same joints as the whole URDF, and no link."""
    assert "<robot" not in text and "<link" not in text
    root, comments = _xml(f"<robot>{text}</robot>")
    assert len(comments) == 1 and "\n" not in comments[0]
    assert {e.tag for e in root.iter()} == {"robot", "joint", "parent", "child", "origin"}
    assert [(j.find("parent").get("link"), j.find("child").get("link")) for j in root.findall("joint")] == _pairs(doc)


def _check_ros1(text: str, doc: dict) -> None:
    root, comments = _xml(text)
    assert len(comments) == 1 and "\n" not in comments[0]
    assert {e.tag for e in root.iter()} == {"launch", "node"}
    assert [tuple(n.get("args").split()[-2:]) for n in root.findall("node")] == _pairs(doc)
    assert all(len(n.get("args").split()) == 9 for n in root.findall("node"))


def _check_ros2(text: str, doc: dict, marker: Path, monkeypatch) -> None:
    tree = ast.parse(text)
    assert [type(s).__name__ for s in tree.body] == ["Expr", "ImportFrom", "ImportFrom", "FunctionDef"]
    assert isinstance(ast.get_docstring(tree), str)
    calls: list[dict] = []
    launch, launch_ros, actions = (types.ModuleType(n) for n in ("launch", "launch_ros", "launch_ros.actions"))
    launch.LaunchDescription = lambda entities: ("LaunchDescription", entities)       # type: ignore[attr-defined]
    actions.Node = lambda **kw: calls.append(kw) or kw                              # type: ignore[attr-defined]
    launch_ros.actions = actions                                                    # type: ignore[attr-defined]
    for name, module in (("launch", launch), ("launch_ros", launch_ros), ("launch_ros.actions", actions)):
        monkeypatch.setitem(sys.modules, name, module)
    namespace: dict = {"__name__": "generated_launch"}
    exec(compile(tree, "generated.launch.py", "exec"), namespace)                   # the point of the test
    description = namespace["generate_launch_description"]()
    assert description[0] == "LaunchDescription" and len(description[1]) == len(_pairs(doc))
    assert [(c["package"], c["executable"]) for c in calls] == [("tf2_ros", "static_transform_publisher")] * len(calls)
    assert [(c["arguments"][15], c["arguments"][17]) for c in calls] == _pairs(doc)
    assert all(len(c["arguments"]) == 18 and c["arguments"][14] == "--frame-id" for c in calls)
    assert not marker.exists()


def _stub_ros2(tmp_path: Path) -> dict[str, str]:
    """PATH with a ``ros2`` that appends its argv, NUL-separated, one record per call, to argv.log."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir(exist_ok=True)
    stub = bin_dir / "ros2"
    stub.write_text('#!/bin/sh\nfor a in "$@"; do printf \'%s\\0\' "$a"; done >> "$ARGV_LOG"\nprintf \'\\n\' '
                    '>> "$ARGV_LOG"\n')
    stub.chmod(0o755)
    return {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ['PATH']}", "ARGV_LOG": str(tmp_path / "argv.log")}


def _run_sh(tmp_path: Path, args: list[str]) -> list[list[str]]:
    log = tmp_path / "argv.log"
    log.unlink(missing_ok=True)
    done = subprocess.run(["sh", *args], env=_stub_ros2(tmp_path), cwd=tmp_path, capture_output=True, timeout=10)
    assert done.returncode == 0, done.stderr
    return [rec.split("\0") for rec in log.read_bytes().decode().split("\0\n")[:-1]]


def _check_shell(text: str, doc: dict, tmp_path: Path, marker: Path) -> None:
    script = tmp_path / "tf.sh"
    script.write_text(text)
    calls = _run_sh(tmp_path, [str(script)])
    assert [(c[:3], c[17:]) for c in calls] == \
        [(["run", "tf2_ros", "static_transform_publisher"], ["--frame-id", a, "--child-frame-id", b])
         for a, b in _pairs(doc)]
    assert all(len(c) == 21 for c in calls)
    assert not marker.exists()


CHECKS = {"yaml": _check_yaml, "json": _check_json, "kalibr": _check_kalibr, "urdf": _check_urdf,
          "urdf-joint": _check_urdf_joint,
          "ros1-launch": _check_ros1}


@pytest.mark.parametrize("rig", [False, True], ids=["calibrate", "rig"])
@pytest.mark.parametrize("fmt", ALL_FORMATS)
def test_every_format_carries_hostile_names_as_data(fmt, rig, tmp_path, monkeypatch):
    marker = tmp_path / "pwned"
    checked = refused = 0
    for name in hostile_names(marker):
        for a, b in ((name, "imu"), ("cam0", name)):
            doc = _rig_doc(a, b) if rig else _doc(a, b)
            if _refused(fmt, [a, b]):
                with pytest.raises(ConfigError, match="cannot be written as"):
                    render_format(doc, fmt)
                refused += 1
                continue
            text = render_format(doc, fmt)
            if fmt == "ros2-launch":
                _check_ros2(text, doc, marker, monkeypatch)
            elif fmt == "tf-static":
                _check_shell(text, doc, tmp_path, marker)
            else:
                CHECKS[fmt](text, doc)
            checked += 1
    assert not marker.exists()
    assert checked >= 10 and refused == sum(_refused(fmt, [n, "imu"]) + _refused(fmt, ["cam0", n])
                                            for n in hostile_names(marker))


def test_json_output_is_strict_even_with_non_finite_numbers():
    doc = {**_doc("cam0", "imu"), "time_offset": {"std_s": float("nan")}, "scale": [float("inf"), -float("inf")]}
    parsed = json.loads(render(doc, "json"), parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))
    assert parsed["time_offset"]["std_s"] is None and parsed["scale"] == [None, None]
    assert yaml.safe_load(render(doc, "yaml"))["time_offset"]["std_s"] is None      # YAML says the same


def test_the_documents_command_line_runs_as_one_command_with_intact_names(tmp_path):
    marker = tmp_path / "pwned"
    for name in hostile_names(marker):
        if "\0" in name:
            continue                                   # no shell word holds NUL (the tf-static writer refuses it)
        line = _doc(name, "imu")["ros2_static_transform"]
        calls = _run_sh(tmp_path, ["-c", line])
        assert len(calls) == 1 and calls[0][17:] == ["--frame-id", name, "--child-frame-id", "imu"]
    assert not marker.exists()


# --- HTML reports -------------------------------------------------------------------------------
class _Tags(html.parser.HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.tags: set[str] = set()

    def handle_starttag(self, tag: str, attrs: list) -> None:
        self.tags.add(tag)


def _tags(text: str) -> set[str]:
    p = _Tags()
    p.feed(text)
    return p.tags


def test_reports_escape_hostile_names(tmp_path):
    from handeye_cli.calibration import calibrate
    from handeye_cli.output.fleet_report import render_fleet_report
    from handeye_cli.output.records import BatchRecord
    from handeye_cli.output.report import render_report

    evil = "cam<script>alert(1)</script><img src=x onerror=alert(2)>'\""
    a, b = simulate_rig(Rig(random_transform(np.random.default_rng(3), 0.3)), duration_s=8.0, seed=4)
    cal = replace(calibrate(a, b), warnings=["a plain warning"])
    hostile = replace(cal, stream_a=replace(cal.stream_a, child_frame_id=evil), warnings=[evil], inputs=Inputs(a=evil))
    assert hostile.frames["a"] == evil                            # in the header, the inputs and the ROS 2 line
    assert _tags(render_report(hostile)) == _tags(render_report(cal))
    plain_doc = document(cal)
    record = {"input": evil, "status": "ok", "matrix": plain_doc["matrix"], "frames": {"a": evil, "b": "imu"},
              "log_span_ns": [1_700_000_000_000_000_000, 1_700_000_010_000_000_000]}
    failed = {"input": evil, "status": "error", "error": evil}
    benign = {**record, "input": "x", "frames": {"a": "cam", "b": "imu"}}
    def fleet(*records):
        return _tags(render_fleet_report([BatchRecord.from_record(r) for r in records]))

    assert fleet(record, failed) == fleet(benign, {**failed, "input": "x", "error": "x"})


# --- reading: the policy is to refuse --------------------------------------------------------------
def _odom_log(path: Path, child_a: str, child_b: str = "cam1") -> Path:
    a, b = simulate_rig(Rig(random_transform(np.random.default_rng(5), 0.3)), duration_s=3.0, rate_a=10, rate_b=10,
                        seed=6)
    return write_mcap(path, [pose_channel("/a/odom", ODOM, records(a, "odom", child_a)),
                             pose_channel("/b/odom", ODOM, records(b, "map", child_b))])


@pytest.mark.parametrize("name", ['cam"""\nimport os\n"""', "cam;touch x", "cam\u2028x", "cam\x00", "c am"])
def test_a_log_with_a_hostile_child_frame_id_is_refused_in_one_line(name, tmp_path, capsys):
    log = _odom_log(tmp_path / "field.mcap", name)
    out = tmp_path / "x.launch.py"
    code, stdout, err = run(capsys, "calibrate", log, "--topic-a", "/a/odom", "--topic-b", "/b/odom", "-o", out, "-q")
    assert code == 2 and not out.exists() and stdout == ""
    assert err.count("\n") == 1 and err.startswith("error: child_frame_id ")
    assert f"{log}:/a/odom" in err and "not a valid frame id" in err


def test_a_hostile_frame_on_a_tf_chain_is_refused(tmp_path, capsys):
    a, _ = simulate_rig(Rig(np.eye(4)), duration_s=3.0, rate_a=10, seed=7)
    evil = "mount\nimport os"
    dynamic = [(int(t), [(int(t), "world", evil, *map(float, p), *map(float, q))])
               for t, p, q in zip(a.stamps_ns, a.xyz, a.quat_xyzw, strict=True)]
    static = [(int(a.stamps_ns[0]), [(int(a.stamps_ns[0]), evil, "cam0", 0.1, 0, 0, 0, 0, 0, 1)])]
    log = write_mcap(tmp_path / "tf.mcap", [Channel("/tf", TF, dynamic),
                                            Channel("/tf_static", TF, static, static=True)])
    from handeye_cli.io import read_stream
    with pytest.raises(HandEyeError, match="not a valid frame id") as info:
        read_stream(log, frames=("world", "cam0"))
    assert "\n" not in str(info.value) and "tf.mcap" in str(info.value)


@pytest.mark.parametrize("value", ["cam\n0", "cam'0", 'cam"0', "cam\u20280", "cam 0", "cam\x000"])
def test_names_given_by_users_obey_the_same_rule(value, capsys, rig, tmp_path):
    code, _, err = run(capsys, "calibrate", rig["a"], rig["b"], "--name-a", value, "-o", tmp_path / "x.yaml")
    assert code == 2 and err.startswith("error: bad frame name") and err.count("\n") == 1
    from handeye_cli.rig import parse_stream
    with pytest.raises(ConfigError, match="bad frame name"):
        parse_stream(f"{value}=/cam0/pose")


def test_a_warning_quoting_a_hostile_name_stays_one_line(capsys):
    """Warnings quote topic and file names from a log: a newline or a terminal escape in one is written as
    its escape, so a CI log shows one `warning:` line and a terminal runs no escape sequence."""
    from handeye_cli.cli.common import warn

    warn("dropped 3 samples of log.mcap:/cam\nwarning: forged\x1b[2J\u2028line")
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("warning: ") and "\x1b" not in err and "\u2028" not in err
    assert "\\n" in err and "\\x1b" in err
