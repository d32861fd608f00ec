"""``handeye batch`` on hostile inputs and environments (issue 20): result names that collide,
FIFOs, symlink loops, a per-input time limit, signals to the batch, a full disk, list files with
odd line breaks, stdout on a full disk, and the mode of a replaced result file."""
from __future__ import annotations

import contextlib
import copy
import errno
import glob
import json
import os
import shutil
import signal
import stat
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml
from _util import ROOT, run

from handeye_cli.fleet import BatchInput, Job, Streams, engine
from handeye_cli.fleet.cache import result_path
from handeye_cli.fleet.discovery import _glob, discover
from handeye_cli.options import Options
from handeye_cli.output import writers

# issue 36: run under -W error, every warning a failure (an unclosed file or pipe: its ResourceWarning,
# reported at garbage collection as PytestUnraisableExceptionWarning); not a filter to hide one
pytestmark = pytest.mark.filterwarnings("error")

LOG = ROOT / "sample_data" / "rig.mcap"
TRUTH = ROOT / "sample_data" / "truth.yaml"
TOPICS = ["--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose"]


def _records(out: str) -> list[dict]:
    return [json.loads(line) for line in out.splitlines()]


def _copy(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(LOG, path)
    return path


def _job(*paths: str) -> Job:
    return Job(BatchInput(paths), Streams(), Options())


# --- result file names -------------------------------------------------------------------------

def test_result_names_are_unique_by_construction_and_the_same_on_every_run():
    inputs = [("robot1/log.mcap",), ("robot1__log.mcap",), ("/robot1/log.mcap",), ("../robot1/log.mcap",),
              ("a_/b.mcap",), ("a/_b.mcap",), ("a+b/c.mcap",), ("a", "b+c"), ("a+b", "c"), ("x~1/y.mcap",),
              ("logs/" + "long-folder-name/" * 20 + "x.mcap",), ("logs/" + "long-folder-name/" * 20 + "y.mcap",),
              ("./robot1/./log.mcap",)]
    names = [result_path("out", _job(*paths), "yaml").name for paths in inputs]
    assert len(set(names[:-1])) == len(names) - 1                         # distinct inputs, distinct names
    assert names[-1] == names[0] == "robot1__log.mcap.yaml"               # the same path: the same, plain name
    assert names[2] == "__robot1__log.mcap.yaml"                          # absolute: readable too
    assert all(len(n.encode()) < 255 for n in names) and "~" in names[1] and "~" in names[10]
    assert names == [result_path("out", _job(*paths), "yaml").name for paths in inputs]


def test_colliding_inputs_keep_both_results_and_skip_done_finds_them(capsys, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    _copy(tmp_path / "robot1" / "log.mcap")
    _copy(tmp_path / "robot1__log.mcap")
    args = ["batch", "robot1/log.mcap", "robot1__log.mcap", *TOPICS, "--output-dir", "results", "--skip-done",
            "-q", "--jobs", "1"]
    code, out, _ = run(capsys, *args)
    assert code == 0 and [r["status"] for r in _records(out)] == ["ok", "ok"]
    files = sorted((tmp_path / "results").iterdir())
    stored = sorted(json.dumps(yaml.safe_load(f.read_text())["batch"]["input"]) for f in files)
    assert len(files) == 2 and stored == sorted(json.dumps(i) for i in ("robot1/log.mcap", "robot1__log.mcap"))
    calls: list[str] = []
    real = engine.run_job
    monkeypatch.setattr(engine, "run_job", lambda job: calls.append(job.input.label) or real(job))
    code, again, _ = run(capsys, *args)
    assert code == 0 and calls == [] and [r["input"] for r in _records(again)] == ["robot1/log.mcap",
                                                                                  "robot1__log.mcap"]


# --- FIFOs, symlink loops, duplicates ----------------------------------------------------------

def test_fifos_never_block_discovery_and_a_given_fifo_is_an_error_record(capsys, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    _copy(tmp_path / "logs" / "a.mcap")
    os.mkfifo(tmp_path / "logs" / "b.mcap")                   # named like a log: still not opened
    os.mkfifo(tmp_path / "pipe.bag")
    (tmp_path / "list.txt").write_text("pipe.bag\n")
    code, out, err = run(capsys, "batch", "logs", "pipe.bag", "@list.txt", *TOPICS, "-q")
    records = _records(out)
    assert code == 2 and [r["input"] for r in records] == ["logs/a.mcap", "logs/b.mcap", "pipe.bag", "pipe.bag"]
    assert [r["status"] for r in records] == ["ok", "error", "error", "error"]
    assert "logs/b.mcap is a FIFO, not a log file" in records[1]["error"]
    assert "pipe.bag is a FIFO, not a log file" in records[2]["error"]
    assert err == ""


def test_a_symlink_loop_under_a_glob_gives_one_record_per_log(capsys, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    _copy(tmp_path / "loopy" / "sub" / "log.mcap")
    (tmp_path / "loopy" / "sub" / "up").symlink_to("..")
    (tmp_path / "loopy" / "up2").symlink_to("..")
    (tmp_path / "loopy" / "alias.mcap").symlink_to("sub/log.mcap")
    os.mkfifo(tmp_path / "loopy" / "pipe.mcap")
    code, out, err = run(capsys, "batch", "loopy/**/*.mcap", *TOPICS, "-q")
    records = _records(out)
    assert code == 2 and [(r["input"], r["status"]) for r in records] == [("loopy/alias.mcap", "ok"),
                                                                          ("loopy/pipe.mcap", "error")]
    assert "loopy/pipe.mcap is a FIFO, not a log file" in records[1]["error"]
    assert err.splitlines() == ["warning: skipped loopy/sub/log.mcap: the same input as loopy/alias.mcap"]


def test_recursive_glob_matches_what_glob_matches_on_a_tree_without_links(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in ("a/x.mcap", "a/b/y.mcap", "a/b/c/z.bag", "a/.hidden/h.mcap", "a/.dot.mcap", "top.mcap"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text("")
    for pattern in ("**/*.mcap", "a/**/*.mcap", "a/**", "a/**/c/*", "**/b/*.mcap", f"{tmp_path}/a/**/*.bag",
                    "a/*/**/*", "a/**/.*.mcap"):
        assert _glob(pattern) == sorted(p.rstrip("/") for p in glob.glob(pattern, recursive=True)), pattern


def test_lists_split_at_newline_only(capsys, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    odd = ["line\u2028sep.mcap", "form\ffeed.mcap", "crlf.mcap"]
    for name in odd:
        _copy(tmp_path / name)
    (tmp_path / "list.txt").write_bytes(f"'{odd[0]}'\n'{odd[1]}'\r\n{odd[2]}\r\n".encode())
    inputs = discover(["@list.txt"])
    assert [i.paths for i in inputs] == [(name,) for name in odd] and not any(i.error for i in inputs)


# --- the per-input time limit and signals ------------------------------------------------------

@pytest.mark.parametrize("jobs, ignore_alarm", [("1", False), ("2", False), ("2", True)])
def test_an_input_past_its_time_limit_is_its_error_record(capsys, monkeypatch, tmp_path, jobs, ignore_alarm):
    monkeypatch.chdir(tmp_path)
    os.mkfifo(tmp_path / "fifo")

    def calibrate(job):               # the fast input: a stub result, so that the limit can be short
        if "slow" in job.input.label:
            if ignore_alarm:          # stuck where the worker's own alarm cannot reach: the batch kills it
                signal.signal(signal.SIGALRM, signal.SIG_IGN)
            open(tmp_path / "fifo").close()               # no one writes it: blocks in the system call
        return {"method": "stub", "log_span_ns": [0, 1]}

    monkeypatch.setattr(engine, "_calibrate", calibrate)
    start = time.monotonic()
    code, out, err = run(capsys, "batch", _copy(tmp_path / "slow.mcap").name, _copy(tmp_path / "fast.mcap").name,
                         *TOPICS, "-q", "--timeout", "0.3", "--jobs", jobs)
    records = _records(out)
    assert code == 2 and err == "" and [r["status"] for r in records] == ["error", "ok"]
    assert records[0]["error"].startswith("no result within 0.3 s (slow.mcap): ")
    assert "--timeout SECONDS" in records[0]["error"] and "\n" not in records[0]["error"]
    assert time.monotonic() - start < 8


def test_the_time_limit_off_the_main_thread_as_in_a_dask_worker(monkeypatch):
    release = threading.Event()
    monkeypatch.setattr(engine, "_calibrate", lambda job: release.wait(10) and {"log_span_ns": [0, 1]})
    job = Job(BatchInput(("slow.mcap",)), Streams(), Options(), timeout=0.2)
    records: list[dict] = []
    worker = threading.Thread(target=lambda: records.append(engine.run_job(job)))
    worker.start()
    worker.join(5)
    release.set()                                     # frees the thread the time limit left behind
    assert records[0]["status"] == "error" and records[0]["error"].startswith("no result within 0.2 s (slow.mcap)")


def test_a_worker_that_dies_is_its_error_record_and_is_replaced(capsys, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)

    def calibrate(job):
        if "die" in job.input.label:
            os._exit(3)
        return {"method": "stub", "log_span_ns": [0, 1]}

    monkeypatch.setattr(engine, "_calibrate", calibrate)
    names = [_copy(tmp_path / f"{name}.mcap").name for name in ("die1", "a", "die2", "b", "c")]
    code, out, _ = run(capsys, "batch", *names, *TOPICS, "-q", "--jobs", "2")
    records = _records(out)
    assert code == 2 and [r["status"] for r in records] == ["error", "ok", "error", "ok", "ok"]
    assert records[0]["error"] == "the worker process died (exit code 3) (die1.mcap): run handeye calibrate on it alone"


def test_timeout_values(capsys, tmp_path):
    code, out, err = run(capsys, "batch", tmp_path / "none.mcap", "--timeout", "0", "-q")
    assert code == 2 and out == "" and err.splitlines() == [
        "error: bad value '0' (--timeout): give a number of seconds > 0, or 'off'"]
    code, out, _ = run(capsys, "batch", tmp_path / "none.mcap", "--timeout", "off", "-q")
    assert code == 2 and _records(out)[0]["error"] == f"file not found: {tmp_path / 'none.mcap'}"


DRIVER = """
import sys
from handeye_cli.fleet import engine
real = engine._calibrate
def calibrate(job):
    if "slow" in job.input.label:
        open({fifo!r}).close()              # no one writes it: the worker blocks until it is killed
    return real(job)
engine._calibrate = calibrate
from handeye_cli.cli import main
main(sys.argv[1:])
"""


def _descendants(pid: int) -> set[int]:
    """The processes below ``pid``: by psutil when installed (CI has it, through dask), else /proc."""
    try:
        import psutil
    except ImportError:
        parents = {}
        for entry in Path("/proc").iterdir():
            if entry.name.isdigit():
                try:
                    fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
                except OSError:
                    continue
                if fields[0] != "Z":                              # a zombie has exited
                    parents[int(entry.name)] = int(fields[1])
        found, frontier = set(), {pid}
        while frontier:
            frontier = {child for child, parent in parents.items() if parent in frontier} - found
            found |= frontier
        return found
    try:
        return {p.pid for p in psutil.Process(pid).children(recursive=True) if p.status() != psutil.STATUS_ZOMBIE}
    except psutil.Error:
        return set()


def _alive(pids: set[int]) -> set[int]:
    """Those of ``pids`` still running (not exited, not zombies)."""
    out = set()
    for pid in pids:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if state != "Z":
            out.add(pid)
    return out


def _children(pid: int, least: int, timeout: float = 20.0) -> set[int]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        children = _descendants(pid)
        if len(children) >= least:
            return children
        time.sleep(0.02)
    raise AssertionError(f"the batch started fewer than {least} worker(s)")


def _gone(pids: set[int], timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while _alive(pids) and time.monotonic() < deadline:
        time.sleep(0.02)
    return not _alive(pids)


@contextlib.contextmanager
def _start(tmp_path: Path, inputs: list[str], out: Path, *extra: str) -> Iterator[subprocess.Popen]:
    """A batch running ``inputs`` (a FIFO blocks its "slow" ones) in a child process; on leaving,
    killed if it still runs, reaped, and its stderr pipe closed (else a ResourceWarning)."""
    os.mkfifo(tmp_path / "fifo")
    driver = DRIVER.format(fifo=str(tmp_path / "fifo"))
    with out.open("w") as stdout:                       # the child holds its own copy
        batch = subprocess.Popen([sys.executable, "-c", driver, "batch", *inputs, *TOPICS, "-q", "--jobs", "2",
                                  *extra], cwd=tmp_path, stdout=stdout, stderr=subprocess.PIPE, text=True)
    with batch:                                         # exit: the pipe closed, the child waited for
        try:
            yield batch
        finally:
            if batch.poll() is None:                    # a failed assertion: do not wait on a blocked batch
                batch.kill()


def test_sigterm_kills_the_workers_keeps_whole_records_and_skip_done_resumes(capsys, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    inputs = [_copy(tmp_path / name).name for name in ("a.mcap", "b.mcap", "c.mcap", "slow.mcap")]
    out = tmp_path / "records.jsonl"
    with _start(tmp_path, inputs, out, "--output-dir", "results", "--skip-done") as batch:
        deadline = time.monotonic() + 30
        while out.read_text().count("\n") < 3 and time.monotonic() < deadline:     # a, b, c done; slow blocks
            time.sleep(0.02)
        workers = _children(batch.pid, 1)
        batch.send_signal(signal.SIGTERM)
        assert batch.wait(10) == 128 + signal.SIGTERM and batch.stderr.read().splitlines()[-1] == "terminated"
    assert _gone(workers)
    text = out.read_text()
    assert text.endswith("\n") and [r["input"] for r in _records(text)] == inputs[:3]
    calls: list[str] = []
    real = engine.run_job
    monkeypatch.setattr(engine, "run_job", lambda job: calls.append(job.input.label) or real(job))
    code, resumed, _ = run(capsys, "batch", *inputs, *TOPICS, "-q", "--jobs", "1", "--output-dir", "results",
                           "--skip-done")
    assert code == 0 and calls == ["slow.mcap"] and [r["input"] for r in _records(resumed)] == inputs
    assert [r["matrix"] for r in _records(resumed)[:3]] == [r["matrix"] for r in _records(text)]


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGHUP])
def test_other_signals_kill_the_workers_too(tmp_path, signum):
    inputs = [_copy(tmp_path / name).name for name in ("slow1.mcap", "slow2.mcap")]
    with _start(tmp_path, inputs, tmp_path / "records.jsonl") as batch:
        workers = _children(batch.pid, 2)
        batch.send_signal(signum)
        assert batch.wait(10) == 128 + signum
    assert _gone(workers) and (tmp_path / "records.jsonl").read_text() == ""


# --- a full disk -------------------------------------------------------------------------------

def test_a_result_file_that_cannot_be_written_is_its_records_error(capsys, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    inputs = [_copy(tmp_path / name).name for name in ("a.mcap", "full.mcap", "c.mcap")]
    calibrated: list[dict] = []                          # the copies are alike: calibrate one, once
    real_calibrate = engine._calibrate
    monkeypatch.setattr(engine, "_calibrate", lambda job: copy.deepcopy(
        calibrated[0] if calibrated else calibrated.append(real_calibrate(job)) or calibrated[0]))
    real = writers._replace_atomically

    def replace(p: Path, text: str) -> None:
        if "full" in p.name:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real(p, text)

    monkeypatch.setattr(writers, "_replace_atomically", replace)
    code, out, _ = run(capsys, "batch", *inputs, *TOPICS, "-q", "--jobs", "1", "--output-dir", "results")
    records = _records(out)
    assert code == 2 and [r["status"] for r in records] == ["error" if "full" in i else "ok" for i in inputs]
    assert records[1]["error"] == ("calibrated (ok), but cannot write (No space left on device) "
                                   "(results/full.mcap.yaml): choose another --output-dir path")
    assert "matrix" in records[1] and sorted(p.name for p in (tmp_path / "results").iterdir()) == [
        "a.mcap.yaml", "c.mcap.yaml"]
    far = tmp_path / "far.yaml"                          # a nominal 1 m away: every input drifted
    far.write_text(TRUTH.read_text().replace("0.168", "1.168"))
    code, out, _ = run(capsys, "batch", *inputs, *TOPICS, "-q", "--jobs", "1", "--output-dir", "results",
                       "--against", far)
    records = _records(out)
    assert code == 1 and [r["status"] for r in records] == ["drift", "error", "drift"]   # drift is still 1
    assert records[1]["error"].startswith("calibrated (drift), but") and records[1]["verdict"]["drift"]


@pytest.mark.parametrize("command", [["calibrate", str(LOG), *TOPICS, "-q"], ["batch", str(LOG), *TOPICS, "-q"],
                                     ["inspect", str(LOG)], ["check", str(TRUTH), "--against", str(TRUTH)]])
def test_stdout_on_a_full_disk_is_one_line_exit_2(command, tmp_path):
    with open("/dev/full", "w") as full:
        done = subprocess.run([sys.executable, "-m", "handeye_cli", *command], stdout=full, stderr=subprocess.PIPE,
                              text=True, cwd=tmp_path, timeout=60)
    assert done.returncode == 2 and done.stderr.splitlines() == [
        "error: cannot write to stdout (No space left on device): free space where it goes, or redirect it "
        "elsewhere"]


# --- the mode of a replaced file ---------------------------------------------------------------

def test_a_replaced_file_keeps_its_mode_and_a_new_one_follows_the_umask(tmp_path):
    private = tmp_path / "private.yaml"
    private.write_text("old\n")
    private.chmod(0o600)
    writers.write_output(private, "new\n")
    assert private.read_text() == "new\n" and stat.S_IMODE(private.stat().st_mode) == 0o600
    old = os.umask(0o027)
    try:
        writers.write_output(tmp_path / "new.yaml", "x\n")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "new.yaml").stat().st_mode) == 0o640
