"""``handeye solve``: the solver alone, on a file of relative motion pairs."""
from __future__ import annotations

from typing import Any

import click

from ..analysis.motions import solve as solve_pairs
from ..config import load_options
from ..io.pairfile import read_pairs
from ..output.document import result_document
from ..output.writers import check_writable, output_format
from ..pipeline import read_prior
from .common import CONTEXT, emit
from .params import flags, output_options


@click.command("solve", context_settings=CONTEXT)
@click.argument("pairs_file", type=click.Path())
@flags("method", "alpha", "prior", "prior_weights")
@output_options
def solve(pairs_file: str, output: str | None, fmt: str | None, **given: Any) -> None:
    """Solve A_i X = X B_i for X = T_a_b from a file of relative motion pairs.

    PAIRS_FILE is a CSV with the header
    ax,ay,az,aqx,aqy,aqz,aqw,bx,by,bz,bqx,bqy,bqz,bqw[,weight] (one motion pair per row:
    translations in metres, quaternions x-y-z-w), or a .npz with arrays A and B of shape
    (N, 4, 4) and optionally weights (N,).

    \b
    Example:
      handeye solve sample_data/pairs.csv --method dqopt --alpha 1
    """
    options = load_options(**given)
    s = options.solver
    check_writable(output, "-o")
    fmt = output_format(output, fmt)
    A, B, weights = read_pairs(pairs_file)
    prior = read_prior(options)
    sol = solve_pairs(A, B, method=s.method, alpha=s.alpha, prior=prior, weights=weights)
    emit(result_document(sol, inputs={"pairs_file": pairs_file}, samples={"pairs": len(A)},
                         warnings=list(sol.warnings)), output, fmt)     # a failed optimality certificate
