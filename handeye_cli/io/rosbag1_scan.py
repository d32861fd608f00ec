"""ROS 1 bags read without rosbags' reader: those it refuses, and indexed bags read by byte range.

:class:`Bag1Scan` reads a bag rosbags refuses: never indexed (the recorder crashed before writing the index)
or cut off. The records are scanned in file order with rosbags' own record-header parser; chunks
(none / bz2 / lz4) are decompressed and their connection and message records read; types come
from each connection's embedded message definition. Everything up to the first damaged record
is read (``truncated`` is set when the file ends inside a record). Reads never ask for more than
the file holds, and a chunk is decompressed to at most the size its header declares and
:data:`.common.CHUNK_LIMIT`.

:class:`Bag1Index` (made by :func:`indexed`) reads an indexed bag named by URL by byte range: the
bag header, the index (connections, chunk infos), then only the chunks holding the wanted
connections, decoded by the same record walk.

:func:`check_lengths` walks a bag's records before rosbags opens it, which would otherwise read
whatever length a damaged record claims (a chunk header claiming 0xFFFFFFF0 bytes: 4 GB).
"""
from __future__ import annotations

import io
from collections import Counter
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, BinaryIO

from rosbags.rosbag1.reader import Header, ReaderError, RecordType, read_uint32
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from ..errors import ReadError
from .common import CHUNK_LIMIT, ChunkError, decode_errors, inflate, open_clamped, unreadable
from .messages import normalize_type, pose_decoder
from .remote import RemoteObject
from .source import Decoder, TopicInfo, spans_by_topic

__all__ = ["Bag1Scan", "Bag1Index", "indexed", "check_lengths"]

_MAGIC = b"#ROSBAG V2.0\n"
_ERRORS: tuple[type[BaseException], ...] = (ReaderError, *decode_errors())


