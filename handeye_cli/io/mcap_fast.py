"""Fast path for pose topics of an indexed MCAP: chunks and message indexes read directly, CDR decoded with numpy.

For each chunk (from the summary's ChunkIndex records) holding a wanted channel: its MessageIndex
records give the offsets of the wanted messages inside the uncompressed chunk; the chunk is
decompressed only through the last wanted message (zstd; lz4 and uncompressed chunks whole) —
see :class:`_Chunks` — and the wanted messages' CDR payloads are copied out. Each topic's payloads
are decoded :data:`_BATCH` messages at a time at computed offsets, vectorised:
``PoseStamped``, ``PoseWithCovarianceStamped`` (header, then 7 doubles), ``TransformStamped``,
``Odometry`` (header, child_frame_id, 7 doubles) and ``TFMessage`` (a sequence of
TransformStamped, handled one element index at a time). Strings (frame ids) vary in length, so
every offset after one is computed per message. Little-endian plain CDR only: a big-endian or
malformed payload, an unknown compression or a damaged index makes :func:`read_fast` leave that
topic (or the file) to the generic reader, which decodes — or reports — every message.

Layout facts: a Message record is opcode 0x05, uint64 length, uint16 channel id, uint32 sequence,
uint64 log time, uint64 publish time, data; CDR alignment is relative to the end of the 4-byte
encapsulation header.
"""
from __future__ import annotations

import contextlib
import mmap
import struct
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import zstandard
from numpy.typing import NDArray

from .common import ChunkError, check_declared, inflate
from .messages import LISTS, SPECS
from .remote import RemoteObject

__all__ = ["FastPoses", "FastTopics", "read_fast", "FAST_TYPES"]

FAST_TYPES = frozenset(t for t, s in SPECS.items() if s.cdr_child is not None) | frozenset(
    t for t, (_, element) in LISTS.items() if SPECS[element].cdr_child)
_U64 = struct.Struct("<Q")
_MSG_HEADER = 31        # opcode 1 + length 8 + channel 2 + sequence 4 + log time 8 + publish time 8
_BATCH = 1 << 13        # messages of a topic decoded together: few numpy calls, small temporaries


class _Decline(Exception):
    """The fast path cannot decode this exactly; the generic reader takes over."""


_UNDECODABLE = (_Decline, IndexError, ValueError)    # a topic's payloads are not what the layout says


@dataclass(frozen=True)
class FastPoses:
    """Pose records of one topic in file order: ``stamps`` int64 [ns] (header stamp or log time),
    ``values`` float64[N, 7] (x, y, z [m], qx, qy, qz, qw), ``pair`` index into ``pairs``
    (frame_id, child_frame_id) in order of first appearance. Duck-types :class:`.common.PoseBuffer`."""

    stamps: NDArray[np.int64]
    values: NDArray[np.float64]
    pair: NDArray[np.intp]
    pair_names: list[tuple[str, str]]

    @property
    def pairs(self) -> dict[tuple[str, str], None]:
        return dict.fromkeys(self.pair_names)

    def __len__(self) -> int:
        return len(self.stamps)

    def arrays(self) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
        return self.stamps, self.values[:, :3], self.values[:, 3:]

    def of_pair(self, k: int) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        m = self.pair == k
        return self.stamps[m], self.values[m]


FastTopics = dict[str, FastPoses]


# --- CDR at computed offsets ------------------------------------------------------------------
def _at(u: NDArray[np.uint8], at: NDArray[np.int64], n: int) -> NDArray[np.uint8]:
    """The ``n`` bytes at each offset ``at`` as rows (N, n) (IndexError past the end of ``u``):
    indexes rows of a strided view of every n-byte window, not N x n bytes one by one."""
    windows: NDArray[np.uint8] = np.ndarray((len(u) - n + 1, n), np.uint8, u, 0, (1, 1))
    return windows[at]


def _u32(u: NDArray[np.uint8], at: NDArray[np.int64]) -> NDArray[np.int64]:
    return np.asarray(_at(u, at, 4).view("<u4")[:, 0], dtype=np.int64)


def _i32(u: NDArray[np.uint8], at: NDArray[np.int64]) -> NDArray[np.int64]:
    return np.asarray(_at(u, at, 4).view("<i4")[:, 0], dtype=np.int64)


def _align(pos: NDArray[np.int64], base: NDArray[np.int64], k: int) -> NDArray[np.int64]:
    return pos + (-(pos - base)) % k


