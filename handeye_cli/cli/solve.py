"""``handeye solve``: the solver alone, on a file of relative motion pairs."""
from __future__ import annotations

from typing import Any

import click

from ..analysis.motions import solve_pairs
from ..analysis.verdict import verdict_for
from ..calibration import read_prior
from ..config import load_options
from ..io.nominal import read_nominal
from ..io.pairfile import read_pairs
from ..output.document import result_document
from .calibrate import summary_line
from .check import verdict_options
from .common import CONTEXT, emit, finish, result_format
from .params import command_options, output_options, quiet_option, refused_report


@click.command("solve", context_settings=CONTEXT)
@click.argument("pairs_file", type=click.Path())
@command_options("solve")
@verdict_options
@output_options
@refused_report("solve has motion pairs only, no streams to plot: run 'handeye calibrate --report FILE' on the "
                "streams")
@quiet_option
def solve(pairs_file: str, output: str | None, fmt: str | None, quiet: bool, against: str | None,
          max_rotation_deg: float, max_translation_m: float, **given: Any) -> None:
    """Solve A_i X = X B_i for X = T_a_b from a file of relative motion pairs.

    PAIRS_FILE is a CSV with the header
    ax,ay,az,aqx,aqy,aqz,aqw,bx,by,bz,bqx,bqy,bqz,bqw[,weight] (one motion pair per row:
    translations in metres, quaternions x-y-z-w), or a .npz with arrays A and B of shape
    (N, 4, 4) and optionally weights (N,).

    \b
    Examples:
      handeye solve sample_data/pairs.csv --method dqopt --alpha 1
      handeye solve pairs.npz --alpha auto --format urdf-joint -o cam.urdf -q
      handeye solve pairs.csv --robust --bootstrap 500 --against robot.urdf  # exit 1: moved

    --robust and --bootstrap N run on the pairs as in calibrate; with --against NOMINAL the result
    gets a drift verdict (frames a, b: a nominal of one transform is used as it is) and the exit code
    is 1 when it drifted.
    """
    options = load_options(**given)
    s, a = options.solver, options.analysis
    fmt = result_format(output, fmt)
    nominal = read_nominal(against) if against else None      # a bad nominal fails before the work
    A, B, weights = read_pairs(pairs_file)
    prior = read_prior(options)
    found = solve_pairs(A, B, method=s.method, alpha=s.alpha, prior=prior, weights=weights, robust=a.robust,
                        bootstrap=a.bootstrap, seed=options.pairs.seed)
    sol = found.solution
    doc = result_document(sol, inputs={"pairs_file": pairs_file}, samples={"pairs": len(A)},
                          warnings=list(sol.warnings), diagnostics=found.sections())   # a failed certificate
    verdict = None if nominal is None else verdict_for(found.judged(), nominal, max_rotation_deg, max_translation_m)
    if verdict is not None:
        doc["verdict"] = verdict.as_dict()
    emit(doc, output, fmt)
    if not quiet:
        click.echo(summary_line(doc), err=True)
    finish(doc, strict=False, quiet=quiet, drift=verdict.summary() if verdict is not None and verdict.drift else None,
           within=verdict.summary() if verdict is not None else None)
