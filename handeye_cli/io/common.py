"""Shared reader plumbing: turning decoder failures into HandEyeErrors, building a PoseStream."""
from __future__ import annotations

import bz2
import functools
import importlib
import io
import json
import os
import sqlite3
import struct
from array import array
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any, BinaryIO

import lz4.frame  # type: ignore[import-untyped]
import numpy as np
import zstandard
from mcap.exceptions import McapError

from ..errors import DataError, HandEyeError, ReadError
from ..streams import PoseStream
from ..untrusted import frame_id_problem
from .messages import BadField

__all__ = ["decode_errors", "corrupt_input", "unreadable", "PoseBuffer", "make_stream", "CHUNK_LIMIT", "ChunkError",
           "check_declared", "inflate", "open_clamped", "Lz4Error"]

CHUNK_LIMIT = 256 * 2**20
"""The most bytes [B] one compressed chunk (MCAP, ROS 1 bag) may decompress to. Recorders write
chunks of 1-4 MiB (MCAP) and 768 kB (ROS 1); a chunk that declares more, or inflates past what it
declares, is damaged or hostile (a 0.3 MB zstd chunk can inflate to 3 GiB), and is skipped or
refused rather than decompressed."""


class ChunkError(ValueError):
    """A chunk that cannot be decompressed within its bounds: it declares more than
    :data:`CHUNK_LIMIT`, inflates past its declared size, or has an unknown compression."""


def check_declared(size: int) -> None:
    """ChunkError if a chunk declaring ``size`` [B] uncompressed is over :data:`CHUNK_LIMIT`."""
    if size > CHUNK_LIMIT:
        raise ChunkError(f"the chunk declares {size} bytes uncompressed, over the {CHUNK_LIMIT >> 20} MiB limit "
                         "(handeye_cli.io.common.CHUNK_LIMIT)")


def inflate(compression: str, data: bytes | memoryview, size: int, *, partial: bool = False) -> bytes:
    """The records [B] in a chunk's compressed ``data`` (``compression``: ``zstd``, ``lz4``, ``bz2``,
    or ``""`` / ``none``), which declares ``size`` [B] uncompressed; never more than ``size`` bytes
    are produced, and ``size`` is at most :data:`CHUNK_LIMIT`. ChunkError if it is larger, if the
    data inflates past it, or for an unknown compression; fewer bytes than declared come back as
    they are (``partial``: data cut off by a crash, decompressed as far as it goes)."""
    check_declared(size)
    if compression in ("", "none"):
        return data if isinstance(data, bytes) else bytes(data)
    if compression == "zstd":
        buf = bytearray(size + 1)
        view, done = memoryview(buf), 0
        with zstandard.ZstdDecompressor().stream_reader(data, read_size=max(1, len(data))) as reader:
            try:
                while done <= size and (got := reader.readinto(view[done:])):
                    done += got
            except zstandard.ZstdError:
                if not partial:
                    raise
        out = bytes(view[:done])
        view.release()
    elif compression in ("lz4", "bz2"):
        try:
            out = _lz4_or_bz2(compression, data, size + 1)
        except (OSError, EOFError, ValueError):
            if not partial:
                raise
            out = b""
    else:
        raise ChunkError(f"unsupported chunk compression {compression!r}")
    if len(out) > size:
        raise ChunkError(f"the {compression} chunk inflates past the {size} bytes it declares")
    return out


class Lz4Error(ValueError):
    """Corrupt lz4 data: lz4 raises a bare RuntimeError for it, which is caught at that one call
    (:func:`inflate`) so that a RuntimeError elsewhere stays a bug, not "cannot read file"."""


def _lz4_or_bz2(compression: str, data: bytes | memoryview, limit: int) -> bytes:
    """At most ``limit`` bytes [B] of the lz4 frame or bz2 stream ``data``; Lz4Error for corrupt lz4 data."""
    if compression == "bz2":
        return bytes(bz2.BZ2Decompressor().decompress(data, max_length=limit))
    try:
        return bytes(lz4.frame.LZ4FrameDecompressor().decompress(data, max_length=limit))
    except RuntimeError as exc:     # lz4's only error type for a damaged frame
        raise Lz4Error(f"corrupt lz4 data: {exc}") from exc


