"""One vocabulary across the commands and the Python API (issue 21): which options a command takes is the
options' scope data; rig takes calibrate's stream options per stream; --report and -q mean one thing or are
refused in one line; one --format vocabulary (with a URDF joint snippet); the CLI and Python accept and refuse
the same values with the same defaults, naming the flag and the keyword respectively."""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from importlib import import_module

import click
import numpy as np
import pytest
import yaml
from _util import ROOT, pose_error, run, write_tum

import handeye_cli
from handeye_cli.cli import COMMANDS, cli
from handeye_cli.cli.params import _default_text, per_stream_forms, scoped
from handeye_cli.errors import ConfigError, HandEyeError
from handeye_cli.geometry import se3
from handeye_cli.io.nominal import read_nominal
from handeye_cli.options import FIELDS, flag, optional_flag
from handeye_cli.output.formats import ALL_FORMATS, SUMMARY_FORMATS
from handeye_cli.rig import RigOptions
from handeye_cli.simulation import Rig, simulate_rig

X = se3.from_xyz_quat(np.array([0.1, -0.05, 0.2]), np.array([0.1, 0.3, -0.2, 0.9]))


def _command(name: str) -> click.Command:
    command = getattr(import_module(f"handeye_cli.cli.{COMMANDS[name]}"), name)
    assert isinstance(command, click.Command)
    return command


def _flags(command: click.Command) -> set[str]:
    """The flags a command takes (a hidden one is a refusal: it takes no value, test_report_and_quiet_…)."""
    assert all(not p.expose_value for p in command.params if getattr(p, "hidden", False))
    return {opt for p in command.params if not getattr(p, "hidden", False) for opt in (*p.opts, *p.secondary_opts)}


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_command_takes_exactly_the_options_its_scope_names(name):
    command = _command(name)
    params = {p.name for p in command.params if not getattr(p, "hidden", False)}
    scope = set(scoped(name))
    assert params & set(FIELDS) == scope                     # each option in scope: a flag of its own name
    assert scope == {k for k, (_, info, _) in FIELDS.items() if name in info.commands}
    flags = _flags(command)
    for key in set(FIELDS) - scope:                           # ... and none out of scope under its name
        dashed = "--" + key.replace("_", "-")
        per = FIELDS[key][1].per_stream
        assert dashed not in flags or (name == "rig" and per and dashed == "--" + per.replace("_", "-")), key
    if name == "rig":                                          # rig: calibrate's stream options, per stream
        for form, keys in per_stream_forms().items():
            if form == "name":                                 # a stream's name is --stream NAME=…
                assert "--stream" in flags
                continue
            assert "--" + form.replace("_", "-") in flags
            if FIELDS[keys[0]][1].parse is optional_flag:
                assert "--no-" + form.replace("_", "-") in flags


