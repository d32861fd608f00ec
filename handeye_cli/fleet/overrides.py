"""Per-input options for a batch (``--per-input FILE``): a YAML mapping of glob patterns of input
paths to the options that differ for the inputs they match, by flat name as in ``--config``::

    "*/robot42/*": {time_offset: 0.02}
    "logs/2026-11-03/*.bag": {gate: off, pairs: all}

An input matches a pattern when one of its paths does (:func:`fnmatch.fnmatch`, ``*`` also
crosses ``/``). Matching entries apply in file order over the shared options (defaults < preset <
--config < flags), so the most specific entry goes last. Every entry is checked when the file
is read: a bad option fails the batch before it starts.
"""
from __future__ import annotations

from dataclasses import dataclass
from fnmatch import fnmatch
from pathlib import Path
from typing import Any

from ..config import read_config
from ..errors import ConfigError
from ..options import Options
from .discovery import BatchInput

__all__ = ["Override", "read_overrides", "options_for"]


@dataclass(frozen=True)
class Override:
    """Options (``values``: flat name, value pairs) for the inputs whose paths match ``pattern``."""

    pattern: str
    values: tuple[tuple[str, Any], ...]
    where: str


def read_overrides(path: str | Path) -> tuple[Override, ...]:
    """The entries of a per-input options file, each checked against the options' parsers."""
    out = []
    for pattern, values in read_config(path).items():
        where = f"{path}: {pattern}"
        if not isinstance(values, dict):
            raise ConfigError("each pattern needs a mapping of option: value", where,
                              'write e.g. "*/robot42/*": {time_offset: 0.02}')
        Options.from_flat(Options(), where, **values)
        out.append(Override(str(pattern), tuple(values.items()), where))
    return tuple(out)


def options_for(item: BatchInput, base: Options, overrides: tuple[Override, ...]) -> Options:
    """``base`` with every matching override applied in order."""
    opts = base
    for o in overrides:
        if any(fnmatch(p, o.pattern) for p in item.paths):
            opts = Options.from_flat(opts, o.where, **dict(o.values))
    return opts
