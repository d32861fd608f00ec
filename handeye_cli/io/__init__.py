"""Readers: any supported log or trajectory file → :class:`~handeye_cli.streams.PoseStream`.

Formats (detected by content, see :func:`detect_format`): MCAP (ROS 2 CDR, ROS 1, Foxglove
JSON channels), ROS 1 ``.bag`` (several split files read as one), ROS 2 bags (directory or bare
``.db3``), TUM, EuRoC CSV and generic CSV. Every stream is ``T_frame_child(t)``: int64 ns
stamps sorted ascending, positions [m], unit quaternions x-y-z-w.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..streams import PoseStream
from .detect import detect_format
from .formats import BY_NAME, LOG_FORMATS, open_log, opened
from .inputs import existing, spooled, valid_frame_id
from .logs import Request, inspect_source, read_requests
from .remote import RemoteObject, current, is_url
from .spec import StreamSpec
from .text import read_text

__all__ = ["StreamSpec", "read_specs", "read_stream", "read_log_streams", "inspect_log", "detect_format",
           "valid_frame_id"]

_TIME_SOURCES = ("header", "log")


def _inputs(paths: str | Path | Sequence[str | Path]) -> tuple[list[Path | RemoteObject], list[str]]:
    """What the readers open for each input and its format: an existing path (``-`` = stdin; logs
    arriving on a pipe spooled to a file), or for a URL a remote object read by range or its local
    copy (see :func:`.formats.opened`)."""
    given = [paths] if isinstance(paths, (str, Path)) else list(paths)
    fmts = [detect_format(p) for p in given]
    found: list[Path | RemoteObject] = []
    for p, f in zip(given, fmts, strict=True):
        if is_url(p):
            found.append(opened(str(p), f))
        else:
            found.append(spooled(existing(p), BY_NAME[f].suffixes[0]) if BY_NAME[f].log else existing(p))
    return found, fmts


def _named(given: str | Path | Sequence[str | Path]) -> list[str]:
    return [str(p) for p in ([given] if isinstance(given, (str, Path)) else given)]


def _noted(stream: PoseStream, names: Sequence[str]) -> PoseStream:
    """``stream`` with the remote session's notes on these inputs (a download to the cache) first in its warnings."""
    notes = tuple(n for n in current().notes if any(n.startswith(f"{name}: ") for name in names))
    return replace(stream, warnings=(*notes, *stream.warnings)) if notes else stream


def read_stream(paths: str | Path | Sequence[str | Path], *, topic: str | None = None,
                frames: tuple[str, str] | None = None, time_source: str = "header",
                columns: Mapping[str, str] | None = None, quiet: bool = True, quaternion_order: str = "auto",
                time_unit: str = "auto") -> PoseStream:
    """Read one pose stream ``T_frame_child(t)``.

    Logs (MCAP, ROS bags): give exactly one of ``topic`` (a pose-carrying topic: PoseStamped,
    PoseWithCovarianceStamped, TransformStamped, Odometry, TFMessage/FrameTransform(s) of one
    frame pair, Foxglove PoseInFrame/PosesInFrame) or ``frames=(parent, child)``, resolved
    through ``/tf`` + ``/tf_static`` into ``T_parent_child``. Several paths = split ROS 1 bags.
    Text files (TUM, EuRoC, CSV; ``-`` = stdin, pipes are read once): one path, no topic/frames;
    ``columns`` maps generic CSV columns (keys ``t, t_unit, x, y, z, qx, qy, qz, qw``);
    ``quaternion_order`` (``"auto"``: the format's, open to the fit | ``"xyzw"`` | ``"wxyz"``) and
    ``time_unit`` (``"auto"`` | ``"s"`` | ``"ms"`` | ``"us"`` | ``"ns"``)
    as in :func:`.text.read_text` (ignored for logs).

    ``time_source``: ``"header"`` (header.stamp / each transform's stamp) or ``"log"`` (the
    recorder's log time; logs only). ``quiet=False`` shows a progress bar on stderr when stderr
    is a terminal.

    Returns the poses of the child frame in the parent frame (text files: ``T_world_<file stem>``):
    int64 nanosecond stamps sorted ascending (repeated stamps dropped, first kept, counted in
    ``duplicates_dropped``), positions in metres, unit Hamilton quaternions in x-y-z-w order.
    Invalid poses are dropped, a clock jumping back keeps its longest run, a truncated recording
    is read up to its last intact message: each with a line in ``warnings`` (``recovered_truncated``
    counts recovered messages). Raises HandEyeError (one line: what, where, how to fix) on any bad input.
    """
    given = _named(paths)
    if not given:
        raise ConfigError("no input file given", "read_stream", "pass a path")
    if len(given) > 1:                          # split ROS 1 bags, read as one
        return read_log_streams(given, [(topic, frames)], time_source=time_source, quiet=quiet)[0]
    return read_specs([StreamSpec(given[0], topic, frames)], time_source=time_source, columns=columns,
                      quaternion_orders=[quaternion_order], time_unit=time_unit, quiet=quiet)[0]


