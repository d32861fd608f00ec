"""Text trajectories: TUM, EuRoC ground-truth CSV and generic CSV with a header.

* TUM: ``timestamp tx ty tz qx qy qz qw`` — seconds, quaternion **w last**; separated by
  spaces, tabs or commas; ``#`` comments.
* EuRoC: ``timestamp[ns], px, py, pz, qw, qx, qy, qz[, …]`` — integer nanoseconds, quaternion
  **w first**, with or without the (17-column) ``#timestamp, p_RS_R_x [m], …`` header.
* CSV: a header row naming the columns; ``columns`` maps the keys ``t, x, y, z, qx, qy, qz, qw``
  to column names and ``t_unit`` (``s``, ``ms``, ``us``, ``ns``) gives the time unit; without
  it the unit comes from the time column's name (``t_ns``, ``stamp [us]``…), else it is detected.
  Common names (``timestamp``, ``tx``, ``pos_x``, ``qw``…) are found without a mapping.

Stamps are parsed exactly into int64 nanoseconds (no float round trip); positions in metres.
Every line is one pose ``T_world_sensor``; the file stem (``stdin`` for ``-``) becomes the child frame (the
world is unnamed: ``frame_id`` is empty).
Numbers are parsed by :mod:`.table` (a vectorised parser, with a line loop for odd input).
"""
from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..errors import ConfigError, ReadError
from ..streams import PoseStream
from .common import make_stream
from .inputs import open_binary, stem_of, valid_frame_id
from .table import Table, fast_table, slow_table

__all__ = ["read_text", "CSV_KEYS", "TIME_UNITS", "QUATERNION_ORDERS"]

CSV_KEYS = ("t", "x", "y", "z", "qx", "qy", "qz", "qw")
TIME_UNITS = ("auto", "s", "ms", "us", "ns")
QUATERNION_ORDERS = ("auto", "xyzw", "wxyz")
_DIGITS = {"s": 9, "ms": 6, "us": 3, "ns": 0}
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
_UNIT_SUFFIX = re.compile(r"\s*\[.*?\]\s*$")
_UNIT_IN_NAME = re.compile(r"(?:\[|_)(ns|us|ms|s)\]?$", re.IGNORECASE)
_TEXT_STAMPS_FIX = "the time column holds no stamps; fix the export"


def _csv_layout(path: Path | str, columns: Mapping[str, str] | None) -> tuple[int, list[int], str | None, str]:
    """(header line number, column indices of t, x, y, z, qx, qy, qz, qw, unit or None, description)."""
    name = str(path)
    with open_binary(path) as f:
        header_no, header_line = next(((n, ln.decode("utf-8", "replace")) for n, ln in enumerate(f, 1)
                                       if ln.strip()), (0, ""))
    raw = [h.strip() for h in header_line.strip().lstrip("#").split(",")]
    header = [_UNIT_SUFFIX.sub("", h).strip() for h in raw]
    lower = {h.lower(): i for i, h in enumerate(header)}
    mapping = dict(columns or {})
    unit = mapping.pop("t_unit", None)
    if unit is not None and unit not in _DIGITS:
        raise ConfigError(f"unknown time unit {unit!r}", f"{name}: csv_columns.t_unit", f"use one of {list(_DIGITS)}")
    index = []
    for key in CSV_KEYS:
        names = (mapping[key],) if key in mapping else _ALIASES[key]
        found = next((lower[n.lower()] for n in names if n.lower() in lower), None)
        if found is None:
            raise ReadError(f"CSV column for {key!r} not found (looked for {', '.join(names)})",
                            f"{name}, line {header_no}", f"map it with ⟦csv_columns='{key}=COLUMN'⟧; header has: "
                            f"{', '.join(header)}")
        index.append(found)
    if unit is None:        # "timestamp [ns]", "t_ns", "stamp_us" … name their unit
        m = _UNIT_IN_NAME.search(raw[index[0]])
        unit = m.group(1).lower() if m else None
    return header_no, index, unit, f"{len(header)} columns ({', '.join(header)})"


def _table(path: Path | str, *, need: int, expected: str, skip: int = 0, t_col: int = 0,
           comma_only: bool = False, exact: bool = False) -> Table:
    """The fast parse when it applies (and has the right width), else the line loop."""
    with open_binary(path) as f:
        table = fast_table(f, skip=skip, t_col=t_col)
    width = table.values.shape[1] if table is not None else 0
    if table is not None and (width == need or (width > need and not exact)):
        return table
    with open_binary(path) as f:
        return slow_table(f, str(path), need=need, expected=expected, skip=skip, t_col=t_col,
                          comma_only=comma_only, exact=exact)


