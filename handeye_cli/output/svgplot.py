"""Charts as standalone SVG documents, for the HTML report of ``handeye calibrate --report``.

A :class:`Chart` is a grid of :class:`Panel` s; a panel maps its data limits (linear, or a log
x axis) onto its box and draws lines, point markers, horizontal and vertical rules, horizontal
bars and histograms, with ticks, grid, axis labels, a title and a legend in the look of
matplotlib's defaults (tab10 colours, DejaVu Sans, ticks outward, 5 % data margins). Sizes are
given in points (1/72 in) and inches as in matplotlib, and drawn at :data:`DPI` pixels per inch.

Rendering is string formatting: about 0.2 s of CPU for the report's four figures of a 60-min log
(10,000 plotted samples per line), where matplotlib (import, layout, Agg, PNG encoding) took 2 to
4 s, as much as the whole plain calibration of that log.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from html import escape
from typing import Any

import numpy as np

from .._typing import FloatArray, IntArray

__all__ = ["DPI", "Chart", "Panel", "linear_ticks", "tick_labels"]

DPI = 90
PT = DPI / 72.0                       # pixels per point
FONT = "DejaVu Sans, Bitstream Vera Sans, Verdana, Arial, sans-serif"
_MINUS = "\u2212"
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")
_STEPS = (1.0, 2.0, 2.5, 5.0, 10.0)   # matplotlib's MaxNLocator steps
_FINE = 0.1                           # the drawing unit of plotted data [px]: coordinates are integers of it


def linear_ticks(lo: float, hi: float, nbins: int) -> FloatArray:
    """Tick values in [lo, hi]: multiples of the smallest step of 1, 2, 2.5 or 5 × 10ᵏ not below
    (hi - lo) / nbins that leaves at least two ticks in range (matplotlib's ``MaxNLocator``)."""
    span = hi - lo
    if not (span > 0 and math.isfinite(span)):
        return np.array([lo])
    raw = span / max(nbins, 1)
    scale = 10.0 ** math.floor(math.log10(raw))
    ticks = np.array([lo])
    for s in (*_STEPS, 20.0):
        step = s * scale
        if step < raw * (1 - 1e-9):
            continue
        ticks = np.arange(math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9) + 1) * step
        if len(ticks) >= 2:
            break
    ticks[np.abs(ticks) < 1e-9 * span] = 0.0
    out: FloatArray = ticks.astype(np.float64)
    return out


def tick_labels(ticks: FloatArray) -> list[str]:
    """Labels of linear ticks with the fewest decimals that tell them apart exactly, and a true minus sign."""
    step = float(np.min(np.diff(ticks))) if len(ticks) > 1 else max(abs(float(ticks[0])), 1.0)
    decimals = next((d for d in range(12) if np.allclose(np.round(ticks, d), ticks, rtol=0, atol=1e-6 * step)), 12)
    return [f"{t:.{decimals}f}".replace("-", _MINUS) for t in ticks]


def _num(v: float) -> str:
    """A pixel coordinate: one decimal, no trailing zeros."""
    text = f"{v:.1f}"
    return text[:-2] if text.endswith(".0") else text


def _style(color: str, width_pt: float, dash: str | None = None, opacity: float = 1.0, unit: float = 1.0) -> str:
    """SVG stroke attributes of a line ``width_pt`` points wide, in drawing units of ``unit`` pixels;
    ``dash`` as matplotlib's "--" or ":"."""
    w = width_pt * PT / unit
    out = f"fill='none' stroke='{color}' stroke-width='{_num(w)}'"
    if dash == "--":
        out += f" stroke-dasharray='{_num(3.7 * w)},{_num(1.6 * w)}'"
    elif dash == ":":
        out += f" stroke-dasharray='{_num(w)},{_num(1.65 * w)}'"
    if opacity < 1.0:
        out += f" stroke-opacity='{opacity:g}'"
    return out


@dataclass
class _Item:
    """One thing drawn in a panel, kept in data coordinates until the limits are known."""

    kind: str                         # line, points, hline, vline, barh or stairs
    x: FloatArray
    y: FloatArray
    color: str
    width: float = 1.5                # line width [pt]; marker size [pt]; bar height [data]
    dash: str | None = None
    opacity: float = 1.0
    marker: str = "."
    label: str | None = None
    text: Sequence[str] = ()


