"""Text trajectories: TUM, EuRoC ground-truth CSV and generic CSV with a header.

* TUM: ``timestamp tx ty tz qx qy qz qw`` — seconds, quaternion **w last**; separated by
  spaces, tabs or commas; ``#`` comments.
* EuRoC: ``timestamp[ns], px, py, pz, qw, qx, qy, qz[, …]`` — integer nanoseconds, quaternion
  **w first**, with or without the (17-column) ``#timestamp, p_RS_R_x [m], …`` header.
* CSV: a header row naming the columns; ``columns`` maps the keys ``t, x, y, z, qx, qy, qz, qw``
  to column names and ``t_unit`` (``s``, ``ms``, ``us``, ``ns``) gives the time unit; without
  it the unit comes from the time column's name (``t_ns``, ``stamp [us]``…), else seconds.
  Common names (``timestamp``, ``tx``, ``pos_x``, ``qw``…) are found without a mapping.

Stamps are parsed exactly into int64 nanoseconds (no float round trip); positions in metres.
Every line is one pose ``T_world_sensor``; the file name becomes the child frame.
"""
from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from decimal import Decimal, InvalidOperation
from pathlib import Path

import numpy as np

from ..errors import HandEyeError
from ..streams import PoseStream
from .common import make_stream

__all__ = ["read_text", "CSV_KEYS"]

CSV_KEYS = ("t", "x", "y", "z", "qx", "qy", "qz", "qw")
_UNITS = {"s": 9, "ms": 6, "us": 3, "ns": 0}
_ALIASES = {
    "t": ("t", "time", "timestamp", "stamp", "timestamp_ns", "time_ns", "t_ns", "sec", "seconds"),
    "x": ("x", "tx", "px", "pos_x", "position_x", "position.x", "p_rs_r_x"),
    "y": ("y", "ty", "py", "pos_y", "position_y", "position.y", "p_rs_r_y"),
    "z": ("z", "tz", "pz", "pos_z", "position_z", "position.z", "p_rs_r_z"),
    "qx": ("qx", "q_x", "rot_x", "orientation_x", "orientation.x", "q_rs_x"),
    "qy": ("qy", "q_y", "rot_y", "orientation_y", "orientation.y", "q_rs_y"),
    "qz": ("qz", "q_z", "rot_z", "orientation_z", "orientation.z", "q_rs_z"),
    "qw": ("qw", "q_w", "rot_w", "orientation_w", "orientation.w", "q_rs_w"),
}
_SPLIT = re.compile(r"[,\s]+")
_COMMA = re.compile(",")
_UNIT_SUFFIX = re.compile(r"\s*\[.*?\]\s*$")
_UNIT_IN_NAME = re.compile(r"(?:\[|_)(ns|us|ms|s)\]?$", re.IGNORECASE)


def _stamp_ns(text: str, digits: int) -> int:
    """Exact int ns from a decimal string in a unit of 10**-digits s ("1.5", "1.7e9", "17")."""
    ns = int(text) if digits == 0 and text.isdigit() else int(Decimal(text).scaleb(digits).to_integral_value())
    if not -2**63 <= ns < 2**63:
        raise ValueError(f"timestamp {text} is out of the int64 nanosecond range (wrong time unit?)")
    return ns


def _rows(path: Path, split: re.Pattern = _SPLIT, skip: int = 0) -> Iterator[tuple[int, list[str]]]:
    """(line number, fields) of the data lines; blank lines, ``#`` comments and line ``skip`` skipped."""
    with open(path, encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            s = line.strip()
            if s and not s.startswith("#") and n != skip:
                yield n, [x.strip() for x in split.split(s)]


def _parse(path: Path, rows: Iterator[tuple[int, list[str]]], need: int, expected: str,
           convert: Callable[[list[str]], tuple[int, list[float]]]) -> PoseStream:
    lines, stamps, values = [], [], []
    for n, fields in rows:
        try:
            if len(fields) < need:
                raise ValueError(f"{len(fields)} values")
            stamp, vals = convert(fields)
        except (ValueError, InvalidOperation) as exc:
            reason = str(exc) or type(exc).__name__
            got = " ".join(fields)
            got = got if len(got) <= 80 else got[:77] + "..."
            raise HandEyeError(f"malformed line ({reason}): expected {expected}, got {got!r}",
                               f"{path}, line {n}", "fix or delete the line") from exc
        lines.append(n)
        stamps.append(stamp)
        values.append(vals)
    v = np.array(values, dtype=np.float64).reshape(-1, 7)
    return make_stream(np.array(stamps, dtype=np.int64), v[:, :3], v[:, 3:], source=str(path),
                       frame_id="world", child_frame_id=path.stem, time_source="header",
                       where=lambda i: f"line {lines[i]}")


def _tum(fields: list[str]) -> tuple[int, list[float]]:
    if len(fields) != 8:
        raise ValueError(f"{len(fields)} values")
    return _stamp_ns(fields[0], 9), [float(x) for x in fields[1:]]


def _euroc(fields: list[str]) -> tuple[int, list[float]]:
    v = [float(x) for x in fields[1:8]]
    return _stamp_ns(fields[0], 0), v[:3] + v[4:7] + v[3:4]


def _csv(path: Path, columns: dict | None) -> PoseStream:
    with open(path, encoding="utf-8") as f:
        header_no, header_line = next(((n, ln) for n, ln in enumerate(f, 1) if ln.strip()), (0, ""))
    raw = [h.strip() for h in header_line.strip().lstrip("#").split(",")]
    header = [_UNIT_SUFFIX.sub("", h).strip() for h in raw]
    lower = {h.lower(): i for i, h in enumerate(header)}
    mapping = dict(columns or {})
    unit = mapping.pop("t_unit", None)
    if unit is not None and unit not in _UNITS:
        raise HandEyeError(f"unknown time unit {unit!r}", f"{path}: columns.t_unit", f"use one of {list(_UNITS)}")
    index = []
    for key in CSV_KEYS:
        names = (mapping[key],) if key in mapping else _ALIASES[key]
        found = next((lower[n.lower()] for n in names if n.lower() in lower), None)
        if found is None:
            raise HandEyeError(f"CSV column for {key!r} not found (looked for {', '.join(names)})",
                               f"{path}, line {header_no}", f"map it with columns={{'{key}': NAME}}; header has: "
                               f"{', '.join(header)}")
        index.append(found)
    if unit is None:        # "timestamp [ns]", "t_ns", "stamp_us" … name their unit; else seconds
        m = _UNIT_IN_NAME.search(raw[index[0]])
        unit = m.group(1).lower() if m else "s"
    digits = _UNITS[unit]

    def convert(fields: list[str]) -> tuple[int, list[float]]:
        return _stamp_ns(fields[index[0]], digits), [float(fields[i]) for i in index[1:]]

    return _parse(path, _rows(path, _COMMA, header_no), max(index) + 1, f"{len(header)} columns ({', '.join(header)})", convert)


def read_text(path: Path, fmt: str, columns: dict | None = None) -> PoseStream:
    """Read one text trajectory (``fmt`` = ``tum``, ``euroc`` or ``csv``) as ``T_world_<stem>``."""
    if columns is not None or fmt == "csv":
        return _csv(path, columns)
    if fmt == "tum":
        return _parse(path, _rows(path), 8, "8 numbers 'timestamp tx ty tz qx qy qz qw'", _tum)
    return _parse(path, _rows(path), 8, "at least 8 comma-separated numbers "
                                        "'timestamp_ns, px, py, pz, qw, qx, qy, qz'", _euroc)
