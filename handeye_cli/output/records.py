"""Reading batch records (JSON Lines) that a killed batch may have cut: by the batch resuming
from its records file (``--skip-done``) and by the fleet report."""
from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

from ..errors import ReadError

__all__ = ["intact_records"]

Record = dict[str, Any]
Warn = Callable[[str], None]


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
            raise ReadError(record, f"{where}:{n}", "pass the JSON Lines output of handeye batch")
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
