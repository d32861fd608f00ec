"""The fleet-trend report (``handeye report verdicts.jsonl -o fleet.html``, ``handeye batch --report``).

One self-contained HTML file, built like :mod:`handeye_cli.output.report` (inline CSS, the same
load script that counts decoded images) with matplotlib figures as base64 PNG: per sensor pair
(``frames.a``/``frames.b``), the extrinsic ``T_a_b`` of every log over log time (the first synced
stamp, UTC) as its deviation from the nominal — rotation vector of ``R_X R_Nᵀ`` [deg] (frame a)
and ``t_X − t_N`` [mm] — with the nominal at zero and the tolerance drawn as a band; without a
verdict the pair's median result is the reference and there is no band. Then the table of
drifted logs and the table of failed ones.
"""
from __future__ import annotations

import base64
import io
import json
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..errors import ConfigError, ReadError
from ..version import __version__
from .report import _CSS, _SCRIPT, _esc
from .svgplot import DPI
from .writers import check_writable, write_output

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["read_records", "render_fleet_report", "write_fleet_report"]

_AXES = ("x", "y", "z")
_COLORS = ("#1f77b4", "#2ca02c", "#9467bd")
_DRIFT = "#d62728"


def read_records(path: str | Path) -> list[dict[str, Any]]:
    """The records of a ``handeye batch`` JSON Lines file (blank lines skipped)."""
    p = Path(path)
    try:
        lines = p.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise ReadError(f"cannot read the records: {e}", str(p), "pass the output of handeye batch") from None
    records = []
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
        except json.JSONDecodeError as e:
            raise ReadError(f"not JSON: {e.msg}", f"{p}:{n}", "pass the JSON Lines output of handeye batch") from None
        except RecursionError:
            raise ReadError("JSON nested too deeply", f"{p}:{n}",
                            "pass the JSON Lines output of handeye batch") from None
        if not (isinstance(record, dict) and "status" in record and "input" in record):
            raise ReadError("not a batch record (no input/status)", f"{p}:{n}", "pass the output of handeye batch")
        records.append(record)
    return records


def _when(record: dict[str, Any]) -> datetime | None:
    span = record.get("log_span_ns")
    return datetime.fromtimestamp(span[0] / 1e9, timezone.utc) if span else None


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


