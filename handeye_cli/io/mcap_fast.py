"""Fast path for pose topics of an indexed MCAP: chunks and message indexes read directly, CDR decoded with numpy.

For each chunk (from the summary's ChunkIndex records) holding a wanted channel: its MessageIndex
records give the offsets of the wanted messages inside the uncompressed chunk; the chunk is
decompressed (``zstandard`` streaming, stopping after the last wanted message; ``lz4``; or
none) and the messages' CDR payloads are decoded at computed offsets, vectorised over the chunk:
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

import struct
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import lz4.frame  # type: ignore[import-untyped]
import numpy as np
import zstandard
from numpy.typing import NDArray

from .messages import LISTS, SPECS

__all__ = ["FastPoses", "FastTopics", "read_fast", "FAST_TYPES"]

FAST_TYPES = frozenset(t for t, s in SPECS.items() if s.cdr_child is not None) | frozenset(
    t for t, (_, element) in LISTS.items() if SPECS[element].cdr_child)
_R = {n: np.arange(n) for n in (4, 56)}
_U64 = struct.Struct("<Q")
_MSG_HEADER = 31        # opcode 1 + length 8 + channel 2 + sequence 4 + log time 8 + publish time 8


class _Decline(Exception):
    """The fast path cannot decode this exactly; the generic reader takes over."""


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
def _u32(u: NDArray[np.uint8], at: NDArray[np.int64]) -> NDArray[np.int64]:
    return np.asarray(u[at[:, None] + _R[4]].view("<u4")[:, 0], dtype=np.int64)


def _i32(u: NDArray[np.uint8], at: NDArray[np.int64]) -> NDArray[np.int64]:
    return np.asarray(u[at[:, None] + _R[4]].view("<i4")[:, 0], dtype=np.int64)


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
    values = u[pos[:, None] + _R[56]].view("<f8")
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
    """(code per string, distinct strings) of the strings at ``start`` of ``length`` bytes."""
    width = int(length.max(initial=0))
    if width == 0:
        return np.zeros(len(start), np.intp), [""]
    cols = np.arange(width)
    if (length == width).all():         # the usual case: one frame id throughout, checked byte by byte
        mat = u[start[:, None] + cols]
        if (mat == mat[0]).all():
            try:
                return np.zeros(len(start), np.intp), [bytes(mat[0]).decode()]
            except UnicodeDecodeError as exc:
                raise _Decline("frame id is not UTF-8") from exc
    mat = np.where(cols < length[:, None], u[np.minimum(start[:, None] + cols, len(u) - 1)], 0).astype(np.uint8)
    rows, codes = np.unique(mat, axis=0, return_inverse=True)
    try:
        return codes.ravel(), [bytes(r).rstrip(b"\0").decode() for r in rows]
    except UnicodeDecodeError as exc:
        raise _Decline("frame id is not UTF-8") from exc


# --- chunks and message indexes ---------------------------------------------------------------
def _message_index(blob: bytes, wanted: set[int]) -> list[tuple[int, NDArray[np.uint64]]]:
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


def _read_to(reader: Any, size: int, raw: bytes) -> bytes:
    """``raw`` extended from the streaming ``reader`` to at least ``size`` bytes (fewer at the end)."""
    while len(raw) < size:
        more = reader.read(size - len(raw))
        if not more:
            break
        raw += more
    return raw


def _chunk_data(f: Any, index: Any, last: int) -> NDArray[np.uint8]:
    """The uncompressed records of the chunk at ``index``, at least through the message record at
    offset ``last``. A zstd chunk whose wanted messages end early is decompressed only that far
    (streaming); otherwise the whole chunk is decompressed and its CRC checked."""
    f.seek(index.chunk_start_offset + 9 + 8 + 8 + 8)
    crc = int.from_bytes(f.read(4), "little")
    n = int.from_bytes(f.read(4), "little")
    compression = f.read(n).decode()
    size = int.from_bytes(f.read(8), "little")
    data = f.read(size)
    total = index.uncompressed_size
    if len(data) != size:
        raise _Decline("chunk cut off")
    if compression == "zstd" and last < total // 2:
        with zstandard.ZstdDecompressor().stream_reader(data) as r:
            raw = _read_to(r, last + 9, b"")
            if len(raw) < last + 9:
                raise _Decline("index beyond chunk")
            return np.frombuffer(_read_to(r, last + 9 + _U64.unpack_from(raw, last + 1)[0], raw), np.uint8)
    if compression == "":
        raw = data
    elif compression == "zstd":
        raw = zstandard.ZstdDecompressor().decompress(data, max_output_size=total)
    elif compression == "lz4":
        raw = lz4.frame.decompress(data)
    else:
        raise _Decline(f"compression {compression!r}")
    if crc and zlib.crc32(raw) != crc:
        raise _Decline("chunk CRC mismatch")
    return np.frombuffer(raw, np.uint8)


class _Collect:
    """One topic's decoded chunks, joined at the end; (frame, child) pairs numbered across chunks."""

    def __init__(self) -> None:
        self.stamps: list[NDArray[np.int64]] = []
        self.values: list[NDArray[np.float64]] = []
        self.pairs: list[NDArray[np.intp]] = []
        self.names: dict[tuple[str, str], int] = {}

    def add(self, u: NDArray[np.uint8], parts: list[tuple[Any, ...]], log_times: NDArray[np.int64], log: bool) -> None:
        msg = np.concatenate([p[0] for p in parts])
        elem = np.concatenate([np.full(len(p[0]), k) for k, p in enumerate(parts)])
        order = np.lexsort((elem, msg))          # message order, then element order within a message
        col = [np.concatenate([p[j] for p in parts])[order] for j in range(1, 7)]
        stamp, fs, fl, cs, cl, values = col
        fcode, fnames = _names(u, fs, fl)
        ccode, cnames = _names(u, cs, cl)
        local = [self.names.setdefault((fnames[a], cnames[b]), len(self.names))
                 for a, b in zip(*np.divmod(np.arange(len(fnames) * len(cnames)), len(cnames)), strict=True)]
        self.pairs.append(np.asarray(local, np.intp)[fcode * len(cnames) + ccode])
        self.stamps.append(log_times[msg[order]] if log else stamp)
        self.values.append(values)

    def result(self) -> FastPoses:
        pair = np.concatenate(self.pairs)
        ids, first = np.unique(pair, return_index=True)
        used = ids[np.argsort(first)].tolist()             # pairs in order of first appearance
        remap = np.zeros(len(self.names), np.intp)
        remap[used] = np.arange(len(used))
        names = list(self.names)
        return FastPoses(np.concatenate(self.stamps), np.concatenate(self.values), remap[pair],
                         [names[k] for k in used])


