"""Each log format's opener (:attr:`.formats.Format.opener`): a :class:`~.source.LogSource`, falling back on
the damaged cases rosbags refuses.

* MCAP → :class:`.mcap_reader.McapSource` (which itself scans files without a usable summary);
* ROS 1 bags → rosbags' AnyReader, once :func:`.rosbag1_scan.check_lengths` finds every record
  within the file; a single bag it refuses (never indexed, cut off, a record claiming more than the
  file holds) is scanned linearly (:class:`.rosbag1_scan.Bag1Scan`) with a warning; one indexed
  bag named by URL is read by byte range (:class:`.rosbag1_scan.Bag1Index`), any other remote bag
  from its download (:meth:`.remote.sessions.Session.cached`, with a note saying why);
* ROS 2 bag directories → AnyReader when ``metadata.yaml`` is there and parses; a corrupt one is
  a one-line error; without one the single storage file is read directly (``.mcap`` through
  McapSource, ``.db3`` through AnyReader) with a warning. A directory with one ``.mcap`` storage
  file is read through McapSource too (fast path, crash recovery).
"""
from __future__ import annotations

import contextlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from ..errors import ReadError
from ..untrusted import load_yaml, yaml_problem
from .mcap_reader import McapSource
from .remote import RemoteObject
from .source import LogSource

if TYPE_CHECKING:
    from .rosbag1_scan import Bag1Index, Bag1Scan
    from .rosbag_reader import BagSource

__all__ = ["open_mcap", "open_bag1", "open_bag2"]


def _bag2_storage(directory: Path) -> tuple[Path | None, str]:
    """(the storage file to read directly or None for AnyReader, the warning to give or "")."""
    meta = directory / "metadata.yaml"
    storage = sorted(directory.glob("*.mcap")) + sorted(directory.glob("*.db3"))
    if meta.is_file():
        try:
            doc = load_yaml(meta.read_text(encoding="utf-8", errors="replace"))   # a log's file: no aliases, bounded
        except yaml.YAMLError as exc:
            what, where = yaml_problem(exc, str(meta))
            raise ReadError(f"corrupt metadata.yaml: {what}", where, "restore metadata.yaml, or delete it to read "
                                                                     "the storage file directly") from exc
        if not isinstance(doc, dict) or "rosbag2_bagfile_information" not in doc:
            raise ReadError("corrupt metadata.yaml: no rosbag2_bagfile_information", str(meta),
                            "restore metadata.yaml, or delete it to read the storage file directly")
        if len(storage) == 1 and storage[0].suffix == ".mcap":
            return storage[0], ""
        return None, ""
    if len(storage) != 1:
        raise ReadError(f"ROS 2 bag without metadata.yaml and with {len(storage)} storage files", str(directory),
                        "pass one .db3 or .mcap storage file")
    return storage[0], f"{directory} has no metadata.yaml; read its storage file {storage[0].name} directly"


def _with_note(src: LogSource, note: str) -> LogSource:
    if note:
        src.notes = (*getattr(src, "notes", ()), note)    # type: ignore[attr-defined]
    return src


def _open_bag1(paths: list[Path]) -> BagSource | Bag1Scan:
    """ROS 1 bag(s) through rosbags (imported only here: an MCAP read by the fast path does without
    it), once :func:`.rosbag1_scan.check_lengths` finds every record within its file (rosbags would
    read whatever length a damaged record claims); a single bag that fails this or that rosbags
    refuses is scanned linearly."""
    from .rosbag1_scan import Bag1Scan, check_lengths
    from .rosbag_reader import BagSource

    damaged = [(p, why) for p in paths if (why := check_lengths(p))]
    if len(paths) > 1:
        if damaged:
            raise ReadError(f"cannot read file: {damaged[0][1]}", str(damaged[0][0]),
                            "pass the intact bags, or this one alone to read it by a linear scan")
        return BagSource(paths, ".bag")
    reason = damaged[0][1] if damaged else ""
    if not reason:
        try:
            return BagSource(paths, ".bag")
        except ReadError as exc:
            reason = exc.what.removeprefix("cannot read file: ")
    return Bag1Scan(paths[0], reason)


def _remote_bag1(objects: list[RemoteObject]) -> Bag1Index | list[Path]:
    """One indexed remote ROS 1 bag read by range, else the local copies of the bags (downloaded
    once, with a note saying why)."""
    from .rosbag1_scan import indexed

    if len(objects) == 1:
        bag = indexed(objects[0])
        if not isinstance(bag, str):
            return bag
        why = f"a ROS 1 bag without a usable index ({bag}) cannot be read by range"
    else:
        why = "split ROS 1 bags are read as one from files"
    return [obj.session.cached(obj.url, why) for obj in objects]


@contextmanager
def _opened(src: LogSource, note: str = "") -> Iterator[LogSource]:
    with src:                       # type: ignore[attr-defined]
        yield _with_note(src, note)


def open_mcap(paths: list[Path | RemoteObject]) -> contextlib.AbstractContextManager[LogSource]:
    """One MCAP, a local file or a remote object read by range."""
    return _opened(McapSource(paths[0]))


def open_bag1(paths: list[Path | RemoteObject]) -> contextlib.AbstractContextManager[LogSource]:
    """ROS 1 bag(s): one indexed remote bag by range, other remote bags from their downloads, local ones
    through rosbags or a linear scan (:func:`_open_bag1`)."""
    remote = [p for p in paths if isinstance(p, RemoteObject)]
    if remote:
        bag = _remote_bag1(remote)
        if not isinstance(bag, list):
            return _opened(bag)
        paths = [*bag, *(p for p in paths if isinstance(p, Path))]
    return _opened(_open_bag1([p for p in paths if isinstance(p, Path)]))


def open_bag2(paths: list[Path | RemoteObject]) -> contextlib.AbstractContextManager[LogSource]:
    """A ROS 2 bag directory or bare ``.db3`` (a URL's is its download): its one ``.mcap`` storage file
    through McapSource, else rosbags."""
    from .rosbag_reader import BagSource

    path, note = paths[0], ""
    assert isinstance(path, Path), "ROS 2 bags are downloaded, never read by range"
    storage = None
    if path.is_dir():
        storage, note = _bag2_storage(path)
    if storage is not None and storage.suffix == ".mcap":
        return _opened(McapSource(storage), note)
    return _opened(BagSource([storage or path], ".db3"), note)