def _figure(fig: Figure, alt: str, caption: str) -> str:
    """Render a matplotlib figure to a base64 PNG ``<figure>`` (zlib level 3: smaller than the
    default 6 on these plots, and faster)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, pil_kwargs={"compress_level": 3})
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    return (f"<figure><img alt='{_esc(alt)}' src='data:image/png;base64,{data}'>"
            f"<figcaption>{caption}</figcaption></figure>")


def _subplots(width: float, height: float, nrows: int, ncols: int, *, margins: tuple[float, float, float, float],
              gaps: tuple[float, float] = (0.0, 0.0), **kwargs: Any) -> tuple[Figure, Any]:
    """A ``width`` x ``height`` [in] figure and its ``nrows`` x ``ncols`` axes (``Figure.subplots``,
    which takes ``kwargs``), placed by fixed ``margins`` (left, right, bottom, top) and ``gaps``
    (between columns, between rows) [in] that leave room for tick labels, axis labels and titles.

    No layout engine: constrained layout measures every text of a figure on each draw."""
    try:
        from matplotlib.figure import Figure
    except ImportError:  # pragma: no cover - depends on the environment
        raise ConfigError("matplotlib is not installed", "--report",
                           "install it: pip install 'handeye-cli[report]'") from None
    left, right, bottom, top = margins
    axes_w = (width - left - right - (ncols - 1) * gaps[0]) / ncols         # mean axes size [in]
    axes_h = (height - bottom - top - (nrows - 1) * gaps[1]) / nrows
    fig = Figure(figsize=(width, height))
    grid = {"left": left / width, "right": 1.0 - right / width, "bottom": bottom / height, "top": 1.0 - top / height,
            "wspace": gaps[0] / axes_w, "hspace": gaps[1] / axes_h}
    return fig, fig.subplots(nrows, ncols, gridspec_kw=grid, **kwargs)


def _pair_figure(name: str, records: list[dict[str, Any]]) -> str:
    """Rotation and translation deviations over log time for one sensor pair."""
    records = sorted(records, key=lambda r: r["log_span_ns"][0])
    times = [_when(r) for r in records]
    rot, trans, has_nominal = _deviations(records)
    drift = np.array([r["status"] == "drift" for r in records])
    fig, axes = _subplots(10, 5.6, 2, 1, margins=(0.8, 0.15, 1.1, 0.15), gaps=(0.0, 0.15), sharex=True)
    verdict = next((r["verdict"] for r in records if "verdict" in r), None)
    limits = (verdict["max_rotation_deg"], verdict["max_translation_m"] * 1000) if verdict else (None, None)
    for ax, values, unit, limit in zip(axes, (rot, trans), ("rotation deviation [deg]", "translation deviation [mm]"),
                                       limits, strict=True):
        if limit is not None:
            ax.axhspan(-limit, limit, color="#8cc79a", alpha=0.3, label="tolerance")
        ax.axhline(0.0, color="#333333", lw=1, label="nominal" if has_nominal else "median")
        for k, axis in enumerate(_AXES):
            ax.plot(times, values[:, k], "o-", ms=4, lw=1, color=_COLORS[k], label=axis)
        for n, t in enumerate(t for t, d in zip(times, drift, strict=True) if d):
            ax.axvline(t, color=_DRIFT, lw=2, alpha=0.5, label=None if n else "drift")
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", fontsize=8, ncol=6)
    axes[1].set_xlabel("log start (UTC)")
    fig.autofmt_xdate(bottom=fig.subplotpars.bottom)          # rotate the dates, keep the margin
    return _figure(fig, f"extrinsic of {name} over time", f"{_esc(name)}: {len(records)} log(s); deviation from the "
                   f"{'nominal, tolerance band in green' if has_nominal else 'median result (no nominal given)'}; "
                   "drifted logs marked by red lines.")


def _row(cells: list[Any]) -> str:
    return "<tr>" + "".join(f"<td>{_esc(c)}</td>" for c in cells) + "</tr>"


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


def render_fleet_report(records: list[dict[str, Any]]) -> str:
    """The report as one HTML string (see the module docstring)."""
    pairs: dict[str, list[dict[str, Any]]] = {}
    for r in records:
        if "matrix" in r and r.get("log_span_ns"):
            f = r.get("frames") or {}
            pairs.setdefault(f"T_{f.get('a', 'a')}_{f.get('b', 'b')}", []).append(r)
    counts = {s: sum(r["status"] == s for r in records) for s in ("ok", "drift", "error")}
    figures = "".join(f"<h2>{_esc(name)}</h2>{_pair_figure(name, rs)}" for name, rs in sorted(pairs.items()))
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    body = (f"<h1>handeye fleet report</h1><p class='sub'>{len(records)} log(s): {counts['ok']} ok, "
            f"{counts['drift']} drift, {counts['error']} error. T_a_b is the pose of frame b in frame a. "
            f"Generated {stamp} by handeye {_esc(__version__)}.</p>"
            f"{figures or '<p class=note>No calibrated log to plot.</p>'}"
            f"<h2>Drifted logs</h2>{_drift_table(records)}<h2>Failed logs</h2>{_error_table(records)}")
    return ("<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            "<meta name='viewport' content='width=device-width, initial-scale=1'>"
            f"<title>handeye fleet report</title><style>{_CSS}</style></head>"
            f"<body><main>{body}</main><script>{_SCRIPT}</script></body></html>\n")


def write_fleet_report(path: str | Path, records: list[dict[str, Any]], flag: str = "-o") -> None:
    """Write the fleet report of batch ``records`` to ``path`` (atomically); a ReadError or WriteError naming
    ``flag`` when it cannot be written or matplotlib is missing (no file is created)."""
    check_writable(path, flag)
    write_output(path, render_fleet_report(records), flag)
