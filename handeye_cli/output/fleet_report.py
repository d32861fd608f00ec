"""The fleet-trend report (``handeye report verdicts.jsonl -o fleet.html``, ``handeye batch --report``).

One self-contained HTML file, built like :mod:`handeye_cli.output.report` and with its SVG charts
(:mod:`handeye_cli.output.svgplot`: no optional dependency): per sensor pair (``frames.a``/``frames.b``)
a chart of six panels, the extrinsic ``T_a_b`` of every log over log time (its first synced stamp,
days since the earliest log, UTC) as its deviation from the nominal — rotation vector of
``R_X R_Nᵀ`` [deg] (frame a) and ``t_X − t_N`` [mm], one panel per axis — with the nominal at zero
and the tolerance as dashed lines; without a verdict the pair's median result is the reference and
there is no tolerance. One line per robot: a robot is an input's path with its dates and times (runs
of 6 or more digits and separators, such as ``2026-11-03`` or ``20261103_120000``) taken out, so that
``logs/2026-11-03/robot42.mcap`` and ``logs/2026-11-04/robot42.mcap`` are one line (``logs/robot42.mcap``) and
``logs/robot01/rig.bag`` and ``logs/robot02/rig.bag`` two. Drifted logs are red crosses. The legend
(robot colours) is HTML below the chart, never over the data. Then the table of drifted logs and the
table of failed ones.
"""
from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..errors import ReadError
from ..version import __version__
from .records import BatchRecord, intact_records
from .report import _CSS, _SCRIPT, esc, figure
from .svgplot import Chart
from .writers import check_writable, write_output

__all__ = ["read_records", "render_fleet_report", "write_fleet_report"]

_AXES = ("x", "y", "z")
_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf")
_DRIFT = "#d62728"
_TOLERANCE = "#2ca02c"
_STAMP = re.compile(r"\d[\d_:.T-]{4,}\d")              # dates and times in a path: 6+ digits and separators
_DAY_NS = 86_400e9


