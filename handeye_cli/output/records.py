"""Batch records (JSON Lines, ``handeye batch``'s output format): reading a records file that a killed
batch may have cut (by the batch resuming from it, ``--skip-done``, and by the fleet report), and the
typed :class:`BatchRecord` that the batch summary and the fleet report read, parsed once where a
record enters (from a worker or from a records file)."""
from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..analysis.verdict import Verdict
from ..errors import ReadError

__all__ = ["BatchRecord", "intact_records"]

Record = dict[str, Any]
Warn = Callable[[str], None]
_FIX = "pass the JSON Lines output of handeye batch"


@dataclass(frozen=True, eq=False)
class BatchRecord:
    """What the batch summary and the fleet report read of one batch record, typed.

    input: the input's label; status: ``ok``, ``drift`` or ``error``; error: its one line (``""`` if none).
    matrix: (4, 4) ``T_a_b`` (pose of frame b in frame a, metres), None when the input was not calibrated.
    frames: the names of frames a and b. log_span_ns: the first and last synced stamp [int64 ns], or None.
    verdict: the drift verdict against the nominal (None without one). warned: whether the result has warnings.
    seconds: the job's wall time [s] (None for a record without it).
    """

    input: str
    status: str
    error: str = ""
    matrix: NDArray[np.float64] | None = None
    frames: tuple[str, str] = ("a", "b")
    log_span_ns: tuple[int, int] | None = None
    verdict: Verdict | None = None
    warned: bool = False
    seconds: float | None = None

    @classmethod
    def from_record(cls, record: Mapping[str, Any]) -> BatchRecord:
        """Parse a record dict (a worker's, or a line of a records file); a field of the wrong shape is a
        ReadError naming the record's input and the field."""
        label = str(record["input"])
        try:
            matrix = None if record.get("matrix") is None else np.asarray(record["matrix"], dtype=float).reshape(4, 4)
            frames = record.get("frames") or {}
            span = record.get("log_span_ns")
            v = record.get("verdict")
            verdict = None if v is None else Verdict(
                float(v["rotation_deg"]), float(v["translation_m"]), float(v["max_rotation_deg"]),
                float(v["max_translation_m"]), v.get("rotation_significant"), v.get("translation_significant"),
                dict(v.get("nominal") or {}), dict(v.get("skipped") or {}))
            seconds = record.get("seconds")
            return cls(label, str(record["status"]), str(record.get("error") or ""), matrix,
                       (str(frames.get("a", "a")), str(frames.get("b", "b"))),
                       None if not span else (int(span[0]), int(span[-1])), verdict, bool(record.get("warnings")),
                       None if seconds is None else float(seconds))
        except (KeyError, TypeError, ValueError, AttributeError, IndexError) as e:
            raise ReadError(f"bad batch record ({type(e).__name__}: {e})", label, _FIX) from None

    @property
    def drifted(self) -> bool:
        """Whether its verdict says drift (also of an error record whose result file could not be written)."""
        return self.verdict is not None and self.verdict.drift


def intact_records(data: bytes, where: str, warn: Warn, *, tail_if_whole: bool = False) -> tuple[list[Record], int]:
    """The records of a JSON Lines text (blank lines skipped) and the byte length of its intact part.
    The piece after the last newline is a line cut by a kill mid-write: it is left out with a
    warning (kept when it is a whole record and ``tail_if_whole``: a file written by another
    tool may end without a newline). A bad line before it is a ReadError naming ``where:LINE``."""
    *lines, tail = data.split(b"\n")
    records: list[Record] = []
    end = 0
    for n, raw in enumerate(lines, 1):
        record = _parse(raw) if raw.strip() else {}
        if isinstance(record, str):
            raise ReadError(record, f"{where}:{n}", _FIX)
        if record:
            records.append(record)
        end += len(raw) + 1
    if tail.strip():
        record = _parse(tail)
        if isinstance(record, dict) and tail_if_whole:
            records.append(record)
            end += len(tail)
        else:
            warn(f"{where}:{len(lines) + 1}: the last line is cut (a batch killed while writing it?): left out")
    return records, end


def _parse(raw: bytes) -> Record | str:
    """A batch record (a JSON object with input and status), else what is wrong with the line."""
    try:
        record = json.loads(raw)
    except ValueError as e:
        return f"not JSON: {getattr(e, 'msg', e)}"
    except RecursionError:
        return "JSON nested too deeply"
    if isinstance(record, dict) and "input" in record and "status" in record:
        return record
    return "not a batch record (no input/status)"
