"""A batch: run every input, judge each result against the nominal, write the records in input order.

Records are JSON Lines (one per input, in input order, written as soon as every earlier input is
done): ``input``, ``status`` (``ok`` | ``drift`` | ``error``), ``error`` (one line) when it failed,
the calibrate result's keys when it calibrated, ``log_span_ns``, ``verdict`` with a nominal,
``result_file`` with ``--output-dir`` (the file written, or null when none was), and ``seconds``
last (the only field that differs between executors and runs). A result file that cannot be
written (a full disk) makes its record an error that says so, keeping the result and verdict; a
full disk (ENOSPC, EDQUOT, or EFBIG from a file-size limit) is also told once, as
:attr:`BatchSummary.full`, which the CLI prints as one ``error:`` line naming the folder. Exit
code: 1 when an input drifted (its verdict says so), else 2 when an input failed, else 3 when
``strict`` and a result has warnings, else 0.
"""
from __future__ import annotations

import heapq
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..analysis.verdict import Judged, Verdict, verdict_for
from ..errors import HandEyeError, WriteError, as_flags, worded
from ..io.nominal import Nominal
from ..io.progress import Progress, progress
from ..output.document import finite
from ..output.records import BatchRecord
from ..output.writers import FULL
from .cache import job_key, load_done, result_path, store
from .engine import Job, run_jobs

__all__ = ["BatchSettings", "BatchSummary", "run_batch", "record_line"]

Record = dict[str, Any]


@dataclass(frozen=True)
class BatchSettings:
    """How a batch runs: nominal and tolerances [deg, m], result files, executor, progress."""

    nominal: Nominal | None = None
    max_rotation_deg: float = 0.5
    max_translation_m: float = 0.005
    output_dir: str | None = None
    fmt: str = "yaml"
    skip_done: bool = False
    strict: bool = False
    workers: int | None = None
    scheduler: str | None = None
    progress: bool = False


_SHOWN = 3                 # slowest inputs and worst verdicts the summary shows
_SHOWN_ERRORS = 5          # error lines the summary shows ("and N more" after them)


@dataclass
class BatchSummary:
    """What a batch produced, gathered record by record (:meth:`add`, typed records) without keeping the
    records: counts, the slowest inputs, the worst verdicts, the first error lines, how many records
    ``--skip-done`` reused, the wall time [s], and whether warnings fail the batch (``--strict``)."""

    strict: bool = False
    seconds: float = 0.0
    counts: dict[str, int] = field(default_factory=lambda: {"ok": 0, "drift": 0, "error": 0})
    reused: int = 0
    drifted: bool = False
    warned: bool = False
    slowest: list[tuple[float, str]] = field(default_factory=list)
    worst: list[tuple[float, int, str, Verdict]] = field(default_factory=list)
    errors: list[tuple[str, str]] = field(default_factory=list)
    full: str | None = None

    def disk_full(self, folder: Path, reason: str) -> None:
        """Note the first result file that a full disk kept from being written (``folder``: ``--output-dir``)."""
        if self.full is None:
            self.full = str(WriteError(f"cannot write the result files ({reason})", str(folder),
                                       "free space there or choose another --output-dir"))

    def add(self, record: BatchRecord, reused: bool = False) -> None:
        """Count one record (``reused``: taken from a result file or the records file, not run)."""
        self.counts[record.status] = self.counts.get(record.status, 0) + 1
        self.reused += reused
        self.warned = self.warned or record.warned
        self.drifted = self.drifted or record.drifted
        if not reused and record.seconds is not None:
            self.slowest = heapq.nlargest(_SHOWN, [*self.slowest, (record.seconds, record.input)])
        if record.verdict is not None:
            entry = (_excess(record.verdict), -self.total, record.input, record.verdict)
            self.worst = heapq.nlargest(_SHOWN, [*self.worst, entry], key=lambda e: e[:2])
        if record.status == "error" and len(self.errors) < _SHOWN_ERRORS:
            self.errors.append((record.input, record.error))

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def count(self, status: str) -> int:
        return self.counts.get(status, 0)

    @property
    def exit_code(self) -> int:
        """1 drift (also of an error record whose result file could not be written), else 2 error,
        else 3 warnings under ``strict``, else 0."""
        if self.drifted:
            return 1
        if self.count("error"):
            return 2
        return 3 if self.strict and self.warned else 0

    def text(self) -> str:
        """The stderr summary: counts, reused results, the slowest inputs, the worst drifts, the
        first error lines (each naming its input) and how many more there are."""
        reused = f" ({self.reused} reused by --skip-done)" if self.reused else ""
        lines = [f"batch: {self.total} input(s){reused} in {self.seconds:.1f} s: {self.count('ok')} ok, "
                 f"{self.count('drift')} drift, {self.count('error')} error"]
        if self.slowest and self.slowest[0][0] > 0:
            lines.append("  slowest: " + ", ".join(f"{name} {s:.2f} s" for s, name in self.slowest))
        for _, _, name, v in self.worst:
            lines.append(f"  {'DRIFT' if v.drift else 'worst'}: {name}: {v.rotation_deg:.3f}° "
                         f"(max {v.max_rotation_deg:g}°), {v.translation_m * 1000:.2f} mm "
                         f"(max {v.max_translation_m * 1000:g} mm)")
        lines += [f"  error: {message if name in message else f'{name}: {message}'}" for name, message in self.errors]
        if self.count("error") > len(self.errors):
            lines.append(f"  … and {self.count('error') - len(self.errors)} more error(s)")
        return "\n".join(lines)


