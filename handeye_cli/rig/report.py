"""The HTML report of a rig calibration (``handeye rig --report FILE``), drawn with calibrate's report module
(:mod:`handeye_cli.output.report`: the same page, cards, tables and SVG figures, no optional dependency) from the
typed :class:`~handeye_cli.rig.result.RigResult`, not its document.

Contents: the warnings; the joint extrinsics ``T_ref_k`` (pose of sensor k in the reference's frame, maps points
from k to ref; translation [m], quaternion x-y-z-w, rotation angle [deg], the noise model's predicted error and,
with ``--bootstrap N``, the bootstrap's σ); each stream's clock offset to the reference [ms]; per calibrated pair
``T_j_k``: the pairs used, the median residuals of ``A_i X = X B_i`` at the joint and at the pairwise-only
``T_j_k`` [deg, mm], the pair's fit test (ratio, limit, passed) and its relative drift test; one figure of the
pairs' median residuals at the joint result; the loop closures and the consistency test in one line each.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..analysis import pair_residuals
from ..geometry import se3
from ..output.report import card, cards, esc, figure, fmt, heading, page, warnings_block
from ..output.svgplot import Chart
from ..output.writers import check_writable, write_output
from .result import RigResult

__all__ = ["render_rig_report", "write_rig_report"]

COLOR_JOINT = "#1f77b4"


def _rows(head: list[str], rows: list[list[str]]) -> str:
    """A table with a header row; every cell is escaped."""
    top = "".join(f"<th>{esc(h)}</th>" for h in head)
    body = "".join("<tr>" + "".join(f"<td class='num'>{esc(c)}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table><tr>{top}</tr>{body}</table>"


def _extrinsics(result: RigResult) -> str:
    """The joint ``T_ref_k`` of every sensor, as the document states it, with its predicted and bootstrap error."""
    ref = result.names[result.reference]
    u, cov = result.uncertainty, result.covariances
    rows = []
    for frame in result.stated():
        k = result.names.index(frame.child)
        t, q = se3.to_xyz_quat(frame.matrix)
        predicted = (f"{np.rad2deg(np.sqrt(np.trace(cov[k, :3, :3]))):.3g}° / "
                     f"{1e3 * np.sqrt(np.trace(cov[k, 3:, 3:])):.3g} mm")
        spread = [] if u is None else [f"{fmt(u.rotation_std_deg[k], 3)}° / {fmt(1e3 * u.translation_std_m[k], 3)} mm"]
        rows.append([f"T_{ref}_{frame.child}", ", ".join(f"{v:.6f}" for v in t), ", ".join(f"{v:.6f}" for v in q),
                     f"{np.rad2deg(se3.rotation_angle(frame.matrix)):.4f}", predicted, *spread])
    head = ["transform", "translation [m]", "quaternion x, y, z, w", "rotation [deg]", "predicted error [deg / mm]",
            *([] if u is None else ["bootstrap σ per axis [deg / mm]"])]
    note = "" if u is not None else "<p class='note'>--bootstrap N adds each extrinsic's bootstrap σ.</p>"
    return card("Joint extrinsics", _rows(head, rows) + note)


def _offsets(result: RigResult) -> str:
    """Each stream's clock offset to the reference: how far its clock is ahead [ms], its σ and how it was found."""
    rows = [[name, f"{off.offset_ns / 1e6:.3f}", "" if off.std_ns is None else f"{off.std_ns / 1e6:.3f}", off.method]
            for name, off in zip(result.names, result.offsets, strict=True)]
    return card("Clock offsets", _rows(["stream", "ahead of the reference [ms]", "σ [ms]", "method"], rows))


