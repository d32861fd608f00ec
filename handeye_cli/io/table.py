"""Numeric text tables (TUM, EuRoC, CSV bodies) → numpy arrays, block by block, without per-line Python.

A :class:`Table` holds the data lines' numbers as float64 and the time column exactly (its decimal
digits, so stamps become int64 nanoseconds without a float round trip in any unit). Two parsers
fill it with identical results: :func:`fast_table` (numpy over 4 MB blocks: separators mapped to
spaces, comment lines blanked, ``np.fromstring`` for the floats, the time column's digits
gathered at computed offsets) and :func:`slow_table` (a line loop with ``Decimal``), which also
serves every input the fast one declines (ragged rows, exponents or more than 9 decimals in the
time column, bad tokens) and produces the line-exact error for malformed input.
"""
from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from typing import BinaryIO

import numpy as np
from numpy.typing import NDArray

from ..errors import ReadError

__all__ = ["Table", "fast_table", "slow_table"]

_BLOCK = 1 << 20                   # [B] parsed at a time: its temporaries take ~40x a block of short lines
_WINDOW = 24                       # longest time token the fast path reads ("-1700000000.123456789" is 21)
_P10 = 10 ** np.arange(19, dtype=np.int64)
_SPACE = np.arange(256, dtype=np.uint8)
_SPACE[[ord("\r"), ord("\t"), ord(","), ord("\v"), ord("\f")]] = ord(" ")
_SPLIT = re.compile(r"[,\s]+")


@dataclass(frozen=True)
class Table:
    """Data lines of a numeric table.

    ``lines``: 1-based line numbers; ``values``: float64[N, k] every column; ``t_int`` / ``t_frac``:
    the time column's integer part and its first 9 decimals as an integer (both ≥ 0) with sign
    ``t_neg``; ``t_exact``: the time tokens as Decimals when the slow path read them (else None).
    """

    lines: NDArray[np.int64]
    values: NDArray[np.float64]
    t_int: NDArray[np.int64]
    t_frac: NDArray[np.int64]
    t_neg: NDArray[np.bool_]
    t_exact: list[Decimal] | None = None

    def time_float(self) -> NDArray[np.float64]:
        """The time column as float64 in the file's unit (for unit detection only)."""
        if self.t_exact is not None:
            return np.array([float(d) for d in self.t_exact], dtype=np.float64)
        t = self.t_int + self.t_frac * 1e-9
        return np.where(self.t_neg, -t, t)

    def stamps_ns(self, digits: int, name: str) -> NDArray[np.int64]:
        """Exact int64 stamps [ns] for a file unit of 10**-digits s (9 = seconds, 0 = nanoseconds);
        decimals beyond 1 ns are rounded half to even. ReadError beyond the int64 range."""
        if self.t_exact is not None:
            ns = [int(d.scaleb(digits).to_integral_value()) for d in self.t_exact]
            bad = next((i for i, v in enumerate(ns) if not -2**63 <= v < 2**63), None)
            if bad is None:
                return np.array(ns, dtype=np.int64)
            raise _range_error(str(self.t_exact[bad]), name, int(self.lines[bad]))
        m = _P10[9 - digits]
        q, r = np.divmod(self.t_frac, m)
        limit = (2**63 - 2 - q) // _P10[digits]
        if (self.t_int > limit).any():
            i = int(np.argmax(self.t_int > limit))
            raise _range_error(f"{self.t_int[i]}.{self.t_frac[i]:09d}", name, int(self.lines[i]))
        ns = self.t_int * _P10[digits] + q
        ns += (2 * r > m) | ((2 * r == m) & (ns % 2 == 1))     # round half to even, like Decimal
        return np.asarray(np.where(self.t_neg, -ns, ns), dtype=np.int64)


def _range_error(token: str, name: str, line: int) -> ReadError:
    return ReadError(f"timestamp {token} is out of the int64 nanosecond range (wrong time unit?)",
                     f"{name}, line {line}", "pass the right unit with ⟦time_unit='s|ms|us|ns'⟧")


