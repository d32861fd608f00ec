"""What the commands share: click settings, the --strict failure, printing a result and a warning."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

from ..errors import HandEyeError, as_flags, one_line, worded
from ..output.formats import render_format
from ..output.writers import check_writable, format_mismatch, output_format, write_output

__all__ = ["CONTEXT", "Drifted", "StrictFailure", "emit", "finish", "report_failure", "result_format", "warn"]

CONTEXT = {"help_option_names": ["-h", "--help"], "max_content_width": 100}


class StrictFailure(Exception):
    """Warnings were raised under ``--strict`` (exit code 3)."""


class Drifted(Exception):
    """The result differs from the nominal extrinsic beyond tolerance (exit code 1)."""


def emit(doc: dict[str, Any], output: str | None, fmt: str | None) -> None:
    """Print the result to stdout (no ``-o`` or ``-o -``) or write it to ``output``, the options its
    warnings and diagnostics name as flags (:func:`~handeye_cli.errors.as_flags`)."""
    write_output(output, render_format(worded(doc, as_flags), output_format(output, fmt)))


def result_format(output: str | None, fmt: str | None) -> str:
    """The format of the result ``-o``/``--format`` ask for, checked before any work: the file can be written,
    and a name that says another format than ``--format`` is one warning line."""
    check_writable(output, "-o")
    mismatch = format_mismatch(output, fmt)
    if mismatch:
        warn(mismatch)
    return output_format(output, fmt)


def warn(message: str) -> None:
    """One ``warning:`` line on stderr; names from a log or file it quotes cannot break the line
    (newlines, U+2028, terminal escapes are written as escapes)."""
    click.echo(f"warning: {one_line(as_flags(message))}", err=True)


def report_failure(write: Callable[[], None]) -> HandEyeError | None:
    """Run ``write`` (a command's ``--report``) before the result is written: its failure is returned, worded as
    the failure after the result it becomes (``finish(late=…)``: the result is still written, exit 2)."""
    try:
        write()
    except HandEyeError as e:
        return type(e)(f"the result was written, but not the report: {e.what}", e.where, e.fix)
    return None


def finish(doc: dict[str, Any], *, strict: bool, quiet: bool, drift: str | None = None, within: str | None = None,
           late: HandEyeError | None = None, poor_fit_accepted: bool = False) -> None:
    """The ending every command that writes a result shares, once the result is written: its warnings on
    stderr, then the exit code a CI job reads — a failure after the result (``late``, e.g. the report) exit 2,
    a drift from the nominal (``drift``: its one-line summary) exit 1, a poor fit kept by
    ``--accept-poor-fit`` or warnings under ``--strict`` exit 3; else 0, with ``within`` (the verdict that
    passed) on stderr unless ``quiet``."""
    for w in doc["warnings"]:
        warn(w)
    if late is not None:
        raise late
    if drift is not None:
        raise Drifted(drift)
    if within is not None and not quiet:
        click.echo(as_flags(within), err=True)
    if poor_fit_accepted:
        raise StrictFailure("the result failed a check (the fit test, the inversion check or a given quaternion "
                            "order: its first warning says which) and was written because of --accept-poor-fit")
    if doc["warnings"] and strict:
        raise StrictFailure(f"{len(doc['warnings'])} warning(s) under --strict (the result was still written)")
