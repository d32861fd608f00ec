"""Run batch inputs: one calibration per input, in this process, a local process pool or on a
Dask distributed cluster — the same :func:`run_job` everywhere, so the records are identical.

A :class:`Job` is picklable (it travels to worker processes and Dask workers); :func:`run_job`
never raises for a bad input: it returns a record with ``status: error`` and the one-line message.
Records hold the calibrate result's keys (``matrix`` = ``T_a_b`` …, see docs/design.md), ``log_span_ns``
(first and last synced stamp, int64 ns) and ``seconds`` (wall time of the job).
"""
from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Any

from ..errors import ConfigError, HandEyeError
from ..options import Options
from .discovery import BatchInput

__all__ = ["Job", "Streams", "run_job", "run_jobs"]

Record = dict[str, Any]
OnDone = Callable[[int, Record], None]


@dataclass(frozen=True)
class Streams:
    """Which streams of a log are a and b: a topic or a (parent, child) TF frame pair each."""

    topic_a: str | None = None
    topic_b: str | None = None
    frames_a: tuple[str, str] | None = None
    frames_b: tuple[str, str] | None = None


@dataclass(frozen=True)
class Job:
    """One input and everything needed to calibrate it: the streams, the calibrate options and the
    working directory its relative paths are relative to (the client's, by default)."""

    input: BatchInput
    streams: Streams
    options: Options
    cwd: str = field(default_factory=os.getcwd)


def _calibrate(job: Job) -> Record:
    """The result document of one input, plus the span of its synced samples. Relative paths are
    read from the client's working directory (``job.cwd``) wherever the job runs, so that a Dask
    worker on a shared file system finds them and every executor records the same ``inputs``."""
    from ..pipeline import calibrate_files

    paths, s = tuple(os.path.join(job.cwd, p) for p in job.input.paths), job.streams
    if len(paths) == 2:            # two text pose files: no topics
        result = calibrate_files(paths[0], paths[1], options=job.options)
    else:
        result = calibrate_files(paths[0], topic_a=s.topic_a, topic_b=s.topic_b, frames_a=s.frames_a,
                                 frames_b=s.frames_b, options=job.options)
    stamps = result.synced.stamps_ns
    return {**result.document(), "log_span_ns": [int(stamps[0]), int(stamps[-1])]}


def run_job(job: Job) -> Record:
    """Calibrate one input: ``{input, status: ok, <result keys>, log_span_ns, seconds}``, or
    ``{input, status: error, error, seconds}`` — never an exception."""
    start = time.perf_counter()
    record: Record = {"input": job.input.label}
    if job.input.error:
        return {**record, "status": "error", "error": job.input.error, "seconds": 0.0}
    try:
        record.update(status="ok", **_calibrate(job))
    except HandEyeError as e:
        record.update(status="error", error=str(e))
    except Exception as e:  # a damaged log must become a record, never abort the batch
        record.update(status="error", error=f"unexpected {type(e).__name__}: {e} ({job.input.label}): run "
                                            "handeye calibrate --debug on it for the traceback")
    record["seconds"] = round(time.perf_counter() - start, 3)
    return record


def _crashed(job: Job, err: BaseException) -> Record:
    return {"input": job.input.label, "status": "error",
            "error": f"the worker process died ({type(err).__name__}) ({job.input.label}): run handeye calibrate "
                     "on it alone", "seconds": 0.0}


def _local(jobs: Sequence[Job], workers: int, on_done: OnDone) -> None:
    if workers <= 1 or len(jobs) <= 1:
        for i, job in enumerate(jobs):
            on_done(i, run_job(job))
        return
    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
    with ProcessPoolExecutor(min(workers, len(jobs)), mp_context=multiprocessing.get_context(method)) as pool:
        futures = {pool.submit(run_job, job): i for i, job in enumerate(jobs)}
        for future in as_completed(futures):
            i = futures[future]
            try:
                on_done(i, future.result())
            except BrokenProcessPool as e:
                on_done(i, _crashed(jobs[i], e))


def _dask(jobs: Sequence[Job], address: str, on_done: OnDone) -> None:
    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
    except ImportError:
        raise ConfigError("dask.distributed is not installed", "--scheduler",
                          "install it: pip install 'handeye-cli[dask]'") from None
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
                on_done(i, future.result())
            except Exception as e:  # a lost worker fails its inputs, not the batch
                on_done(i, _crashed(jobs[i], e))


def run_jobs(jobs: Sequence[Job], on_done: OnDone, *, workers: int | None = None,
             scheduler: str | None = None) -> None:
    """Run every job, calling ``on_done(index, record)`` as each finishes (in completion order):
    on the Dask cluster at ``scheduler``, else in ``workers`` local processes (default: one per core;
    1 runs in this process)."""
    if scheduler:
        _dask(jobs, scheduler, on_done)
    else:
        _local(jobs, workers or os.cpu_count() or 1, on_done)
