"""ROS 1 bags that rosbags refuses: never indexed (the recorder crashed before writing the index)
or cut off. The records are scanned in file order with rosbags' own record-header parser; chunks
(none / bz2 / lz4) are decompressed and their connection and message records read; types come
from each connection's embedded message definition. Everything up to the first damaged record
is read (``truncated`` is set when the file ends inside a record). Reads never ask for more than
the file holds, and a chunk is decompressed to at most the size its header declares and
:data:`.common.CHUNK_LIMIT`.

:func:`check_lengths` walks a bag's records before rosbags opens it, which would otherwise read
whatever length a damaged record claims (a chunk header claiming 0xFFFFFFF0 bytes: 4 GB).
"""
from __future__ import annotations

import io
from collections import Counter
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, BinaryIO

from rosbags.rosbag1.reader import Header, ReaderError, RecordType, decompressors, read_uint32
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from ..errors import ReadError
from .common import CHUNK_LIMIT, ChunkError, decode_errors, inflate, open_clamped
from .messages import normalize_type, pose_decoder
from .source import Decoder, TopicInfo, spans_by_topic

__all__ = ["Bag1Scan", "check_lengths"]

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
        self._spans: dict[int, tuple[int, int]] = {}         # id → (first, last) log time [ns]
        self._skipped: dict[str, None] = {}     # one line per chunk skipped
        for conn, stamp, _ in self._messages(None):
            self._counts[conn] += 1
            lo, hi = self._spans.get(conn, (stamp, stamp))
            self._spans[conn] = (min(lo, stamp), max(hi, stamp))
        if not self._counts:
            lost = "".join(f"; {k}" for k in self._skipped)
            raise ReadError(f"cannot read file: {reason}; no complete message found by a linear scan{lost}", self.name,
                            "the bag is empty or damaged; try `rosbag reindex` (ROS 1)")
        self._span = (min(lo for lo, _ in self._spans.values()), max(hi for _, hi in self._spans.values()))
        self.notes = (f"{self.name} has no usable index ({reason}); read by a linear scan of its records",
                      *self._skipped)

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
        with open_clamped(self._path) as f:
            if f.read(len(_MAGIC)) != _MAGIC:
                raise ReadError("not a ROS 1 bag (wrong magic)", self.name, "check the file")
            yield from self._walk(self._records(f), conns)

    def _walk(self, records: Iterator[tuple[Header, bytes]],
              conns: set[int] | None) -> Iterator[tuple[int, int, bytes]]:
        for header, data in records:
            try:
                op = header.get_uint8("op")
                if op == RecordType.CHUNK:
                    try:
                        raw = _decompress(header.get_string("compression"), data, header.get_uint32("size"))
                    except ChunkError as exc:
                        self._skipped[f"skipped a chunk of {self.name}: {exc}; its messages are lost"] = None
                        continue
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

    def topic_spans(self) -> dict[str, tuple[int, int]]:
        return spans_by_topic((self._conns[cid][0], span) for cid, span in self._spans.items() if cid in self._conns)

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


def _decompress(compression: str, data: bytes, size: int) -> bytes:
    """A chunk's records (``size`` [B] declared); of a chunk cut off, as much as its complete
    compressed blocks give. ChunkError past ``size`` or :data:`.common.CHUNK_LIMIT`."""
    if compression not in ("none", "bz2", "lz4"):
        return bytes(decompressors[compression](data))     # rosbags names the unsupported compression
    return inflate(compression, data, size, partial=True)


def check_lengths(path: Path) -> str:
    """What is wrong with the ROS 1 bag at ``path`` for rosbags to read it safely, or "": a record
    whose header or data claims more bytes than the file holds, or a chunk declaring more than
    :data:`.common.CHUNK_LIMIT` uncompressed. Reads only the records' headers."""
    size = path.stat().st_size
    with open_clamped(path) as f:
        f.seek(len(_MAGIC))
        while (pos := f.tell()) < size:
            try:
                header = Header.read(f)
                n = read_uint32(f)
                if f.tell() + n > size:
                    return f"the record at byte {pos} claims {n} bytes, past the end of the file ({size} bytes)"
                if header.get("op") == bytes([RecordType.CHUNK]) and header.get_uint32("size") > CHUNK_LIMIT:
                    return (f"the chunk at byte {pos} declares {header.get_uint32('size')} bytes uncompressed, over "
                            f"the {CHUNK_LIMIT >> 20} MiB limit (handeye_cli.io.common.CHUNK_LIMIT)")
            except _ERRORS:
                return f"damaged record header at byte {pos}"
            f.seek(n, io.SEEK_CUR)
    return ""