def _check(pos: NDArray[np.int64], end: NDArray[np.int64]) -> None:
    if (pos > end).any():
        raise _Decline("payload shorter than its layout")


Ints = NDArray[np.int64]


def _string(u: NDArray[np.uint8], at: Ints, end: Ints) -> tuple[Ints, Ints, Ints]:
    """(start, length without the NUL, offset after) of the CDR strings at ``at``."""
    _check(at + 4, end)
    n = _u32(u, at)
    if (n < 1).any():
        raise _Decline("string without terminator")
    _check(at + 4 + n, end)
    return at + 4, n - 1, at + 4 + n


def _transform(u: NDArray[np.uint8], at: NDArray[np.int64], base: NDArray[np.int64], end: NDArray[np.int64],
               child: bool) -> tuple[Any, ...]:
    """Header (stamp, frame_id) [+ child_frame_id] + 7 doubles at ``at``: (stamp_ns, frame start,
    frame length, child start, child length, values (N, 7), offset after)."""
    _check(at + 8, end)
    stamp = _i32(u, at) * 1_000_000_000 + _u32(u, at + 4)
    fs, fl, pos = _string(u, at + 8, end)
    cs, cl = np.zeros_like(at), np.zeros_like(at)
    if child:
        cs, cl, pos = _string(u, _align(pos, base, 4), end)
    pos = _align(pos, base, 8)
    _check(pos + 56, end)
    values = _at(u, pos, 56).view("<f8")
    return stamp, fs, fl, cs, cl, values, pos + 56


def _decode(u: NDArray[np.uint8], o: NDArray[np.int64], end: NDArray[np.int64], msgtype: str) -> list[tuple[Any, ...]]:
    """Per element index: (message index, stamp, frame start/len, child start/len, values) arrays."""
    if ((u[o] != 0) | (u[o + 1] != 1)).any():
        raise _Decline("not little-endian plain CDR")
    base = o + 4
    msg = np.arange(len(o))
    if msgtype in SPECS:
        return [(msg, *_transform(u, base, base, end, bool(SPECS[msgtype].cdr_child))[:6])]
    _check(o + 8, end)
    count, pos, out = _u32(u, base), o + 8, []
    for k in range(int(count.max(initial=0))):
        m = count > k
        *rec, after = _transform(u, _align(pos[m], base[m], 4), base[m], end[m], True)
        pos[m] = after
        out.append((msg[m], *rec))
    return out


def _names(u: NDArray[np.uint8], start: Ints, length: Ints) -> tuple[NDArray[np.intp], list[str]]:
    """(code per string, distinct strings) of the strings at ``start`` of ``length`` bytes. Memory
    and time follow the strings' bytes, not count x longest (one 256 kB frame id among short ones
    once made a dense matrix of gigabytes)."""
    width = int(length.max(initial=0))
    if width == 0:
        return np.zeros(len(start), np.intp), [""]
    try:
        if (length == width).all():         # the usual case: one frame id throughout, checked byte by byte
            mat = _at(u, start, width)
            if (mat == mat[0]).all():
                return np.zeros(len(start), np.intp), [bytes(mat[0]).decode()]
        index: dict[bytes, int] = {}
        codes = np.fromiter((index.setdefault(u[s:s + n].tobytes(), len(index))
                             for s, n in zip(start.tolist(), length.tolist(), strict=True)), np.intp, len(start))
        return codes, [k.decode() for k in index]
    except UnicodeDecodeError as exc:
        raise _Decline("frame id is not UTF-8") from exc


