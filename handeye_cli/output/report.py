"""A self-contained HTML report of a calibration (``handeye calibrate --report out.html``).

One HTML file, no external resources: inline CSS, figures drawn as SVG documents by
:mod:`.svgplot` and embedded as base64 ``data:`` URIs of ``<img>`` elements, and a tiny inline
script that records on window load how many images decoded (``<body data-images=… data-loaded=…>``,
used by the tests). The figures of a 60-min log take about 0.2 s of CPU; matplotlib, used before,
took 2 to 4 s (import, layout, rasterising, PNG), as much as the plain calibration of that log.

Conventions: ``X = T_a_b`` is the pose of frame b in frame a (maps points from b to a); each
stream holds ``T_world_sensor(t)``; motions satisfy ``A_i X = X B_i``; quaternions are Hamilton
x-y-z-w; metres, and degrees in everything shown.

Contents: the extrinsic (matrix, translation, quaternion, rotation in degrees), method, α, cost,
pairs used and inputs; the warnings; (1) both trajectories in a's world after applying the
extrinsic, (2) per-pair residuals over time, (3) what each stage kept and each gate dropped
(one log scale, a zero without a bar), (4) the bootstrap spread when given; a titled table for
every other block of the result document (time offset, uncertainty, residuals, robust, solver,
fit test, …; values not computed left out), and the options that differ from the defaults.
It needs no optional dependency.
"""
from __future__ import annotations

import base64
import html
import math
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial.transform import Rotation

from .._typing import BoolArray, FloatArray, IntArray
from ..analysis.residuals import pair_residuals
from ..errors import as_flags
from ..geometry import dualquat as dq
from ..geometry.lie import nearest_rotation
from ..version import __version__
from .document import plain, solver_section, static_transform_command
from .svgplot import Chart
from .writers import check_writable, write_output

if TYPE_CHECKING:
    from ..analysis.robust import RobustResult
    from ..calibration import Calibration
    from ..stages.counts import SampleCounts
    from ..stages.sync import Synced

__all__ = ["write_report", "world_alignment", "render_report", "card", "cards", "esc", "figure", "fmt", "heading",
           "page", "table", "warnings_block"]

MAX_PLOT_POINTS = 10_000
COLOR_A, COLOR_B, COLOR_BAD = "#1f77b4", "#ff7f0e", "#d62728"

# Result keys shown in the header; every other block of the document is a titled table of its own.
_TITLES = {"residuals": "Residual summary", "uncertainty": "Uncertainty", "time_offset": "Time offset",
           "robust": "Outlier rejection", "solver": "Solver", "samples": "Samples per stage",
           "sync": "Synchronisation", "noise_model": "Noise model", "alpha_auto": "α chosen from the data",
           "observability": "Observability", "degrees_of_freedom": "Degrees of freedom",
           "uncertainty_check": "Uncertainty check", "fit_test": "Fit test", "settings": "Settings"}
_HEADER_KEYS = {"matrix", "translation", "quaternion_xyzw", "frames", "method", "alpha", "cost", "pairs_used",
                "version", "warnings", "ros2_static_transform", "inputs"}

_CSS = """
body{font-family:-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif;margin:0;background:#f6f7f9;color:#1d232b}
main{max-width:1140px;margin:0 auto;padding:18px 22px 40px}
h1{font-size:1.5em;margin:.2em 0 .1em}
h2{font-size:1.15em;margin:1.6em 0 .5em;border-bottom:1px solid #d5d9df;padding-bottom:.2em}
.sub{color:#5b6572;font-size:.9em}
.card{background:#fff;border:1px solid #dde1e6;border-radius:6px;padding:12px 16px;margin:10px 0}
.grid{display:flex;flex-wrap:wrap;gap:12px}.grid>.card{flex:1 1 330px;margin:0}
table{border-collapse:collapse;font-size:.92em}td,th{padding:3px 10px 3px 0;text-align:left;vertical-align:top}
th{color:#5b6572;font-weight:600}
td.num,table.matrix td{font-family:ui-monospace,Menlo,Consolas,monospace;text-align:right}
table.matrix td{padding:2px 8px}
.warnings{background:#fff4e5;border:2px solid #e8a33d;border-radius:6px;padding:10px 16px;margin:14px 0}
.warnings h2{border:0;margin:.1em 0 .3em;color:#8a4b00}.warnings li{margin:.25em 0}
.ok{background:#eaf6ec;border:1px solid #8cc79a;border-radius:6px;padding:8px 16px;margin:14px 0;color:#225c2f}
figure{margin:10px 0;background:#fff;border:1px solid #dde1e6;border-radius:6px;padding:8px}
figure img{max-width:100%;height:auto;display:block;margin:0 auto}
figcaption{color:#5b6572;font-size:.88em;margin-top:4px}
pre{background:#fff;border:1px solid #dde1e6;border-radius:6px;padding:8px 12px;
white-space:pre-wrap;word-break:break-all;font-size:.85em}
.note{color:#5b6572;font-style:italic}.card>h2:first-child{margin-top:.2em}
"""

