"""Run batch inputs: one calibration per input, in this process, a local process pool or on a
Dask distributed cluster — the same :func:`run_job` everywhere, so the records are identical.

A :class:`Job` is picklable (it travels to worker processes and Dask workers); :func:`run_job`
never raises for a bad input: it returns a record with ``status: error`` and the one-line message,
also when the job overran its time limit (``Job.timeout``, [s]: SIGALRM in a process's main
thread, which also ends a blocking system call; in a Dask worker's thread the job is left running
in a daemon thread). Local worker processes that do not report by then (plus a grace) are killed
and replaced; all of them are killed and reaped when the batch ends, by error or signal.
Records hold the calibrate result's keys (``matrix`` = ``T_a_b`` …, see docs/design.md), ``log_span_ns``
(first and last synced stamp, int64 ns) and ``seconds`` (wall time of the job).
"""
from __future__ import annotations

import contextlib
import gc
import math
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from multiprocessing.connection import Connection, wait
from typing import Any

from ..errors import ConfigError, HandEyeError, as_flags
from ..io.remote import is_url
from ..io.spec import StreamSpec
from ..options import Options
from ..output.document import calibration_document
from .discovery import BatchInput

__all__ = ["DEFAULT_TIMEOUT_S", "Interrupted", "Job", "Streams", "run_job", "run_jobs"]

Record = dict[str, Any]
OnDone = Callable[[int, Record], None]

DEFAULT_TIMEOUT_S = 600.0       # [s] a batch input's time limit (--timeout)
_GRACE_S = 1.0                  # [s] (+ 10 %) past its limit a worker has to report before it is killed
_SIGNALS = (signal.SIGINT, signal.SIGTERM) + ((signal.SIGHUP,) if hasattr(signal, "SIGHUP") else ())


