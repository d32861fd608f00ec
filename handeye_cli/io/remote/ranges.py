"""Byte ranges of one object asked for in a planned order (:class:`Ranges`): the span constants bound a
request's size and what is asked for ahead."""
from __future__ import annotations

import bisect
import concurrent.futures
from collections.abc import Sequence
from typing import Protocol

_SPAN = 16 << 20            # [B] the most one request of adjacent chunks asks for
_GAP = 64 << 10             # [B] planned ranges this close are asked for in one request (the gap's bytes with them)
_PARALLEL = 16              # requests of one object's planned ranges under way at once, at most …
_AHEAD = 64 << 20           # [B] … holding at most this many bytes asked for ahead of the reader (or one span)


class _Object(Protocol):
    """What :class:`Ranges` asks of its object (a :class:`.objects.RemoteObject`)."""

    size: int

    def fetch(self, start: int, stop: int) -> bytes: ...

    def held(self, start: int, n: int) -> memoryview | None: ...

    def unheld(self, start: int, stop: int) -> tuple[int, int]: ...


class Ranges:
    """Byte ranges of an object asked for in a planned order (use as a context manager): ranges at
    most :data:`_GAP` apart are fetched together, up to :data:`_SPAN` bytes a request; the spans
    after the one being read are asked for at once, on a small thread pool, while the reader works
    through it — at most :data:`_PARALLEL` requests holding at most :data:`_AHEAD` bytes (or one
    span) —, so that the requests' first-byte latencies overlap and fetching overlaps decoding; a
    span is dropped once the reader moves past it (memory holds the span being read and
    :data:`_AHEAD` bytes: a few chunks, never the object)."""

    def __init__(self, obj: _Object, planned: Sequence[tuple[int, int]]) -> None:
        self._obj = obj
        self._spans: list[tuple[int, int]] = []
        for first, n in sorted(planned):
            start, stop = obj.unheld(first, min(first + n, obj.size))   # what was read ahead is not asked again
            last = self._spans[-1] if self._spans else None
            if start == stop:
                continue
            if last and start - last[1] <= _GAP and max(last[1], stop) - last[0] <= _SPAN:
                self._spans[-1] = (last[0], max(last[1], stop))
            else:
                self._spans.append((start, stop))
        self._starts = [a for a, _ in self._spans]
        self._span = (0, b"")
        self._pool: concurrent.futures.ThreadPoolExecutor | None = None
        self._asked: dict[int, concurrent.futures.Future[bytes]] = {}    # span number → its bytes
        self._next = 0                  # the next span to ask for

    def __enter__(self) -> Ranges:
        return self

    def __exit__(self, *exc: object) -> None:
        """Requests not yet sent are dropped; those under way are waited for (each bounded by the
        session's timeout), so that :attr:`Session.bytes_fetched` is complete."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
        self._asked.clear()

    def _ask(self, k: int) -> None:
        """Span ``k`` and those after it asked for, up to :data:`_PARALLEL` requests and :data:`_AHEAD`
        bytes [B] (at least span ``k``); earlier ones forgotten."""
        for old in [j for j in self._asked if j < k]:
            self._asked.pop(old).cancel()
        self._next = max(self._next, k)
        ahead = sum(self._spans[j][1] - self._spans[j][0] for j in self._asked)
        while self._next < len(self._spans) and len(self._asked) < _PARALLEL:
            start, stop = self._spans[self._next]
            if self._asked and ahead + stop - start > _AHEAD:
                break
            if self._pool is None:
                self._pool = concurrent.futures.ThreadPoolExecutor(_PARALLEL, thread_name_prefix="handeye-range")
            self._asked[self._next] = self._pool.submit(self._obj.fetch, start, stop)
            ahead += stop - start
            self._next += 1

    def view(self, start: int, n: int) -> memoryview:
        """The ``n`` bytes from ``start`` (fewer where the object ends)."""
        n = max(0, min(n, self._obj.size - start))
        s, data = self._span
        if s <= start and start + n <= s + len(data):
            return memoryview(data)[start - s:start - s + n]
        if (held := self._obj.held(start, n)) is not None:      # read ahead with the object's size
            return held
        a, b = self._obj.unheld(start, start + n)
        if not (s <= a and b <= s + len(data)):
            self._span = (0, b"")           # the previous span goes before the next arrives
            k = bisect.bisect_right(self._starts, a) - 1
            if k >= 0 and self._spans[k][0] <= a and b <= self._spans[k][1] and (k in self._asked or k >= self._next):
                self._ask(k)
                s, data = self._spans[k][0], self._asked.pop(k).result()
            else:                           # outside the plan (or read already): asked for alone
                s, data = a, self._obj.fetch(a, b)
            self._span = (s, data)
        if (a, b) == (start, start + n):
            return memoryview(data)[start - s:start - s + n]
        ends = self._obj.held(start, a - start), self._obj.held(b, start + n - b)     # read ahead: joined to it
        return memoryview(b"".join((ends[0] or b"", memoryview(data)[a - s:b - s], ends[1] or b"")))