def read_records(path: str | Path, warn: Callable[[str], None]) -> list[BatchRecord]:
    """The records of a ``handeye batch`` JSON Lines file (blank lines skipped), each parsed once into a
    :class:`BatchRecord`: a last line cut by a batch killed mid-write is left out with a warning; a bad line
    before it is a ReadError."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as e:
        raise ReadError(f"cannot read the records: {e.strerror}", str(p), "pass the output of handeye batch") from None
    return [BatchRecord.from_record(r) for r in intact_records(data, str(p), warn, tail_if_whole=True)[0]]


def _robot(label: str) -> str:
    """The robot of an input (see the module docstring); a folder left empty by its date goes too
    (``logs/2026-11-03/robot42.mcap`` → ``logs/robot42.mcap``)."""
    return re.sub(r"(?<=/)/+", "", _STAMP.sub("", label))


def _deviations(records: list[BatchRecord]) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:
    """Per record: rotation deviation [deg] (3) and translation deviation [mm] (3) from the nominal
    (or from the median result when no record has a verdict), and whether the nominal was used."""
    X = np.array([r.matrix for r in records], dtype=float)
    nominals = [r.verdict.nominal for r in records if r.verdict is not None]
    if nominals:
        nominal = nominals[0]
        N_t, N_R = np.asarray(nominal["translation"], dtype=float), Rotation.from_quat(nominal["quaternion_xyzw"])
    else:
        N_t, N_R = np.median(X[:, :3, 3], axis=0), Rotation.from_matrix(X[:, :3, :3]).mean()
    rot = (Rotation.from_matrix(X[:, :3, :3]) * N_R.inv()).as_rotvec(degrees=True)
    return rot, (X[:, :3, 3] - N_t) * 1000.0, bool(nominals)


def _start(record: BatchRecord) -> int:
    """The first synced stamp [ns] of a record the charts hold (they hold those with a span)."""
    assert record.log_span_ns is not None
    return record.log_span_ns[0]


def _when(record: BatchRecord) -> datetime | None:
    return None if record.log_span_ns is None else datetime.fromtimestamp(_start(record) / 1e9, timezone.utc)


def _pair_figure(name: str, records: list[BatchRecord]) -> str:
    """Rotation and translation deviations over log time for one sensor pair, one line per robot."""
    records = sorted(records, key=lambda r: (_robot(r.input), _start(r)))
    t0 = min(_start(r) for r in records)
    days = np.array([(_start(r) - t0) / _DAY_NS for r in records])
    rot, trans, has_nominal = _deviations(records)
    drift = np.array([r.status == "drift" for r in records])
    robots = list(dict.fromkeys(_robot(r.input) for r in records))
    which = np.array([robots.index(_robot(r.input)) for r in records])
    verdict = next((r.verdict for r in records if r.verdict is not None), None)
    limits = (verdict.max_rotation_deg, verdict.max_translation_m * 1000) if verdict else (None, None)
    chart = Chart(10, 5.6)
    panels = chart.grid(2, 3, margins=(0.8, 0.15, 0.6, 0.35), gaps=(0.55, 0.45))
    start = datetime.fromtimestamp(t0 / 1e9, timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    for row, (values, unit, limit) in enumerate(zip((rot, trans), ("rotation [deg]", "translation [mm]"), limits,
                                                    strict=True)):
        for k, axis in enumerate(_AXES):
            panel = panels[3 * row + k]
            panel.title, panel.title_size = f"{axis} {unit}", 10.0
            panel.hline(0.0, "#333333", 1.0)
            if limit is not None:
                panel.hline(limit, _TOLERANCE, 1.0, "--")
                panel.hline(-limit, _TOLERANCE, 1.0, "--")
            for n in range(len(robots)):
                mine = which == n
                color = _COLORS[n % len(_COLORS)]
                panel.line(days[mine], values[mine, k], color, 1.0)
                panel.points(days[mine], values[mine, k], color, 4.0)
            if drift.any():
                panel.points(days[drift], values[drift, k], _DRIFT, 6.0, marker="x")
            if row == 1:
                panel.xlabel = f"days since {start}"
    keys = "".join(f"<span class='key'><span style='color:{_COLORS[n % len(_COLORS)]}'>&#9679;</span> "
                   f"{esc(robot)}</span> " for n, robot in enumerate(robots))
    reference = "nominal, tolerance dashed in green" if has_nominal else "median result (no nominal given)"
    caption = (f"{esc(name)}: {len(records)} log(s) of {len(robots)} robot(s); deviation from the {reference}; "
               f"drifted logs are red crosses.<br>{keys}")
    return figure(chart, f"extrinsic of {name} over time", caption)


def _row(cells: list[object]) -> str:
    return "<tr>" + "".join(f"<td>{esc(c)}</td>" for c in cells) + "</tr>"


def _significant(value: bool | None) -> object:
    return "n/a" if value is None else value


def _drift_table(records: list[BatchRecord]) -> str:
    drifted = [(r, r.verdict) for r in records if r.status == "drift" and r.verdict is not None]
    if not drifted:
        return "<div class='ok'>No log drifted beyond tolerance.</div>"
    rows = "".join(_row([r.input, _when(r) or "", f"{v.rotation_deg:.3f}", f"{v.translation_m * 1000:.2f}",
                         _significant(v.rotation_significant), _significant(v.translation_significant)])
                   for r, v in drifted)
    head = "".join(f"<th>{h}</th>" for h in ("input", "log start (UTC)", "rotation [deg]", "translation [mm]",
                                             "rotation significant", "translation significant"))
    return f"<div class='card' id='drifted'><table><tr>{head}</tr>{rows}</table></div>"


def _error_table(records: list[BatchRecord]) -> str:
    failed = [r for r in records if r.status == "error"]
    if not failed:
        return "<p class='note'>Every log was calibrated.</p>"
    rows = "".join(_row([r.input, r.error]) for r in failed)
    return f"<div class='card' id='failed'><table><tr><th>input</th><th>error</th></tr>{rows}</table></div>"


def render_fleet_report(records: Iterable[BatchRecord]) -> str:
    """The report as one HTML string (see the module docstring) of typed batch records."""
    records = list(records)
    pairs: dict[str, list[BatchRecord]] = {}
    for r in records:
        if r.matrix is not None and r.log_span_ns is not None:
            pairs.setdefault(f"T_{r.frames[0]}_{r.frames[1]}", []).append(r)
    counts = {s: sum(r.status == s for r in records) for s in ("ok", "drift", "error")}
    figures = "".join(f"<h2>{esc(name)}</h2>{_pair_figure(name, rs)}" for name, rs in sorted(pairs.items()))
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    body = (f"<h1>handeye fleet report</h1><p class='sub'>{len(records)} log(s): {counts['ok']} ok, "
            f"{counts['drift']} drift, {counts['error']} error. T_a_b is the pose of frame b in frame a. "
            f"Generated {stamp} by handeye {esc(__version__)}.</p>"
            f"{figures or '<p class=note>No calibrated log to plot.</p>'}"
            f"<h2>Drifted logs</h2>{_drift_table(records)}<h2>Failed logs</h2>{_error_table(records)}")
    return ("<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            "<meta name='viewport' content='width=device-width, initial-scale=1'>"
            f"<title>handeye fleet report</title><style>{_CSS}</style></head>"
            f"<body><main>{body}</main><script>{_SCRIPT}</script></body></html>\n")


def write_fleet_report(path: str | Path, records: list[BatchRecord], flag: str = "-o") -> None:
    """Write the fleet report of batch ``records`` to ``path`` (atomically); a HandEyeError naming
    ``flag`` when it cannot be written (no file is created)."""
    check_writable(path, flag)
    write_output(path, render_fleet_report(records), flag)
