"""Read all streams of a rig: every topic / TF chain of the log in one pass, plus separate files.

A stream is named on the command line as ``NAME=SOURCE``:

* ``NAME=/topic`` — a pose-carrying topic of the log;
* ``NAME=tf:PARENT,CHILD`` — the TF chain PARENT→CHILD of the log (``/tf`` + ``/tf_static``);
* ``NAME=FILE`` — a separate pose file (TUM, EuRoC, CSV) holding ``T_world_sensor``.

Each stream is ``T_frame_child(t)``: int64 ns stamps, positions [m], quaternions x-y-z-w.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

from ..errors import ConfigError
from ..io.remote import is_url
from ..io.spec import StreamSpec
from ..options import Options, frame_name
from ..pipeline import read_streams
from ..streams import PoseStream

__all__ = ["StreamSpec", "parse_stream", "read_rig"]


def parse_stream(text: str) -> StreamSpec:
    """``NAME=/topic``, ``NAME=tf:PARENT,CHILD`` or ``NAME=FILE`` → a named :class:`StreamSpec` (a topic or TF
    chain has no path: it is the rig's log's)."""
    name, sep, source = text.partition("=")
    name, source = name.strip(), source.strip()
    if not sep or not name or not source:
        raise ConfigError(f"bad stream {text!r}", "streams", "write NAME=/topic, NAME=tf:PARENT,CHILD or NAME=FILE")
    name = str(frame_name(name, f"--stream {text}"))       # the name is the sensor's frame in every output
    if source.startswith("tf:"):
        frames = [f.strip() for f in source[3:].split(",")]
        if len(frames) != 2 or not all(frames):
            raise ConfigError(f"bad TF chain {source!r}", f"--stream {text}", "write NAME=tf:PARENT,CHILD")
        return StreamSpec(frames=(frames[0], frames[1]), name=name)
    if Path(source).is_file() or is_url(source):
        return StreamSpec(source, name=name)
    if source.startswith("/"):
        return StreamSpec(topic=source, name=name)
    raise ConfigError(f"{source!r} is neither a topic (/…), a TF chain (tf:PARENT,CHILD) nor an existing file",
                      f"--stream {text}", "check the path, or start a topic with /")


def read_rig(log: str | None, specs: list[StreamSpec], options: Options | None = None, *,
             quiet: bool = True, wxyz: Mapping[str, bool] | None = None) -> dict[str, PoseStream]:
    """Every stream by name, in the order of ``specs`` (each named; a spec without a path is a topic or TF chain
    of ``log``): :func:`handeye_cli.pipeline.read_streams`, the read path of ``calibrate``, so every read option
    of ``options`` (time source, time unit, CSV columns) applies alike, and all streams of the log are read in
    a single pass. ``wxyz``: per stream name, whether its text file stores quaternions w first (unset: the
    format's order)."""
    names = [s.name or "" for s in specs]
    if not all(names) or len(set(names)) != len(names):
        raise ConfigError("stream names repeat or are missing", ", ".join(names),
                          "give every --stream a different NAME")
    in_log = [s for s in specs if s.path is None]
    if in_log and log is None:
        raise ConfigError(f"stream {in_log[0].name} names a topic or TF chain but no log is given", "handeye rig",
                          "pass the log as the first argument: handeye rig LOG --stream …")
    located = [s if s.path is not None else replace(s, path=log) for s in specs]
    orders = ["auto" if name not in (wxyz or {}) else "wxyz" if (wxyz or {})[name] else "xyzw" for name in names]
    return dict(zip(names, read_streams(located, options, quiet=quiet, quaternion_orders=orders), strict=True))