class _Clamped(io.BufferedReader):
    """A binary file whose ``read(n)`` never asks for more than is left in it: a length field
    read from a damaged file (0xFFFFFFF0, 2**63) cannot make a read allocate gigabytes."""

    def __init__(self, raw: io.FileIO) -> None:
        super().__init__(raw)
        self._size = os.fstat(raw.fileno()).st_size

    def read(self, n: int | None = -1) -> bytes:
        if n is not None and n > 0:
            n = min(n, max(0, self._size - self.tell()))
            if n == 0:
                return b""
        return super().read(n)


def open_clamped(path: str | os.PathLike[str]) -> BinaryIO:
    """``path`` opened for reading as a seekable binary file whose reads are clamped to its size."""
    return _Clamped(io.FileIO(path, "rb"))


def _optional_error(module: str, name: str = "ZstdError") -> tuple[type[BaseException], ...]:
    """``module.name`` if that module is installed: a zstd binding's ``ZstdError`` (mcap uses zstandard,
    rosbags compression.zstd or its backport), apsw's ``Error`` (rosbags' SQLite client: a malformed
    ``.db3`` is its ``CorruptError``)."""
    try:
        return (getattr(importlib.import_module(module), name),)
    except (ImportError, AttributeError):
        return ()


@functools.cache
def decode_errors() -> tuple[type[BaseException], ...]:
    """What mcap, rosbags, json, the decompressors and the decoders raise on truncated or corrupt
    input. Not KeyError, IndexError or RuntimeError: raised by handeye's own code they are a bug
    (exit 4), so lz4's bare RuntimeError is caught at its one call and turned into :class:`Lz4Error`,
    and those raised inside mcap's or rosbags' own code are told apart by :func:`corrupt_input`. A
    function, so that rosbags is imported by the readers that use it or on the way to an error, not
    by every run (an MCAP read by the fast path never needs it; importing it costs about 0.05 s of CPU)."""
    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Bag1ReaderError
    from rosbags.rosbag2 import ReaderError as Bag2ReaderError
    from rosbags.serde import SerdeError
    from rosbags.typesys import TypesysError

    zstd_errors = sum(map(_optional_error, ("zstandard", "compression.zstd", "backports.zstd")), ())
    return (McapError, struct.error, OSError, EOFError, AnyReaderError, Bag1ReaderError, Bag2ReaderError,
            SerdeError, TypesysError, UnicodeDecodeError, json.JSONDecodeError, ChunkError, Lz4Error, BadField,
            sqlite3.Error, *_optional_error("apsw", "Error"), *zstd_errors)


_SLIPS = (KeyError, IndexError, AssertionError)
_LIBRARIES = ("mcap", "rosbags")


def _raised_in(exc: BaseException) -> str:
    """The module of the innermost frame of ``exc``'s traceback ("" if none)."""
    tb = exc.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    return "" if tb is None else str(tb.tb_frame.f_globals.get("__name__", ""))


def corrupt_input(exc: BaseException) -> bool:
    """Whether ``exc`` is how a reader's library meets truncated or corrupt input: one of
    :func:`decode_errors`, or a KeyError, IndexError or AssertionError raised inside mcap's or
    rosbags' own code (rosbags checks a bag's index data with ``assert`` and looks a record's
    connection up in a dict). The same three raised by handeye's code — its decoders, the
    decompression rosbags calls back into — are a bug (exit 4)."""
    if isinstance(exc, decode_errors()):
        return True
    return isinstance(exc, _SLIPS) and _raised_in(exc).partition(".")[0] in _LIBRARIES


@contextmanager
def unreadable(where: str, fix: str = "check that the file is complete and of a supported "
                                       "format (handeye inspect FILE)") -> Iterator[None]:
    """Convert a decoder failure inside the block (:func:`corrupt_input`) into a ReadError about ``where``."""
    try:
        yield
    except HandEyeError:
        raise
    except Exception as exc:
        if not corrupt_input(exc):
            raise
        detail = str(exc) or f"in {_raised_in(exc)}"     # rosbags' bare assert on an index
        raise ReadError(f"cannot read file: {type(exc).__name__}: {detail}", where, fix) from exc


