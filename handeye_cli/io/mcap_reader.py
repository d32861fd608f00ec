"""MCAP files. ``mcap`` reads the summary (topics, types, counts) of every complete file.

Pose topics of an indexed file are read by the fast path (:mod:`.mcap_fast`: chunk-level
decompression, message indexes, CDR decoded with numpy). Otherwise messages of a pure ROS 2 file
(profile ``ros2``, CDR channels, ``ros2msg``/``ros2idl`` schemas) are read through rosbags'
AnyReader, and anything else (Foxglove JSON channels, ROS 1 profile, mixed encodings) with
``mcap``, decoding CDR / ROS 1 with a rosbags typestore built from the file's schemas and JSON
with ``json``. Either way only the chunks holding the selected topics are read, in file order
(stamps are sorted afterwards).

A file without a usable summary — written without one, with no Statistics record, or cut off by
a crash (no footer, cut mid-chunk) — is scanned linearly with ``mcap``'s StreamReader: every
intact message is read, and a cut-off file sets ``truncated`` (the readers then warn how many
messages were recovered). Only a file with nothing readable is an error.
"""
from __future__ import annotations

import io
import json
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO

from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Footer, Message, Schema
from mcap.stream_reader import StreamReader, breakup_chunk

from ..errors import ReadError
from .common import CHUNK_LIMIT, ChunkError, decode_errors, inflate, open_clamped, unreadable
from .mcap_fast import FastTopics, message_index, read_fast
from .messages import normalize_type, pose_decoder
from .remote import RemoteObject
from .source import Decoder, TopicInfo, spans_by_topic

if TYPE_CHECKING:
    from .rosbag_reader import BagSource

__all__ = ["McapSource"]

_IDL_SEP = "=" * 80 + "\n"
_RECOVER = "if the recording was cut off, repair it with `mcap recover FILE -o fixed.mcap`"
_ROS2_SCHEMAS = ("ros2msg", "ros2idl", "omgidl")


