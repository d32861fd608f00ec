"""A crash is never read as "a sensor drifted": every exception that is not a HandEyeError exits 4
with one line asking for a report (the traceback only under --debug), click's own failures exit 2,
and a crash while calibrating one batch input is that input's error record (exit 2, not 1)."""
from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys

import click
import numpy as np
import pytest
from _util import ROOT, run

from handeye_cli import __version__

SAMPLES = ROOT / "sample_data"
TOPICS = ["--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose"]

# command → (module, function it calls, arguments that reach that call)
INJECTED = {
    "calibrate": ("handeye_cli.cli.calibrate", "calibrate_specs", [SAMPLES / "rig.mcap", *TOPICS, "-q"]),
    "solve": ("handeye_cli.cli.solve", "read_pairs", [SAMPLES / "pairs.csv"]),
    "inspect": ("handeye_cli.io", "inspect_log", [SAMPLES / "rig.mcap"]),
    "rig": ("handeye_cli.cli.rig", "options_from_cli", [SAMPLES / "rig4.mcap", "--stream", "cam0=/cam0/pose",
                                                        "--stream", "cam1=/cam1/pose"]),
    "compare": ("handeye_cli.cli.compare", "calibrate_specs", [SAMPLES / "rig.mcap", *TOPICS, "-q"]),
    "check": ("handeye_cli.cli.check", "read_result", [SAMPLES / "truth.yaml", "--against", SAMPLES / "truth.yaml"]),
    "batch": ("handeye_cli.cli.batch", "run_batch", [SAMPLES / "rig.mcap", *TOPICS, "-q"]),
    "report": ("handeye_cli.output.fleet_report", "read_records", [SAMPLES / "truth.yaml", "-o", "r.html"]),
}


def _boom(*args: object, **kwargs: object) -> None:
    raise RuntimeError("injected\nfailure")


@pytest.mark.parametrize("command", sorted(INJECTED))
def test_a_crash_exits_4_with_one_line_and_the_traceback_only_under_debug(command, capsys, monkeypatch, tmp_path):
    module, name, args = INJECTED[command]
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(importlib.import_module(module), name, _boom)
    code, out, err = run(capsys, command, *args)
    assert code == 4 and out == ""
    assert err.splitlines() == [f"internal error: RuntimeError: injected failure — this is a bug in handeye "
                                f"{__version__}; please report it with the command line; rerun with --debug "
                                "for the traceback"]
    code, _, err = run(capsys, "--debug", command, *args)
    assert code == 4 and err.startswith("Traceback")
    assert "RuntimeError: injected" in err and err.splitlines()[-1].startswith("internal error: RuntimeError")
    assert not (tmp_path / "r.html").exists()


# handeye's own decoding functions and an input that reaches them: inside the generic MCAP reader's
# guard, a message decoder, inside the guard around opening a bag with rosbags
ROS1 = ("rig_ros1.bag", "--topic-a", "/cam0/odom", "--topic-b", "/cam1/pose")
DECODERS = {"mcap": ("handeye_cli.io.mcap_reader.breakup_chunk", ("rig_json.mcap", *TOPICS)),
            "message": ("handeye_cli.io.messages.extract", ROS1),
            "rosbags": ("handeye_cli.io.rosbag_reader.BagSource._with_suffix", ROS1)}


@pytest.mark.parametrize("error", [KeyError, IndexError, RuntimeError])
@pytest.mark.parametrize("decoder", sorted(DECODERS))
def test_a_bug_in_a_reader_is_an_internal_error_not_an_unreadable_file(capsys, monkeypatch, decoder, error):
    """KeyError, IndexError and RuntimeError raised by handeye's own decoders are bugs (exit 4): only the
    errors a library raises on corrupt input are "cannot read file" (exit 2)."""
    target, (log, *topics) = DECODERS[decoder]

    def bug(*args: object, **kwargs: object) -> None:
        raise error("injected")

    monkeypatch.setattr(target, bug)
    code, out, err = run(capsys, "calibrate", SAMPLES / log, *topics, "-q")
    assert code == 4 and out == "" and "cannot" not in err
    assert err.startswith(f"internal error: {error.__name__}: ")