# --- chunks and message indexes ---------------------------------------------------------------
def message_index(blob: memoryview, wanted: set[int]) -> list[tuple[int, NDArray[np.uint64]]]:
    """(channel id, (log_time, offset) pairs) of the MessageIndex records in ``blob`` for ``wanted``."""
    out, i = [], 0
    while i + 9 <= len(blob):
        opcode, (length,) = blob[i], _U64.unpack_from(blob, i + 1)
        body = i + 9
        if opcode == 0x07:
            cid = int.from_bytes(blob[body:body + 2], "little")
            n = int.from_bytes(blob[body + 2:body + 6], "little")
            if cid in wanted and n:
                out.append((cid, np.frombuffer(blob, "<u8", n // 8, body + 6).reshape(-1, 2)))
        i = body + length
    return out


class _Mapped:
    """A local file mapped, not read: a chunk is decompressed straight from the page cache, without
    first copying it (1.6 GB of images cost 0.15 s to copy, more than decompressing them); the
    pages of a chunk leave the process once the next is asked for, so its resident memory holds
    one chunk, not the file; the map dies with this object and the last array viewing it.

    The file is closed as soon as it is mapped (the map holds its own descriptor): no file object
    stays open through the read, so an interrupt (Ctrl-C, a batch's SIGTERM or time limit) at any
    point of it cannot leave one unclosed (a ResourceWarning)."""

    def __init__(self, path: Path) -> None:
        with open(path, "rb") as f:
            self._mm = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
        self._map = memoryview(self._mm)
        self._used = (0, 0)             # the bytes [start, stop) of the last view

    def view(self, start: int, n: int) -> memoryview:
        """The ``n`` bytes [B] from ``start`` (fewer at the end of the file); the last view's pages released."""
        first, stop = self._used
        if stop > first and hasattr(mmap, "MADV_DONTNEED"):
            first -= first % mmap.PAGESIZE
            self._mm.madvise(mmap.MADV_DONTNEED, first, stop - first)
        view = self._map[start:start + n]
        self._used = (start, start + len(view))
        return view


class _Chunks:
    """Chunk records of one open file, read into buffers reused from chunk to chunk: memory holds
    one compressed chunk and its decompressed records through the last wanted message, whatever
    the file's size.

    Chunk record: opcode 0x06, uint64 length, start / end time, uint64 uncompressed size, uint32
    CRC of the uncompressed records, compression string, uint64 size of the records, the records;
    its MessageIndex records follow it directly. A zstd frame cannot be entered in the middle, so
    the prefix through the last wanted message is the least to decompress; what follows it
    (typically images) is decompressed only where doing the whole frame in one pass is cheaper
    (:meth:`_zstd`). The CRC covers the whole chunk: it is checked when the wanted messages run to
    the chunk's end, and not otherwise, where it would cost decompressing and hashing every byte
    of the other topics (more than all the rest of the read on an image-heavy log; ``mcap``'s
    reader checks no CRC by default). A damaged zstd or lz4 stream usually fails to decompress,
    which leaves the file to the generic reader.
    """

    def __init__(self, source: Any) -> None:
        self._source = source           # :class:`_Mapped` (a local file) or :class:`.remote.ranges.Ranges`
        self._raw = bytearray()         # decompressed zstd records

    @staticmethod
    def _grown(buf: bytearray, size: int, keep: int = 0) -> bytearray:
        """``buf``, or a new buffer of ``size`` bytes [B] holding its first ``keep`` bytes if it is smaller."""
        if len(buf) >= size:
            return buf
        new = bytearray(size)
        new[:keep] = memoryview(buf)[:keep]
        return new

    def read(self, index: Any, wanted: set[int]) -> tuple[list[tuple[int, NDArray[np.uint64]]], NDArray[np.uint8]]:
        """(MessageIndex entries of the ``wanted`` channels, the chunk's uncompressed records through
        its last wanted message) of the chunk at ``index``; ``[]`` and no records if none is wanted.
        The records are a view of the file's map or of a reused buffer, valid until the next call."""
        size = index.chunk_length + index.message_index_length
        view = self._source.view(index.chunk_start_offset, size)   # the last call's records are used by now
        if len(view) != size:
            raise _Decline("chunk cut off")
        entries = message_index(view[index.chunk_length:], wanted)
        if not entries:
            return [], np.zeros(0, np.uint8)
        if view[0] != 0x06:
            raise _Decline("chunk index does not point at a chunk")
        check_declared(index.uncompressed_size)
        crc = int.from_bytes(view[33:37], "little")
        n = int.from_bytes(view[37:41], "little")
        compression = bytes(view[41:41 + n]).decode()
        data = view[49 + n:49 + n + _U64.unpack_from(view, 41 + n)[0]]
        last = max(int(e[:, 1].max()) for _, e in entries)
        if last + 9 > index.uncompressed_size:
            raise _Decline("message index beyond the chunk's records")
        if compression == "zstd":
            held = zstandard.frame_content_size(data)      # from the frame header; -1 if it does not say
            if held not in (-1, index.uncompressed_size):
                raise ChunkError(f"the zstd chunk's frame holds {held} bytes, not the {index.uncompressed_size} "
                                 "it declares")
            raw = self._zstd(data, last, index.uncompressed_size)
        elif compression == "lz4":
            raw = memoryview(inflate("lz4", data, index.uncompressed_size))
        elif compression == "":
            raw = data
        else:
            raise _Decline(f"compression {compression!r}")
        if len(raw) < last + 9:
            raise _Decline("message index beyond the chunk's records")
        stop = last + 9 + _U64.unpack_from(raw, last + 1)[0]
        if stop > len(raw):
            raise _Decline("message beyond the chunk's records")
        if stop == index.uncompressed_size and crc and zlib.crc32(raw[:stop]) != crc:
            raise _Decline("chunk CRC mismatch")
        return entries, np.frombuffer(raw[:stop], np.uint8)

    def _zstd(self, data: memoryview, last: int, total: int) -> memoryview:
        """The decompressed records of the zstd frame ``data`` (``total`` bytes [B] uncompressed)
        through the message record at offset ``last`` [B] (all of them if the frame ends first).

        A record in the first half of the frame is streamed to; one in the second half has the
        whole frame decompressed in one pass instead: zstd then writes straight into the buffer,
        not through its window buffer, which is faster per byte (twice as fast on repetitive data
        such as the images of benchmarks/scale.py), so the whole beats a prefix of over half.
        """
        with zstandard.ZstdDecompressor().stream_reader(data, read_size=len(data)) as reader:
            if 2 * last >= total:
                self._raw = self._grown(self._raw, total)
                return memoryview(self._raw)[:self._fill(reader, 0, total)]
            self._raw = self._grown(self._raw, last + _MSG_HEADER)
            done = self._fill(reader, 0, last + 9)
            if done == last + 9:
                stop = min(total, last + 9 + _U64.unpack_from(self._raw, last + 1)[0])
                self._raw = self._grown(self._raw, stop, done)
                done = self._fill(reader, done, stop)
        return memoryview(self._raw)[:done]

    def _fill(self, reader: Any, start: int, stop: int) -> int:
        """Decompressed bytes ``[start, stop)`` read from ``reader`` into the buffer; the offset
        reached [B] (``stop``, or less at the end of the frame)."""
        view = memoryview(self._raw)
        while start < stop and (got := reader.readinto(view[start:stop])):
            start += got
        return start


class _Collect:
    """One topic: its messages' CDR payloads, gathered from chunk after chunk and decoded
    :data:`_BATCH` at a time; (frame, child) pairs numbered across batches."""

    def __init__(self, msgtype: str, log: bool) -> None:
        self.msgtype, self.log = msgtype, log
        self.payloads: list[NDArray[np.uint8]] = []     # gathered, not yet decoded
        self.starts: list[Ints] = []                    # payload offsets in their concatenation [B]
        self.ends: list[Ints] = []
        self.times: list[Ints] = []                     # log times [ns]
        self.queued, self.queued_bytes = 0, 0
        self.stamps: list[Ints] = []
        self.values: list[NDArray[np.float64]] = []
        self.pairs: list[NDArray[np.intp]] = []
        self.names: dict[tuple[str, str], int] = {}

    def feed(self, u: NDArray[np.uint8], off: Ints, log_times: Ints) -> None:
        """Queue the payloads of the Message records at offsets ``off`` [B] (ascending) of ``u``."""
        if (off + _MSG_HEADER > len(u)).any() or (u[off] != 0x05).any():
            raise _Decline("message index does not point at messages")
        n = _at(u, off + 1, 8).view("<u8")[:, 0].astype(np.int64) - (_MSG_HEADER - 9)
        if (n < 4).any() or (off + _MSG_HEADER + n > len(u)).any():
            raise _Decline("message record shorter than its header or past its chunk")
        first = np.cumsum(n) - n                # where each payload goes among the gathered bytes
        if (n == n[0]).all():                   # the usual case: one frame id throughout
            gathered = _at(u, off + _MSG_HEADER, int(n[0])).ravel()
        else:
            gathered = u[np.repeat(off + _MSG_HEADER - first, n) + np.arange(int(n.sum()))]
        self.payloads.append(gathered)
        self.starts.append(self.queued_bytes + first)
        self.ends.append(self.queued_bytes + first + n)
        self.times.append(log_times)
        self.queued += len(off)
        self.queued_bytes += len(gathered)
        if self.queued >= _BATCH:
            self.decode()

    def decode(self) -> None:
        """Decode the queued payloads."""
        if not self.queued:
            return
        u = np.concatenate(self.payloads)
        log_times = np.concatenate(self.times)
        parts = _decode(u, np.concatenate(self.starts), np.concatenate(self.ends), self.msgtype)
        self.payloads, self.starts, self.ends, self.times = [], [], [], []
        self.queued = self.queued_bytes = 0
        msg = np.concatenate([p[0] for p in parts])
        elem = np.concatenate([np.full(len(p[0]), k) for k, p in enumerate(parts)])
        order = np.lexsort((elem, msg))          # message order, then element order within a message
        col = [np.concatenate([p[j] for p in parts])[order] for j in range(1, 7)]
        stamp, fs, fl, cs, cl, values = col
        fcode, fnames = _names(u, fs, fl)
        ccode, cnames = _names(u, cs, cl)
        combos, inverse = np.unique(fcode * len(cnames) + ccode, return_inverse=True)   # the pairs present
        local = [self.names.setdefault((fnames[a], cnames[b]), len(self.names))
                 for a, b in zip(*np.divmod(combos.tolist(), len(cnames)), strict=True)]
        self.pairs.append(np.asarray(local, np.intp)[inverse.ravel()])
        self.stamps.append(log_times[msg[order]] if self.log else stamp)
        self.values.append(values)

    def result(self) -> FastPoses:
        self.decode()
        pair = np.concatenate(self.pairs)
        ids, first = np.unique(pair, return_index=True)
        used = ids[np.argsort(first)].tolist()             # pairs in order of first appearance
        remap = np.zeros(len(self.names), np.intp)
        remap[used] = np.arange(len(used))
        names = list(self.names)
        return FastPoses(np.concatenate(self.stamps), np.concatenate(self.values), remap[pair],
                         [names[k] for k in used])


@contextlib.contextmanager
def _views(path: Path | RemoteObject, planned: list[tuple[int, int]]) -> Iterator[Any]:
    """The chunk views of a local file (mapped) or of a remote object (:meth:`.remote.RemoteObject.ranges`:
    the ``planned`` [(start, length)] ranges fetched in file order, near ones together, a few at once)."""
    if not isinstance(path, Path):
        with path.ranges(planned) as ranges:
            yield ranges
        return
    yield _Mapped(path)


def read_fast(path: Path | RemoteObject, chunks: Sequence[Any], channels: dict[int, tuple[str, str]], *,
              log_time: bool = False, skipped: list[tuple[int, str]] | None = None) -> FastTopics:
    """Pose records of the channels ``{id: (topic, type)}`` whose type is in :data:`FAST_TYPES`
    (header stamps, or log times with ``log_time``) from the local file ``path`` or a remote object
    (only the chunks holding them are fetched); topics it cannot decode exactly are left out.
    A chunk declaring more than :data:`.common.CHUNK_LIMIT` uncompressed, or an lz4 chunk inflating
    past its declared size, is skipped: (its offset [B], why) is appended to ``skipped``."""
    wanted = {cid: tt for cid, tt in channels.items() if tt[1] in FAST_TYPES}
    types = {topic: {t for tp, t in wanted.values() if tp == topic} for topic, _ in wanted.values()}
    wanted = {cid: tt for cid, tt in wanted.items() if len(types[tt[0]]) == 1}
    msgtypes = dict(wanted.values())
    collect: dict[str, _Collect] = {}
    declined: set[str] = set()
    chunks = [ix for ix in chunks if set(ix.message_index_offsets) & set(wanted)]
    planned = [(ix.chunk_start_offset, ix.chunk_length + ix.message_index_length) for ix in chunks]
    with contextlib.ExitStack() as stack:
        try:
            chunk_reader = _Chunks(stack.enter_context(_views(path, planned)))
        except (OSError, ValueError):     # a file that cannot be mapped: the generic reader's
            return {}
        for index in chunks:
            cids = set(index.message_index_offsets) & set(wanted)
            try:
                entries, u = chunk_reader.read(index, cids)
            except ChunkError as exc:
                if skipped is not None:
                    skipped.append((index.chunk_start_offset, str(exc)))
                continue
            except (_Decline, zstandard.ZstdError, struct.error, ValueError):
                return {}
            for topic in {wanted[c][0] for c, _ in entries} - declined:
                rows = np.concatenate([e for c, e in entries if wanted[c][0] == topic])
                rows = rows[np.argsort(rows[:, 1], kind="stable")].astype(np.int64)
                try:
                    collect.setdefault(topic, _Collect(msgtypes[topic], log_time)).feed(u, rows[:, 1], rows[:, 0])
                except _UNDECODABLE:
                    declined.add(topic)
                    del collect[topic]
    out = {}
    for topic, c in collect.items():
        with contextlib.suppress(*_UNDECODABLE):
            out[topic] = c.result()
    return out