class McapSource:
    """An open MCAP file (use as a context manager), local or a remote object read by byte range
    (:class:`.remote.RemoteObject`: the footer, the summary, then only the chunks holding the topics
    read; rosbags, which needs a path, is not used for it). Message types are normalised to ``pkg/msg/T``.

    ``truncated``: the file ends before its footer (a crashed recording); ``fast=False`` disables
    the numpy fast path (tests compare both paths). Chunks are decompressed by
    :func:`.common.inflate`, never past their declared size nor :data:`.common.CHUNK_LIMIT`: a chunk
    beyond either is skipped, its messages lost, with a line in ``notes``.
    """

    _schemas: dict[int, Schema]
    _channels: dict[int, Channel]
    _counts: dict[int, int]
    _span: tuple[int, int] | None
    _channel_spans: dict[int, tuple[int, int]]     # of a scanned file (an indexed one reads its message indexes)

    def __init__(self, path: Path | RemoteObject, *, fast: bool = True) -> None:
        self.name = path.url if isinstance(path, RemoteObject) else str(path)
        self._path = path
        self._fast = fast
        self.truncated = False
        self._skipped: dict[str, None] = {}     # one line per chunk skipped (see :meth:`_chunk_records`)
        self._notes: tuple[str, ...] = ()
        self._bag: BagSource | None = None      # AnyReader on this file, opened by the first read()
        summary, profile = None, ""
        try:
            with self._open() as f:
                reader = make_reader(f)
                profile = reader.get_header().profile
                summary = reader.get_summary()
        except decode_errors():
            summary = None
        if summary is not None and summary.statistics is not None:
            self._schemas, self._channels = summary.schemas, summary.channels
            self._counts = dict(summary.statistics.channel_message_counts)
            st = summary.statistics
            self._span = (st.message_start_time, st.message_end_time) if st.message_count else None
            self._chunks = list(summary.chunk_indexes)
            self._indexed = True
            self._channel_spans = {}
        else:
            self._scan_index()
        self._ros2 = (self._indexed and profile == "ros2" and isinstance(path, Path)
                      and all(ch.message_encoding == "cdr" for ch in self._channels.values())
                      and all(sc.encoding in _ROS2_SCHEMAS for sc in self._schemas.values()))

    def _open(self) -> BinaryIO:
        """The file, opened for reading: local reads clamped to its size, a remote object read by range."""
        if isinstance(self._path, RemoteObject):
            return self._path.file()     # type: ignore[return-value]
        return open_clamped(self._path)

    def _records(self) -> Iterator[Any]:
        """Every record of a linear scan; at the first damaged or cut-off one, the intact records of
        a chunk cut in the middle are salvaged and the scan stops (``truncated`` set)."""
        with self._open() as f:
            end_of_last = f.tell()
            try:
                for record in StreamReader(f, emit_chunks=True, record_size_limit=None).records:
                    if isinstance(record, Chunk):
                        yield from self._chunk_records(record, end_of_last)
                    else:
                        yield record
                    if isinstance(record, Footer):
                        return
                    end_of_last = f.tell()
            except decode_errors():
                self.truncated = True
                f.seek(end_of_last)
                yield from _salvage_chunk(f)

    @property
    def notes(self) -> tuple[str, ...]:
        """Warnings for every stream read: the opener's (see :mod:`.opening`), then the
        chunks skipped so far."""
        return (*self._notes, *self._skipped)

    @notes.setter
    def notes(self, value: Sequence[str]) -> None:
        self._notes = tuple(v for v in value if v not in self._skipped)

    def _chunk_records(self, chunk: Chunk, offset: int) -> list[Any]:
        """The records of ``chunk`` (the Chunk record at byte ``offset``), or none, with a line in
        :attr:`notes`, when it cannot be decompressed within its bounds."""
        try:
            data = inflate(chunk.compression, chunk.data, chunk.uncompressed_size)
        except ChunkError as exc:
            self._skipped[f"skipped the chunk at byte {offset} of {self.name}: {exc}; its messages are lost"] = None
            return []
        return breakup_chunk(replace(chunk, compression="", data=data))


    def _scan_index(self) -> None:
        """Schemas, channels, counts and span by a linear scan (no usable summary section)."""
        self._schemas, self._channels = {}, {}
        counts: Counter[int] = Counter()
        spans: dict[int, tuple[int, int]] = {}
        with unreadable(self.name, _RECOVER):
            for record in self._records():
                if isinstance(record, Message):
                    counts[record.channel_id] += 1
                    lo, hi = spans.get(record.channel_id, (record.log_time, record.log_time))
                    spans[record.channel_id] = (min(lo, record.log_time), max(hi, record.log_time))
                elif isinstance(record, Schema):
                    self._schemas[record.id] = record
                elif isinstance(record, Channel):
                    self._channels[record.id] = record
        if self._skipped and not counts:
            raise ReadError(f"cannot read file: no message outside the chunks skipped ({next(iter(self._skipped))})",
                            self.name, "the file is damaged or hostile; re-record or re-export it")
        if self.truncated and not counts:
            raise ReadError("cannot read file: the MCAP is cut off before its first complete message",
                            self.name, _RECOVER)
        self._counts, self._chunks, self._indexed, self._channel_spans = dict(counts), [], False, spans
        self._span = (min(lo for lo, _ in spans.values()), max(hi for _, hi in spans.values())) if spans else None

    def __enter__(self) -> McapSource:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._bag is not None:
            self._bag.__exit__(*exc)

    def _schema_name(self, channel: Any) -> str:
        schema = self._schemas.get(channel.schema_id)
        return normalize_type(schema.name) if schema is not None else ""

    def topics(self) -> list[TopicInfo]:
        rows: dict[str, TopicInfo] = {}
        for cid, ch in self._channels.items():
            n = self._counts.get(cid, 0)
            old = rows.get(ch.topic)
            rows[ch.topic] = (TopicInfo(ch.topic, self._schema_name(ch), ch.message_encoding, n) if old is None
                              else TopicInfo(ch.topic, old.msgtype, old.encoding, old.count + n))
        return list(rows.values())

    def span(self) -> tuple[int, int] | None:
        return self._span

    def topic_spans(self) -> dict[str, tuple[int, int]]:
        """Of a scanned file, what the scan saw; of an indexed one, from the MessageIndex records of
        the chunks that hold each channel's first and last messages (one read of a chunk's message
        indexes, which follow it, serves every channel; no chunk decompressed). A topic with a channel
        the indexes do not cover is left out."""
        spans = dict(self._channel_spans)
        if self._indexed:
            read: dict[int, dict[int, tuple[int, int]]] = {}
            with self._open() as f, unreadable(self.name):
                def times(ix: Any) -> dict[int, tuple[int, int]]:
                    if ix.chunk_start_offset not in read:
                        f.seek(ix.chunk_start_offset + ix.chunk_length)
                        try:
                            entries = message_index(memoryview(f.read(ix.message_index_length)),
                                                    set(ix.message_index_offsets))
                        except ValueError:      # an index record past its section: no times from it
                            entries = []
                        read[ix.chunk_start_offset] = {cid: (int(r[:, 0].min()), int(r[:, 0].max()))
                                                       for cid, r in entries}
                    return read[ix.chunk_start_offset]

                for cid in self._channels:
                    chunks = [ix for ix in self._chunks if cid in ix.message_index_offsets]
                    first, last = _edge_time(chunks, cid, times), _edge_time(chunks, cid, times, last=True)
                    if first is not None and last is not None:
                        spans[cid] = (first, -last)
        out = spans_by_topic((self._channels[cid].topic, span) for cid, span in spans.items() if cid in self._channels)
        unknown = {ch.topic for cid, ch in self._channels.items() if cid not in spans and self._counts.get(cid)}
        return {topic: span for topic, span in out.items() if topic not in unknown}

    def read_fast(self, topics: Sequence[str], time_source: str) -> FastTopics:
        """Pose arrays of the ``topics`` the numpy fast path can decode (little-endian CDR of the
        fixed-layout ROS 2 pose types in an indexed file), stamped by ``time_source`` (``header``
        or ``log``); the rest is left to :meth:`read`."""
        if not (self._fast and self._indexed):
            return {}
        wanted = {cid: (ch.topic, self._schema_name(ch)) for cid, ch in self._channels.items()
                  if ch.topic in topics and ch.message_encoding == "cdr"}
        skipped: list[tuple[int, str]] = []
        with unreadable(self.name):
            out = read_fast(self._path, self._chunks, wanted, log_time=time_source == "log", skipped=skipped)
        for offset, reason in skipped:
            self._skipped[f"skipped the chunk at byte {offset} of {self.name}: {reason}; its messages are lost"] = None
        return out

    def _decoder(self, channel: Any) -> Decoder:
        from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

        schema = self._schemas.get(channel.schema_id)
        name = self._schema_name(channel)
        enc = channel.message_encoding
        if enc == "json":
            return pose_decoder(name, json.loads)
        if enc not in ("cdr", "ros1") or schema is None:
            raise ReadError(f"unsupported message encoding {enc!r}", f"{self.name}:{channel.topic}",
                            "handeye reads CDR, ROS 1 and JSON channels")
        store = get_typestore(Stores.EMPTY)
        text = schema.data.decode()
        if schema.encoding == "ros2idl":
            blocks = text.split(_IDL_SEP)[1:] if text.startswith(f"{_IDL_SEP}IDL: ") else [f"\n{text}"]
            for block in blocks:
                store.register(get_types_from_idl(block.split("\n", 1)[1]))
        else:
            store.register(get_types_from_msg(text, name))
        if enc == "cdr":
            return pose_decoder(name, lambda b: store.deserialize_cdr(b, name), cdr=True)
        return pose_decoder(name, lambda b: store.deserialize_ros1(b, name))

    def read(self, topics: Sequence[str]) -> Iterator[tuple[str, int, bytes, Decoder]]:
        if self._skipped or any(ix.uncompressed_size > CHUNK_LIMIT for ix in self._chunks):
            self._ros2 = False      # rosbags cannot skip a chunk: its read would end at the bomb
        if self._ros2 and self._bag is None:
            from .rosbag_reader import BagSource

            assert isinstance(self._path, Path), "rosbags reads local files only (see __init__)"
            try:
                self._bag = BagSource([self._path], ".mcap")
            except ReadError:        # e.g. a schema rosbags cannot parse: use mcap below
                self._ros2 = False
        if self._bag is not None:
            yield from self._bag.read(topics)
            return
        with unreadable(self.name):
            decoders = {cid: self._decoder(ch) for cid, ch in self._channels.items() if ch.topic in topics}
        with unreadable(self.name):
            for record in self._records() if not self._chunks else self._indexed_records(set(decoders)):
                if isinstance(record, Message) and record.channel_id in decoders:
                    yield (self._channels[record.channel_id].topic, record.log_time, record.data,
                           decoders[record.channel_id])

    def _indexed_records(self, channels: set[int]) -> Iterator[Any]:
        """The records of the chunks that may hold messages of ``channels``, in file order."""
        with self._open() as f:
            for index in self._chunks:
                if index.message_index_offsets and not channels & set(index.message_index_offsets):
                    continue
                f.seek(index.chunk_start_offset + 9)
                yield from self._chunk_records(Chunk.read(ReadDataStream(f)), index.chunk_start_offset)


