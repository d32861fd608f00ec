"""``handeye solve``: the solver alone, on a file of relative motion pairs."""
from __future__ import annotations

from typing import Any

import click

from ..analysis.motions import solve as solve_pairs
from ..config import load_options
from ..io.pairfile import read_pairs
from ..output.document import result_document
from ..pipeline import read_prior
from .calibrate import summary_line
from .common import CONTEXT, emit, result_format, warn
from .params import command_options, output_options, quiet_option, refused_report


@click.command("solve", context_settings=CONTEXT)
@click.argument("pairs_file", type=click.Path())
@command_options("solve")
@output_options
@refused_report("solve has motion pairs only, no streams to plot: run 'handeye calibrate --report FILE' on the "
                "streams")
@quiet_option
def solve(pairs_file: str, output: str | None, fmt: str | None, quiet: bool, **given: Any) -> None:
    """Solve A_i X = X B_i for X = T_a_b from a file of relative motion pairs.

    PAIRS_FILE is a CSV with the header
    ax,ay,az,aqx,aqy,aqz,aqw,bx,by,bz,bqx,bqy,bqz,bqw[,weight] (one motion pair per row:
    translations in metres, quaternions x-y-z-w), or a .npz with arrays A and B of shape
    (N, 4, 4) and optionally weights (N,).

    \b
    Examples:
      handeye solve sample_data/pairs.csv --method dqopt --alpha 1
      handeye solve pairs.npz --alpha auto --format urdf-joint -o cam.urdf -q
    """
    options = load_options(**given)
    s = options.solver
    fmt = result_format(output, fmt)
    A, B, weights = read_pairs(pairs_file)
    prior = read_prior(options)
    sol = solve_pairs(A, B, method=s.method, alpha=s.alpha, prior=prior, weights=weights)
    doc = result_document(sol, inputs={"pairs_file": pairs_file}, samples={"pairs": len(A)},
                          warnings=list(sol.warnings))      # a failed optimality certificate
    emit(doc, output, fmt)
    if not quiet:
        click.echo(summary_line(doc), err=True)
    for w in doc["warnings"]:
        warn(w)