def _blocks(f: BinaryIO) -> Iterator[tuple[int, bytes]]:
    """(number of lines before the block, block of whole lines ending in a newline)."""
    rest, line0 = b"", 0
    while True:
        data = f.read(_BLOCK)
        if not data:
            break
        data = rest + data
        cut = data.rfind(b"\n") + 1
        if cut == 0:
            rest = data
            continue
        yield line0, data[:cut]
        line0 += data.count(b"\n", 0, cut)
        rest = data[cut:]
    if rest:
        yield line0, rest + b"\n"


def _time_digits(b: NDArray[np.uint8],
                 pos: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]] | None:
    """(integer part, 9-decimal fraction, negative) of the plain decimal tokens starting at ``pos``
    of the space-separated buffer ``b``; None if any token is not ``[-]digits[.digits≤9]``."""
    win = np.concatenate([b, np.full(_WINDOW, 32, np.uint8)])[pos[:, None] + np.arange(_WINDOW)]
    end = win <= 32
    if not end.any(axis=1).all():
        return None
    length = np.argmax(end, axis=1)
    neg = win[:, 0] == ord("-")
    col = np.arange(_WINDOW)
    inside = (col >= neg[:, None]) & (col < length[:, None])
    digit = (win >= ord("0")) & (win <= ord("9"))
    dot = win == ord(".")
    if ((inside & ~digit & ~dot).any() or (dot & inside).sum(axis=1).max(initial=0) > 1
            or (length - neg == 0).any()):
        return None
    point = np.where((dot & inside).any(axis=1), np.argmax(dot & inside, axis=1), length)
    if (point - neg > 18).any() or (length - point - 1 > 9).any():
        return None
    d = win.astype(np.int64) - ord("0")
    if (point == point[0]).all() and (length == length[0]).all() and (neg == neg[0]).all():  # one layout
        p, n, s = int(point[0]), int(length[0]), int(neg[0])
        t_int = d[:, s:p] @ _P10[:p - s][::-1]
        t_frac = d[:, p + 1:n] @ _P10[9 - (n - p - 1):9][::-1] if n > p + 1 else np.zeros(len(pos), np.int64)
        return t_int, t_frac, neg
    t_int = np.zeros(len(pos), np.int64)
    t_frac = np.zeros(len(pos), np.int64)
    for j in range(int(length.max())):
        is_int = inside[:, j] & (j < point)
        t_int += np.where(is_int, d[:, j] * _P10[np.clip(point - 1 - j, 0, 18)], 0)
        is_frac = inside[:, j] & (j > point)
        t_frac += np.where(is_frac, d[:, j] * _P10[np.clip(9 - (j - point), 0, 18)], 0)
    return t_int, t_frac, neg


def _fast_block(block: bytes, line0: int, skip: int, k: int | None,
                t_col: int) -> tuple[Table, int] | None:
    """One block's Table and its column count, or None when the fast path declines."""
    b = _SPACE[np.frombuffer(block, np.uint8)]
    newline = np.flatnonzero(b == 10)
    ws = b <= 32
    starts = np.flatnonzero(~ws & np.r_[True, ws[:-1]])
    line_of = np.searchsorted(newline, starts)
    first = np.r_[True, line_of[1:] != line_of[:-1]]
    drop = starts[first][(b[starts[first]] == ord("#")) | (line_of[first] + line0 + 1 == skip)]
    if len(drop):
        b = b.copy()
        ends = newline[np.searchsorted(newline, drop)]
        for s, e in zip(drop.tolist(), ends.tolist(), strict=True):
            b[s:e] = 32
        keep = ~np.isin(line_of, np.searchsorted(newline, drop))
        starts, line_of = starts[keep], line_of[keep]
    if not len(starts):
        return Table(np.zeros(0, np.int64), np.zeros((0, k or 0)), *(np.zeros(0, np.int64),) * 2,
                     np.zeros(0, bool)), k or 0
    rows, counts = np.unique(line_of, return_counts=True)
    k = k or int(counts[0])
    if (counts != k).any() or t_col >= k:
        return None
    try:
        values = np.fromstring(b.tobytes().decode("ascii"), sep=" ")
    except (UnicodeDecodeError, ValueError):
        return None
    if len(values) != len(rows) * k:
        return None
    t = _time_digits(b, starts.reshape(-1, k)[:, t_col])
    if t is None:
        return None
    return Table(rows.astype(np.int64) + line0 + 1, values.reshape(-1, k), *t), k