@dataclass
class Panel:
    """Axes in a box (left, top, width, height) [px] of the chart. Add items, then set what
    differs from the defaults: ``xlim`` (data; default, as for y: the items' range + 5 %),
    ``xlog``, ``equal`` (same scale on both axes, the shorter range widened),
    ``grid`` ("both", "x", or ""), ``yticks`` (names of bar rows), ``legend`` (a corner such as
    "upper right", or None), labels and their font sizes [pt]."""

    box: tuple[float, float, float, float]
    items: list[_Item] = field(default_factory=list)
    title: str = ""
    xlabel: str = ""
    ylabel: str = ""
    title_size: float = 12.0
    label_size: float = 10.0
    tick_size: float = 10.0
    xlim: tuple[float, float] | None = None
    xlog: bool = False
    equal: bool = False
    grid: str = "both"
    xticklabels: bool = True
    xbins: int | None = None
    yticks: Sequence[str] = ()
    legend: str | None = None
    legend_size: float = 8.0
    off: bool = False

    def line(self, x: Any, y: Any, color: str, width: float = 1.5, dash: str | None = None,
             opacity: float = 1.0, label: str | None = None) -> None:
        """A polyline through the points (x, y); ``width`` [pt]."""
        self.items.append(_Item("line", _array(x), _array(y), color, width, dash, opacity, label=label))

    def points(self, x: Any, y: Any, color: str, size: float = 2.0, marker: str = ".",
               label: str | None = None) -> None:
        """Markers at the points: ``"."`` dots or ``"x"`` crosses, ``size`` [pt]."""
        self.items.append(_Item("points", _array(x), _array(y), color, size, marker=marker, label=label))

    def hline(self, y: float, color: str, width: float = 0.8, dash: str | None = None,
              label: str | None = None) -> None:
        """A horizontal rule across the panel at data ``y``."""
        self.items.append(_Item("hline", np.zeros(0), np.array([y]), color, width, dash, label=label))

    def vline(self, x: float, color: str, width: float = 0.8, dash: str | None = None) -> None:
        """A vertical rule across the panel at data ``x``."""
        self.items.append(_Item("vline", np.array([x]), np.zeros(0), color, width, dash))

    def barh(self, values: Any, color: str, texts: Sequence[str] = (), height: float = 0.8) -> None:
        """Horizontal bars from 0 to each value, one per row (row k at y = k, from the bottom), with an
        optional text after each bar's end."""
        v = _array(values)
        self.items.append(_Item("barh", v, np.arange(len(v), dtype=float), color, height, text=texts))

    def stairs(self, counts: Any, edges: Any, color: str, opacity: float = 1.0) -> None:
        """A filled histogram: ``counts`` (K,) between ``edges`` (K+1,)."""
        self.items.append(_Item("stairs", _array(edges), _array(counts), color, opacity=opacity))

    # ------------------------------------------------------------------------------------------
    # limits and the mapping to pixels

    def _data_range(self, axis: str) -> tuple[float, float, bool]:
        """(min, max, whether it starts at a bar's or histogram's zero) of the items along an axis."""
        values: list[FloatArray] = []
        sticky = False
        for it in self.items:
            if axis == "x":
                if it.kind in ("line", "points", "vline", "stairs"):
                    values.append(it.x)
                elif it.kind == "barh":
                    values += [it.x, np.zeros(1)]
                    sticky = True
            elif it.kind in ("line", "points", "hline"):
                values.append(it.y)
            elif it.kind == "stairs":
                values += [it.y, np.zeros(1)]
                sticky = True
            elif it.kind == "barh":
                values.append(np.r_[it.y - it.width / 2, it.y + it.width / 2])
        finite = np.concatenate(values) if values else np.zeros(0)
        finite = finite[np.isfinite(finite) & ((finite > 0) if (axis == "x" and self.xlog) else True)]
        if len(finite) == 0:
            return (1.0, 10.0, False) if (axis == "x" and self.xlog) else (0.0, 1.0, False)
        return float(finite.min()), float(finite.max()), sticky

    def _limits(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """Data limits (x, y): given, or the items' range with 5 % margins (none past a bar's zero);
        with ``equal``, the range of the axis with fewer data per pixel widened about its centre."""
        def auto(axis: str, log: bool) -> tuple[float, float]:
            lo, hi, sticky = self._data_range(axis)
            if log:
                lo, hi = math.log10(lo), math.log10(hi)
            if hi == lo:
                lo, hi = lo - (abs(lo) * 0.05 or 0.5), hi + (abs(hi) * 0.05 or 0.5)
            pad = 0.05 * (hi - lo)
            lo2, hi2 = lo - pad, hi + pad
            if sticky and lo >= 0 > lo2:
                lo2 = 0.0
            return (10.0 ** lo2, 10.0 ** hi2) if log else (lo2, hi2)
        x = self.xlim if self.xlim is not None else auto("x", self.xlog)
        y = auto("y", False)
        if self.equal and not self.xlog:
            w, h = self.box[2], self.box[3]
            per_px = max((x[1] - x[0]) / w, (y[1] - y[0]) / h)
            cx, cy = (x[0] + x[1]) / 2, (y[0] + y[1]) / 2
            x, y = (cx - per_px * w / 2, cx + per_px * w / 2), (cy - per_px * h / 2, cy + per_px * h / 2)
        return x, y

    def _mappers(self) -> tuple[Any, Any, tuple[float, float], tuple[float, float]]:
        (x0, x1), (y0, y1) = self._limits()
        left, top, w, h = self.box
        if self.xlog:
            lx0, lx1 = math.log10(x0), math.log10(x1)

            def fx(v: FloatArray) -> FloatArray:
                with np.errstate(divide="ignore", invalid="ignore"):
                    out: FloatArray = left + (np.log10(v) - lx0) / (lx1 - lx0) * w
                return out
        else:
            def fx(v: FloatArray) -> FloatArray:
                out: FloatArray = left + (np.asarray(v, dtype=float) - x0) / (x1 - x0) * w
                return out

        def fy(v: FloatArray) -> FloatArray:
            out: FloatArray = top + h - (np.asarray(v, dtype=float) - y0) / (y1 - y0) * h
            return out
        return fx, fy, (x0, x1), (y0, y1)

    # ------------------------------------------------------------------------------------------
    # drawing

    def svg(self, clip_id: str) -> str:
        """The panel's SVG elements; ``clip_id`` names its clip path (unique within the chart)."""
        left, top, w, h = self.box
        if self.off:
            return self._title()
        fx, fy, xl, yl = self._mappers()
        xt, xlabels, xminor = self._xticks(xl)
        yt = np.arange(len(self.yticks), dtype=float) if self.yticks else linear_ticks(
            yl[0], yl[1], _nbins(h, self.tick_size, 2))
        ylabels = list(self.yticks) if self.yticks else tick_labels(yt)
        yt_in = (yt >= min(yl) - 1e-9 * abs(yl[1] - yl[0])) & (yt <= max(yl) + 1e-9 * abs(yl[1] - yl[0]))
        xt_in = (xt >= xl[0] * (1 - 1e-9)) & (xt <= xl[1] * (1 + 1e-9)) if self.xlog else \
            (xt >= xl[0] - 1e-9 * (xl[1] - xl[0])) & (xt <= xl[1] + 1e-9 * (xl[1] - xl[0]))
        px, py = fx(xt[xt_in]), fy(yt[yt_in])
        out = [f"<rect x='{_num(left)}' y='{_num(top)}' width='{_num(w)}' height='{_num(h)}' fill='white'/>"]
        grid = _style("#b0b0b0", 0.8, opacity=0.3)
        if self.grid in ("both", "x") and len(px):
            out.append(f"<path {grid} d='" + "".join(f"M{_num(v)} {_num(top)}v{_num(h)}" for v in px) + "'/>")
        if self.grid == "both" and len(py):
            out.append(f"<path {grid} d='" + "".join(f"M{_num(left)} {_num(v)}h{_num(w)}" for v in py) + "'/>")
        out.append(f"<clipPath id='{clip_id}'><rect x='{_num(left)}' y='{_num(top)}' width='{_num(w)}' "
                   f"height='{_num(h)}'/></clipPath><g clip-path='url(#{clip_id})'><g transform='scale({_FINE})'>")
        out += [self._item(it, fx, fy) for it in self.items if it.kind != "barh"]
        out.append("</g></g>")
        out += [self._bars(it, fx, fy) for it in self.items if it.kind == "barh"]
        out.append(f"<rect x='{_num(left)}' y='{_num(top)}' width='{_num(w)}' height='{_num(h)}' "
                   f"{_style('black', 0.8)}/>")
        out.append(self._ticks(px, [s for s, keep in zip(xlabels, xt_in, strict=True) if keep], py,
                               [s for s, keep in zip(ylabels, yt_in, strict=True) if keep],
                               fx(xminor[(xminor > xl[0]) & (xminor < xl[1])])))
        if self.legend:
            out.append(self._legend())
        return "".join(out)

    def _xticks(self, xl: tuple[float, float]) -> tuple[FloatArray, list[str], FloatArray]:
        """Major x ticks, their labels and minor ticks (log axes: decades labelled 10ᵏ, minor at 2–9 × 10ᵏ)."""
        if not self.xlog:
            ticks = linear_ticks(xl[0], xl[1], self.xbins or _nbins(self.box[2], self.tick_size, 3))
            return ticks, tick_labels(ticks), np.zeros(0)
        k0, k1 = math.floor(math.log10(xl[0])), math.ceil(math.log10(xl[1]))
        exps = np.arange(k0, k1 + 1)
        stride = max(1, math.ceil(len(exps) / _nbins(self.box[2], self.tick_size, 3)))
        exps = exps[exps % stride == 0]
        minor = (np.arange(2, 10)[None, :] * 10.0 ** np.arange(k0, k1 + 1)[:, None]).ravel()
        return 10.0 ** exps, [f"10{str(int(e)).translate(_SUPERSCRIPT)}" for e in exps], minor

    def _item(self, it: _Item, fx: Any, fy: Any) -> str:
        """One item's element, in units of ``_FINE`` pixels."""
        left, top, w, h = _ints(np.array(self.box)).tolist()
        if it.kind == "line":
            return _line(fx(it.x), fy(it.y), it)
        if it.kind == "points":
            return _markers(fx(it.x), fy(it.y), it.marker, it.color, it.width)
        if it.kind in ("hline", "vline") and not np.isfinite(np.r_[it.x, it.y]).all():
            return ""                                                  # a rule at NaN is not drawn
        if it.kind == "hline":
            return f"<path {_style(it.color, it.width, it.dash, unit=_FINE)} d='M{left} {_ints(fy(it.y))[0]}h{w}'/>"
        if it.kind == "vline":
            return f"<path {_style(it.color, it.width, it.dash, unit=_FINE)} d='M{_ints(fx(it.x))[0]} {top}v{h}'/>"
        # stairs: the outline of the filled histogram, closed along zero
        xs, ys = _ints(fx(it.x)).tolist(), _ints(fy(np.r_[0.0, it.y, 0.0])).tolist()
        d = f"M{xs[0]} {ys[0]}" + "".join(f"V{ys[k + 1]}H{xs[k + 1]}" for k in range(len(it.y))) + f"V{ys[-1]}Z"
        opacity = f" fill-opacity='{it.opacity:g}'" if it.opacity < 1 else ""
        return f"<path fill='{it.color}'{opacity} d='{d}'/>"

    def _bars(self, it: _Item, fx: Any, fy: Any) -> str:
        """Bars from zero (from the panel's left edge on a log axis) and the texts after their ends."""
        left = self.box[0]
        base = float(fx(np.array([0.0]))[0]) if not self.xlog else left
        out = []
        for k, (v, y) in enumerate(zip(it.x, it.y, strict=True)):
            end = float(fx(np.array([v]))[0]) if v > 0 or not self.xlog else left
            y_top, y_bottom = float(fy(np.array([y + it.width / 2]))[0]), float(fy(np.array([y - it.width / 2]))[0])
            out.append(f"<rect x='{_num(min(base, end))}' y='{_num(y_top)}' width='{_num(abs(end - base))}' "
                       f"height='{_num(y_bottom - y_top)}' fill='{it.color}'/>")
            if k < len(it.text):
                out.append(self._text(max(end, base) + 3, (y_top + y_bottom) / 2, it.text[k], 8, "start", "central"))
        return "".join(out)

    def _ticks(self, px: FloatArray, xlabels: list[str], py: FloatArray, ylabels: list[str], minor: FloatArray) -> str:
        """Tick marks (outward), tick labels, axis labels and the title."""
        left, top, w, h = self.box
        bottom = top + h
        major, small = 3.5 * PT, 2.0 * PT
        d = "".join(f"M{_num(v)} {_num(bottom)}v{_num(major)}" for v in px)
        d += "".join(f"M{_num(v)} {_num(bottom)}v{_num(small)}" for v in minor)
        d += "".join(f"M{_num(left)} {_num(v)}h{_num(-major)}" for v in py)
        out = [f"<path {_style('black', 0.8)} d='{d}'/>"] if d else []
        fs = self.tick_size
        if self.xticklabels:
            y = bottom + major + 2 + fs * PT
            out += [self._text(x, y, s, fs, "middle") for x, s in zip(px, xlabels, strict=True)]
        out += [self._text(left - major - 3, y, s, fs if not self.yticks else 8, "end", "central")
                for y, s in zip(py, ylabels, strict=True)]
        if self.xlabel:
            out.append(self._text(left + w / 2, bottom + major + 5 + (fs + self.label_size) * PT, self.xlabel,
                                  self.label_size, "middle"))
        if self.ylabel:
            width = max((len(s) for s in ylabels), default=1) * 0.62 * fs * PT
            x = left - major - 3 - width - 5
            out.append(f"<text transform='translate({_num(x)} {_num(top + h / 2)}) rotate(-90)' "
                       f"font-size='{_num(self.label_size * PT)}' text-anchor='middle'>{escape(self.ylabel)}</text>")
        if self.title:
            out.append(self._title())
        return "".join(out)

    def _title(self) -> str:
        left, top, w, _ = self.box
        return self._text(left + w / 2, top - 0.5 * self.title_size * PT, self.title, self.title_size, "middle")

    def _legend(self) -> str:
        """A legend box in the named corner, one row per labelled item."""
        entries = [it for it in self.items if it.label]
        if not entries:
            return ""
        fs = self.legend_size * PT
        row, sample = 1.4 * fs, 2.0 * fs
        width = sample + 0.8 * fs + max(len(it.label or "") for it in entries) * 0.6 * fs + 0.8 * fs
        height = row * len(entries) + 0.6 * fs
        left, top, w, h = self.box
        pad = 0.5 * fs
        x = left + w - width - pad if "right" in (self.legend or "") else left + pad
        y = top + pad if "upper" in (self.legend or "") else top + h - height - pad
        out = [f"<rect x='{_num(x)}' y='{_num(y)}' width='{_num(width)}' height='{_num(height)}' "
               f"rx='{_num(0.25 * fs)}' fill='white' fill-opacity='0.8' stroke='#cccccc' stroke-width='{_num(PT)}'/>"]
        for k, it in enumerate(entries):
            cy = y + 0.3 * fs + row * (k + 0.5)
            x0, x1 = x + 0.4 * fs, x + 0.4 * fs + sample
            if it.kind == "points":
                mark = _markers(np.array([(x0 + x1) / 2]), np.array([cy]), it.marker, it.color, it.width)
            else:
                mark = _line(np.array([x0, x1]), np.array([cy, cy]), it)
            out.append(f"<g transform='scale({_FINE})'>{mark}</g>")
            out.append(self._text(x1 + 0.4 * fs, cy, it.label or "", self.legend_size, "start", "central"))
        return "".join(out)

    @staticmethod
    def _text(x: float, y: float, text: str, size_pt: float, anchor: str, baseline: str = "auto") -> str:
        base = "" if baseline == "auto" else f" dominant-baseline='{baseline}'"
        return (f"<text x='{_num(x)}' y='{_num(y)}' font-size='{_num(size_pt * PT)}' text-anchor='{anchor}'{base}>"
                f"{escape(text)}</text>")


def _array(v: Any) -> FloatArray:
    out: FloatArray = np.asarray(v, dtype=float).reshape(-1)
    return out


def _nbins(length_px: float, font_pt: float, per_label: float) -> int:
    """At most 9 tick intervals, fewer on a short axis (matplotlib's tick space: the axis length over
    ``per_label`` times the label font size)."""
    return max(1, min(9, int(length_px / PT / (font_pt * per_label))))


def _line(x: FloatArray, y: FloatArray, it: _Item) -> str:
    """A line item's path through pixel points, in units of ``_FINE`` px."""
    return f"<path {_style(it.color, it.width, it.dash, it.opacity, _FINE)} d='{_polyline(x, y)}'/>"


def _ints(v: FloatArray) -> IntArray:
    """Pixel coordinates as integers in units of ``_FINE`` pixels."""
    out: IntArray = np.rint(np.asarray(v, dtype=float) / _FINE).astype(np.int64)
    return out


def _polyline(x: FloatArray, y: FloatArray) -> str:
    """Path data (units of ``_FINE`` px, relative steps) through the pixel points (x, y); a
    non-finite point breaks the line."""
    ok = np.isfinite(x) & np.isfinite(y)
    parts = []
    for run in np.split(np.arange(len(x)), np.flatnonzero(np.diff(ok)) + 1):
        if len(run) and ok[run[0]]:
            xi, yi = _ints(x[run]), _ints(y[run])
            steps = np.column_stack((np.diff(xi), np.diff(yi))).ravel().tolist()
            parts.append(f"M{xi[0]} {yi[0]}" + ("l" + " ".join(map(str, steps)) if steps else ""))
    return "".join(parts)


def _markers(x: FloatArray, y: FloatArray, marker: str, color: str, size_pt: float) -> str:
    """Dots (round caps of zero-length strokes) or crosses at the finite pixel points, as one path
    in units of ``_FINE`` px."""
    ok = np.isfinite(x) & np.isfinite(y)
    xi, yi = _ints(x[ok]), _ints(y[ok])
    if not len(xi):
        return ""
    moves = np.column_stack((np.diff(xi), np.diff(yi))).tolist()
    if marker == "x":
        a = int(round(size_pt * PT / 2 / _FINE))
        cross = f"m{-a} {-a}l{2 * a} {2 * a}m0 {-2 * a}l{-2 * a} {2 * a}m{a} {-a}"
        d = f"M{xi[0]} {yi[0]}{cross}" + "".join(f"m{dx} {dy}{cross}" for dx, dy in moves)
        return f"<path {_style(color, 1.0, unit=_FINE)} d='{d}'/>"
    d = f"M{xi[0]} {yi[0]}h0" + "".join(f"m{dx} {dy}h0" for dx, dy in moves)
    return (f"<path fill='none' stroke='{color}' stroke-width='{_num(size_pt * PT / _FINE)}' "
            f"stroke-linecap='round' d='{d}'/>")


class Chart:
    """A ``width`` x ``height`` [in] chart of panels laid out by :meth:`grid`; :meth:`svg` renders it."""

    def __init__(self, width: float, height: float) -> None:
        self.width, self.height = width * DPI, height * DPI
        self.panels: list[Panel] = []

    def grid(self, nrows: int, ncols: int, *, margins: tuple[float, float, float, float],
             gaps: tuple[float, float] = (0.0, 0.0), width_ratios: Sequence[float] | None = None) -> list[Panel]:
        """``nrows`` x ``ncols`` panels (row by row) inside fixed ``margins`` (left, right, bottom, top)
        and with ``gaps`` (between columns, between rows) [in], columns as wide as ``width_ratios``."""
        left, right, bottom, top = (m * DPI for m in margins)
        gx, gy = gaps[0] * DPI, gaps[1] * DPI
        ratios = np.asarray(width_ratios if width_ratios is not None else np.ones(ncols), dtype=float)
        widths = (self.width - left - right - (ncols - 1) * gx) * ratios / ratios.sum()
        xs = left + np.r_[0.0, np.cumsum(widths + gx)[:-1]]
        h = (self.height - top - bottom - (nrows - 1) * gy) / nrows
        panels = [Panel((float(xs[c]), top + r * (h + gy), float(widths[c]), h)) for r in range(nrows)
                  for c in range(ncols)]
        self.panels += panels
        return panels

    def svg(self) -> str:
        """The chart as a standalone SVG document."""
        body = "".join(p.svg(f"c{k}") for k, p in enumerate(self.panels))
        return (f"<svg xmlns='http://www.w3.org/2000/svg' width='{_num(self.width)}' height='{_num(self.height)}' "
                f"viewBox='0 0 {_num(self.width)} {_num(self.height)}' font-family='{FONT}' fill='#000'>"
                f"<rect width='100%' height='100%' fill='white'/>{body}</svg>")