def read_fast(path: Path, chunks: Sequence[Any], channels: dict[int, tuple[str, str]], *,
              log_time: bool = False) -> FastTopics:
    """Pose records of the channels ``{id: (topic, type)}`` whose type is in :data:`FAST_TYPES`
    (header stamps, or log times with ``log_time``); topics it cannot decode exactly are left out."""
    wanted = {cid: tt for cid, tt in channels.items() if tt[1] in FAST_TYPES}
    types = {topic: {t for tp, t in wanted.values() if tp == topic} for topic, _ in wanted.values()}
    wanted = {cid: tt for cid, tt in wanted.items() if len(types[tt[0]]) == 1}
    collect: dict[str, _Collect] = {}
    declined: set[str] = set()
    with open(path, "rb") as f:
        for index in chunks:
            cids = set(index.message_index_offsets) & set(wanted)
            if not cids:
                continue
            f.seek(index.chunk_start_offset + index.chunk_length)
            try:
                entries = _message_index(f.read(index.message_index_length), cids)
                if not entries:
                    continue
                u = _chunk_data(f, index, max(int(e[:, 1].max()) for _, e in entries))
            except (_Decline, zstandard.ZstdError, RuntimeError, struct.error, ValueError):
                return {}
            for topic in {wanted[c][0] for c, _ in entries} - declined:
                rows = np.concatenate([e for c, e in entries if wanted[c][0] == topic])
                rows = rows[np.argsort(rows[:, 1], kind="stable")]
                off = rows[:, 1].astype(np.int64)
                try:
                    if (off + _MSG_HEADER > len(u)).any() or (u[off] != 0x05).any():
                        raise _Decline("message index does not point at messages")
                    length = u[off[:, None] + np.arange(1, 9)].view("<u8")[:, 0].astype(np.int64)
                    end = off + 9 + length
                    _check(end, np.full_like(end, len(u)))
                    parts = _decode(u, off + _MSG_HEADER, end, wanted[next(iter(
                        c for c in cids if wanted[c][0] == topic))][1])
                    collect.setdefault(topic, _Collect()).add(u, parts, rows[:, 0].astype(np.int64), log_time)
                except (_Decline, IndexError):
                    declined.add(topic)
                    collect.pop(topic, None)
    return {topic: c.result() for topic, c in collect.items() if topic not in declined}