def _bag_damaged(path, damage: str):
    """A one-topic ROS 1 bag (uncompressed chunk) damaged so that rosbags' own code raises a KeyError or an
    AssertionError: a message record whose time disagrees with the bag's index (rosbags checks it with
    ``assert``), or a message definition naming a type it does not define (the typestore's KeyError)."""
    from _logs import POSE, pose_channel, records, write_bag1

    from handeye_cli.simulation import Rig, simulate_rig

    a, _ = simulate_rig(Rig(np.eye(4)), duration_s=5.0, rate_a=20.0, rate_b=20.0, seed=7)
    data = write_bag1(path, [pose_channel("/a", POSE, records(a, "w", ""))]).read_bytes()
    if damage == "assert":
        stamp = data.index(b"time=", data.index(b"op=\x02")) + 5       # the first message record's stamp
        data = data[:stamp] + bytes([data[stamp] ^ 1]) + data[stamp + 1:]
    else:
        data = data.replace(b"geometry_msgs/Pose pose\n", b"geometry_msgs/Pxse pose\n")
    path.write_bytes(data)
    return path


@pytest.mark.parametrize(("damage", "what"), [
    ("assert", "cannot read file: AssertionError: in rosbags.rosbag1.reader ("),
    ("undefined", "cannot decode message: KeyError: 'geometry_msgs/msg/Pxse' (")])
def test_a_damaged_file_a_library_meets_with_its_own_key_or_assertion_error_is_bad_input(capsys, tmp_path,
                                                                                         damage, what):
    """The other side of the test above: raised inside rosbags' own code on a damaged bag, the same errors are
    "cannot read" (one line, exit 2), as a cut-off file is."""
    path = _bag_damaged(tmp_path / "d.bag", damage)
    code, out, err = run(capsys, "calibrate", path, "--topic-a", "/a", "--topic-b", "/a", "-q")
    assert code == 2 and out == "" and len(err.splitlines()) == 1
    assert err.startswith(f"error: {what}{path}"), err
    path.write_bytes(path.read_bytes()[:300])                         # cut short as well
    code, out, err = run(capsys, "calibrate", path, "--topic-a", "/a", "--topic-b", "/a", "-q")
    assert code == 2 and out == "" and len(err.splitlines()) == 1 and err.startswith("error: "), err


def test_a_crash_in_one_batch_input_is_its_error_record_not_a_drift(capsys, monkeypatch):
    from handeye_cli.fleet import engine

    real = engine._calibrate

    def crash_on_ros1(job):
        if job.input.paths[0].endswith(".bag"):
            raise RuntimeError("injected")
        return real(job)

    monkeypatch.setattr(engine, "_calibrate", crash_on_ros1)
    for jobs in ("1", "2"):                              # in this process, and in worker processes
        code, out, err = run(capsys, "batch", SAMPLES / "rig.mcap", SAMPLES / "rig_ros1.bag", *TOPICS, "-q",
                             "--jobs", jobs)
        records = [json.loads(line) for line in out.splitlines()]
        assert code == 2 and err == "" and [r["status"] for r in records] == ["ok", "error"]
        error = records[1]["error"]
        assert error.startswith("unexpected RuntimeError: injected (") and "--debug" in error


def test_click_failures_exit_2_never_1(capsys, monkeypatch):
    code, out, err = run(capsys, "calibrate", "a.tum", "--pairs")               # a usage error
    assert code == 2 and out == "" and "requires an argument" in err
    code, _, err = run(capsys, "batch", SAMPLES / "rig.mcap", "--jobs", "0")   # a bad parameter
    assert code == 2 and "--jobs" in err
    module = importlib.import_module("handeye_cli.cli.check")

    def generic(*args: object, **kwargs: object) -> None:
        raise click.ClickException("something click-ish")                     # exit_code 1 by default

    monkeypatch.setattr(module, "read_result", generic)
    code, _, err = run(capsys, "check", SAMPLES / "truth.yaml", "--against", SAMPLES / "truth.yaml")
    assert code == 2 and err.strip() == "error: something click-ish"


def test_keyboard_interrupt_exits_130(capsys, monkeypatch):
    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(importlib.import_module("handeye_cli.cli.solve"), "read_pairs", interrupted)
    code, out, err = run(capsys, "solve", SAMPLES / "pairs.csv")
    assert code == 130 and out == "" and err.strip() == "aborted"


@pytest.mark.parametrize("command", [["--version"], ["inspect", str(SAMPLES / "rig.mcap")]])
def test_a_closed_stdout_exits_2_not_1(command):
    read, write = os.pipe()
    os.close(read)                                    # every write to the pipe fails: EPIPE
    try:
        done = subprocess.run([sys.executable, "-m", "handeye_cli", *command], stdout=write,
                              stderr=subprocess.PIPE, text=True, timeout=60)
    finally:
        os.close(write)
    assert done.returncode == 2 and len(done.stderr.splitlines()) == 1
    assert done.stderr.startswith("error: cannot write to stdout (Broken pipe)")
