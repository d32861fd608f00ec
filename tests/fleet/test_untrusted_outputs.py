"""Where handeye writes, in a folder others can write to (issue 36): a planted symbolic link is
replaced, never written through; a planted FIFO in ``--output-dir`` is replaced, never opened; a
full disk (a real ``RLIMIT_FSIZE``) is one line naming the folder; a FIFO among the logs is an
error record; a nominal whose numbers overflow is one line naming the joint, with warnings as errors.
Every hostile situation is made for real and every run goes through the command line."""
from __future__ import annotations

import errno
import json
import os
import resource
import shutil
import signal
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from _util import ROOT

# issue 36: run under -W error, every warning a failure (an unclosed file or pipe: its ResourceWarning,
# reported at garbage collection as PytestUnraisableExceptionWarning); not a filter to hide one
pytestmark = pytest.mark.filterwarnings("error")

LOG = ROOT / "sample_data" / "rig.mcap"
TRUTH = ROOT / "sample_data" / "truth.yaml"
TOPICS = ["--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose"]
VICTIM = b"the user's own file: not to be touched\n"


def _handeye(cwd: Path, *args: str, preexec=None, timeout: float = 60) -> subprocess.CompletedProcess:
    """``python -W error -m handeye_cli ARGS`` in ``cwd``, importing this checkout's package (not an
    installed one: a relative PYTHONPATH would not survive the change of folder)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-W", "error", "-m", "handeye_cli", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout, preexec_fn=preexec, stdin=subprocess.DEVNULL)


def _records(out: str) -> list[dict]:
    return [json.loads(line) for line in out.splitlines()]


def _log(path: Path) -> Path:
    """A copy of the sample log (copies, not links: a batch runs one input once, told by its inode)."""
    shutil.copyfile(LOG, path)
    return path


def _victim(tmp_path: Path) -> Path:
    victim = tmp_path / "victim.txt"
    victim.write_bytes(VICTIM)
    return victim


# --- 1. planted symbolic links ---------------------------------------------------------------

def test_a_planted_link_in_the_output_folder_is_replaced_and_its_target_untouched(tmp_path):
    victim = _victim(tmp_path)
    _log(tmp_path / "a.mcap")
    _log(tmp_path / "c.mcap")
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.mcap.yaml").symlink_to(victim)             # the name a.mcap's result takes
    os.mkfifo(out / "c.mcap.yaml")                       # a FIFO no one reads: opening it would block
    records = tmp_path / "records.jsonl"
    records.symlink_to(victim)
    report = tmp_path / "fleet.html"
    report.symlink_to(victim)
    done = _handeye(tmp_path, "batch", "a.mcap", "c.mcap", *TOPICS, "-q", "--jobs", "1", "--output-dir", "out",
                    "-o", "records.jsonl", "--report", "fleet.html", timeout=30)
    assert done.returncode == 0, done.stderr
    assert victim.read_bytes() == VICTIM
    for path in (out / "a.mcap.yaml", out / "c.mcap.yaml", records, report):
        assert not path.is_symlink() and path.is_file(), path
    assert "matrix:" in (out / "a.mcap.yaml").read_text() and "matrix:" in (out / "c.mcap.yaml").read_text()
    assert [r["status"] for r in _records(records.read_text())] == ["ok", "ok"]
    assert "<html" in report.read_text().lower()
    assert sorted(p.name for p in out.iterdir()) == ["a.mcap.yaml", "c.mcap.yaml"]      # no temporary left


def test_o_onto_a_planted_link_replaces_the_link_by_a_new_file(tmp_path):
    command = ["calibrate", str(LOG), *TOPICS, "-q"]
    victim = _victim(tmp_path)
    victim.chmod(0o600)                                  # the new file is not the target: not its mode either
    link = tmp_path / "result.json"
    link.symlink_to(victim)
    report = tmp_path / "report.html"
    report.symlink_to(victim)
    umask = os.umask(0o022)
    try:
        done = _handeye(tmp_path, *command, "-o", "result.json", "--report", "report.html")
    finally:
        os.umask(umask)
    assert done.returncode == 0, done.stderr
    assert victim.read_bytes() == VICTIM and not link.is_symlink() and link.read_text().lstrip().startswith("{")
    assert stat.S_IMODE(link.stat().st_mode) == 0o644 and stat.S_IMODE(victim.stat().st_mode) == 0o600
    assert not report.is_symlink() and "<html" in report.read_text().lower()
    # a link the user names to a device (as /dev/stdout is) is still written through
    device = tmp_path / "null.json"
    device.symlink_to(os.devnull)
    done = _handeye(tmp_path, *command, "-o", "null.json")
    assert done.returncode == 0, done.stderr
    assert device.is_symlink() and os.readlink(device) == os.devnull


def test_skip_done_does_not_trust_a_planted_link_to_a_result(tmp_path):
    _log(tmp_path / "a.mcap")
    first = _handeye(tmp_path, "batch", "a.mcap", *TOPICS, "-q", "--output-dir", "out")
    assert first.returncode == 0, first.stderr
    kept = tmp_path / "kept.yaml"                        # a result of the user's, planted under the name
    (tmp_path / "out" / "a.mcap.yaml").rename(kept)
    (tmp_path / "out" / "a.mcap.yaml").symlink_to(kept)
    before = kept.read_bytes()
    again = _handeye(tmp_path, "batch", "a.mcap", *TOPICS, "-q", "--output-dir", "out", "--skip-done")
    assert again.returncode == 0, again.stderr
    assert kept.read_bytes() == before and not (tmp_path / "out" / "a.mcap.yaml").is_symlink()
    assert _records(again.stdout)[0]["seconds"] > 0      # run again, not taken through the link


def test_skip_done_neither_reads_nor_appends_through_a_planted_records_link(tmp_path):
    _log(tmp_path / "a.mcap")
    victim = tmp_path / "victim.jsonl"                   # a record line: read through the link, a.mcap would be done
    victim.write_text('{"input": "a.mcap", "status": "ok", "seconds": 0}\n')
    before = victim.read_bytes()
    (tmp_path / "records.jsonl").symlink_to(victim)
    done = _handeye(tmp_path, "batch", "a.mcap", *TOPICS, "-q", "-o", "records.jsonl", "--skip-done")
    assert done.returncode == 0, done.stderr
    assert victim.read_bytes() == before and not (tmp_path / "records.jsonl").is_symlink()
    records = _records((tmp_path / "records.jsonl").read_text())
    assert [r["input"] for r in records] == ["a.mcap"] and records[0]["seconds"] > 0     # run, not taken


# --- 2. a full disk --------------------------------------------------------------------------

def _small_disk() -> None:
    """Files of this process may hold at most 1 kB: a write past it fails with EFBIG (SIGXFSZ ignored)."""
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (1024, 1024))


def test_a_full_disk_under_output_dir_is_one_line_naming_the_folder_and_every_record_says(tmp_path):
    for name in ("a.mcap", "c.mcap"):
        _log(tmp_path / name)
    done = _handeye(tmp_path, "batch", "a.mcap", "c.mcap", *TOPICS, "-q", "--jobs", "2", "--output-dir", "out",
                    preexec=_small_disk, timeout=30)
    records = _records(done.stdout)
    assert done.returncode == 2
    assert done.stderr.splitlines() == [
        f"error: cannot write the result files ({os.strerror(errno.EFBIG)}) (out): free space there or choose "
        "another --output-dir"]
    assert [(r["input"], r["status"], r["result_file"]) for r in records] == [("a.mcap", "error", None),
                                                                                ("c.mcap", "error", None)]
    assert all("matrix" in r for r in records) and list((tmp_path / "out").iterdir()) == []
    done = _handeye(tmp_path, "batch", "a.mcap", *TOPICS, "-q", "--output-dir", "out")
    assert done.returncode == 0 and done.stderr == ""
    assert _records(done.stdout)[0]["result_file"] == "out/a.mcap.yaml"


def test_calibrate_o_onto_a_full_disk_is_one_line_and_leaves_the_old_file_whole(tmp_path):
    old = tmp_path / "result.yaml"
    old.write_bytes(VICTIM)                              # an earlier result: a failed write must not cut it
    done = _handeye(tmp_path, "calibrate", LOG, *TOPICS, "-q", "-o", "result.yaml", preexec=_small_disk)
    assert done.returncode == 2
    assert done.stderr.splitlines() == [
        f"error: cannot write ({os.strerror(errno.EFBIG)}) (result.yaml): choose another -o path"]
    assert old.read_bytes() == VICTIM and sorted(p.name for p in tmp_path.iterdir()) == ["result.yaml"]


def test_a_planted_link_and_fifo_as_a_result_file_and_its_cache_are_replaced(tmp_path):
    victim = _victim(tmp_path)
    _log(tmp_path / "a.mcap")
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.mcap.urdf").symlink_to(victim)
    os.mkfifo(out / "a.mcap.urdf.handeye.json")          # the batch key's file (the cache): opening it would block
    done = _handeye(tmp_path, "batch", "a.mcap", *TOPICS, "-q", "--output-dir", "out", "--format", "urdf",
                    timeout=30)
    assert done.returncode == 0, done.stderr
    assert victim.read_bytes() == VICTIM
    assert all(not p.is_symlink() and p.is_file() for p in out.iterdir())
    assert sorted(p.name for p in out.iterdir()) == ["a.mcap.urdf", "a.mcap.urdf.handeye.json"]
    again = _handeye(tmp_path, "batch", "a.mcap", *TOPICS, "-q", "--output-dir", "out", "--format", "urdf",
                     "--skip-done")
    assert again.returncode == 0 and _records(again.stdout)[0]["seconds"] == _records(done.stdout)[0]["seconds"]


# --- 3. special files among the inputs ---------------------------------------------------------

def test_a_fifo_in_a_searched_folder_is_an_error_record_and_never_opened(tmp_path):
    logs = tmp_path / "logs"
    logs.mkdir()
    _log(logs / "a.mcap")
    os.mkfifo(logs / "b.mcap")                           # no one writes it: opening it would block the batch
    _log(logs / "c.mcap")
    done = _handeye(tmp_path, "batch", "--jobs", "2", "logs", *TOPICS, "-q", timeout=30)
    records = _records(done.stdout)
    assert done.returncode == 2 and done.stderr == ""
    assert [(r["input"], r["status"]) for r in records] == [("logs/a.mcap", "ok"), ("logs/b.mcap", "error"),
                                                            ("logs/c.mcap", "ok")]
    assert records[1]["error"].startswith("logs/b.mcap is a FIFO, not a log file")
    # named explicitly, alone: the same error record, no hang
    done = _handeye(tmp_path, "batch", "logs/b.mcap", *TOPICS, "-q", timeout=30)
    assert done.returncode == 2 and done.stderr == ""
    assert [(r["input"], r["status"]) for r in _records(done.stdout)] == [("logs/b.mcap", "error")]


# --- 5. nominals whose numbers overflow ----------------------------------------------------------

_HUGE = {
    "urdf": ("robot.urdf", '<robot name="r"><link name="a"/><link name="b"/><joint name="mount" type="fixed">'
             '<parent link="a"/><child link="b"/><origin xyz="1e308 1e308 0" rpy="0 0 0"/></joint></robot>',
             "joint mount"),
    "ros1-launch": ("tf.launch", '<launch><node pkg="tf2_ros" type="static_transform_publisher" name="s" '
                    'args="1e308 1e308 0 0 0 0 a b"/></launch>', "x y z yaw pitch roll"),
    "ros2-launch": ("tf.launch.py", "from launch import LaunchDescription\nfrom launch_ros.actions import Node\n"
                    "Node(package='tf2_ros', executable='static_transform_publisher',\n"
                    "     arguments=['0', '0', '0', '1e200', '0', '0', '1', 'a', 'b'])\n", "x y z qx qy qz qw"),
    "tf-static": ("tf.sh", "ros2 run tf2_ros static_transform_publisher --x 1e308 --y 1e308 --frame-id a "
                  "--child-frame-id b\n", "--x"),
    "kalibr": ("camchain.yaml", "cam0:\n  T_cam_imu: [[1, 0, 0, 1e308], [0, 1, 0, 1e308], [0, 0, 1, 0], "
               "[0, 0, 0, 1]]\n", "cam0.T_cam_imu"),
    "result": ("nominal.json", json.dumps({"frames": {"a": "a", "b": "b"}, "translation": [1e308, 1e308, 0],
                                           "quaternion_xyzw": [0, 0, 0, 1]}), "'translation'"),
}


@pytest.fixture(scope="module")
def result_file(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("result")
    done = _handeye(folder, "calibrate", LOG, *TOPICS, "-q", "-o", "r.yaml")
    assert done.returncode == 0, done.stderr
    return folder / "r.yaml"


@pytest.mark.parametrize("kind", _HUGE)
def test_a_nominal_whose_numbers_overflow_is_one_line_naming_the_file_and_field(kind, result_file, tmp_path):
    name, text, field = _HUGE[kind]
    (tmp_path / name).write_text(text)
    done = _handeye(tmp_path, "check", result_file, "--against", name, "--format", "json")
    assert done.returncode == 2 and done.stdout == ""
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and name in lines[0] and field in lines[0], lines
    assert "beyond ±1e+150" in lines[0]


def test_a_result_read_back_whose_numbers_overflow_is_one_line(result_file, tmp_path):
    import yaml

    doc = yaml.safe_load(result_file.read_text())
    doc["matrix"][0][3] = 1e308
    (tmp_path / "r.yaml").write_text(yaml.safe_dump(doc))
    done = _handeye(tmp_path, "check", "r.yaml", "--against", result_file, "--format", "json")
    assert done.returncode == 2 and done.stdout == ""
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and "'matrix'" in lines[0] and "r.yaml" in lines[0] and "beyond" in lines[0], lines