def test_rig_and_batch_and_calibrate_share_the_scope_of_pair_options():
    assert set(scoped("batch")) == set(scoped("calibrate")) == set(scoped("compare"))
    # rig: every pair option but those of stream a/b (taken per stream); its prior is the nominal of every sensor
    assert set(scoped("rig")) == {k for k in scoped("calibrate") if not FIELDS[k][1].per_stream}
    assert set(scoped("solve")) == {"method", "alpha", "prior", "prior_weights", "robust", "bootstrap", "seed"}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Two TUM files (20 s, 10/8 Hz): a, and b with its translations in half-metres (monocular-like)."""
    d = tmp_path_factory.mktemp("vocab")
    a, b = simulate_rig(Rig(X, 0), duration_s=20, rate_a=10, rate_b=8, sigma_r=np.deg2rad(0.05), sigma_t=0.0005,
                        seed=3)
    half = type(b)(b.stamps_ns, b.xyz * 2.0, b.quat_xyzw)
    wxyz = d / "b_wxyz.tum"
    np.savetxt(wxyz, np.c_[b.stamps_ns / 1e9, b.xyz, b.quat_xyzw[:, [3, 0, 1, 2]]], fmt="%.9f")
    return {"a": write_tum(d / "a.tum", a), "b": write_tum(d / "b.tum", b), "half": write_tum(d / "half.tum", half),
            "wxyz": wxyz, "dir": d}


def _rig(capsys, files, *args):
    code, out, err = run(capsys, "rig", "--pairs", "consecutive", "--format", "json", "-q", *args)
    return code, (json.loads(out) if code == 0 else None), err


def _T(doc) -> np.ndarray:
    t = doc["transforms"][0]
    return se3.from_xyz_quat(np.asarray(t["translation"]), np.asarray(t["quaternion_xyzw"]))


def test_rig_takes_scale_per_stream_as_calibrate_takes_it(capsys, files):
    streams = ("--stream", f"a={files['a']}", "--stream", f"b={files['half']}")
    code, doc, err = _rig(capsys, files, *streams, "--scale", "b=0.5")
    assert code == 0, err
    assert pose_error(_T(doc), X)[1] < 0.01 and doc["settings"]["scales"] == {"b": {"value": 0.5}}
    code, doc, err = _rig(capsys, files, *streams, "--scale", "b=auto")
    assert code == 0, err
    assert abs(doc["settings"]["scales"]["b"]["value"] - 0.5) < 0.01 and pose_error(_T(doc), X)[1] < 0.01
    code, _, err = _rig(capsys, files, *streams, "--scale", "b=fast")
    assert code == 2 and err.strip().splitlines()[-1] == (
        "error: bad value 'fast' (--scale): give a number of metres per unit of stream b > 0, or 'auto'")


def test_rig_takes_wxyz_and_no_invert_per_stream_and_a_bare_time_offset(capsys, files):
    code, doc, err = _rig(capsys, files, "--stream", f"a={files['a']}", "--stream", f"b={files['wxyz']}",
                          "--wxyz", "b", "--no-invert", "a", "--time-offset", "0")
    assert code == 0, err
    assert pose_error(_T(doc), X)[0] < 0.2
    s = doc["settings"]
    assert s["wxyz"] == {"b": True} and s["not_inverted"] == ["a"] and s["time_offsets"] == {"b": 0.0}
    code, _, err = _rig(capsys, files, "--stream", f"a={files['a']}", "--stream", f"b={files['b']}",
                        "--invert", "b", "--no-invert", "b")
    assert code == 2 and "both --invert and --no-invert" in err


def test_rig_refuses_name_a_naming_the_stream_flag_that_names_a_sensor(capsys, files):
    """Issue 21 ('rig lacks --name-*'): a rig's sensor is named by --stream NAME=…, which is its frame in every
    output; calibrate's --name-a/-b are refused in one line saying so, not click's bare 'No such option'."""
    for side in "ab":
        code, _, err = _rig(capsys, files, "--stream", f"a={files['a']}", "--stream", f"b={files['b']}",
                            f"--name-{side}", "cam")
        line = err.strip().splitlines()
        assert code == 2 and len(line) == 1 and f"(--name-{side}):" in line[0] and "--stream NAME=SOURCE" in line[0]
    code, doc, err = _rig(capsys, files, "--stream", f"cam={files['a']}", "--stream", f"imu={files['b']}")
    assert code == 0 and (doc["transforms"][0]["parent"], doc["transforms"][0]["child"]) == ("cam", "imu"), err


def test_time_offset_default_is_one_everywhere():
    default = FIELDS["time_offset"][2]
    assert default == "auto"
    for name in ("calibrate", "batch", "compare"):
        (p,) = [p for p in _command(name).params if p.name == "time_offset"]
        assert p.default is None and f"[default: {default}]" in (p.help or "")     # None: options.py's default
    (p,) = [p for p in _command("rig").params if p.name == "time_offset_values"]
    assert f"[default: {default}]" in (p.help or "")


def test_report_and_quiet_mean_one_thing_or_are_refused(capsys, files, tmp_path):
    pairs = tmp_path / "pairs.csv"
    code, _, err = run(capsys, "solve", ROOT / "sample_data" / "pairs.csv")
    assert code == 0 and err.startswith("T_a_") and "pairs" in err       # the summary, as calibrate prints it
    code, out, err = run(capsys, "solve", ROOT / "sample_data" / "pairs.csv", "-q")
    assert code == 0 and "matrix:" in out and err == ""
    for args in (("solve", pairs, "--report", tmp_path / "r.html"), ("check", pairs, "--report", tmp_path / "r.html"),
                 ("check", pairs, "-q"),
                 ("report", pairs, "-o", tmp_path / "f.html", "--report", tmp_path / "r.html")):
        code, _, err = run(capsys, *args)
        line = err.strip().splitlines()
        flag_ = "-q" if "-q" in args else "--report"
        assert code == 2 and len(line) == 1 and line[0].startswith("error: ") and f"({flag_}):" in line[0], (args, err)
    report = tmp_path / "compare.html"
    code, out, err = run(capsys, "compare", files["a"], files["b"], "--pairs", "consecutive", "--report", report,
                         "-q")
    assert code == 0 and "dqopt" in out and report.read_text(encoding="utf-8").startswith("<!DOCTYPE html>")


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_one_format_vocabulary(name):
    (fmt,) = [p for p in _command(name).params if p.name == "fmt"] or [None]
    if name in ("calibrate", "solve", "rig", "batch"):
        assert fmt is not None and tuple(fmt.type.choices) == ALL_FORMATS        # batch: of --output-dir's files
    elif name in ("check", "compare", "inspect"):
        assert fmt is not None and tuple(fmt.type.choices) == SUMMARY_FORMATS
    else:
        assert fmt is None                                                      # report writes HTML only


def test_batch_output_dir_writes_every_result_format(capsys, files, tmp_path):
    fleet = tmp_path / "robot01"
    fleet.mkdir()
    for name in ("a", "b"):
        (fleet / f"{name}.tum").symlink_to(files[name])
    for fmt in ALL_FORMATS:
        out = tmp_path / fmt
        code, records, err = run(capsys, "batch", fleet, "--pairs", "consecutive", "-j", "1", "-q", "--output-dir",
                                 out, "--format", fmt)
        assert code == 0 and json.loads(records)["status"] == "ok", err
        (written,) = [p for p in out.iterdir() if not p.name.endswith(".handeye.json") or fmt == "json"]
        X_read = read_nominal(written).transform(*json.loads(records)["frames"].values())
        assert np.allclose(X_read, json.loads(records)["matrix"], atol=1e-9), fmt


def test_urdf_joint_pastes_into_a_robot_and_reads_back(capsys, files, tmp_path):
    code, out, err = run(capsys, "calibrate", files["a"], files["b"], "--pairs", "consecutive", "--name-a",
                         "base&link", "--name-b", "cam<1>", "--format", "urdf-joint", "-q")
    assert code == 0, err
    joint = ET.fromstring(f"<robot>{out}</robot>")
    assert [e.tag for e in joint] == ["joint"] and "<link" not in out and "<robot" not in out
    assert joint[0].find("parent").get("link") == "base&link" and joint[0].find("child").get("link") == "cam<1>"
    assert "&amp;" in out and "&lt;" in out                    # escaped by quoteattr
    robot = tmp_path / "robot.urdf"
    robot.write_text(f'<robot name="r"><link name="base&amp;link"/><link name="cam&lt;1&gt;"/>{out}</robot>',
                     encoding="utf-8")
    code, doc_text, _ = run(capsys, "calibrate", files["a"], files["b"], "--pairs", "consecutive", "--name-a",
                            "base&link", "--name-b", "cam<1>", "-q", "--format", "json")
    assert np.allclose(read_nominal(robot).transform("base&link", "cam<1>"), json.loads(doc_text)["matrix"],
                       atol=1e-9)


@pytest.mark.parametrize(("name", "fmt", "warned"), [("x.launch.xml", "ros2-launch", True), ("x.urdf", "json", True),
                                                     ("x.urdf", "urdf-joint", False), ("x.launch.py", "ros2-launch",
                                                                                        False)])
def test_a_name_that_says_another_format_is_one_warning(capsys, files, tmp_path, name, fmt, warned):
    code, _, err = run(capsys, "calibrate", files["a"], files["b"], "--pairs", "consecutive", "-q", "--format", fmt,
                       "-o", tmp_path / name)
    mismatch = [line for line in err.splitlines() if "though its name says" in line]
    assert code == 0 and len(mismatch) == int(warned)
    code, _, err = run(capsys, "rig", "--stream", f"a={files['a']}", "--stream", f"b={files['b']}", "--pairs",
                       "consecutive", "-q", "--format", fmt, "-o", tmp_path / f"rig-{name}")
    assert code == 0 and sum("though its name says" in line for line in err.splitlines()) == int(warned)
    assert not warned or mismatch[0].startswith(f"warning: {name} is written as --format {fmt}")


# Probe values per option: a valid one, a bad one, and the words every parser is asked about
PROBES = ("bogus", "auto", "off", "-1", "0.5", "3")


def _python(key: str, value) -> tuple[str, str | None]:
    """calibrate_files with the keyword (under gate paper, whose limits max_jump* are): refused naming what,
    or accepted (the missing file is then the error)."""
    try:
        handeye_cli.calibrate_files("missing_a.tum", "missing_b.tum", **{"gate": "paper", key: value})
    except ConfigError as e:
        return "refused", e.where
    except HandEyeError:
        return "accepted", None
    raise AssertionError("a missing file was read")


def _cli(capsys, key: str, value) -> tuple[str, str]:
    _, info, _ = FIELDS[key]
    dashed = "--" + key.replace("_", "-")
    args = [dashed if value else f"--no-{dashed[2:]}"] if info.parse in (flag, optional_flag) else [dashed, str(value)]
    gate = [] if key == "gate" else ["--gate", "paper"]
    code, _, err = run(capsys, "calibrate", "missing_a.tum", "missing_b.tum", *args, *gate)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    return ("accepted" if "file not found" in err else "refused"), err


@pytest.mark.parametrize("key", sorted(FIELDS))
def test_cli_flag_and_python_keyword_share_default_and_values(capsys, key):
    _, info, default = FIELDS[key]
    (param,) = [p for p in _command("calibrate").params if p.name == key]
    if not info.secret:     # the flag's default is "not given": options.py's, which its help shows
        shown = f"[default: {_default_text(default)}]" if "[default:" not in info.help else "[default: "
        assert param.default is None and (param.help or "").count("[default: ") == 1 and shown in (param.help or "")
    probes = (True, False) if info.parse in (flag, optional_flag) else (*PROBES, *info.choices,
                                                                         *(c.upper() for c in info.choices))
    for value in probes:
        py, where = _python(key, value)
        on_cli, line = _cli(capsys, key, value)
        assert on_cli == py, (key, value, line)
        if py == "refused":
            assert where == key                                    # Python: the keyword
            assert f"(--{key.replace('_', '-')})" in line or "Invalid value for '--" in line    # CLI: the flag


@pytest.mark.parametrize(("field", "flag_", "value"), [("time_offsets", "--time-offset", "soon"),
                                                       ("scales", "--scale", "-2")])
def test_rig_cli_and_python_refuse_alike_naming_flag_and_keyword(capsys, files, field, flag_, value):
    opts = RigOptions(**{field: {"b": value}})
    with pytest.raises(ConfigError) as e:
        handeye_cli.calibrate_rig_files(None, [f"a={files['a']}", f"b={files['b']}"], opts)
    assert e.value.where == field
    code, _, err = run(capsys, "rig", "--stream", f"a={files['a']}", "--stream", f"b={files['b']}", flag_,
                       f"b={value}")
    assert code == 2 and err.strip() == f"error: {e.value.what} ({flag_}): {e.value.fix}"


def test_command_line_help_keeps_examples_on_every_command():
    for name in COMMANDS:
        assert "Example" in (_command(name).help or ""), name
    assert cli.help and "Examples" in cli.help


def test_rig_settings_record_scale_as_yaml(capsys, files, tmp_path):
    out = tmp_path / "rig.yaml"
    code, _, err = run(capsys, "rig", "--stream", f"a={files['a']}", "--stream", f"b={files['half']}", "--scale",
                       "b=0.5", "--pairs", "consecutive", "-q", "-o", out)
    assert code == 0, err
    assert yaml.safe_load(out.read_text(encoding="utf-8"))["settings"]["scales"]["b"]["value"] == 0.5


def test_library_errors_name_keywords_and_the_cli_their_flags(capsys, files):
    with pytest.raises(ConfigError) as e:
        handeye_cli.load_options(preset="no-such-preset")
    assert e.value.where == "preset"
    with pytest.raises(ConfigError) as e:
        handeye_cli.calibrate_rig_files(None, [f"a={files['a']}", f"b={files['b']}"], RigOptions(block_s=0.0))
    assert e.value.where == "block_s"
    code, _, err = run(capsys, "rig", "--stream", f"a={files['a']}", "--stream", f"b={files['b']}", "--block", "0")
    assert code == 2 and err.strip() == f"error: {e.value.what} (--block): {e.value.fix}"
    code, _, err = run(capsys, "rig", "--stream", f"a={files['a']}")
    assert code == 2 and "(--stream)" in err


def test_a_nominal_frame_is_taken_from_the_topic_only_when_one_matches(capsys, tmp_path):
    """/cam0/pose names cam0 in a robot URDF; with a link 'pose' too, the topic names two: one clear line."""
    joints = ('<joint name="j0" type="fixed"><parent link="base"/><child link="cam0"/><origin xyz="0 0 1"/></joint>'
              '<joint name="j1" type="fixed"><parent link="cam0"/><child link="cam1"/>'
              '<origin xyz="0.168 -0.1792 0.1344" rpy="0.4525 0.7216 0.4525"/></joint>')
    log = ROOT / "sample_data" / "rig.mcap"
    for links, ok in (("base cam0 cam1", True), ("base cam0 cam1 pose", False)):
        extra = '<joint name="j2" type="fixed"><parent link="base"/><child link="pose"/></joint>' if not ok else ""
        urdf = tmp_path / "robot.urdf"
        urdf.write_text(f'<robot name="r">{"".join(f"<link name={chr(34)}{n}{chr(34)}/>" for n in links.split())}'
                        f"{joints}{extra}</robot>", encoding="utf-8")
        code, out, err = run(capsys, "calibrate", log, "--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose",
                             "--against", urdf, "--format", "json", "-q")
        if ok:
            assert code == 0 and json.loads(out)["verdict"]["nominal"]["frames"] == ["cam0", "cam1"], err
        else:
            assert code == 2 and len(err.strip().splitlines()) == 1 and "--name-a/--name-b" in err
            assert "'cam0_pose' is not in the nominal" in err


@pytest.mark.parametrize(("key", "value"), [("method", "DQopt"), ("method", "Tsai"), ("method", "bogus"),
                                            ("alpha", "AUTO"), ("alpha", "off"), ("alpha", "-1"), ("alpha", "2")])
def test_solve_cli_and_python_share_values_and_case_rule(capsys, key, value):
    from handeye_cli.io.pairfile import read_pairs

    pairs = ROOT / "sample_data" / "pairs.csv"
    A, B, w = read_pairs(pairs)
    try:
        handeye_cli.solve(A, B, weights=w, **{key: value})
        python = "accepted"
    except ConfigError as e:
        python = "refused"
        assert e.where == key
    code, out, err = run(capsys, "solve", pairs, f"--{key}", value, "-q")
    assert (code == 0) == (python == "accepted"), err
    assert python == "refused" or "matrix:" in out


# A stream is named the same way everywhere (issue 21): /topic, tf:PARENT,CHILD or FILE, parsed by one function
# (io.spec.stream_source) for calibrate, compare, batch (flags and per-input entries), rig and the Python API;
# --topic-a and --frames-a PARENT CHILD (topic_a, frames_a=(PARENT, CHILD)) are its synonyms.
RIG_LOG = ROOT / "sample_data" / "rig.mcap"
CONSECUTIVE = ("--pairs", "consecutive", "-q")


def _calibrated(capsys, *args) -> dict:
    code, out, err = run(capsys, "calibrate", *args, *CONSECUTIVE, "--format", "json")
    assert code == 0, err
    return json.loads(out)


@pytest.fixture(scope="module")
def log_pair():
    """The Python API's calibration of rig.mcap's /cam0/pose against the TF chain odom → cam1."""
    return handeye_cli.calibrate_files(RIG_LOG, stream_a="/cam0/pose", stream_b="tf:odom,cam1", pairs="consecutive")


def test_calibrate_and_python_name_a_stream_in_one_spelling_and_its_synonyms(capsys, log_pair):
    shared = _calibrated(capsys, RIG_LOG, "--stream-a", "/cam0/pose", "--stream-b", "tf:odom,cam1")
    synonyms = _calibrated(capsys, RIG_LOG, "--topic-a", "/cam0/pose", "--frames-b", "odom", "cam1")
    assert shared["matrix"] == synonyms["matrix"] == log_pair.matrix.tolist() and shared["inputs"] == synonyms["inputs"]
    assert shared["inputs"]["a"]["topic"] == "/cam0/pose" and shared["inputs"]["b"]["frames"] == ["odom", "cam1"]


def test_batch_names_a_stream_in_one_spelling_in_flags_and_per_input_entries(capsys, tmp_path, log_pair):
    code, out, err = run(capsys, "batch", RIG_LOG, "--stream-a", "/cam0/pose", "--stream-b", "tf:odom,cam1",
                         *CONSECUTIVE, "-j", "1")
    assert code == 0 and json.loads(out)["matrix"] == log_pair.matrix.tolist(), err
    (tmp_path / "p.yaml").write_text('"rig.mcap": {stream_b: "tf:odom,cam1"}\n', encoding="utf-8")
    code, out, err = run(capsys, "batch", RIG_LOG, "--stream-a", "/cam0/pose", "--stream-b", "/cam1/pose",
                         "--per-input", tmp_path / "p.yaml", *CONSECUTIVE, "-j", "1")
    assert code == 0 and json.loads(out)["matrix"] == log_pair.matrix.tolist(), err     # the entry's stream b


def test_rig_names_a_stream_in_one_spelling_on_the_command_line_and_in_python(capsys):
    streams = ["cam0=/cam0/pose", "cam1=tf:odom,cam1"]
    code, out, err = run(capsys, "rig", RIG_LOG, *(w for s in streams for w in ("--stream", s)), *CONSECUTIVE,
                         "--format", "json")
    assert code == 0, err
    rig = handeye_cli.calibrate_rig_files(str(RIG_LOG), streams, RigOptions(options=handeye_cli.load_options(
        pairs="consecutive")))
    assert json.loads(out)["transforms"][0]["translation"] == rig.document()["transforms"][0]["translation"]
    assert rig.document()["inputs"]["streams"]["cam1"]["frames"] == ["odom", "cam1"]


def test_a_file_source_is_a_stream_of_its_own_in_calibrate_and_python(capsys, files):
    positional = _calibrated(capsys, files["a"], files["b"])
    assert _calibrated(capsys, "--stream-a", files["a"], "--stream-b", files["b"])["matrix"] == positional["matrix"]
    assert _calibrated(capsys, files["a"], "--stream-b", files["b"])["matrix"] == positional["matrix"]
    cal = handeye_cli.calibrate_files(stream_a=str(files["a"]), stream_b=str(files["b"]), pairs="consecutive")
    assert cal.matrix.tolist() == positional["matrix"]
    code, _, err = run(capsys, "calibrate", files["a"], files["a"], "--stream-b", files["b"])
    assert code == 2 and "2 inputs given for 1 stream(s)" in err, err
    code, _, err = run(capsys, "calibrate", "--stream-b", files["b"])
    assert code == 2 and err.startswith("error: no input given (inputs)") and "--stream-a FILE" in err, err


BAD_CHAIN = "bad TF chain 'tf:odom': it takes two frame names, PARENT CHILD"


@pytest.mark.parametrize("argv, flag_", [
    (("calibrate", RIG_LOG, "--stream-a", "tf:odom", "--stream-b", "/cam1/pose"), "(--stream-a)"),
    (("compare", RIG_LOG, "--stream-a", "/cam0/pose", "--stream-b", "tf:odom"), "(--stream-b)"),
    (("batch", RIG_LOG, "--stream-a", "tf:odom", "--stream-b", "/cam1/pose"), "(--stream-a)"),
    (("rig", RIG_LOG, "--stream", "a=tf:odom", "--stream", "b=/cam1/pose"), "(--stream)"),
])
def test_a_bad_tf_chain_is_refused_alike_by_every_command_naming_parent_child(capsys, argv, flag_):
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == "" and err.startswith(f"error: {BAD_CHAIN} {flag_}") and len(err.splitlines()) == 1
    assert "the parent first" in err and "tf:odom,base_link" in err


def test_the_python_api_and_a_per_input_entry_refuse_a_bad_chain_in_their_own_words(capsys, tmp_path):
    with pytest.raises(ConfigError) as info:
        handeye_cli.calibrate_files(RIG_LOG, stream_a="tf:odom", stream_b="/cam1/pose")
    assert str(info.value).startswith(f"{BAD_CHAIN} (stream_a)") and "stream_a='tf:odom,base_link'" in str(info.value)
    with pytest.raises(ConfigError, match=r"\(frames_a\): .*frames_a=\('odom', 'base_link'\)"):
        handeye_cli.calibrate_files(RIG_LOG, frames_a=("odom",), stream_b="/cam1/pose")
    with pytest.raises(ConfigError, match=rf"^{BAD_CHAIN} \(streams\)"):
        handeye_cli.calibrate_rig_files(str(RIG_LOG), ["a=tf:odom", "b=/cam1/pose"])
    with pytest.raises(ConfigError, match=r"stream a is named twice \(stream_a/topic_a\)"):
        handeye_cli.calibrate_files(RIG_LOG, stream_a="/cam0/pose", topic_a="/cam0/pose", stream_b="/cam1/pose")
    (tmp_path / "p.yaml").write_text('"*": {stream_a: "tf:odom"}\n', encoding="utf-8")
    code, _, err = run(capsys, "batch", RIG_LOG, "--per-input", tmp_path / "p.yaml")
    assert code == 2 and err.startswith(f"error: {BAD_CHAIN} ({tmp_path / 'p.yaml'}: *: stream_a)"), err


def test_every_install_hint_names_an_extra_of_this_distribution():
    """Issue 37: install hints named another distribution (``dask[distributed]``, ``fsspec s3fs``, ``gcsfs``),
    where a user of handeye installs its extras. Every ``pip install`` in the package's source installs
    ``'handeye-cli[EXTRA]'`` (or, in a checkout, ``'.[EXTRA]'``) with EXTRA one of pyproject's
    ``[project.optional-dependencies]``, and every hint names ``handeye-cli[``."""
    import re

    section = (ROOT / "pyproject.toml").read_text().split("[project.optional-dependencies]")[1].split("\n[")[0]
    extras = set(re.findall(r"^(\w+) = \[", section, re.M))          # tomllib is Python 3.11+
    assert {"dask", "remote", "gcs"} <= extras
    hints = 0
    for path in sorted((ROOT / "handeye_cli").rglob("*.py")):
        text = path.read_text()
        for m in re.finditer(r"pip install\s+(\S+)", text):
            hints += 1
            spec = re.match(r"'(handeye-cli|\.)\[(\w+)\]'", m.group(1))
            assert spec and spec.group(2) in extras, (path.name, m.group(0))
            line = text[text.rfind("\n", 0, m.start()) + 1:text.find("\n", m.end())]
            assert "handeye-cli[" in line or spec.group(1) == ".", (path.name, line)
        if "pip install" in text:
            assert "handeye-cli[" in text, path.name
    assert hints >= 4                                            # batch, the Dask engine, fsspec, a file system
    help_text = run_help("batch")
    assert "pip install 'handeye-cli[dask]'" in help_text and "dask[distributed]" not in help_text


def run_help(command: str) -> str:
    """``handeye COMMAND --help`` as printed (click's runner, unwrapped)."""
    from click.testing import CliRunner

    result = CliRunner().invoke(cli, [command, "--help"], terminal_width=1000)
    assert result.exit_code == 0, result.output
    return " ".join(result.output.split())
