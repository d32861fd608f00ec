"""Which inputs a batch runs: files, directories searched recursively by content, globs,
``@list.txt`` and ``-`` (a list on stdin), and URLs (objects, prefixes and globs: see :func:`_remote`).

An input is one log (MCAP, ROS 1 bag, ROS 2 bag directory or bare ``.db3``) or two text pose files
(TUM/EuRoC) of streams a and b. In a list (``@file`` or stdin) a line holds one path or two
(``A B``, shell-quoted when a path has spaces); blank lines and ``#`` comments are skipped; relative
paths are relative to the working directory. A directory is searched recursively, in name order,
by content (not by extension): logs are recognised by their magic bytes, a ROS 2 bag directory by
its ``metadata.yaml``, and a folder holding exactly two text pose files of one format (TUM or
EuRoC) gives one input of the two, in name order (a, then b). Files named like logs (``.mcap``,
``.bag``, ``.db3``) are kept even when damaged, so that they are reported rather than silently
skipped; other regular files (CSV, YAML, images …) are skipped. A FIFO, socket or device — found in
a folder, matched by a pattern or named — is never opened (opening a FIFO no one writes would
block forever; they are told apart by ``os.stat``, which does not open them) and never skipped: it
becomes an input that fails, its record an ``error`` saying what it is, as does an argument that
names nothing. Glob
patterns with ``**`` are expanded by a walk that follows a symlinked folder only the first time it
meets that folder, so a link to ``..`` cannot loop; an input met twice (a symlink and its target,
overlapping arguments) is kept the first time only, told apart by the identity of its files
(``st_dev``, ``st_ino``), with a warning.
"""
from __future__ import annotations

import glob
import os
import shlex
import stat
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from fnmatch import fnmatchcase
from pathlib import Path
from typing import TextIO

from ..errors import HandEyeError, as_flags
from ..io.detect import LOG_FORMATS, LOG_SUFFIXES, detect_format
from ..io.remote import current, is_url

__all__ = ["BatchInput", "discover"]

_TEXT_FORMATS = ("tum", "euroc")
_SPECIAL = ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
            (stat.S_ISBLK, "a block device"))

Warn = Callable[[str], None]


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
        return "log" if path.suffix.lower() in LOG_SUFFIXES else None
    return "log" if fmt in LOG_FORMATS else fmt if fmt in _TEXT_FORMATS else None


