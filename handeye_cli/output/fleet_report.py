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
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..errors import ReadError
from ..version import __version__
from .records import intact_records
from .report import _CSS, _SCRIPT, esc, figure
from .svgplot import Chart
from .writers import check_writable, write_output

__all__ = ["read_records", "render_fleet_report", "report_fields", "write_fleet_report"]

_AXES = ("x", "y", "z")
_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf")
_DRIFT = "#d62728"
_TOLERANCE = "#2ca02c"
_FIELDS = ("input", "status", "error", "matrix", "frames", "log_span_ns", "verdict")
_VERDICT = ("drift", "nominal", "rotation_deg", "translation_m", "max_rotation_deg", "max_translation_m",
            "rotation_significant", "translation_significant")
_STAMP = re.compile(r"\d[\d_:.T-]{4,}\d")              # dates and times in a path: 6+ digits and separators
_DAY_NS = 86_400e9


def report_fields(record: dict[str, Any]) -> dict[str, Any]:
    """What the report reads of a batch record (the batch keeps only this of each record)."""
    out = {k: record[k] for k in _FIELDS if k in record}
    if isinstance(out.get("verdict"), dict):
        out["verdict"] = {k: out["verdict"][k] for k in _VERDICT if k in out["verdict"]}
    return out


def read_records(path: str | Path, warn: Callable[[str], None]) -> list[dict[str, Any]]:
    """The records of a ``handeye batch`` JSON Lines file (blank lines skipped): a last line cut by
    a batch killed mid-write is left out with a warning; a bad line before it is a ReadError."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as e:
        raise ReadError(f"cannot read the records: {e.strerror}", str(p), "pass the output of handeye batch") from None
    return [report_fields(r) for r in intact_records(data, str(p), warn, tail_if_whole=True)[0]]


def _robot(label: str) -> str:
    """The robot of an input (see the module docstring); a folder left empty by its date goes too
    (``logs/2026-11-03/robot42.mcap`` → ``logs/robot42.mcap``)."""
    return re.sub(r"(?<=/)/+", "", _STAMP.sub("", label))


def _deviations(records: list[dict[str, Any]]) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:
    """Per record: rotation deviation [deg] (3) and translation deviation [mm] (3) from the nominal
    (or from the median result when no record has a verdict), and whether the nominal was used."""
    X = np.array([r["matrix"] for r in records], dtype=float)
    nominals = [r["verdict"]["nominal"] for r in records if "verdict" in r]
    if nominals:
        nominal = nominals[0]
        N_t, N_R = np.asarray(nominal["translation"], dtype=float), Rotation.from_quat(nominal["quaternion_xyzw"])
    else:
        N_t, N_R = np.median(X[:, :3, 3], axis=0), Rotation.from_matrix(X[:, :3, :3]).mean()
    rot = (Rotation.from_matrix(X[:, :3, :3]) * N_R.inv()).as_rotvec(degrees=True)
    return rot, (X[:, :3, 3] - N_t) * 1000.0, bool(nominals)


def _when(record: dict[str, Any]) -> datetime | None:
    span = record.get("log_span_ns")
    return datetime.fromtimestamp(span[0] / 1e9, timezone.utc) if span else None


def _pair_figure(name: str, records: list[dict[str, Any]]) -> str:
    """Rotation and translation deviations over log time for one sensor pair, one line per robot."""
    records = sorted(records, key=lambda r: (_robot(r["input"]), r["log_span_ns"][0]))
    t0 = min(r["log_span_ns"][0] for r in records)
    days = np.array([(r["log_span_ns"][0] - t0) / _DAY_NS for r in records])
    rot, trans, has_nominal = _deviations(records)
    drift = np.array([r["status"] == "drift" for r in records])
    robots = list(dict.fromkeys(_robot(r["input"]) for r in records))
    which = np.array([robots.index(_robot(r["input"])) for r in records])
    verdict = next((r["verdict"] for r in records if "verdict" in r), None)
    limits = (verdict["max_rotation_deg"], verdict["max_translation_m"] * 1000) if verdict else (None, None)
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


def _row(cells: list[Any]) -> str:
    return "<tr>" + "".join(f"<td>{esc(c)}</td>" for c in cells) + "</tr>"


def _drift_table(records: list[dict[str, Any]]) -> str:
    drifted = [r for r in records if r["status"] == "drift"]
    if not drifted:
        return "<div class='ok'>No log drifted beyond tolerance.</div>"
    rows = "".join(_row([r["input"], _when(r) or "", f"{r['verdict']['rotation_deg']:.3f}",
                         f"{r['verdict']['translation_m'] * 1000:.2f}",
                         r["verdict"].get("rotation_significant", "n/a"),
                         r["verdict"].get("translation_significant", "n/a")]) for r in drifted)
    head = "".join(f"<th>{h}</th>" for h in ("input", "log start (UTC)", "rotation [deg]", "translation [mm]",
                                             "rotation significant", "translation significant"))
    return f"<div class='card' id='drifted'><table><tr>{head}</tr>{rows}</table></div>"


def _error_table(records: list[dict[str, Any]]) -> str:
    failed = [r for r in records if r["status"] == "error"]
    if not failed:
        return "<p class='note'>Every log was calibrated.</p>"
    rows = "".join(_row([r["input"], r.get("error", "")]) for r in failed)
    return f"<div class='card' id='failed'><table><tr><th>input</th><th>error</th></tr>{rows}</table></div>"


def render_fleet_report(records: Iterable[dict[str, Any]]) -> str:
    """The report as one HTML string (see the module docstring)."""
    records = list(records)
    pairs: dict[str, list[dict[str, Any]]] = {}
    for r in records:
        if "matrix" in r and r.get("log_span_ns"):
            f = r.get("frames") or {}
            pairs.setdefault(f"T_{f.get('a', 'a')}_{f.get('b', 'b')}", []).append(r)
    counts = {s: sum(r["status"] == s for r in records) for s in ("ok", "drift", "error")}
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


def write_fleet_report(path: str | Path, records: list[dict[str, Any]], flag: str = "-o") -> None:
    """Write the fleet report of batch ``records`` to ``path`` (atomically); a HandEyeError naming
    ``flag`` when it cannot be written (no file is created)."""
    check_writable(path, flag)
    write_output(path, render_fleet_report(records), flag)