class Interrupted(KeyboardInterrupt):
    """The batch was sent SIGTERM or SIGHUP (``signum``): it stops like on Ctrl-C, workers killed."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@dataclass(frozen=True)
class Streams:
    """Which streams of a log are a and b: each a source without a path (a topic or a TF chain of every input,
    :func:`~handeye_cli.io.spec.stream_source`), a pose file of its own (a path), or None (unnamed)."""

    a: StreamSpec | None = None
    b: StreamSpec | None = None


@dataclass(frozen=True)
class Job:
    """One input and everything needed to calibrate it: the streams, the calibrate options, the
    working directory its relative paths are relative to (the client's, by default) and the time
    limit [s] after which it is an error record (None: none; ``handeye batch`` gives
    :data:`DEFAULT_TIMEOUT_S` unless --timeout says otherwise)."""

    input: BatchInput
    streams: Streams
    options: Options
    cwd: str = field(default_factory=os.getcwd)
    timeout: float | None = None


def _located(spec: StreamSpec | None, cwd: str) -> StreamSpec | None:
    """A stream named as a pose file of its own, its relative path read from ``cwd`` as the inputs' are."""
    if spec is None or spec.path is None or is_url(spec.path):
        return spec
    return replace(spec, path=os.path.join(cwd, spec.path))


def _calibrate(job: Job) -> Record:
    """The result document of one input, plus the span of its synced samples. Relative paths are
    read from the client's working directory (``job.cwd``) wherever the job runs, so that a Dask
    worker on a shared file system finds them and every executor records the same ``inputs``."""
    from ..calibration import calibrate_files

    paths = tuple(p if is_url(p) else os.path.join(job.cwd, p) for p in job.input.paths)     # a URL: opened here
    if len(paths) == 2:            # two text pose files: no topics
        result = calibrate_files(paths[0], paths[1], options=job.options)
    else:
        result = calibrate_files(paths[0], stream_a=_located(job.streams.a, job.cwd),
                                 stream_b=_located(job.streams.b, job.cwd), options=job.options)
    stamps = result.synced.stamps_ns
    return {**calibration_document(result), "log_span_ns": [int(stamps[0]), int(stamps[-1])]}


class _Expired(BaseException):
    """The job's time limit passed (a BaseException: no ``except Exception`` of a reader swallows it)."""


@contextmanager
def _alarm(seconds: float | None) -> Iterator[None]:
    """Raise :class:`_Expired` in this (main) thread after ``seconds``: SIGALRM also interrupts a
    blocking system call, such as opening a FIFO no one writes."""
    if seconds is None:
        yield
        return

    def expire(signum: int, frame: Any) -> None:
        raise _Expired

    old = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def _attempt(job: Job) -> Record:
    """``{status: ok, <result keys>, log_span_ns}`` or ``{status: error, error}`` — never an exception."""
    try:
        return {"status": "ok", **_calibrate(job)}
    except HandEyeError as e:
        return {"status": "error", "error": e.line(as_flags)}
    except Exception as e:  # a damaged log must become a record, never abort the batch
        return {"status": "error", "error": f"unexpected {type(e).__name__}: {' '.join(str(e).split())} "
                                            f"({job.input.label}): run handeye calibrate --debug on it for the "
                                            "traceback"}


def _timed_out(job: Job) -> Record:
    return {"status": "error", "error": f"no result within {job.timeout:g} s ({job.input.label}): it may be a "
                                        "FIFO, a hung file system or a pathological log; raise --timeout SECONDS "
                                        "or give --timeout off"}


def _limited(job: Job) -> Record:
    """:func:`_attempt` within ``job.timeout``: by SIGALRM in the main thread, else (a Dask worker's
    thread) by waiting for a daemon thread, which is then left behind."""
    if job.timeout is None or (threading.current_thread() is threading.main_thread() and hasattr(signal, "SIGALRM")):
        try:
            with _alarm(job.timeout):
                return _attempt(job)
        except _Expired:
            return _timed_out(job)
    box: list[Record] = []
    worker = threading.Thread(target=lambda: box.append(_attempt(job)), daemon=True)
    worker.start()
    worker.join(job.timeout)
    return box[0] if box else _timed_out(job)


def run_job(job: Job) -> Record:
    """Calibrate one input within ``job.timeout``: ``{input, status: ok, <result keys>, log_span_ns,
    seconds}``, or ``{input, status: error, error, seconds}`` — never an exception."""
    start = time.perf_counter()
    if job.input.error:
        return {"input": job.input.label, "status": "error", "error": job.input.error, "seconds": 0.0}
    record = {"input": job.input.label, **_limited(job)}
    record["seconds"] = round(time.perf_counter() - start, 3)
    return record


def _crashed(job: Job, err: BaseException | str) -> Record:
    what = err if isinstance(err, str) else type(err).__name__
    return {"input": job.input.label, "status": "error",
            "error": f"the worker process died ({what}) ({job.input.label}): run handeye calibrate "
                     "on it alone", "seconds": 0.0}


def _serve(conn: Connection) -> None:
    """A worker process: run the jobs that come through ``conn``, sending back each one's record,
    until the batch closes it (or kills the process)."""
    for signum in _SIGNALS:                  # inherited from the batch (fork): die as a process should
        signal.signal(signum, signal.SIG_DFL)
    _die_with_parent()
    while True:
        try:
            job = conn.recv()
        except (EOFError, OSError):
            return
        conn.send(run_job(job))


def _die_with_parent() -> None:
    """Linux: have the kernel kill this worker when the batch process dies, even by SIGKILL."""
    if sys.platform.startswith("linux"):
        import ctypes

        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)       # PR_SET_PDEATHSIG


class _Worker:
    """A worker process of :func:`_local` and the job it runs (``index``, None when idle), with the
    time [s, monotonic] after which the batch kills it: the job's own limit plus a grace."""

    def __init__(self, context: Any) -> None:
        self.conn, theirs = context.Pipe()
        self.process = context.Process(target=_serve, args=(theirs,), daemon=True)
        self.process.start()
        theirs.close()
        self.index: int | None = None
        self.deadline = math.inf

    def give(self, index: int, job: Job) -> bool:
        """Send it ``job``; False (and the worker is stopped) when it cannot take it."""
        try:
            self.conn.send(job)
        except OSError:
            self.stop()
            return False
        self.index = index
        self.deadline = math.inf if job.timeout is None else time.monotonic() + job.timeout * 1.1 + _GRACE_S
        return True

    def result(self, job: Job) -> Record | None:
        """The record of its job once it is done, died or overran (then it is killed), else None."""
        if self.conn.poll():
            try:
                record: Record = self.conn.recv()
            except (EOFError, OSError):
                self.stop()
                return _crashed(job, f"exit code {self.process.exitcode}")
        elif time.monotonic() >= self.deadline:
            self.stop()
            return {"input": job.input.label, **_timed_out(job), "seconds": round(float(job.timeout or 0), 3)}
        else:
            return None
        self.index, self.deadline = None, math.inf
        return record

    @property
    def alive(self) -> bool:
        return self.process.exitcode is None

    def stop(self) -> None:
        """Kill and reap the process."""
        if self.alive:
            self.process.kill()
        self.process.join()
        self.conn.close()


