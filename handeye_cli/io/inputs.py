"""Input paths that can be read only once: ``-`` (stdin) and pipes (``<(cat a.tum)``, FIFOs).

Their bytes are copied on first use to a temporary file kept for the process (in 1 MiB pieces:
memory holds one piece), so detecting the format and reading the stream both see the same bytes,
nothing is read twice, and the readers that seek (MCAP, bags) get a regular file. The copy stops
with a one-line error past :data:`STREAM_LIMIT` (an endless input such as ``yes |``); a named
FIFO is opened without blocking and waits at most :data:`FIFO_WAIT_S` for data (no writer, or a
writer gone quiet, is an error, not a hang). Other special files (``/dev/zero``, block devices,
sockets) are refused: they are no recording.
"""
from __future__ import annotations

import atexit
import os
import re
import select
import shutil
import stat
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from ..errors import ReadError

__all__ = ["STDIN", "STREAM_LIMIT", "FIFO_WAIT_S", "is_stream", "existing", "read_head", "open_binary", "spooled",
           "stem_of", "valid_frame_id"]

STDIN = "-"
STREAM_LIMIT = 4 << 30
"""The most bytes [B] copied from stdin or a pipe; past it the input is refused (endless input)."""
FIFO_WAIT_S = 10.0
"""How long [s] reading a named FIFO waits for its writer, and then for each next piece of data."""
_PIECE = 1 << 20            # [B] read and written at a time
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


def _copy(read: Callable[[int], bytes], dst: BinaryIO, name: str) -> None:
    """The bytes ``read(n)`` gives to ``dst`` until it gives none, at most :data:`STREAM_LIMIT`."""
    total = 0
    while piece := read(_PIECE):
        total += len(piece)
        if total > STREAM_LIMIT:
            raise ReadError(f"input without end: more than {STREAM_LIMIT >> 20} MiB "
                            "(handeye_cli.io.inputs.STREAM_LIMIT)", name,
                            "write the recording to a file and pass its path")
        dst.write(piece)


def _fifo_reader(fd: int, name: str) -> Callable[[int], bytes]:
    """``read(n)`` of the FIFO ``fd`` opened non-blocking: each piece waited for at most :data:`FIFO_WAIT_S`."""
    poll = select.poll()
    poll.register(fd, select.POLLIN)

    def read(n: int) -> bytes:
        while True:
            if not poll.poll(FIFO_WAIT_S * 1000):
                raise ReadError(f"no one wrote to the FIFO for {FIFO_WAIT_S:g} s", name,
                                "start the writer first, or pass a regular file")
            try:
                return os.read(fd, n)
            except BlockingIOError:
                continue

    return read


def _spool(path: str | Path) -> Path:
    """The temporary regular file holding the content of the stream ``path`` (copied on first use)."""
    key = str(path)
    if key in _SPOOLED:
        return _SPOOLED[key]
    tmp = Path(tempfile.mkdtemp(prefix="handeye-stdin-"))
    atexit.register(shutil.rmtree, tmp, True)
    target = tmp / stem_of(path)
    try:
        if key == STDIN:
            with open(target, "wb") as dst:
                _copy(sys.stdin.buffer.read, dst, key)
        else:
            mode = os.stat(key).st_mode
            if not stat.S_ISFIFO(mode):
                kind = "a character device" if stat.S_ISCHR(mode) else "a special file"
                raise ReadError(f"{kind}, not a file or a pipe", key, "pass a recording or trajectory file")
            fd = os.open(key, os.O_RDONLY | os.O_NONBLOCK)      # a plain open would wait for a writer forever
            try:
                with open(target, "wb") as dst:
                    _copy(_fifo_reader(fd, key), dst, key)
            finally:
                os.close(fd)
    except OSError as exc:
        raise ReadError(f"cannot read: {exc.strerror or exc}", key, "check the path and permissions") from exc
    _SPOOLED[key] = target
    return target


def read_head(path: str | Path, n: int) -> bytes:
    """The first ``n`` bytes (of a stream: without losing the rest)."""
    with open_binary(path) as f:
        return f.read(n)


def open_binary(path: str | Path) -> BinaryIO:
    """The whole content as a binary file object, positioned at the start."""
    return open(_spool(path) if is_stream(path) else path, "rb")


def spooled(path: Path, suffix: str) -> Path:
    """A seekable regular file with the content of ``path`` (a stream's copy, named with ``suffix``)."""
    if not is_stream(path):
        return path
    target = _spool(path)
    named = target.with_name(f"{stem_of(path)}{suffix}")
    if not named.exists():
        os.link(target, named)
    return named


def stem_of(path: str | Path) -> str:
    """The name a text stream's child frame gets: the file stem, ``stdin`` for ``-``."""
    return "stdin" if str(path) == STDIN else Path(path).stem


def valid_frame_id(name: str) -> str:
    """A tf2-valid frame id from a file stem or topic: no leading ``/``, other ``/`` and characters
    outside ``[A-Za-z0-9_.-]`` become ``_`` (``"/cam0/pose"`` → ``"cam0_pose"``)."""
    return _FRAME_CHARS.sub("_", name.strip().lstrip("/")) or "sensor"
