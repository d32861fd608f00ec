"""A progress bar on stderr for long reads; silent when stderr is not a terminal or when quiet."""
from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Protocol

import click

__all__ = ["Progress", "progress"]


class Progress(Protocol):
    """What ``progress`` yields: ``update(n)`` advances the bar by n messages."""

    def update(self, n_steps: int) -> None: ...


class _Silent:
    def update(self, n_steps: int) -> None:
        pass


@contextmanager
def progress(total: int, label: str, *, quiet: bool = True) -> Iterator[Progress]:
    """A bar counting ``total`` messages on stderr (``update(n)`` advances it by n).

    Off (a no-op object) when ``quiet`` is true, stderr is not a TTY or total is 0.
    """
    if quiet or total <= 0 or not sys.stderr.isatty():
        yield _Silent()
        return
    with click.progressbar(length=total, label=label, file=sys.stderr) as bar:
        yield bar