def _auto_unit(t: NDArray[np.float64], name: str, notes: list[str], *, seconds_defined: bool) -> str:
    """The time unit of the stamps: epoch-sized values name their unit by magnitude (silently; no
    recording is 10¹¹ s long); small values (time since start) are seconds where the format defines
    them so (``seconds_defined``: TUM — an arm's station capture steps seconds apart), else (a CSV
    without a unit) read by their median step, with a warning."""
    magnitude = float(np.median(np.abs(t)))
    for limit, unit in ((1e17, "ns"), (1e14, "us"), (1e11, "ms"), (1e8, "s")):
        if magnitude >= limit:
            return unit
    if seconds_defined:
        return "s"
    steps = np.diff(t)
    step = float(np.median(steps[steps > 0])) if (steps > 0).any() else 0.0
    if step <= 1.0:
        return "s"
    unit = "ms" if step <= 1e3 else "us" if step <= 1e6 else "ns"
    notes.append(f"the stamps of {name} are small (median {magnitude:g}) and step by a median {step:g}: read as "
                 f"{unit} since start ({10 ** (9 - _DIGITS[unit]) / step:.4g} Hz); if that is "
                 "wrong, pass the unit with ⟦time_unit='s|ms|us|ns'⟧")
    return unit


def _columns(values: NDArray[np.float64], cols: NDArray[np.intp]) -> NDArray[np.float64]:
    """``values[:, cols]``, as a view when the columns are adjacent and in order (no copy of a large table)."""
    if (np.diff(cols) == 1).all():
        return values[:, cols[0]:cols[-1] + 1]
    return values[:, cols]


def _check_args(quaternion_order: str, time_unit: str) -> None:
    if quaternion_order not in QUATERNION_ORDERS:
        raise ConfigError(f"unknown quaternion order {quaternion_order!r}", "quaternion_order",
                          "use auto (the format's), xyzw (⟦wxyz_a=False⟧ / ⟦wxyz_b=False⟧) or wxyz "
                          "(⟦wxyz_a=True⟧ / ⟦wxyz_b=True⟧)")
    if time_unit not in TIME_UNITS:
        raise ConfigError(f"unknown time unit {time_unit!r}", "time_unit", "use ⟦time_unit='auto|s|ms|us|ns'⟧")


def read_text(path: Path | str, fmt: str, columns: Mapping[str, str] | None = None, *, quaternion_order: str = "auto",
              time_unit: str = "auto") -> PoseStream:
    """Read one text trajectory (``fmt`` = ``tum``, ``euroc`` or ``csv``; ``-`` = stdin) as
    ``T_world_<stem>``: int64 ns stamps, positions [m], quaternions x-y-z-w.

    ``quaternion_order``: the order of the four quaternion columns (``"wxyz"``: scalar first), or
    ``"auto"``: the format's (TUM and a CSV's qx, qy, qz, qw columns x-y-z-w, EuRoC w first), recorded
    in the stream's ``quaternion_order`` so that the pipeline can test the other order by the fit.
    ``time_unit``: ``"auto"`` (EuRoC ns; TUM seconds, as the format defines them, unless epoch-sized
    values name ns/us/ms by magnitude; CSV: the time column's name, e.g. ``t_ns``; otherwise by
    magnitude, or by the median step for time since start — with a warning naming ``--time-unit``)
    or one of ``s``, ``ms``, ``us``, ``ns`` for every format.
    """
    _check_args(quaternion_order, time_unit)
    name, notes = str(path), list[str]()
    if columns is not None or fmt == "csv":
        skip, index, unit, expected = _csv_layout(path, columns)
        table = _table(path, need=max(index) + 1, expected=f"at least {max(index) + 1} fields of {expected}",
                       skip=skip, t_col=index[0], comma_only=True)
        order = "xyzw"                      # the columns named qx, qy, qz, qw
    elif fmt == "tum":
        index, unit, order = list(range(8)), None, "xyzw"
        table = _table(path, need=8, expected="8 numbers 'timestamp tx ty tz qx qy qz qw'", exact=True)
    else:
        index, unit, order = list(range(8)), "ns", "wxyz"
        table = _table(path, need=8, expected="at least 8 comma-separated numbers "
                                              "'timestamp_ns, px, py, pz, qw, qx, qy, qz'")
    if not len(table.lines):
        raise ReadError("empty file: no data lines", name, "check the file")
    if time_unit != "auto":
        unit = time_unit
    elif unit is None:
        unit = _auto_unit(table.time_float(), name, notes, seconds_defined=fmt == "tum" and columns is None)
    cols = np.asarray(index[1:])
    xyz = _columns(table.values, cols[:3])
    open_order = quaternion_order == "auto"                 # the format's: the fit may overturn it
    if not open_order:
        order = quaternion_order
    quat = _columns(table.values, cols[[4, 5, 6, 3]] if order == "wxyz" else cols[3:])
    lines = table.lines
    return make_stream(table.stamps_ns(_DIGITS[unit], name), xyz, quat, source=name, frame_id="",
                       child_frame_id=valid_frame_id(stem_of(path)), time_source="header",
                       where=lambda i: f"line {lines[i]}", warnings=notes, zero_stamps_fix=_TEXT_STAMPS_FIX,
                       quaternion_order=order if open_order else None)
