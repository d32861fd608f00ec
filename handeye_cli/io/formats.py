"""The input formats, one table (:data:`FORMATS`): what detection knows of each (magic bytes, the
suffixes that promise a log), how it is opened (a local file, or a URL read by byte range or from
its download), what a copy of it is named. :mod:`.detect`, :func:`open_log` and :func:`opened`
read it; nothing else names a format's bytes or suffix.
"""
from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..errors import ReadError
from .opening import open_bag1, open_bag2, open_mcap
from .remote import RemoteObject, current
from .source import LogSource

__all__ = ["Format", "FORMATS", "LOG_FORMATS", "LOG_SUFFIXES", "BY_NAME", "MAGIC_BYTES", "by_magic", "by_suffix",
           "open_log", "opened"]

Opener = Callable[[list[Path | RemoteObject]], contextlib.AbstractContextManager[LogSource]]


def _by_range(obj: RemoteObject) -> str:
    return ""


def _mcap_by_range(obj: RemoteObject) -> str:
    if obj.prefetch_summary():
        return ""
    return "an MCAP without a summary (cut short, or written without one) cannot be read by range"


@dataclass(frozen=True)
class Format:
    """One input format. ``magic``: its first bytes (b"" for text, told by its lines: :func:`.detect.text_format`);
    ``suffixes``: a log's, the first given to a copy (a spooled pipe, rosbags' symlink); ``title``: its name in
    "not a valid … file"; ``opener``: the open log of its path(s) (None: text, read by :mod:`.text`); ``whole``:
    why a URL of it is downloaded to the session's cache ("": read by byte range), and ``by_range``: why the
    object at a URL cannot be read by range after all ("": it can), judged by its bytes fetched so far."""

    name: str
    magic: bytes
    suffixes: tuple[str, ...]
    title: str
    opener: Opener | None
    whole: str = ""
    by_range: Callable[[RemoteObject], str] = _by_range

    @property
    def log(self) -> bool:
        return self.opener is not None

    @property
    def range_readable(self) -> bool:
        return not self.whole


_TEXT = "a text file is read whole"
FORMATS = (
    Format("mcap", b"\x89MCAP0\r\n", (".mcap",), "MCAP", open_mcap, by_range=_mcap_by_range),
    # a bag without a usable index is downloaded by its opener (.opening._remote_bag1)
    Format("rosbag1", b"#ROSBAG V2.0", (".bag",), "ROS 1 bag", open_bag1),
    Format("rosbag2", b"SQLite format 3\x00", (".db3",), "ROS 2 SQLite bag", open_bag2,
           whole="a ROS 2 bag is read from a file"),
    Format("tum", b"", (), "TUM", None, whole=_TEXT),
    Format("euroc", b"", (), "EuRoC", None, whole=_TEXT),
    Format("csv", b"", (), "CSV", None, whole=_TEXT),
)
BY_NAME = {f.name: f for f in FORMATS}
LOG_FORMATS = tuple(f.name for f in FORMATS if f.log)
LOG_SUFFIXES = tuple(suffix for f in FORMATS if f.log for suffix in f.suffixes)
"""The suffixes that promise a log (lower case), as a batch's search of a folder or a bucket matches them."""
MAGIC_BYTES = max(len(f.magic) for f in FORMATS)
"""The most bytes [B] a format's magic needs."""


def by_magic(head: bytes) -> Format | None:
    """The log format whose magic ``head`` starts with."""
    return next((f for f in FORMATS if f.magic and head.startswith(f.magic)), None)


def by_suffix(suffix: str) -> Format | None:
    """The log format a file name's ``suffix`` (lower case) promises."""
    return next((f for f in FORMATS if suffix in f.suffixes), None)


def open_log(paths: list[Path | RemoteObject], fmts: list[str]) -> contextlib.AbstractContextManager[LogSource]:
    """The open log of ``paths`` (several only for split ROS 1 bags; a remote object is an MCAP or a ROS 1 bag)."""
    if len(paths) > 1 and (len(set(fmts)) > 1 or fmts[0] != "rosbag1"):
        raise ReadError("several files are read as one log only when all are ROS 1 .bag files",
                        ", ".join(map(str, paths)), "pass one file, or the split .bag files of one recording")
    opener = BY_NAME[fmts[0]].opener
    assert opener is not None, "text is read by .text, not opened as a log"
    return opener(paths)


def opened(url: str, fmt: str) -> Path | RemoteObject:
    """What the reader of format ``fmt`` opens for ``url``: the object read by byte range where the format
    and the object allow it (:attr:`Format.whole`, :attr:`Format.by_range`), else its local copy
    (:meth:`.remote.sessions.Session.cached`, with a note saying why)."""
    session, f = current(), BY_NAME[fmt]
    if f.whole:
        return session.cached(url, f.whole)
    obj = session.open(url)
    why = f.by_range(obj)
    return session.cached(url, why) if why else obj
