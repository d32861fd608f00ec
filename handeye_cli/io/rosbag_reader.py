"""ROS 1 ``.bag`` files (one or several split files), ROS 2 bag directories and bare ``.db3`` /
``.mcap`` files via ``rosbags.highlevel.AnyReader``.

AnyReader picks the bag version by suffix only, so a file detected by content under another
name is opened through a temporary symlink with the right suffix.

rosbags decompresses chunks whole (an MCAP chunk with no bound, a ROS 1 chunk into whatever it
inflates to): its decompressor tables are pointed at :func:`.common.inflate` here, so a chunk
never yields more than it declares (MCAP) nor more than :data:`.common.CHUNK_LIMIT`; past that
the read is a one-line error. A ROS 1 bag's record lengths are checked against the file before
rosbags sees it (:func:`.rosbag1_scan.check_lengths`, called by :func:`.opening.open_log`).
"""
from __future__ import annotations

import os
import sqlite3
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import ExitStack, closing
from functools import partial
from pathlib import Path

from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import reader as bag1_reader
from rosbags.rosbag2 import storage_mcap
from rosbags.typesys import Stores, get_typestore

from ..errors import ReadError
from .common import CHUNK_LIMIT, inflate, unreadable
from .messages import normalize_type, pose_decoder
from .source import Decoder, TopicInfo, spans_by_topic

__all__ = ["BagSource"]

storage_mcap.DECOMPRESSORS.update(zstd=partial(inflate, "zstd"), lz4=partial(inflate, "lz4"))
bag1_reader.decompressors.update(bz2=partial(inflate, "bz2", size=CHUNK_LIMIT),
                                 lz4=partial(inflate, "lz4", size=CHUNK_LIMIT))


class BagSource:
    """Open bag(s) of one format, named by the suffix rosbags knows it by (``.bag``: any number of
    ROS 1 files; ``.db3``: one ROS 2 bag directory or ``.db3``; ``.mcap``: one ROS 2 ``.mcap``)."""

    def __init__(self, paths: Sequence[Path], suffix: str) -> None:
        self.name = ", ".join(str(p) for p in paths)
        self._db3 = ([q for p in paths for q in (sorted(Path(p).glob("*.db3")) if Path(p).is_dir() else [Path(p)])]
                     if suffix == ".db3" else [])
        self._stack = ExitStack()
        with unreadable(self.name):
            try:
                real = [self._with_suffix(Path(p), suffix) for p in paths]
                self._reader = self._stack.enter_context(
                    AnyReader(real, default_typestore=get_typestore(Stores.ROS2_HUMBLE)))
            except BaseException:
                self._stack.close()
                raise

    def _with_suffix(self, p: Path, suffix: str) -> Path:
        if p.is_dir() or p.suffix == suffix:
            return p
        tmp = Path(self._stack.enter_context(tempfile.TemporaryDirectory(prefix="handeye-")))
        link = tmp / (p.stem + suffix)
        os.symlink(p.resolve(), link)
        return link

    def __enter__(self) -> BagSource:
        return self

    def __exit__(self, *exc: object) -> None:
        self._stack.close()

    def topics(self) -> list[TopicInfo]:
        return [TopicInfo(topic, normalize_type(info.msgtype or ""),
                          getattr(info.connections[0].ext, "serialization_format", "ros1"),
                          info.msgcount)
                for topic, info in self._reader.topics.items()]

    def span(self) -> tuple[int, int] | None:
        r = self._reader    # rosbags' end_time is exclusive: last log time + 1
        return (r.start_time, r.end_time - 1) if r.message_count else None

    def topic_spans(self) -> dict[str, tuple[int, int]]:
        """ROS 1: from rosbags' connection indexes (pinned internals, as :mod:`.rosbag1_scan`'s);
        ROS 2 sqlite3: one grouped query on each ``.db3`` (read-only); other storage: none known."""
        spans: list[tuple[str, tuple[int, int]]] = []
        for reader in self._reader.readers:
            for conn in reader.connections:
                times = getattr(reader, "indexes", {}).get(conn.id)
                if times:
                    spans.append((conn.topic, (times[0].time, times[-1].time)))
        for db in self._db3:
            try:
                with closing(sqlite3.connect(f"{db.resolve().as_uri()}?mode=ro", uri=True)) as con:
                    spans += [(topic, (lo, hi)) for topic, lo, hi in con.execute(
                        "SELECT topics.name, MIN(messages.timestamp), MAX(messages.timestamp) FROM messages "
                        "JOIN topics ON messages.topic_id = topics.id GROUP BY topics.name")
                              if isinstance(lo, int) and isinstance(hi, int)]
            except sqlite3.Error:       # rosbags read it; the spans are only for inspect's rates
                continue
        return spans_by_topic(spans)

    def _decoder(self, msgtype: str, cdr: bool) -> Decoder:
        reader = self._reader
        return pose_decoder(normalize_type(msgtype), lambda b: reader.deserialize(b, msgtype), cdr=cdr)

    def read(self, topics: Sequence[str]) -> Iterator[tuple[str, int, bytes, Decoder]]:
        conns = [c for c in self._reader.connections if c.topic in topics]
        if not conns:       # AnyReader.messages(connections=[]) would yield every message
            return
        decoders = {(c.topic, c.msgtype): self._decoder(
            c.msgtype, getattr(c.ext, "serialization_format", "") == "cdr") for c in conns}
        counts = dict.fromkeys(topics, 0)
        with unreadable(self.name):
            for conn, log_ns, raw in self._reader.messages(connections=conns):
                if not isinstance(raw, (bytes, bytearray, memoryview)) or not isinstance(log_ns, int):
                    raise ReadError(f"message row holds {type(raw).__name__} data at {type(log_ns).__name__} time, "
                                    "not bytes at an integer time [ns] (a NULL, TEXT or INTEGER value in the "
                                    "bag's messages table)", f"{self.name}:{conn.topic}, message {counts[conn.topic]}",
                                    "the bag is corrupt: repair its messages table, or read another topic "
                                    "(⟦stream_a⟧/⟦stream_b='/topic'⟧)")
                counts[conn.topic] += 1
                yield conn.topic, log_ns, raw, decoders[(conn.topic, conn.msgtype)]