class _Bag1:
    """What the two readers of a ROS 1 bag without rosbags share (a LogSource once a subclass fills
    ``_conns``, ``_counts`` and ``_span`` and defines :meth:`_messages`): walking records and the
    chunks inside them, topics, decoders from each connection's embedded message definition."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.truncated = False
        self._conns: dict[int, tuple[str, str, str]] = {}     # id → (topic, type, message definition)
        self._counts: Counter[int] = Counter()
        self._spans: dict[int, tuple[int, int]] = {}         # id → (first, last) log time [ns]
        self._skipped: dict[str, None] = {}     # one line per chunk skipped
        self._span: tuple[int, int] | None = None
        self._notes: tuple[str, ...] = ()

    @property
    def notes(self) -> tuple[str, ...]:
        """Warnings for every stream read: the reader's and the opener's, then the chunks skipped so far."""
        return (*self._notes, *self._skipped)

    @notes.setter
    def notes(self, value: Sequence[str]) -> None:
        self._notes = tuple(v for v in value if v not in self._skipped)

    def __enter__(self) -> _Bag1:
        return self

    def __exit__(self, *exc: object) -> None:
        pass

    def _messages(self, conns: set[int] | None) -> Iterator[tuple[int, int, bytes]]:
        """(connection id, log time [ns], raw message) of the connections ``conns`` (None: all)."""
        raise NotImplementedError

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
                    self._conns[header.get_uint32("conn")] = _connection(header, data)
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
        with unreadable(self.name):     # a damaged message definition
            decoders = {cid: self._decoder(*self._conns[cid][1:]) for cid in ids}
        self.truncated = False
        for conn, stamp, raw in self._messages(ids):
            yield self._conns[conn][0], stamp, raw, decoders[conn]


def _connection(header: Header, data: bytes) -> tuple[str, str, str]:
    """(topic, type, message definition) of a connection record."""
    meta = Header.read(io.BytesIO(len(data).to_bytes(4, "little") + data))   # its fields, unprefixed
    return header.get_string("topic"), meta.get_string("type"), meta.get_string("message_definition")


class Bag1Scan(_Bag1):
    """A ROS 1 bag read by a linear scan (a LogSource)."""

    def __init__(self, path: Path, reason: str) -> None:
        super().__init__(str(path))
        self._path = path
        for conn, stamp, _ in self._messages(None):
            self._counts[conn] += 1
            lo, hi = self._spans.get(conn, (stamp, stamp))
            self._spans[conn] = (min(lo, stamp), max(hi, stamp))
        if not self._counts:
            lost = "".join(f"; {k}" for k in self._skipped)
            raise ReadError(f"cannot read file: {reason}; no complete message found by a linear scan{lost}", self.name,
                            "the bag is empty or damaged; try `rosbag reindex` (ROS 1)")
        self._span = (min(lo for lo, _ in self._spans.values()), max(hi for _, hi in self._spans.values()))
        self._notes = (f"{self.name} has no usable index ({reason}); read by a linear scan of its records",)

    def _messages(self, conns: set[int] | None) -> Iterator[tuple[int, int, bytes]]:
        """(connection id, log time [ns], raw message) in file order; registers connections."""
        with open_clamped(self._path) as f:
            if f.read(len(_MAGIC)) != _MAGIC:
                raise ReadError("not a ROS 1 bag (wrong magic)", self.name, "check the file")
            yield from self._walk(self._records(f), conns)


class Bag1Index(_Bag1):
    """An indexed ROS 1 bag read by byte range (a LogSource on a :class:`.remote.RemoteObject`):
    the bag header record, then the index it points at (connection records and chunk infos, one
    request), then only the chunks holding the connections read, each with the index data records
    that follow it (:meth:`.remote.RemoteObject.ranges`). Counts and the log-time span come from the
    chunk infos, as rosbags takes them; messages come sorted by log time as rosbags yields them.

    :func:`indexed` says whether an object can be read so; one that cannot (never indexed, cut
    short, a damaged index) is downloaded and read like a local file."""

    def __init__(self, obj: RemoteObject, index_pos: int, chunk_infos: list[tuple[int, int, int, dict[int, int]]],
                 conns: dict[int, tuple[str, str, str]]) -> None:
        super().__init__(obj.url)
        self._obj = obj
        self._conns = dict(conns)
        self._infos = chunk_infos                   # (position [B], start, end [ns], {connection: count})
        ends = sorted({pos for pos, *_ in chunk_infos} | {index_pos})
        self._extent = dict(zip(ends, ends[1:], strict=False))   # a chunk and its index data: to the next
        for _, _, _, counts in chunk_infos:
            self._counts.update(counts)
        timed = [(start, end) for _, start, end, counts in chunk_infos if any(counts.values())]
        self._span = (min(s for s, _ in timed), max(e for _, e in timed)) if timed else None

    def _messages(self, conns: set[int] | None) -> Iterator[tuple[int, int, bytes]]:
        """The messages of the chunks holding ``conns``, in order of log time (file order among equal times)."""
        yield from self._in_chunks(sorted(pos for pos, _, _, counts in self._infos
                                          if conns is None or any(counts.get(c) for c in conns)), conns)

    def topic_spans(self) -> dict[str, tuple[int, int]]:
        """Each topic's first and last log time [ns], exact as a local read's: from the first and the last chunk
        holding each connection (by the chunk infos' times), read by range; the other chunks are not fetched."""
        ends: dict[int, tuple[tuple[int, int], tuple[int, int]]] = {}     # id → ((start, pos), (end, pos))
        for pos, start, end, counts in self._infos:
            for cid in (c for c, n in counts.items() if n):
                first, last = ends.get(cid, ((start, pos), (end, pos)))
                ends[cid] = (min(first, (start, pos)), max(last, (end, pos)))
        if not self._spans and ends:
            for conn, stamp, _ in self._in_chunks(sorted({p for (_, a), (_, b) in ends.values() for p in (a, b)}),
                                                  None):
                lo, hi = self._spans.get(conn, (stamp, stamp))
                self._spans[conn] = (min(lo, stamp), max(hi, stamp))
        return super().topic_spans()

    def _in_chunks(self, chunks: list[int], conns: set[int] | None) -> Iterator[tuple[int, int, bytes]]:
        """The messages of ``conns`` (None: all) in the chunks at ``chunks`` (file positions, ascending), in order
        of log time."""
        found: list[tuple[int, int, int, bytes]] = []
        with self._obj.ranges([(pos, self._extent[pos] - pos) for pos in chunks]) as ranges:
            for pos in chunks:
                records = self._records(io.BytesIO(ranges.view(pos, self._extent[pos] - pos)))
                chunk = next(records, None)             # the chunk record; the index data after it is not needed
                if chunk is None or chunk[0].get("op") != bytes([RecordType.CHUNK]):
                    raise ReadError(f"the bag's index points at byte {pos}, which holds no chunk", self.name,
                                    "the bag is damaged; try `rosbag reindex` (ROS 1)")
                found += ((stamp, len(found) + k, conn, raw)
                          for k, (conn, stamp, raw) in enumerate(self._walk(iter([chunk]), conns)))
        found.sort(key=lambda m: m[:2])
        for stamp, _, conn, raw in found:
            yield conn, stamp, raw


def indexed(obj: RemoteObject) -> Bag1Index | str:
    """The ROS 1 bag ``obj`` read by byte range (:class:`Bag1Index`), or why it cannot be: no index
    (the recorder never wrote one), an index past the object's end (cut short), or a damaged one.
    Asks for the bag header (already held from detecting the format) and the index."""
    f: BinaryIO = obj.file()     # type: ignore[assignment]
    try:
        if f.read(len(_MAGIC)) != _MAGIC:
            return "not a ROS 1 bag (wrong magic)"
        header = Header.read(f, RecordType.BAGHEADER)
        index_pos, n_conns, n_chunks = (header.get_uint64("index_pos"), header.get_uint32("conn_count"),
                                        header.get_uint32("chunk_count"))
        if header.get("encryptor"):
            return "an encrypted bag"
    except _ERRORS:
        return "a damaged bag header"
    if index_pos == 0:
        return "it was never indexed"
    if not f.tell() <= index_pos < obj.size:
        return f"its index at byte {index_pos} lies past the end of the object ({obj.size} bytes)"
    index = io.BytesIO(obj.read_at(index_pos, obj.size - index_pos))   # what the tail held, else one request
    conns: dict[int, tuple[str, str, str]] = {}
    infos: list[tuple[int, int, int, dict[int, int]]] = []
    try:
        for _ in range(n_conns):
            head = Header.read(index, RecordType.CONNECTION)
            conns[head.get_uint32("conn")] = _connection(head, index.read(read_uint32(index)))
        for _ in range(n_chunks):
            head = Header.read(index, RecordType.CHUNK_INFO)
            data = index.read(read_uint32(index))
            count = head.get_uint32("count")
            if head.get_uint32("ver") != 1 or len(data) != 8 * count:
                return "a damaged index (chunk info)"
            pairs = [int.from_bytes(data[k:k + 4], "little") for k in range(0, len(data), 4)]
            infos.append((head.get_uint64("chunk_pos"), head.get_time("start_time") if count else 0,
                          head.get_time("end_time") if count else 0, dict(zip(pairs[::2], pairs[1::2], strict=True))))
    except _ERRORS:
        return "a damaged index"
    if any(not len(_MAGIC) < pos < index_pos for pos, *_ in infos):
        return "a damaged index (a chunk outside the bag's data)"
    return Bag1Index(obj, index_pos, infos, conns)


def _decompress(compression: str, data: bytes, size: int) -> bytes:
    """A chunk's records (``size`` [B] declared); of a chunk cut off, as much as its complete
    compressed blocks give. ChunkError past ``size`` or :data:`.common.CHUNK_LIMIT`."""
    if compression not in ("none", "bz2", "lz4"):
        raise ReaderError(f"unsupported chunk compression {compression!r}")
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
