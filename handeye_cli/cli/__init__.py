"""The ``handeye`` command line: click commands that parse options, call the library and print.

One module per command (:data:`COMMANDS`, each imported only when run); :mod:`.params` generates
the flags from :mod:`handeye_cli.options`. Exit codes: 0 success; 1 a drift verdict; 2 bad input
or an unsolvable problem, and click's usage errors (one line on stderr, no output file); 3 warnings
under ``--strict``; 4 an internal error (an exception that is not a :class:`HandEyeError`: a bug,
one line asking for a report, the traceback with ``--debug``); 130 Ctrl-C, 128 + N when a batch
is ended by signal N.

Before numpy is first imported, the command line caps BLAS at one thread unless the environment
sets a thread count: every matrix handeye factorises has 8 columns, where BLAS threads only wait
for each other (threaded OpenBLAS was slower on 2 cores, never faster), and ``handeye batch``
runs one process per core.
"""
from __future__ import annotations

import difflib
import os
import sys
import traceback
from importlib import import_module
from typing import NoReturn

if not {"OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"} & set(os.environ):
    os.environ["OPENBLAS_NUM_THREADS"] = os.environ["MKL_NUM_THREADS"] = "1"

import click

from ..errors import KEYWORD_FLAGS, HandEyeError, as_flags
from ..version import __version__
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

    def resolve_command(self, ctx: click.Context,
                        args: list[str]) -> tuple[str | None, click.Command | None, list[str]]:
        """As click's, with "did you mean" for a mistyped command (click offers it for options only)."""
        if args and args[0] not in COMMANDS and not args[0].startswith("-"):
            close = difflib.get_close_matches(args[0], COMMANDS, n=1, cutoff=0.6)
            if close:
                ctx.fail(f"No such command {args[0]!r}. (Did you mean {close[0]!r}?)")
        return super().resolve_command(ctx, args)

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
    """Entry point of the ``handeye`` script: run the command, map errors to exit codes (see the
    module docstring); an unexpected exception is a bug: one line asking for a report, exit 4."""
    args = sys.argv[1:] if argv is None else list(argv)
    debug = "--debug" in args
    try:
        code = cli.main(args=args, prog_name="handeye", standalone_mode=False)
    except HandEyeError as e:
        _fail(f"error: {_as_flags(e).line(as_flags)}", 2, debug)
    except click.ClickException as e:       # usage errors are 2; click's generic ones would be 1 (= drift)
        ctx = getattr(e, "ctx", None)
        hint = f" (run '{ctx.command_path} --help')" if ctx is not None else ""
        _fail(f"error: {e.format_message()}{hint}", 2, debug)
    except Drifted as e:
        _fail(f"drift: {as_flags(str(e))}", 1, False)
    except StrictFailure as e:
        _fail(f"error: {e}", 3, False)
    except SystemExit as e:                 # click exits 1 by itself only when stdout is a closed pipe
        if e.code in (0, None):
            raise
        _fail("error: cannot write to stdout (Broken pipe): read all of the output, or redirect it", 2, debug)
    except (click.Abort, KeyboardInterrupt) as e:    # click turns Ctrl-C into Abort; a batch's SIGTERM too
        signum = getattr(e.__cause__, "signum", None) or getattr(e, "signum", None) or 2     # 2: SIGINT
        _fail("aborted" if signum == 2 else "terminated", 128 + signum, False)
    except Exception as e:
        _fail(f"internal error: {type(e).__name__}: {' '.join(str(e).split())} — this is a bug in handeye "
              f"{__version__}; please report it with the command line; rerun with --debug for the traceback",
              4, debug)
    sys.exit(code if isinstance(code, int) else 0)


# the library's keywords that are no option of options.py, and their flags
_KEYWORDS = {**KEYWORD_FLAGS, "max_rotation_deg": "--max-rotation-deg", "max_translation_m": "--max-translation-m",
             **{f"{kind}_{side}": f"--{kind}-{side}" for kind in ("stream", "topic", "frames") for side in "ab"}}


def _as_flags(error: HandEyeError) -> HandEyeError:
    """The command line's words for an error: the library names an option by its key (``(max_jump)``, the
    Python keyword; a rig's ``(scales)``, RigOptions' field; ``a/b`` for two keys); given on the command line,
    that is its flag (``(--max-jump)``, ``(--scale)``). A key in a file (``c.yaml: max_jump``) stays the file's
    key. The one place the CLI translates; the Python API keeps the keys."""
    from dataclasses import fields

    from ..options import FIELDS
    from ..rig import RigOptions

    flags = {**_KEYWORDS, **{k: "--" + k.replace("_", "-") for k in FIELDS},
             **{f.name: f.metadata["flag"] for f in fields(RigOptions) if "flag" in f.metadata}}
    keys = error.where.split("/") if error.where else []
    if not keys or not all(k in flags for k in keys):
        return error
    return type(error)(error.what, "/".join(flags[k] for k in keys), error.fix)


def _fail(line: str, code: int, debug: bool) -> NoReturn:
    """Print the traceback (under ``--debug``) and ``line`` on stderr; exit with ``code``."""
    if debug:
        traceback.print_exc()
    click.echo(line, err=True)
    sys.exit(code)
