"""One object read by byte range (:class:`RemoteObject`, what it fetched kept for re-reading) and a seekable
file on it (:class:`RangeFile`)."""
from __future__ import annotations

import os
import struct
from collections import OrderedDict
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

from .ranges import Ranges

_READAHEAD = 4 << 10        # [B] the least a request asks for (small reads: headers, records of a summary)
_TAIL = 16 << 10            # [B] an object's last bytes, asked for with its size (an MCAP's footer and summary,
                            # a ROS 1 bag's index: the rest, if longer, in one more request)
_HELD = 64 << 20            # [B] the most fetched bytes kept for re-reading (footer, summary, head)
_FOOTER = 37                # Footer record (opcode 1 + length 8 + 8 + 8 + 4) + magic 8
_MCAP_MAGIC = b"\x89MCAP0\r\n"


class _Owner(Protocol):
    """What a :class:`RemoteObject` asks of its session (a :class:`.sessions.Session`)."""

    def call(self, url: str, what: str, fn: Any, *args: Any, tries: int | None = None) -> Any: ...

    def count(self, n: int) -> None: ...

    def cached(self, url: str, why: str) -> Path: ...


class RemoteObject:
    """One object read by byte range: ``size`` [B]; what :meth:`read_at` fetched is kept (at most
    :data:`_HELD` bytes, oldest dropped first) so that re-reading a header or the summary costs nothing."""

    def __init__(self, owner: _Owner, url: str, fs: Any, path: str, size: int) -> None:
        self.session, self.url, self._fs, self._path, self.size = owner, url, fs, path, size
        self.name = url
        self._held: OrderedDict[int, bytes] = OrderedDict()

    def __str__(self) -> str:
        return self.url

    def fetch(self, start: int, stop: int) -> bytes:
        """The bytes ``[start, stop)`` in one request (fewer only if the object ends first), counted."""
        stop = min(stop, self.size)
        if stop <= start:
            return b""
        data: bytes = self.session.call(self.url, f"reading bytes {start}-{stop}",
                                        lambda: self._fs.cat_file(self._path, start=start, end=stop))
        self.session.count(len(data))
        return data

    def hold(self, start: int, data: bytes) -> None:
        """Keep ``data``, the object's bytes from ``start``, for re-reading (at most :data:`_HELD`: oldest out)."""
        self._held[start] = data
        while sum(map(len, self._held.values())) > _HELD and len(self._held) > 1:
            self._held.popitem(last=False)

    def held(self, start: int, n: int) -> memoryview | None:
        """The ``n`` bytes from ``start`` if one block held has them all, else None."""
        for s, d in self._held.items():
            if s <= start and start + n <= s + len(d):
                return memoryview(d)[start - s:start - s + n]
        return None

    def unheld(self, start: int, stop: int) -> tuple[int, int]:
        """The bytes ``[start, stop)`` less what blocks held give at either end (the object's first
        and last bytes, read ahead): ``(a, b)``, empty (``a == b``) if nothing is left."""
        a, b = start, stop
        for s, d in self._held.items():
            if s <= a < s + len(d):
                a = min(stop, s + len(d))
        for s, d in self._held.items():
            if s < b <= s + len(d):
                b = s
        return a, max(a, b)

    def read_at(self, pos: int, n: int) -> bytes:
        """``n`` bytes from ``pos`` (fewer at the end): from what is held, else one request of at least
        :data:`_READAHEAD` bytes."""
        out = bytearray()
        while n > 0 and pos < self.size:
            block = next(((s, d) for s, d in self._held.items() if s <= pos < s + len(d)), None)
            if block is None:
                nxt = min((s for s in self._held if s > pos), default=self.size)
                want = min(max(n, _READAHEAD), nxt - pos) if nxt - pos >= n else nxt - pos
                data = self.fetch(pos, pos + want)
                if not data:
                    break
                self.hold(pos, data)
                block = (pos, data)
            s, d = block
            piece = d[pos - s:pos - s + n]
            out += piece
            pos, n = pos + len(piece), n - len(piece)
        return bytes(out)

    def prefetch_summary(self) -> bool:
        """Hold the MCAP footer and the summary it points at (what the object's last bytes, held since
        it was opened, do not cover: in one request); whether there is a summary (False: no footer —
        cut short — or written without one)."""
        if self.size < len(_MCAP_MAGIC) + _FOOTER:
            return False
        tail = self.read_at(self.size - _FOOTER, _FOOTER)
        if tail[-8:] != _MCAP_MAGIC or tail[0] != 0x02:
            return False
        (summary_start,) = struct.unpack_from("<Q", tail, 9)
        if not 0 < summary_start < self.size - _FOOTER:
            return False
        self.read_at(summary_start, self.size - _FOOTER - summary_start)
        return True

    def file(self) -> RangeFile:
        """A seekable binary file object reading this object by range."""
        return RangeFile(self)

    def ranges(self, planned: Sequence[tuple[int, int]]) -> Ranges:
        """Views of the byte ranges ``planned`` [(start, length)], to be asked for in that order."""
        return Ranges(self, planned)


class RangeFile:
    """A read-only, seekable binary file on a :class:`RemoteObject` (reads never past its end)."""

    def __init__(self, obj: RemoteObject) -> None:
        self._obj, self._pos = obj, 0
        self.name = obj.url

    def read(self, n: int | None = -1) -> bytes:
        if n is None or n < 0:
            n = self._obj.size - self._pos
        data = self._obj.read_at(self._pos, n)
        self._pos += len(data)
        return data

    def readinto(self, buf: Any) -> int:
        data = self.read(len(buf))
        memoryview(buf).cast("B")[:len(data)] = data
        return len(data)

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        base = {os.SEEK_SET: 0, os.SEEK_CUR: self._pos, os.SEEK_END: self._obj.size}[whence]
        self._pos = max(0, base + offset)
        return self._pos

    def tell(self) -> int:
        return self._pos

    def seekable(self) -> bool:
        return True

    def readable(self) -> bool:
        return True

    def close(self) -> None:
        """Nothing to release: the object's held bytes belong to its session."""

    def __enter__(self) -> RangeFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
