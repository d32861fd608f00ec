"""``handeye compare``: every method on the same motion pairs, in one table.

The streams are read, synchronised, gated and paired exactly as ``handeye calibrate`` does (same
flags); then every solver of ``--method`` (the optimal dqopt, the paper's approximations,
Daniilidis, and the classical Tsai–Lenz, Park–Martin, Horaud–Dornaika, Andreff) solves those
pairs, and the robot-world methods (Shah, Li, refined) solve the synchronised absolute poses.
Each row: ``T_a_b`` (translation [m], rotation vector [deg]), cost (8) on the pairs at the same α,
residual medians, the difference to dqopt, and the time taken.
"""
from __future__ import annotations

from typing import Any

import click
import numpy as np

from ..calibration import calibrate_specs, stream_specs
from ..comparison import MethodResult, compare_methods
from ..output.document import plain, render
from ..output.writers import check_writable, output_format, write_output
from .calibrate import write_run_report
from .common import CONTEXT
from .params import (
    command_options,
    options_from_cli,
    quiet_option,
    report_option,
    stream_options,
    stream_values,
    summary_format,
)

__all__ = ["compare"]


def _table(rows: list[MethodResult]) -> str:
    head = (f"{'method':<20} {'x [m]':>9} {'y [m]':>9} {'z [m]':>9} {'angle [°]':>9} {'cost':>11} "
            f"{'res [°]':>8} {'res [mm]':>8} {'Δ [°]':>8} {'Δ [mm]':>8} {'ms':>8}")
    lines = [head]
    for r in rows:
        x, y, z = r.matrix[:3, 3]
        angle = float(np.linalg.norm(r.rotation_vector_deg))
        lines.append(f"{r.method:<20} {x:>9.4f} {y:>9.4f} {z:>9.4f} {angle:>9.3f} {r.cost:>11.4e} "
                     f"{r.rotation_median_deg:>8.3f} {1e3 * r.translation_median_m:>8.2f} "
                     f"{r.vs_dqopt_deg:>8.4f} {1e3 * r.vs_dqopt_m:>8.2f} {1e3 * r.seconds:>8.2f}")
    return "\n".join(lines) + "\n"


@click.command("compare", context_settings=CONTEXT)
@click.argument("inputs", nargs=-1)
@stream_options
@command_options("compare")
@report_option
@click.option("-o", "--output", metavar="FILE", help="Write the table here instead of stdout.")
@summary_format("text (a table), or the rows as YAML/JSON.")
@quiet_option
def compare(inputs: tuple[str, ...], **p: Any) -> None:
    """Compare every method on the same motion pairs: result, cost, residuals, time.

    Reads and pairs the streams as 'handeye calibrate' does (same flags; --method only picks the
    reference row's solver for the pairs' warnings), then solves them with every method,
    including Tsai–Lenz, Park–Martin, Horaud–Dornaika, Andreff and the robot-world forms.

    \b
    Examples:
      handeye compare sample_data/rig.mcap --topic-a /cam0/pose --topic-b /cam1/pose
      handeye compare a.tum b.tum --format json -o methods.json --report pairs.html -q

    --report FILE is calibrate's page of the pairs every method solved (the --method row's result).
    """
    options = options_from_cli(p)
    spec_a, spec_b = stream_specs(inputs, **stream_values(p))
    check_writable(p["output"], "-o")
    if p["report_file"]:
        check_writable(p["report_file"], "--report")
    fmt = p["fmt"] or ("text" if not p["output"] or p["output"] == "-" or not p["output"].endswith(
        (".json", ".yaml", ".yml")) else output_format(p["output"], None))
    cal = calibrate_specs(spec_a, spec_b, options, quiet=p["quiet"])
    rows = compare_methods(cal)
    text = _table(rows) if fmt == "text" else render(plain({"frames": cal.frames, "pairs_used": len(cal.pairs),
                                                            "alpha": cal.solution.alpha,
                                                            "methods": [r.as_dict() for r in rows]}), fmt)
    write_output(p["output"], text)
    late = write_run_report(p["report_file"], cal) if p["report_file"] else None
    if late is not None:
        raise late
