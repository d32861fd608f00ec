"""What the commands share: click settings, the --strict failure, printing a result and a warning."""
from __future__ import annotations

from typing import Any

import click

from ..errors import one_line
from ..output.formats import render_format
from ..output.writers import output_format, write_output

__all__ = ["CONTEXT", "Drifted", "StrictFailure", "emit", "warn"]

CONTEXT = {"help_option_names": ["-h", "--help"], "max_content_width": 100}


class StrictFailure(Exception):
    """Warnings were raised under ``--strict`` (exit code 3)."""


class Drifted(Exception):
    """The result differs from the nominal extrinsic beyond tolerance (exit code 1)."""


def emit(doc: dict[str, Any], output: str | None, fmt: str | None) -> None:
    """Print the result to stdout (no ``-o`` or ``-o -``) or write it to ``output``."""
    write_output(output, render_format(doc, output_format(output, fmt)))


def warn(message: str) -> None:
    """One ``warning:`` line on stderr; names from a log or file it quotes cannot break the line
    (newlines, U+2028, terminal escapes are written as escapes)."""
    click.echo(f"warning: {one_line(message)}", err=True)
