"""A thousand logs a night (issue 23 item 4): the records file (``-o``) a batch appends record by
record, resumed with ``--skip-done`` after SIGINT, SIGTERM or SIGKILL with no lost or duplicated
record (a line cut mid-write is re-done), and the progress bar on a terminal only."""
from __future__ import annotations

import contextlib
import json
import os
import pty
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from _util import ROOT, run
from test_adversarial_batch import TOPICS, _children, _copy, _gone, _start

from handeye_cli.fleet import engine

# issue 36: run under -W error, every warning a failure (an unclosed file or pipe: its ResourceWarning,
# reported at garbage collection as PytestUnraisableExceptionWarning); not a filter to hide one
pytestmark = pytest.mark.filterwarnings("error")


def _lines(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()]


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
def test_a_signalled_batch_resumes_from_its_records_file(capsys, monkeypatch, tmp_path, signum):
    monkeypatch.chdir(tmp_path)
    inputs = [_copy(tmp_path / name).name for name in ("a.mcap", "b.mcap", "c.mcap", "slow.mcap", "d.mcap")]
    records = tmp_path / "records.jsonl"
    with _start(tmp_path, inputs, tmp_path / "stdout", "-o", "records.jsonl", "--skip-done") as batch:
        deadline = time.monotonic() + 30
        while (not records.exists() or records.read_text().count("\n") < 3) and time.monotonic() < deadline:
            time.sleep(0.02)                             # a, b, c done; slow blocks its worker, d waits behind it
        workers = _children(batch.pid, 1)
        batch.send_signal(signum)
        assert batch.wait(10) == (128 + signum if signum != signal.SIGKILL else -signal.SIGKILL)
    assert _gone(workers)                                # SIGKILL too: the workers die with the batch
    text = records.read_text()
    assert text.endswith("\n") and [r["input"] for r in _lines(records)] == inputs[:3]   # whole records only
    assert (tmp_path / "stdout").read_text() == ""
    if signum == signal.SIGKILL:                         # a kill in the middle of a write leaves a cut line
        with records.open("a") as f:
            f.write(json.dumps(_lines(records)[0] | {"input": "slow.mcap"})[:57])
    calls: list[str] = []
    real = engine.run_job
    monkeypatch.setattr(engine, "run_job", lambda job: calls.append(job.input.label) or real(job))
    code, out, err = run(capsys, "batch", *inputs, *TOPICS, "--jobs", "1", "-o", "records.jsonl", "--skip-done")
    assert code == 0 and out == "" and calls == ["slow.mcap", "d.mcap"]
    assert [r["input"] for r in _lines(records)] == inputs               # each input once, in order
    assert records.read_text().startswith(text)                          # the kept records untouched
    assert "3 reused by --skip-done" in err and "5 ok" in err
    assert ("the last line is cut" in err) == (signum == signal.SIGKILL)


def test_a_records_file_damaged_before_its_last_line_is_refused(capsys, tmp_path):
    (tmp_path / "records.jsonl").write_text('{"input": "a.mcap", "status": "ok"}\nnot json\n')
    code, out, err = run(capsys, "batch", ROOT / "sample_data" / "rig.mcap", *TOPICS, "-o", tmp_path / "records.jsonl",
                         "--skip-done")
    assert code == 2 and out == "" and "records.jsonl:2" in err and len(err.strip().splitlines()) == 1
    code, _, err = run(capsys, "batch", ROOT / "sample_data" / "rig.mcap", *TOPICS, "-o", tmp_path / "records.jsonl",
                       "-q")
    assert code == 0 and [r["status"] for r in _lines(tmp_path / "records.jsonl")] == ["ok"]   # no resume: afresh


@contextlib.contextmanager
def _batch(stderr: int, *inputs: Path) -> Iterator[subprocess.Popen]:
    """``handeye batch`` on ``inputs`` in a child; on leaving, killed if it still runs, reaped, its pipes closed."""
    with subprocess.Popen([sys.executable, "-m", "handeye_cli", "batch", *map(str, inputs), *TOPICS, "--jobs", "1"],
                          stdout=subprocess.PIPE, stderr=stderr) as batch:
        try:
            yield batch
        finally:
            if batch.poll() is None:                     # a failed assertion: do not wait on it forever
                batch.kill()


def test_the_progress_bar_shows_on_a_terminal_only(tmp_path):
    inputs = [_copy(tmp_path / f"{k}.mcap") for k in range(3)]
    master, slave = pty.openpty()
    try:
        with _batch(slave, *inputs) as batch:            # exit: its stdout pipe closed, the child waited for
            os.close(slave)
            slave = -1
            seen = b""
            while True:
                try:
                    chunk = os.read(master, 4096)
                except OSError:                          # the terminal closed: the batch has ended
                    break
                if not chunk:
                    break
                seen += chunk
            assert batch.wait(30) == 0 and len(batch.stdout.read().splitlines()) == 3
    finally:
        os.close(master)
        if slave >= 0:
            os.close(slave)
    text = seen.decode(errors="replace")
    assert "batch" in text and "100%" in text and "3 ok" in text
    with _batch(subprocess.PIPE, *inputs) as piped:
        out, err = piped.communicate(timeout=30)
    assert piped.returncode == 0 and "%" not in err.decode() and "3 ok" in err.decode()