def _excess(v: Verdict) -> float:
    """How far beyond its tolerance a verdict is, as the larger of the two ratios."""
    return max(v.rotation_deg / max(v.max_rotation_deg, 1e-12), v.translation_m / max(v.max_translation_m, 1e-12))


def record_line(record: Record) -> str:
    """One JSON Lines record (strict JSON: non-finite numbers are null)."""
    return json.dumps(finite(record), separators=(",", ":"), allow_nan=False)


def _judge(record: Record, s: BatchSettings) -> Record:
    """The record in its final key order, with the verdict (status drift) when there is a nominal, the options
    it names as flags (a batch is the command line's)."""
    seconds = record.pop("seconds")
    if record["status"] != "error" and s.nominal is not None:
        try:
            verdict = verdict_for(Judged.from_document(record), s.nominal, s.max_rotation_deg, s.max_translation_m)
        except HandEyeError as e:
            record.update(status="error", error=e.line(as_flags))
        except Exception as e:  # a bug met by one input's result: that input's error, not the batch's
            record.update(status="error", error=f"unexpected {type(e).__name__} judging the result: "
                                                f"{' '.join(str(e).split())} ({record['input']}): this is a bug, "
                                                "please report it")
        else:
            record.update(status="drift" if verdict.drift else "ok", verdict=verdict.as_dict())
    head: Record = {k: record.pop(k) for k in ("input", "status", "error") if k in record}
    return worded({**head, **record, "seconds": seconds}, as_flags)


def _with_file(record: Record, path: Path | None) -> Record:
    """``record`` with its ``result_file`` (``path``, or None: not written) just before ``seconds``."""
    seconds = record.pop("seconds", None)
    record.pop("result_file", None)
    return {**record, "result_file": None if path is None else str(path), "seconds": seconds}


class _Ordered:
    """Emits records in input order: a record that finishes before an earlier input's waits here
    (only those: the memory is the records finished ahead of the slowest running input, not the
    batch's); each record, in order, is parsed once into a :class:`BatchRecord` for the summary and
    ``observe``."""

    def __init__(self, emit: Callable[[str], None], observe: Callable[[BatchRecord], None] | None,
                 summary: BatchSummary, bar: Progress) -> None:
        self.waiting: dict[int, tuple[Record, bool, bool]] = {}
        self.next, self.emit, self.observe, self.summary, self.bar = 0, emit, observe, summary, bar

    def done(self, i: int, record: Record, *, reused: bool = False, written: bool = False) -> None:
        """Input ``i``'s record (``reused``: not run; ``written``: already in the records file)."""
        self.waiting[i] = (record, reused, written)
        self.bar.update(1)
        while self.next in self.waiting:
            record, reused, written = self.waiting.pop(self.next)
            if not written:
                self.emit(record_line(record))
            typed = BatchRecord.from_record(record)
            self.summary.add(typed, reused)
            if self.observe is not None:
                self.observe(typed)
            self.next += 1


def _key(job: Job) -> str:
    """The skip-done key of a runnable job, or "" (not cached) when its files cannot be read: the
    job itself then reports why."""
    if job.input.error:
        return ""
    try:
        return job_key(job)
    except OSError:
        return ""


def run_batch(jobs: Sequence[Job], settings: BatchSettings, emit: Callable[[str], None], *,
              done: dict[str, Record] | None = None, observe: Callable[[BatchRecord], None] | None = None
              ) -> BatchSummary:
    """Run ``jobs``, emitting each record line (in input order) through ``emit``. ``done`` holds
    records already in the records file (by input; ``--skip-done``): those inputs are not run and
    their records not emitted again. ``observe`` sees every record, typed, in input order (the fleet report)."""
    start = time.perf_counter()
    done = done or {}
    out_dir = Path(settings.output_dir) if settings.output_dir else None
    if out_dir is not None and not out_dir.is_dir():
        try:
            out_dir.mkdir(parents=True)
        except OSError as e:
            raise WriteError(f"cannot create the output folder: {e.strerror}", str(out_dir),
                             "choose another --output-dir") from None
    summary = BatchSummary(settings.strict)
    with progress(len(jobs), "batch", quiet=not settings.progress) as bar:
        ordered = _Ordered(emit, observe, summary, bar)
        keys: dict[int, str] = {}

        def finish(i: int, record: Record) -> None:
            record = _judge(record, settings)
            written = None
            if out_dir is not None and "matrix" in record:
                try:
                    written = store(out_dir, jobs[i], record, keys.get(i, ""), settings.fmt)
                except HandEyeError as e:            # e.g. a full disk: this input's error, not the batch's
                    if isinstance(e, WriteError) and e.errno in FULL:
                        summary.disk_full(out_dir, e.strerror or "no space")
                    status = record.pop("status")
                    record = {"input": record.pop("input"), "status": "error",
                              "error": f"calibrated ({status}), but {e}", **record}
            ordered.done(i, record if out_dir is None else _with_file(record, written))

        todo = []
        for i, job in enumerate(jobs):
            if job.input.label in done:
                ordered.done(i, done[job.input.label], reused=True, written=True)
                continue
            if out_dir is not None:
                keys[i] = _key(job)
            stored = (load_done(out_dir, job, keys[i], settings.fmt)
                      if out_dir is not None and settings.skip_done and keys[i] else None)
            if stored is None or out_dir is None:
                todo.append(i)
            else:
                ordered.done(i, _with_file(_judge(stored, settings), result_path(out_dir, job, settings.fmt)),
                             reused=True)
        run_jobs([jobs[i] for i in todo], lambda k, r: finish(todo[k], r), workers=settings.workers,
                 scheduler=settings.scheduler)
    summary.seconds = time.perf_counter() - start
    return summary
