"""The ``handeye`` command line: click commands that parse options, call the library and print.

Exit codes: 0 success; 2 bad input or an unsolvable problem (one line on stderr, no output
file); 3 warnings under ``--strict``.
"""
from __future__ import annotations

import sys
import traceback

import click

from . import __version__
from .errors import HandEyeError
from .output import FORMATS, format_for_path, render, result_document, write_atomic
from .pairfile import read_extrinsic, read_pairs
from .solvers import METHODS, Prior, solve

_CONTEXT = {"help_option_names": ["-h", "--help"], "max_content_width": 100}


class StrictFailure(Exception):
    """Warnings were raised under ``--strict`` (exit code 3)."""


def emit(doc: dict, output: str | None, fmt: str | None) -> None:
    """Print the result to stdout, or write it atomically to ``output``."""
    text = render(doc, format_for_path(output, fmt))
    if output:
        write_atomic(output, text)
    else:
        click.echo(text, nl=False)


def parse_prior(path: str | None, weights: str) -> Prior | None:
    """``--prior FILE --prior-weights a,b`` → :class:`Prior` (eq 26), or None."""
    if path is None:
        return None
    try:
        a, b = (float(v) for v in weights.split(","))
    except ValueError:
        raise HandEyeError(f"bad --prior-weights {weights!r}", "--prior-weights",
                           "give two non-negative numbers a,b, e.g. 1,1") from None
    return Prior(read_extrinsic(path), a, b)


output_options = [
    click.option("-o", "--output", type=click.Path(dir_okay=False), help="Write the result here "
                 "(atomically) instead of stdout; a .json suffix selects JSON."),
    click.option("--format", "fmt", type=click.Choice(FORMATS), help="Output format [default: yaml, "
                 "or json for a .json output file]."),
]
solver_options = [
    click.option("--method", type=click.Choice(METHODS), default="dqopt", show_default=True,
                 help="Solver: dqopt is the global optimum; the others are the paper's approximations "
                 "and Daniilidis' method."),
    click.option("--prior", "prior_file", type=click.Path(), help="Prior extrinsic T_a_b (a handeye result "
                 "or YAML with translation and quaternion_xyzw); fixes directions the motion cannot observe."),
    click.option("--prior-weights", default="1,1", show_default=True,
                 help="Weights a,b of the prior's rotation and translation terms (eq 26)."),
]


def _apply(options: list):
    def decorate(f):
        for option in reversed(options):
            f = option(f)
        return f
    return decorate


@click.group(context_settings=_CONTEXT)
@click.version_option(__version__, "-V", "--version", prog_name="handeye")
@click.option("--debug", is_flag=True, help="Show the full traceback on errors.")
def cli(debug: bool) -> None:
    """Optimal hand-eye / extrinsic calibration between two rigidly attached pose sources.

    The result is T_a_b: the pose of frame b (second stream) in frame a (first stream); it
    maps points from b to a. Quaternions are x-y-z-w.

    \b
    Examples:
      handeye calibrate sample_data/rig.mcap --topic-a /cam0/pose --topic-b /cam1/pose
      handeye inspect sample_data/rig.mcap
      handeye solve sample_data/pairs.csv --method dqopt
    """


@cli.command(context_settings=_CONTEXT)
@click.argument("pairs_file", type=click.Path())
@_apply(solver_options)
@click.option("--alpha", type=float, default=1.0, show_default=True,
              help="Weight of translational residuals [1/m] (eq 8).")
@_apply(output_options)
def solve_cmd(pairs_file: str, method: str, prior_file: str | None, prior_weights: str, alpha: float,
              output: str | None, fmt: str | None) -> None:
    """Solve A_i X = X B_i for X = T_a_b from a file of relative motion pairs.

    PAIRS_FILE is a CSV with the header
    ax,ay,az,aqx,aqy,aqz,aqw,bx,by,bz,bqx,bqy,bqz,bqw[,weight] (one motion pair per row:
    translations in metres, quaternions x-y-z-w), or a .npz with arrays A and B of shape
    (N, 4, 4) and optionally weights (N,).

    \b
    Example:
      handeye solve sample_data/pairs.csv --method dqopt --alpha 1
    """
    A, B, weights = read_pairs(pairs_file)
    sol = solve(A, B, method=method, alpha=alpha, prior=parse_prior(prior_file, prior_weights), weights=weights)
    emit(result_document(sol, inputs={"pairs_file": pairs_file}, samples={"pairs": len(A)}), output, fmt)


solve_cmd.name = "solve"


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``handeye`` script: run the command, map errors to exit codes."""
    args = sys.argv[1:] if argv is None else list(argv)
    debug = "--debug" in args
    try:
        code = cli.main(args=args, prog_name="handeye", standalone_mode=False)
    except HandEyeError as e:
        if debug:
            traceback.print_exc()
        click.echo(f"error: {e}", err=True)
        sys.exit(2)
    except click.ClickException as e:
        if debug:
            traceback.print_exc()
        hint = f" (run '{e.ctx.command_path} --help')" if getattr(e, "ctx", None) else ""
        click.echo(f"error: {e.format_message()}{hint}", err=True)
        sys.exit(e.exit_code)
    except StrictFailure as e:
        click.echo(f"error: {e}", err=True)
        sys.exit(3)
    except click.Abort:
        click.echo("aborted", err=True)
        sys.exit(130)
    sys.exit(code if isinstance(code, int) else 0)