def _edges(result: RigResult) -> tuple[str, list[str], np.ndarray]:
    """The per-pair table, and for the figure each pair's name and median residuals at the joint result
    (rotation [deg], translation [mm])."""
    names, rows, labels, medians = result.names, [], [], []
    for edge, correction in zip(result.edges, result.corrections, strict=True):
        cal, (j, k) = edge.calibration, (names[edge.j], names[edge.k])
        mask = None if cal.weights is None else cal.weights > 0
        joint = pair_residuals(cal.pairs.A, cal.pairs.B, result.T(j, k)).summary(mask)
        alone = pair_residuals(cal.pairs.A, cal.pairs.B, edge.matrix).summary(mask)
        fit = cal.diagnostics.fit
        verdict = ("not tested" if fit is None else
                   f"{'passed' if fit.passed else 'FAILED'}: {fit.ratio:.3g}× (limit {fit.threshold:g}×)")
        drift = (f"{'corrected' if correction.applied else 'none'} (p {correction.p_value:.2g})")
        rows.append([f"{j}–{k}", str(len(cal.pairs)),
                     f"{joint.rotation_median_deg:.4f} / {1e3 * joint.translation_median_m:.3f}",
                     f"{alone.rotation_median_deg:.4f} / {1e3 * alone.translation_median_m:.3f}", verdict, drift])
        labels.append(f"{j}–{k}")
        medians.append((joint.rotation_median_deg, 1e3 * joint.translation_median_m))
    head = ["pair", "pairs used", "median residual, joint [deg / mm]", "pairwise only [deg / mm]", "fit test",
            "relative drift"]
    return card("Pairs", _rows(head, rows)), labels, np.asarray(medians, dtype=float).reshape(-1, 2)


def _residual_figure(labels: list[str], medians: np.ndarray) -> str:
    if not labels:
        return "<p class='note'>No calibrated pairs.</p>"
    chart = Chart(12.0, max(2.4, 0.32 * len(labels) + 1.0))
    axes = chart.grid(1, 2, margins=(1.2, 0.12, 0.5, 0.3), gaps=(1.4, 0.0))
    for ax, column, unit in ((axes[0], 0, "deg"), (axes[1], 1, "mm")):
        values = medians[::-1, column]
        ax.barh(values, COLOR_JOINT, texts=[fmt(v, 3) for v in values])
        ax.yticks, ax.grid = labels[::-1], "x"
        ax.title, ax.xlabel = f"median residual at the joint result [{unit}]", unit
        ax.xlim = (0.0, 1.25 * max(float(values.max()), 1e-12))
    return figure(chart, "pair residuals", "Each calibrated pair's median residual of A_i X = X B_i at the joint "
                  "T_j_k = T_ref_j⁻¹ T_ref_k (its own pairs and weights).")


def _closures(result: RigResult) -> str:
    worst = max(result.closures, key=lambda c: c.rotation_deg, default=None)
    c = result.consistency
    lines = [f"χ² consistency of the pairwise estimates: {c.statistic:.4g} on {c.dof} dof (p {c.p_value:.3g})"
             + (f"; suspect stream: {result.names[c.suspect]}" if c.suspect is not None else "")]
    if worst is not None:
        lines.append(f"worst pairwise loop closure {'–'.join(result.names[i] for i in worst.nodes)}: "
                     f"{worst.rotation_deg:.3f}° / {1e3 * worst.translation_m:.2f} mm (the joint result closes every "
                     "loop)")
    return card("Consistency", "".join(f"<p>{esc(line)}</p>" for line in lines))


def render_rig_report(result: RigResult) -> str:
    """The rig's report as one HTML string (see the module docstring)."""
    ref = esc(result.names[result.reference])
    edges, labels, medians = _edges(result)
    body = [heading("handeye rig report", f"Every sensor's T_{ref}_k: the pose of sensor k in the reference "
                    f"frame <b>{ref}</b> (maps points from k to {ref}), {len(result.names)} sensors."),
            warnings_block(result.warnings), cards([_extrinsics(result), _offsets(result)]),
            "<h2>Pairs: residuals and fit</h2>", _residual_figure(labels, medians), cards([edges, _closures(result)])]
    return page(body)


def write_rig_report(path: str | Path, result: RigResult) -> None:
    """Write the rig's report to ``path`` (``-``: stdout; a regular file replaced atomically). Raises
    :class:`~handeye_cli.errors.HandEyeError` (a ``WriteError``) when it cannot be written."""
    check_writable(path, "⟦report⟧")
    write_output(path, render_rig_report(result), "⟦report⟧")
