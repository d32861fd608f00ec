"""Which inputs a batch runs: files, directories searched recursively by content, globs,
``@list.txt`` and ``-`` (a list on stdin).

An input is one log (MCAP, ROS 1 bag, ROS 2 bag directory or bare ``.db3``) or two text pose
files (TUM/EuRoC) of streams a and b. In a list (``@file`` or stdin) a line holds one path or
two (``A B``, shell-quoted when a path has spaces); blank lines and ``#`` comments are skipped;
relative paths are relative to the working directory. A directory is searched recursively, in
name order, by content (not by extension): logs are recognised by their magic bytes, a ROS 2
bag directory by its ``metadata.yaml``, and a folder holding exactly two text pose files of one
format (TUM or EuRoC) gives one input of the two, in name order (a, then b). Files named like logs (``.mcap``, ``.bag``,
``.db3``) are kept even when damaged, so that they are reported rather than silently skipped;
other files (CSV, YAML, images …) are skipped. An argument that names nothing becomes an input
that fails with that message.
"""
from __future__ import annotations

import glob
import os
import shlex
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from ..errors import HandEyeError
from ..io.detect import LOG_FORMATS, detect_format

__all__ = ["BatchInput", "discover"]

_LOG_SUFFIXES = (".mcap", ".bag", ".db3")
_TEXT_FORMATS = ("tum", "euroc")


@dataclass(frozen=True)
class BatchInput:
    """One unit of a batch: ``paths`` (a log, or text files a and b) and the ``label`` records show.
    ``error`` says why it cannot run (set by discovery, e.g. a path that does not exist)."""

    paths: tuple[str, ...]
    error: str | None = None

    @property
    def label(self) -> str:
        return self.paths[0] if len(self.paths) == 1 else shlex.join(self.paths)


def _kind(path: Path) -> str | None:
    """"log", a text pose format ("tum", "euroc") or None (not an input) — by content."""
    try:
        fmt = detect_format(path)
    except HandEyeError:
        return "log" if path.suffix.lower() in _LOG_SUFFIXES else None
    return "log" if fmt in LOG_FORMATS else fmt if fmt in _TEXT_FORMATS else None


def _search(root: Path) -> list[BatchInput]:
    """The inputs under a directory (see the module docstring)."""
    found: list[BatchInput] = []
    for folder, dirs, files in os.walk(root):
        here = Path(folder)
        if "metadata.yaml" in files:
            found.append(BatchInput((str(here),)))
            dirs[:] = []
            continue
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        texts: dict[str, list[str]] = {}
        for name in sorted(f for f in files if not f.startswith(".")):
            kind = _kind(here / name)
            if kind == "log":
                found.append(BatchInput((str(here / name),)))
            elif kind is not None:
                texts.setdefault(kind, []).append(str(here / name))
        for fmt, paths in texts.items():
            error = None if len(paths) == 2 else (
                f"{len(paths)} {fmt.upper()} file(s) in {here}: a folder needs exactly two (stream a, then b); "
                "list pairs as 'A B' lines in an @list file")
            found.append(BatchInput(tuple(paths), error))
    return sorted(found, key=lambda i: i.paths)


def _expand(arg: str) -> list[BatchInput]:
    """One argument: a file, a directory, or a glob pattern."""
    path = Path(arg)
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        inputs = _search(path)
        return inputs or [BatchInput((arg,), f"no logs found in the folder {arg}")]
    if path.exists():
        return [BatchInput((arg,))]
    if glob.has_magic(arg):
        matches = sorted(glob.glob(arg, recursive=True))
        if matches:
            return [i for m in matches for i in _expand(m)]
        return [BatchInput((arg,), f"the pattern {arg} matches no file")]
    return [BatchInput((arg,), f"file not found: {arg}")]


def _lines(lines: Iterable[str], where: str) -> list[BatchInput]:
    out: list[BatchInput] = []
    for n, line in enumerate(lines, 1):
        try:
            words = shlex.split(line, comments=True)
        except ValueError as e:
            out.append(BatchInput((line.strip(),), f"{where}:{n}: {e}"))
            continue
        if len(words) == 1:
            out.extend(_expand(words[0]))
        elif len(words) == 2:
            missing = [w for w in words if not Path(w).is_file()]
            out.append(BatchInput(tuple(words), f"file not found: {missing[0]}" if missing else None))
        elif words:
            out.append(BatchInput(tuple(words), f"{where}:{n}: a line holds one log or two pose files (a b)"))
    return out


def discover(args: Iterable[str], stdin: TextIO | None = None) -> list[BatchInput]:
    """The batch inputs the arguments name, in argument order (see the module docstring)."""
    out: list[BatchInput] = []
    for arg in args:
        if arg == "-":
            out.extend(_lines(stdin or [], "stdin"))
        elif arg.startswith("@"):
            listing = Path(arg[1:])
            try:
                text = listing.read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError) as e:
                out.append(BatchInput((arg,), f"cannot read the list {listing}: {e}"))
                continue
            out.extend(_lines(text.splitlines(), str(listing)))
        else:
            out.extend(_expand(arg))
    return out
