"""Input paths that can be read only once: ``-`` (stdin) and pipes (``<(cat a.tum)``, FIFOs).

Their bytes are read on first use and kept for the process, so detecting the format and reading
the stream both see the same bytes and nothing is opened twice. A log (MCAP, bag) arriving on a
pipe is spooled to a temporary file, because its readers seek.
"""
from __future__ import annotations

import atexit
import io
import re
import shutil
import stat
import sys
import tempfile
from pathlib import Path
from typing import BinaryIO

from ..errors import ReadError

__all__ = ["STDIN", "is_stream", "existing", "read_head", "open_binary", "spooled", "stem_of", "valid_frame_id"]

STDIN = "-"
_BYTES: dict[str, bytes] = {}
_SPOOLED: dict[str, Path] = {}
_FRAME_CHARS = re.compile(r"[^A-Za-z0-9_.\-]")


def is_stream(path: str | Path) -> bool:
    """``-`` or a path that is neither a regular file nor a directory (a pipe, FIFO, character device)."""
    if str(path) == STDIN:
        return True
    try:
        mode = Path(path).stat().st_mode
    except OSError:
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


def existing(path: str | Path) -> Path:
    """``path`` as a Path (``-`` stays ``-``), or a ReadError if nothing is there."""
    p = Path(path)
    if str(path) != STDIN and not p.exists():
        raise ReadError("file not found", str(p), "check the path")
    return p


def _slurp(path: str | Path) -> bytes:
    key = str(path)
    if key not in _BYTES:
        try:
            if key == STDIN:
                _BYTES[key] = sys.stdin.buffer.read()
            else:
                with open(path, "rb") as f:
                    _BYTES[key] = f.read()
        except OSError as exc:
            raise ReadError(f"cannot read: {exc.strerror or exc}", key, "check the path and permissions") from exc
    return _BYTES[key]


def read_head(path: str | Path, n: int) -> bytes:
    """The first ``n`` bytes (of a stream: without losing the rest)."""
    if is_stream(path):
        return _slurp(path)[:n]
    with open(path, "rb") as f:
        return f.read(n)


def open_binary(path: str | Path) -> BinaryIO:
    """The whole content as a binary file object, positioned at the start."""
    if is_stream(path):
        return io.BytesIO(_slurp(path))
    return open(path, "rb")


def spooled(path: Path, suffix: str) -> Path:
    """A seekable regular file with the content of ``path`` (a stream is copied once to a temporary file)."""
    if not is_stream(path):
        return path
    key = str(path)
    if key not in _SPOOLED:
        tmp = Path(tempfile.mkdtemp(prefix="handeye-stdin-"))
        atexit.register(shutil.rmtree, tmp, True)
        target = tmp / f"{stem_of(path)}{suffix}"
        target.write_bytes(_slurp(path))
        _SPOOLED[key] = target
    return _SPOOLED[key]


def stem_of(path: str | Path) -> str:
    """The name a text stream's child frame gets: the file stem, ``stdin`` for ``-``."""
    return "stdin" if str(path) == STDIN else Path(path).stem


def valid_frame_id(name: str) -> str:
    """A tf2-valid frame id from a file stem or topic: no leading ``/``, other ``/`` and characters
    outside ``[A-Za-z0-9_.-]`` become ``_`` (``"/cam0/pose"`` → ``"cam0_pose"``)."""
    return _FRAME_CHARS.sub("_", name.strip().lstrip("/")) or "sensor"