def _local(jobs: Sequence[Job], workers: int, on_done: OnDone) -> None:
    """Run the jobs in this process (one worker), else in up to ``workers`` worker processes. A
    worker that dies is its job's error record; one that overruns its job's time limit (and a
    grace) is killed; both are replaced. A finished job's worker gets its next job before
    ``on_done`` runs for the record, so the parent's work overlaps the workers'. Each worker imports
    the calibration library and the log readers its inputs need itself, the workers at once
    (importing the library in the parent before the fork took as long: benchmarks/batch.py). Every
    worker is killed and reaped when this returns or raises (an error, SIGINT, SIGTERM, SIGHUP)."""
    if workers <= 1 or len(jobs) <= 1:
        for i, job in enumerate(jobs):
            on_done(i, run_job(job))
        return
    context: Any = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods()
                                               else "spawn")
    if context.get_start_method() == "fork":    # what the parent imported stays put: no collection in
        gc.freeze()                             # a worker touches (copies) those pages
    waiting = list(range(len(jobs)))[::-1]
    pool: list[_Worker] = []
    finished: list[tuple[int, Record]] = []     # handed to on_done once the idle workers have new jobs
    try:
        while True:
            pool = [w for w in pool if w.alive]
            idle = [w for w in pool if w.index is None]
            while waiting and (idle or len(pool) < workers):
                worker = idle.pop() if idle else _Worker(context)
                if worker not in pool:
                    pool.append(worker)
                if not worker.give(waiting[-1], jobs[waiting[-1]]):
                    pool.remove(worker)              # it died while idle: the job goes to another
                    continue
                waiting.pop()
            for done_index, done_record in finished:  # the parent's work per record (verdict, result
                on_done(done_index, done_record)      # file, fsync) while the workers run the next jobs
            finished.clear()
            busy = [w for w in pool if w.index is not None]
            if not busy:
                return
            first = min(w.deadline for w in busy)
            wait([w.conn for w in busy], None if first == math.inf else max(0.0, first - time.monotonic()))
            for worker in busy:
                index = worker.index
                assert index is not None
                record = worker.result(jobs[index])
                if record is not None:
                    finished.append((index, record))
    finally:
        for worker in pool:
            worker.stop()


def _dask(jobs: Sequence[Job], address: str, on_done: OnDone) -> None:
    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
    except ImportError:
        raise ConfigError("dask.distributed is not installed", "--scheduler",
                          "install it: pip install 'handeye-cli[dask]' (in a checkout: "
                          "pip install '.[dask]')") from None
    try:
        client = Client(address, timeout=30, set_as_default=False)  # type: ignore[no-untyped-call]
    except (OSError, TimeoutError) as e:
        raise ConfigError(f"cannot connect to the Dask scheduler: {e}", address,
                          "check --scheduler ADDRESS (e.g. tcp://host:8786)") from None
    with client:
        futures = client.map(run_job, list(jobs), pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        for future in dask_completed(futures, loop=client.loop):  # type: ignore[no-untyped-call]
            i = index[future.key]
            try:
                record = future.result()
            except Exception as e:  # a lost worker fails its inputs, not the batch
                record = _crashed(jobs[i], e)
            on_done(i, record)


def run_jobs(jobs: Sequence[Job], on_done: OnDone, *, workers: int | None = None,
             scheduler: str | None = None) -> None:
    """Run every job, calling ``on_done(index, record)`` as each finishes (in completion order):
    on the Dask cluster at ``scheduler``, else in ``workers`` local processes (default: one per core;
    1 runs in this process). SIGINT, SIGTERM and SIGHUP raise :class:`Interrupted` meanwhile (in
    the main thread), after which the local workers are killed."""
    with _stop_on_signals():
        if scheduler:
            _dask(jobs, scheduler, on_done)
        else:
            _local(jobs, workers or os.cpu_count() or 1, on_done)


@contextmanager
def _stop_on_signals() -> Iterator[None]:
    """Turn SIGINT, SIGTERM and SIGHUP into :class:`Interrupted` (and ignore the next ones while the
    workers are cleaned up); the handlers are restored on exit. Only the main thread gets signals."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum: int, frame: Any) -> None:
        for s in _SIGNALS:
            signal.signal(s, signal.SIG_IGN)
        raise Interrupted(signum)

    old = {s: signal.signal(s, stop) for s in _SIGNALS}
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)
