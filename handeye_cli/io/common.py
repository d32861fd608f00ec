"""Shared reader plumbing: turning decoder failures into HandEyeErrors, building a PoseStream."""
from __future__ import annotations

import importlib
import json
import struct
from array import array
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager

import numpy as np
from mcap.exceptions import McapError
from rosbags.highlevel import AnyReaderError
from rosbags.rosbag1 import ReaderError as Bag1ReaderError
from rosbags.rosbag2 import ReaderError as Bag2ReaderError
from rosbags.serde import SerdeError
from rosbags.typesys import TypesysError

from ..errors import HandEyeError
from ..streams import PoseStream

__all__ = ["DECODE_ERRORS", "unreadable", "PoseBuffer", "make_stream"]


def _optional_error(module: str) -> tuple[type[BaseException], ...]:
    """``module.ZstdError`` if that zstd binding is installed (mcap uses zstandard, rosbags
    compression.zstd or its backport)."""
    try:
        return (importlib.import_module(module).ZstdError,)
    except (ImportError, AttributeError):
        return ()


_ZSTD_ERRORS = sum(map(_optional_error, ("zstandard", "compression.zstd", "backports.zstd")), ())

DECODE_ERRORS: tuple[type[BaseException], ...] = (
    McapError, struct.error, OSError, EOFError, AnyReaderError, Bag1ReaderError, Bag2ReaderError,
    SerdeError, TypesysError, KeyError, IndexError, UnicodeDecodeError, json.JSONDecodeError,
    RuntimeError, *_ZSTD_ERRORS)
"""What mcap, rosbags, json and the decoders raise on truncated or corrupt input (lz4 raises a
bare RuntimeError on a corrupt chunk)."""


@contextmanager
def unreadable(where: str, fix: str = "check that the file is complete and of a supported "
                                       "format (handeye inspect FILE)") -> Iterator[None]:
    """Convert a decoder failure inside the block into a HandEyeError about ``where``."""
    try:
        yield
    except HandEyeError:
        raise
    except DECODE_ERRORS as exc:
        detail = str(exc) or type(exc).__name__
        raise HandEyeError(f"cannot read file: {type(exc).__name__}: {detail}", where, fix) from exc


class PoseBuffer:
    """Growable columns of pose records, without keeping per-message objects alive.

    ``where`` (record index → text such as "message 17") names bad samples in errors.
    """

    def __init__(self) -> None:
        self.stamps = array("q")
        self.values = array("d")
        self.pairs: dict[tuple[str, str], None] = {}    # (frame, child) pairs seen, in order
        self._last: tuple = ()

    def add(self, records: Sequence[tuple]) -> None:
        """Append pose records ``(stamp_ns, frame, child, x, y, z, qx, qy, qz, qw)``."""
        for rec in records:
            self.stamps.append(rec[0])
            self.values.extend(rec[3:])
            if rec[1:3] != self._last:
                self._last = rec[1:3]
                self.pairs[self._last] = None

    def __len__(self) -> int:
        return len(self.stamps)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(stamps int64[N], xyz float64[N, 3], quat_xyzw float64[N, 4])."""
        v = np.frombuffer(self.values, dtype=np.float64).reshape(-1, 7)
        return np.frombuffer(self.stamps, dtype=np.int64).copy(), v[:, :3].copy(), v[:, 3:].copy()


def make_stream(stamps: np.ndarray, xyz: np.ndarray, quat: np.ndarray, *, source: str,
                frame_id: str, child_frame_id: str, time_source: str,
                where: Callable[[int], str] = lambda i: f"message {i}") -> PoseStream:
    """Validate, sort by stamp, drop exact duplicate stamps (keep the first), normalise quaternions.

    ``where(i)`` names sample ``i`` (in input order) in error messages, e.g. "line 12".
    Raises HandEyeError for an empty stream, non-finite positions, NaN or zero quaternions.
    """
    if len(stamps) == 0:
        raise HandEyeError("empty stream: no poses", source,
                           "choose a topic, frame pair or file that carries poses (handeye inspect FILE)")
    norm = np.linalg.norm(quat, axis=1)
    bad = ~(np.isfinite(norm) & (norm > 1e-12) & np.isfinite(xyz).all(axis=1))
    if bad.any():
        i = int(np.argmax(bad))
        raise HandEyeError(f"invalid pose: NaN/inf value or zero-norm quaternion "
                           f"{quat[i].tolist()}", f"{source}, {where(i)}",
                           f"remove or fix the {int(bad.sum())} invalid sample(s) (tracking dropouts?)")
    order = np.argsort(stamps, kind="stable")
    stamps = stamps[order]
    keep = np.r_[True, stamps[1:] != stamps[:-1]]
    order = order[keep]
    return PoseStream(stamps[keep], xyz[order], quat[order] / norm[order, None],
                      frame_id=frame_id, child_frame_id=child_frame_id, source=source,
                      time_source=time_source, duplicates_dropped=int((~keep).sum()))
