"""ROS 1 bags that rosbags refuses: never indexed (the recorder crashed before writing the index)
or cut off. The records are scanned in file order with rosbags' own record-header parser; chunks
(none / bz2 / lz4) are decompressed and their connection and message records read; types come
from each connection's embedded message definition. Everything up to the first damaged record
is read (``truncated`` is set when the file ends inside a record).
"""
from __future__ import annotations

import bz2
import io
from collections import Counter
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, BinaryIO

import lz4.frame  # type: ignore[import-untyped]
from rosbags.rosbag1.reader import Header, ReaderError, RecordType, decompressors, read_uint32
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from ..errors import ReadError
from .common import decode_errors
from .messages import normalize_type, pose_decoder
from .source import Decoder, TopicInfo

__all__ = ["Bag1Scan"]

_MAGIC = b"#ROSBAG V2.0\n"
_ERRORS: tuple[type[BaseException], ...] = (ReaderError, KeyError, *decode_errors())


class Bag1Scan:
    """A ROS 1 bag read by a linear scan (a LogSource). ``notes``: warnings for every stream read."""

    def __init__(self, path: Path, reason: str) -> None:
        self.name = str(path)
        self._path = path
        self.truncated = False
        self._conns: dict[int, tuple[str, str, str]] = {}     # id → (topic, type, message definition)
        self._counts: Counter[int] = Counter()
        stamps = []
        for conn, stamp, _ in self._messages(None):
            self._counts[conn] += 1
            stamps.append(stamp)
        if not self._counts:
            raise ReadError(f"cannot read file: {reason}; no complete message found by a linear scan", self.name,
                            "the bag is empty or damaged; try `rosbag reindex` (ROS 1)")
        self._span = (min(stamps), max(stamps))
        self.notes = (f"{self.name} has no usable index ({reason}); read by a linear scan of its records",)

    def __enter__(self) -> Bag1Scan:
        return self

    def __exit__(self, *exc: object) -> None:
        pass

    def _records(self, src: BinaryIO) -> Iterator[tuple[Header, bytes]]:
        """(header, data) of the records of ``src`` until its end or a damaged record (``truncated``).
        A chunk cut off at the end comes with the bytes that are there (its complete records are read)."""
        while True:
            if not src.read(1):
                return
            src.seek(-1, io.SEEK_CUR)
            try:
                header = Header.read(src)
                size = read_uint32(src)
            except _ERRORS:
                self.truncated = True
                return
            data = src.read(size)
            if len(data) < size:
                self.truncated = True
                if header.get("op") == bytes([RecordType.CHUNK]):
                    yield header, data
                return
            yield header, data

    def _messages(self, conns: set[int] | None) -> Iterator[tuple[int, int, bytes]]:
        """(connection id, log time [ns], raw message) in file order; registers connections."""
        with open(self._path, "rb") as f:
            if f.read(len(_MAGIC)) != _MAGIC:
                raise ReadError("not a ROS 1 bag (wrong magic)", self.name, "check the file")
            yield from self._walk(self._records(f), conns)

    def _walk(self, records: Iterator[tuple[Header, bytes]],
              conns: set[int] | None) -> Iterator[tuple[int, int, bytes]]:
        for header, data in records:
            try:
                op = header.get_uint8("op")
                if op == RecordType.CHUNK:
                    raw = _decompress(header.get_string("compression"), data)
                    yield from self._walk(self._records(io.BytesIO(raw)), conns)
                elif op == RecordType.CONNECTION:
                    meta = Header.read(io.BytesIO(len(data).to_bytes(4, "little") + data))   # fields, unprefixed
                    self._conns[header.get_uint32("conn")] = (
                        header.get_string("topic"), meta.get_string("type"), meta.get_string("message_definition"))
                elif op == RecordType.MSGDATA:
                    conn = header.get_uint32("conn")
                    if conns is None or conn in conns:
                        yield conn, header.get_time("time"), data
            except _ERRORS:
                self.truncated = True
                return

    def topics(self) -> list[TopicInfo]:
        rows: dict[str, TopicInfo] = {}
        for cid, (topic, typ, _) in self._conns.items():
            old = rows.get(topic)
            rows[topic] = TopicInfo(topic, normalize_type(typ), "ros1", self._counts[cid] + (old.count if old else 0))
        return list(rows.values())

    def span(self) -> tuple[int, int] | None:
        return self._span

    def _decoder(self, typ: str, msgdef: str) -> Decoder:
        store = get_typestore(Stores.EMPTY)
        name = normalize_type(typ)
        store.register(get_types_from_msg(msgdef, name))
        return pose_decoder(name, lambda b: store.deserialize_ros1(b, name))

    def read(self, topics: Sequence[str]) -> Iterator[tuple[str, int, bytes, Any]]:
        ids = {cid for cid, (topic, _, _) in self._conns.items() if topic in topics}
        decoders = {cid: self._decoder(*self._conns[cid][1:]) for cid in ids}
        self.truncated = False
        for conn, stamp, raw in self._messages(ids):
            yield self._conns[conn][0], stamp, raw, decoders[conn]


def _decompress(compression: str, data: bytes) -> bytes:
    """A chunk's records; of a chunk cut off, as much as its complete compressed blocks give."""
    if compression == "none":
        return data
    stream = {"bz2": bz2.BZ2Decompressor, "lz4": lz4.frame.LZ4FrameDecompressor}.get(compression)
    if stream is None:
        return bytes(decompressors[compression](data))     # rosbags names the unsupported compression
    try:
        return bytes(stream().decompress(data))
    except (OSError, EOFError, RuntimeError, ValueError):
        return b""