class PoseBuffer:
    """Growable columns of pose records, without keeping per-message objects alive.

    ``where`` (record index → text such as "message 17") names bad samples in errors.
    """

    def __init__(self) -> None:
        self.stamps = array("q")
        self.values = array("d")
        self.pairs: dict[tuple[str, str], None] = {}    # (frame, child) pairs seen, in order
        self._last: tuple[Any, ...] = ()

    def add(self, records: Sequence[tuple[Any, ...]]) -> None:
        """Append pose records ``(stamp_ns, frame, child, x, y, z, qx, qy, qz, qw)``."""
        for rec in records:
            self.stamps.append(rec[0])
            self.values.extend(rec[3:])
            if rec[1:3] != self._last:
                self._last = rec[1:3]
                self.pairs[(rec[1], rec[2])] = None

    def add_arrays(self, pair: tuple[str, str], stamps: np.ndarray, values: np.ndarray) -> None:
        """Append int64 stamps [ns] and (N, 7) values (x, y, z, qx, qy, qz, qw) of one (frame, child) pair."""
        self.stamps.frombytes(np.ascontiguousarray(stamps, dtype=np.int64).tobytes())
        self.values.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
        if len(stamps):
            self._last = pair
            self.pairs[pair] = None

    def __len__(self) -> int:
        return len(self.stamps)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(stamps int64[N], xyz float64[N, 3], quat_xyzw float64[N, 4])."""
        v = np.frombuffer(self.values, dtype=np.float64).reshape(-1, 7)
        return np.frombuffer(self.stamps, dtype=np.int64).copy(), v[:, :3].copy(), v[:, 3:].copy()


_MAX_POSITION_M = 1e8        # |x| beyond this is a corrupt sample, not a position
_MIN_JUMP_NS = 500_000_000   # a backward step shorter than this (or 10 median steps) is jitter, not a clock jump
LOG_STAMPS_FIX = "the publisher did not set header.stamp; use the recorder's clock with ⟦time_source='log'⟧"


def _drop_invalid(idx: np.ndarray, xyz: np.ndarray, quat: np.ndarray, source: str,
                  where: Callable[[int], str], notes: list[str]) -> np.ndarray:
    """Indices of the valid samples among ``idx``: finite, |position| <= 1e8 m, a non-zero finite
    quaternion. Invalid ones are dropped with a warning naming the first; DataError if none is valid."""
    with np.errstate(all="ignore"):     # inf/NaN/1e300 rows must not leak numpy RuntimeWarnings
        norm = np.sqrt(np.einsum("ij,ij->i", quat, quat))
        ok = np.isfinite(norm) & (norm > 1e-12) & (np.abs(xyz) <= _MAX_POSITION_M).all(axis=1)
    if ok.all():
        return idx
    bad = np.flatnonzero(~ok)
    first = int(bad[0])
    detail = f"position {xyz[first].tolist()}, quaternion {quat[first].tolist()}"
    if not ok.any():
        raise DataError("no valid pose: every sample has a NaN/inf value, |position| > 1e8 m or a zero-norm "
                        f"quaternion ({detail})", f"{source}, {where(first)}",
                        "check the exporter (wrong columns or units?)")
    notes.append(f"dropped {len(bad)} invalid pose(s) of {source} (NaN/inf, |position| > 1e8 m or zero-norm "
                 f"quaternion), the first at {where(first)}: {detail}")
    return np.asarray(idx[ok])


def _longest_run(stamps: np.ndarray, source: str, where: Callable[[int], str], notes: list[str]) -> slice:
    """The samples (in arrival order) to keep when the clock jumps back.

    A jump is a backward step longer than 0.5 s and 10 median forward steps. A few jumps split the
    stream into runs and only the longest run is kept (a warning per jump): pairing across a clock
    jump would be wrong. Many backward steps are a reordering, not a jump: everything is kept (and
    sorted by the caller).
    """
    n = len(stamps)
    step = np.diff(stamps)
    forward = step[step > 0]
    if n < 3 or not len(forward):
        return slice(0, n)
    limit = max(_MIN_JUMP_NS, 10 * int(np.median(forward)))
    jumps = np.flatnonzero(step < -limit)
    if not len(jumps) or len(jumps) > max(1, n // 100):
        return slice(0, n)
    bounds = np.r_[0, jumps + 1, n]
    k = int(np.argmax(np.diff(bounds)))
    for j in jumps:
        notes.append(f"clock of {source} jumps back {-step[j] / 1e9:.3f} s at t={stamps[j] / 1e9:.3f} s "
                     f"({where(int(j) + 1)}); kept the longest run without a jump "
                     f"({bounds[k + 1] - bounds[k]} of {n} samples)")
    return slice(int(bounds[k]), int(bounds[k + 1]))


def make_stream(stamps: np.ndarray, xyz: np.ndarray, quat: np.ndarray, *, source: str,
                frame_id: str, child_frame_id: str, time_source: str,
                where: Callable[[int], str] = lambda i: f"message {i}", warnings: Sequence[str] = (),
                recovered_truncated: int = 0, zero_stamps_fix: str | None = LOG_STAMPS_FIX,
                quaternion_order: str | None = None) -> PoseStream:
    """Validate and order reader output (arrays in arrival order) into a :class:`PoseStream`.

    Refuses (ReadError) a non-empty ``frame_id`` or ``child_frame_id`` that breaks the frame-id rule
    (:func:`handeye_cli.untrusted.frame_id_problem`): such names would reach the generated launch
    files and scripts. Drops invalid poses (warning), keeps the longest run when the clock jumps back (warning),
    sorts by stamp, drops repeated stamps keeping the first (``duplicates_dropped``; a warning
    when a repeat carries a different pose), normalises quaternions (x-y-z-w). ``where(i)`` names
    sample ``i`` (arrival order) in messages, e.g. "line 12". ``warnings`` are the reader's own.
    DataError for an empty stream, no valid pose, every sample at one stamp, or — unless
    ``zero_stamps_fix`` is None — every stamp zero (``zero_stamps_fix`` says what to do).
    ``quaternion_order``: see :attr:`PoseStream.quaternion_order`.
    """
    for role, name in (("frame_id", frame_id), ("child_frame_id", child_frame_id)):
        problem = frame_id_problem(name) if name else None     # an empty id (PoseStamped without one) is allowed
        if problem:
            raise ReadError(f"{role} {name!r} is not a valid frame id: {problem}", source,
                            "fix the recording's frame ids (tf2 refuses such ids too), or export the poses to a "
                            "TUM/CSV file and read that")
    if len(stamps) == 0:     # the reader's first warning may say why (a chunk skipped, a cut-off file)
        raise DataError("empty stream: no poses" + "".join(f" ({w})" for w in warnings[:1]), source,
                        "choose a topic, frame pair or file that carries poses (handeye inspect FILE)")
    notes = list(warnings)
    stamps = np.asarray(stamps, dtype=np.int64)
    if zero_stamps_fix is not None and len(stamps) > 1 and not stamps.any():
        raise DataError(f"the stamps are all zero ({len(stamps)} samples)", source, zero_stamps_fix)
    if len(stamps) > 1 and (stamps == stamps[0]).all():     # before the per-sample copies below
        raise DataError(f"all {len(stamps)} samples carry the same stamp ({int(stamps[0])} ns): one pose, no motion",
                        source, "record a trajectory: stamps must advance (wrong time column? ⟦csv_columns='t=COL'⟧)")
    idx = _drop_invalid(np.arange(len(stamps)), xyz, quat, source, where, notes)
    idx = idx[_longest_run(stamps[idx], source, lambda i: where(int(idx[i])), notes)]
    idx = idx[np.argsort(stamps[idx], kind="stable")]
    t = stamps[idx]
    repeat = np.r_[False, t[1:] == t[:-1]]
    if repeat.any():
        first = idx[np.maximum.accumulate(np.where(repeat, 0, np.arange(len(t))))]
        differs = repeat & ((xyz[idx] != xyz[first]).any(axis=1) | (quat[idx] != quat[first]).any(axis=1))
        if differs.any():
            notes.append(f"{int(differs.sum())} sample(s) of {source} repeat a stamp with a different pose "
                         f"(the first is kept), e.g. {where(int(idx[np.argmax(differs)]))}")
    idx = idx[~repeat]
    rows: np.ndarray | slice = idx
    if len(idx) == len(stamps) and not np.any(np.diff(idx) != 1):    # nothing moved: no copies
        rows = slice(None)
    q = quat[rows]
    return PoseStream(t[~repeat], xyz[rows], q / np.sqrt(np.einsum("ij,ij->i", q, q))[:, None],
                      frame_id=frame_id, child_frame_id=child_frame_id, source=source,
                      time_source=time_source, duplicates_dropped=int(repeat.sum()),
                      warnings=tuple(notes), recovered_truncated=recovered_truncated,
                      quaternion_order=quaternion_order)