_FIELDS = ("lines", "values", "t_int", "t_frac", "t_neg")


def _size(f: BinaryIO) -> int:
    """Bytes from the current position to the end of ``f`` (0 if it cannot seek)."""
    try:
        here = f.tell()
        end = f.seek(0, 2)
        f.seek(here)
        return end - here
    except (OSError, ValueError):
        return 0


class _Rows:
    """Table columns filled block by block into arrays sized from the file size (no concatenation
    of per-block parts, whose copy would double the peak memory); grown by half when short."""

    def __init__(self) -> None:
        self.n = 0
        self.cols: dict[str, np.ndarray] = {}

    def add(self, part: Table, capacity: int) -> None:
        m = len(part.lines)
        if not self.cols:
            self.cols = {a: np.empty((max(capacity, m),) + getattr(part, a).shape[1:], getattr(part, a).dtype)
                         for a in _FIELDS}
        if self.n + m > len(self.cols["lines"]):
            grow = max(self.n + m, len(self.cols["lines"]) * 3 // 2)
            for a, col in self.cols.items():
                self.cols[a] = np.resize(col, (grow,) + col.shape[1:])
        for a in _FIELDS:
            self.cols[a][self.n:self.n + m] = getattr(part, a)
        self.n += m

    def table(self) -> Table:
        c = {a: col[:self.n] for a, col in self.cols.items()}
        return Table(c["lines"], c["values"], c["t_int"], c["t_frac"], c["t_neg"])


def fast_table(f: BinaryIO, *, skip: int = 0, t_col: int = 0) -> Table | None:
    """The numeric table in ``f`` (lines ``#…``, blank lines and line number ``skip`` ignored;
    fields separated by spaces, tabs or commas; every data line the same number of fields), or
    None if the fast path cannot read it exactly (then use :func:`slow_table`)."""
    rows, k, size = _Rows(), None, _size(f)
    for line0, block in _blocks(f):
        got = _fast_block(block, line0, skip, k, t_col)
        if got is None:
            return None
        part, k = got
        if len(part.lines):     # rows expected in the whole file, from this block's bytes per row (+2 %)
            rows.add(part, int(size / len(block) * len(part.lines) * 1.02) + 16)
    return rows.table() if rows.n else None


def slow_table(f: BinaryIO, name: str, *, need: int, expected: str, skip: int = 0, t_col: int = 0,
               comma_only: bool = False, exact: bool = False) -> Table:
    """The same Table (first ``need`` columns) by a line loop; ReadError naming the line for a
    malformed one (fewer than ``need`` fields — or not exactly ``need`` with ``exact`` —, a field
    that is not a number). ``comma_only``: split on commas only (CSV)."""
    lines, stamps, rows = [], [], []
    for n, raw in enumerate(f, 1):
        s = raw.decode("utf-8", errors="replace").strip()
        if not s or s.startswith("#") or n == skip:
            continue
        fields = [x.strip() for x in (s.split(",") if comma_only else _SPLIT.split(s))]
        try:
            if len(fields) < need or (exact and len(fields) != need):
                raise ValueError(f"{len(fields)} values")
            stamps.append(Decimal(fields[t_col]))
            if not stamps[-1].is_finite():
                raise ValueError(f"time {fields[t_col]} is not a number")
            rows.append([float(x) for x in fields[:need]])
        except (ValueError, InvalidOperation) as exc:
            reason = str(exc) if not isinstance(exc, InvalidOperation) else f"time {fields[t_col]!r} is not a number"
            got = " ".join(fields)
            got = got if len(got) <= 80 else got[:77] + "..."
            raise ReadError(f"malformed line ({reason}): expected {expected}, got {got!r}",
                            f"{name}, line {n}", "fix or delete the line") from exc
        lines.append(n)
    zeros = np.zeros(len(stamps), np.int64)
    return Table(np.array(lines, dtype=np.int64), np.array(rows, dtype=np.float64).reshape(-1, need),
                 zeros, zeros, zeros.astype(bool), stamps)