def read_specs(specs: Sequence[StreamSpec], *, time_source: str = "header", columns: Mapping[str, str] | None = None,
               quaternion_orders: Sequence[str] | None = None, time_unit: str = "auto", quiet: bool = True
               ) -> list[PoseStream]:
    """The streams of ``specs``, in their order, each as :func:`read_stream` returns it: each input is
    found, detected and (a pipe) spooled once; every stream of one log is read in a single pass over it.
    ``quaternion_orders``: per spec, as :func:`read_stream`'s ``quaternion_order`` (default ``"auto"``);
    the other keywords as :func:`read_stream`'s, for every spec. Raises HandEyeError on any bad input."""
    if time_source not in _TIME_SOURCES:
        raise ConfigError(f"unknown time source {time_source!r}", "time_source", "use 'header' or 'log'")
    orders = list(quaternion_orders or ["auto"] * len(specs))
    found: dict[str, tuple[Path | RemoteObject, str]] = {}
    in_log: dict[str, list[int]] = {}
    streams: dict[int, PoseStream] = {}
    for k, spec in enumerate(specs):
        if spec.path is None:
            raise ConfigError(f"stream {spec.name or k} names no file", "read_specs", "give every StreamSpec a path")
        if spec.path not in found:
            (p,), (fmt,) = _inputs(spec.path)
            found[spec.path] = (p, fmt)
        p, fmt = found[spec.path]
        if fmt in LOG_FORMATS:
            in_log.setdefault(spec.path, []).append(k)
        elif spec.topic is not None or spec.frames is not None:
            raise ConfigError(f"a {fmt.upper()} text file holds one stream: no topic/frames and one file per stream",
                              str(p), "drop ⟦topic⟧/⟦frames⟧ and pass one text file per stream")
        else:
            stream = read_text(_local(p), fmt, columns, quaternion_order=orders[k], time_unit=time_unit)
            streams[k] = _noted(stream, [spec.path])
    for path, ks in in_log.items():
        p, fmt = found[path]
        read = _read_log([p], [fmt], [(specs[k].topic, specs[k].frames) for k in ks], time_source, quiet, [path])
        streams.update(zip(ks, read, strict=True))
    return [streams[k] for k in range(len(specs))]


def read_log_streams(paths: str | Path | Sequence[str | Path], requests: Sequence[Request], *,
                     time_source: str = "header", quiet: bool = True) -> list[PoseStream]:
    """Several streams of one log (MCAP, ROS bags; several paths = split ROS 1 bags) in a single
    pass, one per request ``(topic, None)`` or ``(None, (parent, child))``, each as
    :func:`read_stream` returns it. Raises HandEyeError on any bad input."""
    plist, fmts = _inputs(paths)
    if time_source not in _TIME_SOURCES:
        raise ConfigError(f"unknown time source {time_source!r}", "time_source", "use 'header' or 'log'")
    if not plist or fmts[0] not in LOG_FORMATS:
        raise ConfigError("not a log (MCAP, ROS 1 or ROS 2 bag)", ", ".join(map(str, plist)) or "read_log_streams",
                           "a text file holds one stream: read one file per stream with read_stream")
    return _read_log(plist, fmts, requests, time_source, quiet, _named(paths))


def _local(p: Path | RemoteObject) -> Path:
    """A text input's local file (a URL's text is always its cached copy)."""
    assert isinstance(p, Path), "text objects are downloaded, never read by range"
    return p


def _read_log(plist: list[Path | RemoteObject], fmts: list[str], requests: Sequence[Request], time_source: str,
              quiet: bool, names: list[str]) -> list[PoseStream]:
    for topic, frames in requests:
        if (topic is None) == (frames is None):
            raise ConfigError("give exactly one of a topic or a (parent, child) frame pair", ", ".join(map(str, plist)),
                              "name each stream as /topic or tf:PARENT,CHILD (⟦stream_a⟧/⟦stream_b⟧)")
    with open_log(plist, fmts) as src:
        if any(map(is_url, names)):
            src.name = ", ".join(names)
        return [_noted(s, names) for s in read_requests(src, requests, time_source=time_source, quiet=quiet)]


def inspect_log(path: str | Path, *, quiet: bool = True) -> dict[str, Any]:
    """A JSON-able overview of one file.

    Logs: ``format``, ``path``, ``start_ns``/``end_ns``/``duration_ns`` (log time),
    ``topics`` [{topic, type, encoding, count, first_ns, last_ns, rate_hz, rate_over, pose}] (each
    topic rated over its own span; ``rate_over``: ``topic``, ``log`` when the file does not tell
    the topic's span, ``latched`` for ``/tf_static``, whose rate is None), ``tf_frames``
    [{parent, child, static, count}] from every TF message (``tf_messages``), ``warnings``
    (the file cut off or damaged: what was lost; read without an index).
    Text files: ``format``, ``path``, ``rows``, ``start_ns``, ``end_ns``, ``duration_ns``, ``rate_hz``.
    """
    (p,), (fmt,) = _inputs(path)
    shown = str(path) if is_url(path) else str(p)
    if fmt not in LOG_FORMATS:
        s = read_text(_local(p), fmt)
        span = int(s.stamps_ns[-1] - s.stamps_ns[0])
        return {"format": fmt, "path": shown, "rows": len(s) + s.duplicates_dropped,
                "start_ns": int(s.stamps_ns[0]), "end_ns": int(s.stamps_ns[-1]), "duration_ns": span,
                "rate_hz": round((len(s) - 1) / span * 1e9, 3) if span else 0.0}
    with open_log([p], [fmt]) as src:
        src.name = shown
        return {"format": fmt, "path": shown, **inspect_source(src, quiet)}
