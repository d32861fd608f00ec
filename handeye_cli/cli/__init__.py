"""The ``handeye`` command line: click commands that parse options, call the library and print.

One module per command (:data:`COMMANDS`, each imported only when run); :mod:`.params` generates
the flags from :mod:`handeye_cli.options`. Exit codes: 0 success; 2 bad input or an unsolvable
problem (one line on stderr, no output file); 3 warnings under ``--strict``.

Before numpy is first imported, the command line caps BLAS at one thread unless the environment
sets a thread count: every matrix handeye factorises has 8 columns, where BLAS threads only wait
for each other (threaded OpenBLAS was slower on 2 cores, never faster), and ``handeye batch``
runs one process per core.
"""
from __future__ import annotations

import os
import sys
import traceback
from importlib import import_module

if not {"OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"} & set(os.environ):
    os.environ["OPENBLAS_NUM_THREADS"] = os.environ["MKL_NUM_THREADS"] = "1"

import click

from .. import __version__
from ..errors import HandEyeError
from .common import CONTEXT, Drifted, StrictFailure

__all__ = ["COMMANDS", "cli", "main"]


# command name → module of this package that defines it (as a function of the same name):
# each is imported only when run or listed, so a command pays only for the stages it uses
COMMANDS = {"batch": "batch", "calibrate": "calibrate", "check": "check", "compare": "compare",
            "inspect": "inspect", "report": "batch", "rig": "rig", "solve": "solve"}


class LazyGroup(click.Group):
    """A click group whose subcommands (:data:`COMMANDS`) are imported on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in COMMANDS:
            return None
        command = getattr(import_module(f".{COMMANDS[cmd_name]}", __name__), cmd_name)
        assert isinstance(command, click.Command)
        return command


@click.group(cls=LazyGroup, context_settings=CONTEXT)
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
        ctx = getattr(e, "ctx", None)
        hint = f" (run '{ctx.command_path} --help')" if ctx is not None else ""
        click.echo(f"error: {e.format_message()}{hint}", err=True)
        sys.exit(e.exit_code)
    except Drifted as e:
        click.echo(f"drift: {e}", err=True)
        sys.exit(1)
    except StrictFailure as e:
        click.echo(f"error: {e}", err=True)
        sys.exit(3)
    except click.Abort:
        click.echo("aborted", err=True)
        sys.exit(130)
    sys.exit(code if isinstance(code, int) else 0)

