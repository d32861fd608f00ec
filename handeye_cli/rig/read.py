"""Read all streams of a rig: every topic / TF chain of the log in one pass, plus separate files.

A stream is named on the command line as ``NAME=SOURCE``:

* ``NAME=/topic`` — a pose-carrying topic of the log;
* ``NAME=tf:PARENT,CHILD`` — the TF chain PARENT→CHILD of the log (``/tf`` + ``/tf_static``);
* ``NAME=FILE`` — a separate pose file (TUM, EuRoC, CSV) holding ``T_world_sensor``.

Each stream is ``T_frame_child(t)``: int64 ns stamps, positions [m], quaternions x-y-z-w.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..io import read_log_streams, read_stream
from ..io.remote import is_url
from ..options import frame_name
from ..streams import PoseStream

__all__ = ["StreamSpec", "parse_stream", "read_rig"]


@dataclass(frozen=True)
class StreamSpec:
    """One named stream: a topic or a ``(parent, child)`` frame pair of the rig's log, or a file."""

    name: str
    topic: str | None = None
    frames: tuple[str, str] | None = None
    path: str | None = None

    def describe(self) -> dict[str, Any]:
        if self.path:
            return {"file": self.path}
        return {"topic": self.topic} if self.topic else {"frames": list(self.frames or ())}


def parse_stream(text: str) -> StreamSpec:
    """``NAME=/topic``, ``NAME=tf:PARENT,CHILD`` or ``NAME=FILE`` → :class:`StreamSpec`."""
    name, sep, source = text.partition("=")
    name, source = name.strip(), source.strip()
    if not sep or not name or not source:
        raise ConfigError(f"bad stream {text!r}", "--stream", "write NAME=/topic, NAME=tf:PARENT,CHILD or NAME=FILE")
    name = str(frame_name(name, f"--stream {text}"))       # the name is the sensor's frame in every output
    if source.startswith("tf:"):
        frames = [f.strip() for f in source[3:].split(",")]
        if len(frames) != 2 or not all(frames):
            raise ConfigError(f"bad TF chain {source!r}", f"--stream {text}", "write NAME=tf:PARENT,CHILD")
        return StreamSpec(name, frames=(frames[0], frames[1]))
    if Path(source).is_file() or is_url(source):
        return StreamSpec(name, path=source)
    if source.startswith("/"):
        return StreamSpec(name, topic=source)
    raise ConfigError(f"{source!r} is neither a topic (/…), a TF chain (tf:PARENT,CHILD) nor an existing file",
                      f"--stream {text}", "check the path, or start a topic with /")


def read_rig(log: str | None, specs: list[StreamSpec], *, time_source: str = "header",
             columns: Mapping[str, str] | None = None, quiet: bool = True) -> dict[str, PoseStream]:
    """Read every stream, in the order of ``specs``: all topics and TF chains of ``log`` in a
    single pass (:func:`handeye_cli.io.read_log_streams`), separate files one by one."""
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        raise ConfigError("stream names repeat", ", ".join(names), "give every --stream a different NAME")
    in_log = [s for s in specs if s.path is None]
    if in_log and log is None:
        raise ConfigError(f"stream {in_log[0].name} names a topic or TF chain but no log is given", "handeye rig",
                          "pass the log as the first argument: handeye rig LOG --stream …")
    streams: dict[str, PoseStream] = {}
    if in_log and log is not None:
        read = read_log_streams(log, [(s.topic, s.frames) for s in in_log], time_source=time_source, quiet=quiet)
        streams.update(zip((s.name for s in in_log), read, strict=True))
    for s in specs:
        if s.path is not None:
            streams[s.name] = read_stream(s.path, time_source=time_source, columns=dict(columns) if columns else None,
                                         quiet=quiet)
    return {s.name: streams[s.name] for s in specs}