def _edge_time(chunks: list[Any], cid: int, times: Callable[[Any], dict[int, tuple[int, int]]], *,
               last: bool = False) -> int | None:
    """The first log time [ns] of channel ``cid`` in ``chunks`` (the chunk indexes holding it), or
    minus the last one with ``last``: ``times(chunk)`` (the chunk's (first, last) per channel) asked
    in order of the chunks' start (end) time until no later chunk can hold an earlier (later)
    message. None when the indexes list none (a damaged index: the topic is then rated over the
    log's span)."""
    def bound(ix: Any) -> int:
        return -int(ix.message_end_time) if last else int(ix.message_start_time)

    best: int | None = None
    for ix in sorted(chunks, key=bound):
        if best is not None and bound(ix) > best:
            break
        if cid in (got := times(ix)):
            edge = -got[cid][1] if last else got[cid][0]
            best = edge if best is None else min(best, edge)
    return best


def _salvage_chunk(f: BinaryIO) -> Iterator[Any]:
    """The complete records inside a Chunk record cut off at the position of ``f`` (zstd, lz4 or
    uncompressed: decompressed as far as the bytes go, within the size it declares); nothing if
    no chunk starts there."""
    head = f.read(41)
    if len(head) < 41 or head[0] != 0x06:
        return
    n = int.from_bytes(head[37:41], "little")
    compression = f.read(n).decode(errors="replace")
    f.read(8)
    try:
        data = inflate(compression, f.read(), int.from_bytes(head[25:33], "little"), partial=True)
        yield from StreamReader(io.BytesIO(data), skip_magic=True).records
    except decode_errors():
        return
