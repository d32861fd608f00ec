"""Read all streams of a rig: every topic / TF chain of the log in one pass, plus separate files.

A stream is named on the command line as ``NAME=SOURCE``, SOURCE in the spelling every command shares
(:mod:`handeye_cli.io.spec`):

* ``NAME=/topic`` — a pose-carrying topic of the log;
* ``NAME=tf:PARENT,CHILD`` — the TF chain PARENT→CHILD of the log (``/tf`` + ``/tf_static``), the parent first;
* ``NAME=FILE`` — a separate pose file (TUM, EuRoC, CSV) holding ``T_world_sensor``.

Each stream is ``T_frame_child(t)``: int64 ns stamps, positions [m], quaternions x-y-z-w.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

from ..calibration import read_streams
from ..errors import ConfigError
from ..io.spec import SOURCE_FORMS, StreamSpec, stream_source
from ..options import Options, frame_name
from ..streams import PoseStream

__all__ = ["StreamSpec", "parse_stream", "read_rig"]


def parse_stream(text: str) -> StreamSpec:
    """``NAME=SOURCE`` → a named :class:`StreamSpec`: SOURCE in the spelling every command shares, parsed by
    :func:`~handeye_cli.io.spec.stream_source` (``/topic`` or ``tf:PARENT,CHILD`` of the rig's log: no path;
    ``FILE``)."""
    name, sep, source = text.partition("=")
    name, source = name.strip(), source.strip()
    if not sep or not name or not source:
        raise ConfigError(f"bad stream {text!r}", "streams", f"write NAME=SOURCE, SOURCE one of {SOURCE_FORMS}")
    name = str(frame_name(name, f"⟦streams='{text}'⟧"))       # the name is the sensor's frame in every output
    spec = stream_source("streams", source)
    assert spec is not None                                 # a source was given
    return replace(spec, name=name)


def read_rig(log: str | None, specs: list[StreamSpec], options: Options | None = None, *,
             quiet: bool = True, wxyz: Mapping[str, bool] | None = None) -> dict[str, PoseStream]:
    """Every stream by name, in the order of ``specs`` (each named; a spec without a path is a topic or TF chain
    of ``log``): :func:`handeye_cli.calibration.read_streams`, the read path of ``calibrate``, so every read option
    of ``options`` (time source, time unit, CSV columns) applies alike, and all streams of the log are read in
    a single pass. ``wxyz``: per stream name, whether its text file stores quaternions w first (unset: the
    format's order)."""
    names = [s.name or "" for s in specs]
    if not all(names) or len(set(names)) != len(names):
        raise ConfigError("stream names repeat or are missing", ", ".join(names),
                          "give every ⟦streams⟧ a different NAME")
    in_log = [s for s in specs if s.path is None]
    if in_log and log is None:
        raise ConfigError(f"stream {in_log[0].name} names a topic or TF chain but no log is given", "handeye rig",
                          "pass the log as the first argument: handeye rig LOG ⟦streams⟧ …")
    located = [s if s.path is not None else replace(s, path=log) for s in specs]
    orders = ["auto" if name not in (wxyz or {}) else "wxyz" if (wxyz or {})[name] else "xyzw" for name in names]
    return dict(zip(names, read_streams(located, options, quiet=quiet, quaternion_orders=orders), strict=True))
