"""A batch: run every input, judge each result against the nominal, write the records in input order.

Records are JSON Lines (one per input, in input order, written as soon as every earlier input is
done): ``input``, ``status`` (``ok`` | ``drift`` | ``error``), ``error`` (one line) when it failed,
the calibrate result's keys when it calibrated, ``log_span_ns``, ``verdict`` with a nominal, and
``seconds`` last (the only field that differs between executors and runs). A result file that
cannot be written (a full disk) makes its record an error that says so, keeping the result and
verdict. Exit code: 1 when an input drifted (its verdict says so), else 2 when an input failed,
else 3 when ``strict`` and a result has warnings, else 0.
"""
from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..analysis.verdict import verdict_for
from ..errors import HandEyeError, WriteError
from ..io.nominal import Nominal
from ..io.progress import Progress, progress
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


@dataclass
class BatchSummary:
    """What a batch produced: the records in input order, the wall time [s], and whether warnings
    fail the batch (``--strict``)."""

    records: list[Record] = field(default_factory=list)
    seconds: float = 0.0
    strict: bool = False

    def count(self, status: str) -> int:
        return sum(r["status"] == status for r in self.records)

    @property
    def exit_code(self) -> int:
        """1 drift (also of an error record whose result file could not be written), else 2 error,
        else 3 warnings under ``strict``, else 0."""
        if any(r.get("verdict", {}).get("drift") for r in self.records):
            return 1
        if self.count("error"):
            return 2
        return 3 if self.strict and any(r.get("warnings") for r in self.records) else 0

    def text(self) -> str:
        """The stderr summary: counts, the slowest inputs, the worst drifts."""
        lines = [f"batch: {len(self.records)} input(s) in {self.seconds:.1f} s: {self.count('ok')} ok, "
                 f"{self.count('drift')} drift, {self.count('error')} error"]
        slow = sorted(self.records, key=lambda r: -r["seconds"])[:3]
        if slow and slow[0]["seconds"] > 0:
            lines.append("  slowest: " + ", ".join(f"{r['input']} {r['seconds']:.2f} s" for r in slow))
        judged = [r for r in self.records if "verdict" in r]
        worst = sorted(judged, key=lambda r: -_excess(r["verdict"]))[:3]
        for r in worst:
            v = r["verdict"]
            lines.append(f"  {'DRIFT' if v['drift'] else 'worst'}: {r['input']}: {v['rotation_deg']:.3f}° "
                         f"(max {v['max_rotation_deg']:g}°), {v['translation_m'] * 1000:.2f} mm "
                         f"(max {v['max_translation_m'] * 1000:g} mm)")
        lines += [f"  error: {r['error']}" for r in self.records if r["status"] == "error"][:5]
        return "\n".join(lines)


def _excess(v: dict[str, Any]) -> float:
    """How far beyond its tolerance a verdict is, as the larger of the two ratios."""
    return max(float(v["rotation_deg"]) / max(float(v["max_rotation_deg"]), 1e-12),
               float(v["translation_m"]) / max(float(v["max_translation_m"]), 1e-12))


def _finite(value: Any) -> Any:
    """NaN and infinities → None (null), recursively: JSON Lines consumers (jq) reject NaN."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite(v) for v in value]
    return value


def record_line(record: Record) -> str:
    """One JSON Lines record (strict JSON: non-finite numbers are null)."""
    return json.dumps(_finite(record), separators=(",", ":"), allow_nan=False)


def _judge(record: Record, s: BatchSettings) -> Record:
    """The record in its final key order, with the verdict (status drift) when there is a nominal."""
    seconds = record.pop("seconds")
    if record["status"] != "error" and s.nominal is not None:
        try:
            verdict = verdict_for(record, s.nominal, s.max_rotation_deg, s.max_translation_m)
        except HandEyeError as e:
            record.update(status="error", error=str(e))
        except Exception as e:  # a bug met by one input's result: that input's error, not the batch's
            record.update(status="error", error=f"unexpected {type(e).__name__} judging the result: "
                                                f"{' '.join(str(e).split())} ({record['input']}): this is a bug, "
                                                "please report it")
        else:
            record.update(status="drift" if verdict.drift else "ok", verdict=verdict.as_dict())
    head: Record = {k: record.pop(k) for k in ("input", "status", "error") if k in record}
    return {**head, **record, "seconds": seconds}


class _Ordered:
    """Buffers records that finish early and emits them in input order."""

    def __init__(self, n: int, emit: Callable[[str], None], bar: Progress) -> None:
        self.records: list[Record | None] = [None] * n
        self.next, self.emit, self.bar = 0, emit, bar

    def done(self, i: int, record: Record) -> None:
        self.records[i] = record
        self.bar.update(1)
        while self.next < len(self.records) and self.records[self.next] is not None:
            self.emit(record_line(self.records[self.next]))  # type: ignore[arg-type]
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


def run_batch(jobs: Sequence[Job], settings: BatchSettings, emit: Callable[[str], None]) -> BatchSummary:
    """Run ``jobs``, emitting each record line (in input order) through ``emit``."""
    start = time.perf_counter()
    out_dir = Path(settings.output_dir) if settings.output_dir else None
    if out_dir is not None and not out_dir.is_dir():
        try:
            out_dir.mkdir(parents=True)
        except OSError as e:
            raise WriteError(f"cannot create the output folder: {e.strerror}", str(out_dir),
                             "choose another --output-dir") from None
    keys = [_key(j) if out_dir is not None else "" for j in jobs]
    with progress(len(jobs), "batch", quiet=not settings.progress) as bar:
        ordered = _Ordered(len(jobs), emit, bar)

        def finish(i: int, record: Record) -> None:
            record = _judge(record, settings)
            if out_dir is not None and "matrix" in record:
                try:
                    store(result_path(out_dir, jobs[i], settings.fmt), record, keys[i], settings.fmt)
                except HandEyeError as e:            # e.g. a full disk: this input's error, not the batch's
                    status = record.pop("status")
                    record = {"input": record.pop("input"), "status": "error",
                              "error": f"calibrated ({status}), but {e}", **record}
            ordered.done(i, record)

        todo = []
        for i, job in enumerate(jobs):
            stored = (load_done(result_path(out_dir, job, settings.fmt), keys[i])
                      if out_dir is not None and settings.skip_done and keys[i] else None)
            if stored is None:
                todo.append(i)
            else:
                ordered.done(i, _judge(stored, settings))
        run_jobs([jobs[i] for i in todo], lambda k, r: finish(todo[k], r), workers=settings.workers,
                 scheduler=settings.scheduler)
    return BatchSummary([r for r in ordered.records if r is not None], time.perf_counter() - start, settings.strict)