_SCRIPT = """
window.addEventListener("load", function () {
  var imgs = Array.prototype.slice.call(document.images);
  document.body.dataset.images = String(imgs.length);
  document.body.dataset.loaded = String(imgs.filter(function (i) {
    return i.complete && i.naturalWidth > 0; }).length);
});
"""


# ----------------------------------------------------------------------------------------------
# numbers and small HTML pieces

def fmt(value: Any, digits: int = 6) -> str:
    """A human-readable value: floats to ``digits`` significant digits, lists recursively."""
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if not math.isfinite(v):
            return str(v)
        return f"{v:.{digits}g}"
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(fmt(v, digits) for v in value) + "]"
    return str(value)


def esc(value: Any) -> str:
    """``value`` as HTML text; the options a message names as flags (a report is the command line's ``--report``)."""
    return html.escape(as_flags(str(value)), quote=True)


def _empty(value: Any) -> bool:
    """Nothing to show: None (a statistic not computed), an empty list or dict."""
    return value is None or (isinstance(value, (list, tuple, dict)) and not value)


def _flatten(d: dict[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    """Nested dicts → ``[("a.b", value), …]``, empty values left out."""
    rows: list[tuple[str, Any]] = []
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and v:
            rows.extend(_flatten(v, key + "."))
        elif not _empty(v):
            rows.append((key, v))
    return rows


def table(value: Any) -> str:
    """A two-column key/value table of a (nested) dict; other values as one line."""
    if not isinstance(value, dict):
        return f"<p class='num'>{esc(fmt(value))}</p>"
    flat = _flatten(value)
    if not flat:
        return "<p class='note'>(empty)</p>"
    rows = "".join(f"<tr><th>{esc(k)}</th><td class='num'>{esc(fmt(v))}</td></tr>" for k, v in flat)
    return f"<table>{rows}</table>"


def figure(chart: Chart, alt: str, caption: str) -> str:
    """A chart as a ``<figure>`` whose image is the SVG document in a base64 ``data:`` URI."""
    data = base64.b64encode(chart.svg().encode("utf-8")).decode("ascii")
    return (f"<figure><img alt='{esc(alt)}' src='data:image/svg+xml;base64,{data}'>"
            f"<figcaption>{caption}</figcaption></figure>")


def _thin(n: int) -> IntArray:
    """Indices of at most MAX_PLOT_POINTS evenly spread samples out of n."""
    return np.arange(n) if n <= MAX_PLOT_POINTS else np.linspace(0, n - 1, MAX_PLOT_POINTS).astype(int)


# ----------------------------------------------------------------------------------------------
# trajectories

def world_alignment(synced: Synced, T_a_b: FloatArray) -> FloatArray:
    """The transform ``T_wa_wb`` from b's world to a's world implied by the extrinsic.

    Each synced sample gives ``T_wa_wb(t) = T_wa_a(t) · X · T_wb_b(t)⁻¹``; the estimate is their
    chordal mean rotation (SVD projection of the summed rotation matrices) and the per-axis
    median translation (robust to the odd tracking jump). Raises ``ValueError`` without samples.
    """
    if len(synced) == 0:
        raise ValueError("no synced samples to align the two worlds")
    X = np.asarray(T_a_b, dtype=float)
    q_x, _ = dq.from_transforms(X)
    R_g = Rotation.from_quat(dq.multiply(dq.multiply(synced.quat_a, q_x), dq.conjugate(synced.quat_b)))   # T_wa_wb(t)
    t_g = synced.xyz_a + Rotation.from_quat(synced.quat_a).apply(X[:3, 3]) - R_g.apply(synced.xyz_b)
    out = np.eye(4)
    out[:3, :3] = nearest_rotation(R_g.as_matrix().sum(axis=0))
    out[:3, 3] = np.median(t_g, axis=0)
    return out


def _a_as_b_places_it(T_wa_wb: FloatArray, X: FloatArray, xyz_b: FloatArray, quat_b: FloatArray) -> FloatArray:
    """(N, 3) positions [m] in a's world of sensor a as b's poses ``T_wb_b`` (positions [m], x-y-z-w
    quaternions) place it: the translations of ``T_wa_wb · T_wb_b · X⁻¹``."""
    a_in_b = -X[:3, :3].T @ X[:3, 3]                                  # translation of X⁻¹ = T_b_a
    in_world_b = Rotation.from_quat(quat_b).apply(a_in_b) + xyz_b
    positions: FloatArray = in_world_b @ T_wa_wb[:3, :3].T + T_wa_wb[:3, 3]
    return positions


def _trajectory_section(calibration: Calibration, X: FloatArray) -> str:
    synced = calibration.synced
    if len(synced) == 0:
        return "<p class='note'>No synced samples: the trajectories cannot be aligned.</p>"
    G = world_alignment(synced, X)
    stream_a, stream_b = calibration.stream_a, calibration.stream_b
    ia, ib = _thin(len(stream_a)), _thin(len(stream_b))            # the plotted samples
    p_a = stream_a.xyz[ia]
    p_b = _a_as_b_places_it(G, X, stream_b.xyz[ib], stream_b.quat_xyzw[ib])
    # alignment error at the synced samples
    err = np.linalg.norm(synced.xyz_a - _a_as_b_places_it(G, X, synced.xyz_b, synced.quat_b), axis=1)
    t0 = int(synced.stamps_ns[0])
    ts = (synced.stamps_ns - t0) / 1e9

    chart = Chart(12.0, 4.0)
    axes = chart.grid(1, 3, margins=(0.65, 0.12, 0.5, 0.3), gaps=(0.85, 0.0), width_ratios=[1, 1, 1.25])
    for ax, (i, j, name) in zip(axes[:2], ((0, 1, "xy"), (0, 2, "xz")), strict=True):
        ax.line(p_a[:, i], p_a[:, j], COLOR_A, width=2.4, opacity=0.45, label="a")
        ax.line(p_b[:, i], p_b[:, j], COLOR_B, width=0.9, dash="--", label="b · X⁻¹ in a's world")
        ax.xlabel, ax.ylabel = f"{name[0]} [m]", f"{name[1]} [m]"
        ax.title = f"{name} view (frame of world a)"
        ax.equal = True
    axes[0].legend = "lower right"
    k = _thin(len(ts))
    axes[2].points(ts[k], err[k], COLOR_A, size=2.0)
    axes[2].xlabel, axes[2].ylabel = "time since first synced sample [s]", "|p_a − p_b| [m]"
    axes[2].title = "position disagreement at synced samples"
    rot = Rotation.from_matrix(G[:3, :3])
    caption = (f"Stream b mapped into a's world: positions of T_wa_wb · T_wb_b(t) · X⁻¹, with T_wa_wb the "
               f"consensus of T_wa_a(t) · X · T_wb_b(t)⁻¹ over {len(synced)} synced samples "
               f"(translation {esc(fmt(G[:3, 3], 4))} m, rotation {np.rad2deg(rot.magnitude()):.3f}°). "
               f"Position disagreement: median {np.median(err):.4g} m, 95th percentile "
               f"{np.percentile(err, 95):.4g} m.")
    return figure(chart, "trajectories", caption)


# ----------------------------------------------------------------------------------------------
# residuals over time

def _rejected_mask(robust: RobustResult | None, n: int) -> BoolArray:
    """The pairs ``--robust`` rejected (of ``n``), as a mask."""
    mask = np.zeros(n, dtype=bool)
    if robust is not None:
        rejected = np.asarray(robust.rejected, dtype=int)
        mask[rejected[(rejected >= 0) & (rejected < n)]] = True
    return mask


def _residual_section(calibration: Calibration, X: FloatArray) -> str:
    pairs = calibration.pairs
    if len(pairs) == 0:
        return "<p class='note'>No motion pairs.</p>"
    res = pair_residuals(pairs.A, pairs.B, X)
    t0 = int(calibration.synced.stamps_ns[0]) if len(calibration.synced) else int(pairs.t_i_ns.min())
    t = (pairs.t_j_ns - t0) / 1e9
    bad = _rejected_mask(calibration.robust, len(pairs))
    chart = Chart(12.0, 4.6)
    axes = chart.grid(2, 1, margins=(0.75, 0.12, 0.5, 0.3), gaps=(0.0, 0.12))
    k = _thin(len(t))
    good = k[~bad[k]]
    for ax, values, label in ((axes[0], res.rotation_deg, "rotation [deg]"),
                              (axes[1], res.translation_m, "translation [m]")):
        ax.points(t[good], values[good], COLOR_A, size=2.5, label="pairs")
        if bad.any():
            ax.points(t[bad], values[bad], COLOR_BAD, size=4.0, marker="x", label="rejected (--robust)")
        med, p95 = np.median(values[~bad] if (~bad).any() else values), np.percentile(values, 95)
        ax.hline(med, "black", label=f"median {med:.3g}")
        ax.hline(p95, "black", dash=":", label=f"95th pct {p95:.3g}")
        ax.ylabel, ax.legend = label, "upper right"
        ax.xlim = (t.min() - 0.05 * np.ptp(t), t.max() + 0.05 * np.ptp(t)) if np.ptp(t) > 0 else None   # shared
    axes[0].xticklabels = False
    axes[1].xlabel = "pair time t_j since first synced sample [s]"
    axes[0].title = f"per-pair residuals of A_i X = X B_i ({len(pairs)} pairs)"
    caption = ("Rotation: angle between R_A·R_X and R_X·R_B; translation: |R_A t_X + t_A − R_X t_B − t_X| "
               "(frame a). Plotted against the later stamp t_j of each pair.")
    return figure(chart, "residuals over time", caption)


# ----------------------------------------------------------------------------------------------
# samples per stage

def _samples_section(samples: SampleCounts) -> str:
    """Two bar panels on one log scale: what each stage read or kept, and what each gate removed
    (:meth:`SampleCounts.losses`). A count of 0 draws no bar, and one dropped sample of thousands
    a short one beside theirs."""
    drops = samples.losses()
    kept = {k: v for k, v in samples.as_dict().items() if k not in drops}
    top = max(1, *kept.values(), *drops.values())
    chart = Chart(12.0, max(2.4, 0.32 * max(len(kept), len(drops)) + 1.0))
    axes = chart.grid(1, 2, margins=(1.45, 0.12, 0.4, 0.3), gaps=(1.75, 0.0))
    for ax, data, color, title in ((axes[0], kept, COLOR_A, "what each stage read / kept"),
                                   (axes[1], drops, COLOR_BAD, "what each gate dropped")):
        names, values = list(data)[::-1], np.array(list(data.values())[::-1], dtype=float)
        ax.barh(values, color, texts=[fmt(v) for v in values])
        ax.yticks, ax.xlog, ax.grid, ax.title = names, True, "x", title
        ax.xlim = (0.5, top * 4.0)
    return figure(chart, "samples per stage", "Counts from the result's <code>samples</code>, both panels on one "
                   "log scale (a count of 0 has no bar).")


# ----------------------------------------------------------------------------------------------
# bootstrap

def _bootstrap_section(deviations: FloatArray | None) -> str:
    if deviations is None:
        return ""
    d = deviations[np.isfinite(deviations).all(axis=1)]
    if len(d) == 0:
        return "<p class='note'>Bootstrap: no finite replicates.</p>"
    chart = Chart(12.0, 5.0)
    axes = chart.grid(2, 3, margins=(0.4, 0.12, 0.4, 0.25), gaps=(0.45, 0.7))
    labels = ("rotation", "translation")
    units = ("deg", "m")
    for r in range(2):
        for c, axis in enumerate("xyz"):
            ax = axes[3 * r + c]
            v = d[:, 3 * r + c]
            lo, hi = np.percentile(v, [2.5, 97.5])
            counts, edges = np.histogram(v, bins=min(40, max(8, len(v) // 10)))
            ax.stairs(counts, edges, (COLOR_A, COLOR_B)[r], opacity=0.85)
            ax.vline(lo, "black", width=0.9, dash=":")
            ax.vline(hi, "black", width=0.9, dash=":")
            ax.title = f"{labels[r]} {axis}: σ = {np.std(v, ddof=1) if len(v) > 1 else 0.0:.3g} {units[r]}"
            ax.xlabel = f"deviation [{units[r]}]"
            ax.title_size, ax.label_size, ax.tick_size, ax.grid = 9.0, 8.0, 7.0, ""
            ax.xbins = 5                                      # long labels such as −0.0004 do not overlap
    std = d.std(axis=0, ddof=1) if len(d) > 1 else np.zeros(6)
    rows = "".join(f"<tr><th>{name}</th>" + "".join(f"<td class='num'>{s:.4g}</td>" for s in std[3 * r:3 * r + 3])
                   + "</tr>" for r, name in enumerate(("rotation σ [deg]", "translation σ [m]")))
    table = f"<table><tr><th></th><th>x</th><th>y</th><th>z</th></tr>{rows}</table>"
    caption = (f"{len(d)} bootstrap replicates: deviation of X per axis, rotation as a rotation vector [deg] "
               "and translation [m]; dotted lines bound the central 95 %.")
    return figure(chart, "bootstrap spread", caption) + f"<div class='card'>{table}</div>"


# ----------------------------------------------------------------------------------------------
# header

def _header(calibration: Calibration, X: FloatArray) -> str:
    rot = Rotation.from_matrix(X[:3, :3])
    q = rot.as_quat(canonical=True)
    t = X[:3, 3]
    frames, sol = calibration.frames, calibration.solution
    fa, fb = esc(frames["a"]), esc(frames["b"])
    facts = [("method", sol.method), ("α [1/m]", sol.alpha), ("cost", sol.cost), ("pairs used", sol.pairs),
             ("version", __version__)]
    facts_html = "".join(f"<tr><th>{esc(k)}</th><td class='num'>{esc(fmt(v))}</td></tr>"
                         for k, v in facts if v is not None)
    matrix = "".join("<tr>" + "".join(f"<td>{v:.6f}</td>" for v in row) + "</tr>" for row in X)
    pose = [("translation [m]", ", ".join(f"{v:.6f}" for v in t)),
            ("quaternion x, y, z, w", ", ".join(f"{v:.6f}" for v in q)),
            ("rotation angle [deg]", f"{np.rad2deg(rot.magnitude()):.4f}"),
            ("rotation vector [deg]", ", ".join(f"{v:.4f}" for v in np.rad2deg(rot.as_rotvec()))),
            ("roll, pitch, yaw [deg] (fixed x-y-z)", ", ".join(f"{v:.4f}" for v in rot.as_euler("xyz", degrees=True)))]
    pose_html = "".join(f"<tr><th>{esc(k)}</th><td class='num'>{esc(v)}</td></tr>" for k, v in pose)
    inputs = plain(calibration.inputs.as_dict())
    inputs_html = table(inputs) if inputs else "<p class='note'>(not recorded)</p>"
    ros = static_transform_command(sol.translation, sol.quaternion_xyzw, frames)
    return (heading("handeye calibration report", f"Extrinsic T_{fa}_{fb}: the pose of frame <b>{fb}</b> in frame "
                   f"<b>{fa}</b> (maps points from {fb} to {fa}).")
            + f"{warnings_block(calibration.warnings)}"
            f"<div class='grid'><div class='card'><h2>T_{fa}_{fb}</h2><table class='matrix'>{matrix}</table>"
            f"<table>{pose_html}</table></div>"
            f"<div class='card'><h2>Solve</h2><table>{facts_html}</table><h2>Inputs</h2>{inputs_html}</div></div>"
            f"<h2>ROS 2 static transform</h2><pre>{esc(ros)}</pre>")


def heading(title: str, what: str) -> str:
    """The page's heading: ``title``, and ``what`` it shows (HTML), with when and by which version."""
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    return f"<h1>{title}</h1><p class='sub'>{what} Generated {stamp} by handeye {esc(__version__)}.</p>"


def warnings_block(warnings: Sequence[str]) -> str:
    if not warnings:
        return "<div class='ok'>No warnings.</div>"
    items = "".join(f"<li>{esc(w)}</li>" for w in warnings)
    return f"<div class='warnings' id='warnings'><h2>⚠ {len(warnings)} warning(s)</h2><ul>{items}</ul></div>"


def _settings(calibration: Calibration) -> str:
    """The options that produced the result, as the differences from the defaults."""
    changed = calibration.options.changed()
    rows = [("configuration file", calibration.config_file), ("preset", calibration.preset)]
    head = "".join(f"<tr><th>{k}</th><td class='num'>{esc(v)}</td></tr>" for k, v in rows if v)
    if not changed:
        return f"<table>{head}</table><p class='note'>Options: the defaults.</p>"
    return f"<table>{head}</table><p class='note'>Options: the defaults, except:</p>{table(changed)}"


def _tables(calibration: Calibration) -> str:
    """A titled table per block of the result not shown in the header, in the document's order (the sample
    counts, the solver, each diagnostic section, the settings), from the calibration; empty values left out."""
    blocks = [("samples", calibration.samples.as_dict()), ("solver", solver_section(calibration.solution)),
              *calibration.diagnostics.items(), ("settings", None)]
    parts = []
    for key, value in blocks:
        value = plain(value)
        if key in _HEADER_KEYS or (key != "settings" and _empty(value)):
            continue
        parts.append(card(_TITLES.get(key, key.replace("_", " ").capitalize()),
                           _settings(calibration) if key == "settings" else table(value)))
    return cards(parts)


def card(title: str, body: str) -> str:
    return f"<div class='card'><h2>{esc(title)}</h2>{body}</div>"


def cards(parts: Sequence[str]) -> str:
    return f"<div class='grid'>{''.join(parts)}</div>" if parts else ""


def page(body: Sequence[str]) -> str:
    """The self-contained HTML document around ``body``'s parts."""
    return ("<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            "<meta name='viewport' content='width=device-width, initial-scale=1'>"
            f"<meta name='generator' content='handeye {esc(__version__)}'>"
            f"<title>handeye report</title><style>{_CSS}</style></head>"
            f"<body><main>{''.join(body)}</main><script>{_SCRIPT}</script></body></html>\n")


# ----------------------------------------------------------------------------------------------
# entry points

def render_report(calibration: Calibration, bootstrap_deviations: FloatArray | None = None) -> str:
    """The report as one HTML string (see :func:`write_report`), from the typed calibration (not its document)."""
    if bootstrap_deviations is not None:
        bootstrap_deviations = np.asarray(bootstrap_deviations, dtype=float)
        if bootstrap_deviations.ndim != 2 or bootstrap_deviations.shape[1] != 6:
            raise ValueError(f"bootstrap_deviations must have shape (K, 6), got {bootstrap_deviations.shape}")
    X = np.asarray(calibration.matrix, dtype=float)
    body = [_header(calibration, X),
            "<h2>1. Trajectories after applying the extrinsic</h2>", _trajectory_section(calibration, X),
            "<h2>2. Residuals over time</h2>", _residual_section(calibration, X),
            "<h2>3. Samples kept and dropped per stage</h2>", _samples_section(calibration.samples)]
    if bootstrap_deviations is not None:
        body += ["<h2>4. Bootstrap spread</h2>", _bootstrap_section(bootstrap_deviations)]
    tables = _tables(calibration)
    if tables:
        body += ["<h2>Diagnostics</h2>", tables]
    return page(body)


def write_report(path: str | Path, calibration: Calibration) -> None:
    """Write a self-contained HTML report of ``calibration`` to ``path`` (``-``: stdout).

    The report shows the result (:func:`~handeye_cli.output.document.calibration_document`), the
    trajectories after applying ``T_a_b``, the per-pair residuals over time, the samples each stage
    kept and dropped and, when the bootstrap ran, its spread. Raises
    :class:`~handeye_cli.errors.HandEyeError` when the file cannot be written; a regular file is
    replaced atomically, so a failure leaves no half-written report.
    """
    check_writable(path, "⟦report⟧")           # fail before the rendering work
    page = render_report(calibration, calibration.bootstrap_deviations())
    write_output(path, page, "⟦report⟧")