def _special(path: str | Path) -> str | None:
    """What kind of special file ``path`` is ("a FIFO" …), or None for a regular file, a folder or
    a path that does not exist — by ``os.stat``, which never blocks on a FIFO."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None
    return next((what for test, what in _SPECIAL if test(mode)), None)


def _not_a_file(path: str, what: str) -> str:
    return (f"{path} is {what}, not a log file: handeye batch reads only regular files and folders "
            "(a FIFO no one writes would block it); copy the data to a file and give that")


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
            what = _special(here / name)
            if what is not None:
                found.append(BatchInput((str(here / name),), _not_a_file(str(here / name), what)))
                continue
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
    """One argument, or a path a glob pattern matched: a file, a directory, or a glob pattern. A
    special file is an error input."""
    if is_url(arg):
        return _remote(arg)
    path = Path(arg)
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        inputs = _search(path)
        return inputs or [BatchInput((arg,), f"no logs found in the folder {arg}")]
    what = _special(path)
    if what is not None:
        return [BatchInput((arg,), _not_a_file(arg, what))]
    if path.exists():
        return [BatchInput((arg,))]
    if glob.has_magic(arg):
        matches = _glob(arg)
        if matches:
            return [i for m in matches for i in _expand(m)]
        return [BatchInput((arg,), f"the pattern {arg} matches no file")]
    return [BatchInput((arg,), f"file not found: {arg}")]


def _remote(url: str) -> list[BatchInput]:
    """The inputs a URL names: an object; a folder (a prefix: ``s3://bucket/logs/``) or a glob
    (``s3://bucket/*/2026-11-*.mcap``), whose objects named like logs (``.mcap``, ``.bag``, ``.db3``)
    are the inputs, a folder holding ``metadata.yaml`` one ROS 2 bag. Listing costs a request, not
    reading every object (text pose pairs are listed in an @list file)."""
    session = current()
    try:
        if glob.has_magic(url.split("://", 1)[1]):
            found = session.listing(url, pattern=True)
            if not found:
                return [BatchInput((url,), f"the pattern {url} matches no object")]
        elif url.endswith("/") or session.is_folder(url):
            found = session.listing(url)
        else:
            return [BatchInput((url,))]
        for name in [n for n, folder in found if folder]:
            found += session.listing(name)
    except HandEyeError as e:
        return [BatchInput((url,), e.line(as_flags))]
    bags = sorted({name.rsplit("/", 1)[0] for name, _ in found if name.endswith("/metadata.yaml")})
    logs = {name for name, folder in found if not folder and name.lower().endswith(LOG_SUFFIXES)
            and not any(name.startswith(bag + "/") for bag in bags)}
    inputs = [BatchInput((name,)) for name in sorted(logs | set(bags))]
    return inputs or [BatchInput((url,), f"no logs found under {url}")]


def _glob(pattern: str) -> list[str]:
    """The paths ``pattern`` matches, sorted, as :func:`glob.glob` (``recursive=True``) gives them
    but loop-safe: ``**`` walks each folder once, however many symlinks lead to it."""
    if "**" not in pattern:
        return sorted(glob.glob(pattern))
    parts = pattern.split(os.sep)
    k = next(i for i, part in enumerate(parts) if glob.has_magic(part))
    base, rest = os.sep.join(parts[:k]), parts[k:]
    root = base or "."
    try:
        seen = {_identity(root)}
    except OSError:
        return []
    out = [base] if base and _match(rest, []) else []
    for folder, dirs, files in os.walk(root, followlinks=True):
        rel = os.path.relpath(folder, root)
        names = [] if rel == "." else rel.split(os.sep)
        keep = []
        for d in sorted(d for d in dirs if not d.startswith(".")):
            try:
                identity = _identity(os.path.join(folder, d))
            except OSError:
                continue
            if identity not in seen:
                seen.add(identity)
                keep.append(d)
        dirs[:] = keep
        out += [os.path.join(base, *names, f) for f in (*keep, *files) if _match(rest, [*names, f])]
    return sorted(out)


def _match(pattern: list[str], names: list[str]) -> bool:
    """Whether the path components ``names`` match the pattern's (``**``: any number of them;
    neither ``**`` nor ``*`` matches a name with a leading dot, as in :mod:`glob`)."""
    if not pattern:
        return not names
    if pattern[0] == "**":
        shown = next((i for i, name in enumerate(names) if name.startswith(".")), len(names))
        return any(_match(pattern[1:], names[i:]) for i in range(shown + 1))
    return (bool(names) and (pattern[0].startswith(".") or not names[0].startswith("."))
            and fnmatchcase(names[0], pattern[0]) and _match(pattern[1:], names[1:]))


def _identity(path: str | Path) -> tuple[int, int]:
    st = os.stat(path)
    return st.st_dev, st.st_ino


def _unique(inputs: list[BatchInput], warn: Warn) -> list[BatchInput]:
    """``inputs`` without those whose files are the same as an earlier input's (by identity)."""
    first: dict[tuple[tuple[int, int] | str, ...], BatchInput] = {}
    out = []
    for item in inputs:
        try:
            identity = tuple(p if is_url(p) else _identity(p) for p in item.paths) if item.error is None else None
        except OSError:
            identity = None
        if identity is not None and identity in first:
            warn(f"skipped {item.label}: the same input as {first[identity].label}")
            continue
        if identity is not None:
            first[identity] = item
        out.append(item)
    return out


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
            special = [(w, what) for w in words if (what := _special(w)) is not None]
            missing = [w for w in words if not is_url(w) and not Path(w).is_file()]
            error = (_not_a_file(*special[0]) if special else f"file not found: {missing[0]}" if missing else None)
            out.append(BatchInput(tuple(words), error))
        elif words:
            out.append(BatchInput(tuple(words), f"{where}:{n}: a line holds one log or two pose files (a b)"))
    return out


def discover(args: Iterable[str], stdin: TextIO | None = None, warn: Warn | None = None) -> list[BatchInput]:
    """The batch inputs the arguments name, in argument order (see the module docstring); ``warn``
    is told of the inputs skipped (met twice). A list is split at ``\\n`` only (a trailing ``\\r`` dropped), not
    at the other line breaks of :meth:`str.splitlines` (form feed, U+2028 …), which a path may hold."""
    warn = warn or (lambda message: None)
    out: list[BatchInput] = []
    for arg in args:
        if arg == "-":
            out.extend(_lines(_split(stdin.read() if stdin else ""), "stdin"))
        elif arg.startswith("@"):
            listing = Path(arg[1:])
            try:
                text = listing.read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError) as e:
                out.append(BatchInput((arg,), f"cannot read the list {listing}: {e}"))
                continue
            out.extend(_lines(_split(text), str(listing)))
        else:
            out.extend(_expand(arg))
    return _unique(out, warn)


def _split(text: str) -> list[str]:
    """The lines of a list: split at ``\\n``, a trailing ``\\r`` dropped."""
    return [line.removesuffix("\r") for line in text.split("\n")]
