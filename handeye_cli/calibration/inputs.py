"""The inputs of one calibration: streams a and b named (:func:`stream_specs`, the spelling every command and
the Python API share), read (:func:`read_streams`, the one read path of calibrate, rig and batch), checked
(:func:`check_samples`, :func:`refuse_unread`), inverted where the options say so, and the prior read.

Each stream holds ``T_world_sensor(t)``: int64 ns stamps, positions [m], quaternions x-y-z-w.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError, DataError, HandEyeError
from ..io.nominal import read_nominal
from ..io.spec import StreamSpec, stream_source
from ..options import FIELDS, Options, ReadOptions
from ..solvers import Prior
from ..streams import PoseStream

__all__ = ["Inputs", "Source", "check_samples", "inverted", "inverted_as_read", "read_prior", "read_streams",
           "refuse_unread", "stream_specs"]

Source = str | Path | StreamSpec | PoseStream


def stream_specs(inputs: Sequence[Source], *, stream_a: str | StreamSpec | None = None,
                 stream_b: str | StreamSpec | None = None, topic_a: str | None = None, topic_b: str | None = None,
                 frames_a: str | Sequence[str] | None = None, frames_b: str | Sequence[str] | None = None
                 ) -> tuple[StreamSpec | PoseStream, StreamSpec | PoseStream]:
    """Streams a and b of one calibration, as ``handeye calibrate`` / ``compare`` and :func:`~.run.calibrate_files` name
    them: ``inputs`` (a log; or one file, :class:`StreamSpec` or in-memory ``PoseStream`` per stream, a then b)
    and each stream's source in the shared spelling (``stream_a``: ``/topic``, ``tf:PARENT,CHILD`` or ``FILE``, or
    its synonyms ``topic_a``, ``frames_a`` = (PARENT, CHILD); :func:`~handeye_cli.io.spec.stream_source` parses
    them). A topic or TF chain is read from the log (a: the first input, b: the last); a FILE is a stream of its
    own and takes no input; a stream named by neither is its input, whole."""
    sources = (stream_source("stream_a", stream_a, topic=topic_a, frames=frames_a),
               stream_source("stream_b", stream_b, topic=topic_b, frames=frames_b))
    own = [s is not None and s.path is not None for s in sources]
    shown = " ".join(map(str, inputs)) or "no input"
    if len(inputs) > 2 - sum(own):
        raise ConfigError(f"{len(inputs)} inputs given for {2 - sum(own)} stream(s) read from them", shown,
                          "pass one log, or one file per stream (a then b); a stream named as a FILE "
                          "(⟦stream_a=FILE⟧) takes none")
    if not inputs and not all(own):
        raise ConfigError("no input given", "inputs", "pass a log, or one pose file per stream (a then b), or name "
                          "both streams as files (⟦stream_a=FILE⟧ ⟦stream_b=FILE⟧)")
    if len(inputs) == 1 and not any(own) and not all(s is not None for s in sources):
        raise ConfigError("one input needs a topic or a TF chain for each stream", shown,
                          "add ⟦stream_a⟧/⟦stream_b='/topic'⟧ or tf:PARENT,CHILD (see 'handeye inspect "
                          f"{inputs[0]}'), or pass two pose files")
    specs: list[StreamSpec | PoseStream] = []
    for k, source in enumerate(sources):
        if source is not None and source.path is not None:
            specs.append(source)
            continue
        item = inputs[0] if k == 0 else inputs[-1]
        if not isinstance(item, str | Path | PoseStream | StreamSpec):
            raise ConfigError(f"cannot read a stream from {type(item).__name__}", "calibrate_files",
                              "give a file path, a StreamSpec or a PoseStream")
        if isinstance(item, PoseStream | StreamSpec):
            if source is not None:
                raise ConfigError("a topic or TF chain was given for a stream that is not a file",
                                  f"stream_{'ab'[k]}", "name a stream's source only with a log's path")
            specs.append(item)
        else:
            specs.append(StreamSpec(str(item)) if source is None else replace(source, path=str(item)))
    if sum(isinstance(s, StreamSpec) and s.path == "-" for s in specs) > 1:
        raise ConfigError("stdin ('-') can feed only one stream", shown, "pass the other as a file")
    return specs[0], specs[1]


def read_streams(specs: Sequence[StreamSpec | PoseStream], options: Options | None = None, *,
                 quiet: bool = True, quaternion_orders: Sequence[str] | None = None) -> list[PoseStream]:
    """The streams of ``specs`` (a PoseStream is taken as it is), as the files hold them: the one read path of
    calibrate, rig and batch. Each input is detected once and every stream of one log read in one pass
    (:func:`~handeye_cli.io.read_specs`); ``options.read`` sets the time source, CSV columns and time unit of
    every file, ``wxyz_a`` / ``wxyz_b`` the quaternion order of the first / second stream (a rig's others: the
    format's, open to the fit), or ``quaternion_orders`` per spec (``auto``, ``xyzw``, ``wxyz``: a rig's, by stream
    name). :func:`~.run.calibrate_read` inverts them where the options say so."""
    from ..io import read_specs  # mcap/rosbags: import only when reading

    read = (options or Options()).read
    wxyz = (read.wxyz_a, read.wxyz_b)
    files = [(k, s) for k, s in enumerate(specs) if isinstance(s, StreamSpec)]
    orders = [quaternion_orders[k] if quaternion_orders else "auto" if k > 1 or wxyz[k] is None
              else "wxyz" if wxyz[k] else "xyzw" for k, _ in files]
    read_now = read_specs([s for _, s in files], time_source=read.time_source,
                          columns=dict(read.csv_columns) if read.csv_columns else None, quaternion_orders=orders,
                          time_unit=read.time_unit, quiet=quiet)
    streams = dict(zip((k for k, _ in files), read_now, strict=True))
    return [s if isinstance(s, PoseStream) else streams[k] for k, s in enumerate(specs)]


def inverted_as_read(a: PoseStream, b: PoseStream, read: ReadOptions) -> tuple[PoseStream, PoseStream]:
    """Streams a and b inverted where ``invert_a`` / ``invert_b`` say so (``T_sensor_world`` → ``T_world_sensor``):
    after the quaternion order is chosen, which re-reads a file's columns (:func:`~.run.calibrate_read`)."""
    return (a.inverted() if read.invert_a else a), (b.inverted() if read.invert_b else b)


# The read options that only a file reader applies: the streams each concerns (a: 0, b: 1) and how to do
# without it. An in-memory PoseStream is already parsed, so these are refused for it, not recorded as applied.
_FILE_ONLY: dict[str, tuple[tuple[int, ...], str]] = {
    **{f"wxyz_{s}": ((k,), f"a PoseStream's quat_xyzw is x-y-z-w by definition: reorder the array "
                           f"(q_wxyz[:, [1, 2, 3, 0]]) and leave wxyz_{s} unset") for k, s in enumerate("ab")},
    "time_unit": ((0, 1), "a PoseStream's stamps are int64 nanoseconds (PoseStream.from_seconds converts "
                          "seconds): leave time_unit unset"),
    "csv_columns": ((0, 1), "a PoseStream has no columns: leave csv_columns unset"),
    "time_source": ((0, 1), "a PoseStream's stamps are the ones it was built with: leave time_source unset, or "
                            "read the log with calibrate_files"),
    **{name: ((0, 1), f"in-memory PoseStreams are read from no URL: leave {name} unset")
       for name in ("storage_option", "remote_timeout", "remote_retries", "remote_deadline")},
}


def refuse_unread(read: ReadOptions, in_memory: tuple[bool, bool]) -> None:
    """Refuse a read option (keyword or configuration key) set away from its default where no file reader
    reads the stream it concerns: ``in_memory`` says which of a, b are PoseStreams."""
    for name, (sides, fix) in _FILE_ONLY.items():
        value = getattr(read, name)
        if value != FIELDS[name][2] and all(in_memory[k] for k in sides):
            which = f"stream {'ab'[sides[0]]} is an in-memory PoseStream" if len(sides) == 1 else \
                "both streams are in-memory PoseStreams"
            shown = "***" if FIELDS[name][1].secret else repr(value)       # a credential is not repeated
            raise ConfigError(f"{name}={shown} applies to reading a file, but {which}", name, fix)



@dataclass(frozen=True)
class Inputs:
    """What one calibration read (the result's ``inputs``, :meth:`as_dict`): each stream's source — a
    :class:`~handeye_cli.io.spec.StreamSpec` (its file, and topic or TF frames), an in-memory stream's ``source``
    label, or None (not said) — how the stamps were read (``time_source``), which streams were inverted before use,
    and the bytes fetched from object storage [B] (URL inputs; None: none)."""

    a: StreamSpec | str | None = None
    b: StreamSpec | str | None = None
    time_source: str | None = None
    inverted: tuple[bool, bool] = (False, False)
    bytes_fetched: int | None = None

    @classmethod
    def of(cls, spec_a: StreamSpec | PoseStream, spec_b: StreamSpec | PoseStream, read: ReadOptions,
           bytes_fetched: int | None = None) -> Inputs:
        """The inputs of streams named ``spec_a``, ``spec_b`` and read with ``read``."""
        label = [s if isinstance(s, StreamSpec) else s.source or "in memory" for s in (spec_a, spec_b)]
        return cls(label[0], label[1], read.time_source, inverted(read), bytes_fetched)

    def frames(self, key: str) -> tuple[str, str] | None:
        """The TF pair (parent, child) stream ``key`` (``a``, ``b``) was read from, or None."""
        spec = self.a if key == "a" else self.b
        return (spec.frames[0], spec.frames[1]) if isinstance(spec, StreamSpec) and spec.frames else None

    def topics(self) -> tuple[str | None, str | None]:
        """Each stream's topic (None: not read from a topic)."""
        a, b = (s.topic if isinstance(s, StreamSpec) and s.topic else None for s in (self.a, self.b))
        return a, b

    def as_dict(self) -> dict[str, Any]:
        """The result's ``inputs``."""
        out: dict[str, Any] = {k: s.describe() if isinstance(s, StreamSpec) else {"stream": s}
                               for k, s in (("a", self.a), ("b", self.b)) if s is not None}
        if self.time_source is not None:
            out["time_source"] = self.time_source
        out.update({key: True for key, on in zip(("invert_a", "invert_b"), self.inverted, strict=True) if on})
        if self.bytes_fetched is not None:
            out["bytes_fetched"] = self.bytes_fetched
        return out


def inverted(read: ReadOptions) -> tuple[bool, bool]:
    """Which streams the read options invert before use (a, b)."""
    return bool(read.invert_a), bool(read.invert_b)


def check_samples(stream: PoseStream, label: str) -> None:
    """A stream built in memory whose samples hold a NaN or infinite value or a zero-norm quaternion is
    refused naming the first as the user indexes the arrays (``label``, e.g. ``stream b``, then ``sample 10``,
    0-based), not as a
    motion later (``motions_b[401]``). Streams read from files have such samples dropped already
    (with a warning), so this is quiet for them."""
    quat = stream.quat_xyzw
    bad = ~(np.isfinite(stream.xyz).all(axis=1) & np.isfinite(quat).all(axis=1)) | ~(np.abs(quat) > 0).any(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise DataError(f"{label}, sample {k} (0-based: xyz[{k}] {stream.xyz[k].tolist()}, quat_xyzw[{k}] "
                        f"{quat[k].tolist()}) has a NaN or infinite value or a zero-norm quaternion; "
                        f"{int(bad.sum())} such sample(s) in all", stream.source or label,
                        "remove or repair those samples (a file's are dropped with a warning)")


def read_prior(options: Options, frames: tuple[str, str] | None = None) -> Prior | None:
    """The prior of the options (``prior``: any nominal :func:`~handeye_cli.io.nominal.read_nominal`
    reads, the transform between ``frames`` (a, b); ``prior_weights``: paper eq 26), or None."""
    s = options.solver
    if s.prior is None:
        return None
    try:
        T = read_nominal(s.prior).transform(*(frames or (None, None)))
    except HandEyeError as e:                 # name the flag that chose the file
        fix = e.fix.replace("⟦against⟧", "⟦prior⟧") if e.fix else "check ⟦prior⟧"
        raise type(e)(e.what, e.where.replace("⟦against⟧", "⟦prior⟧"),
                      fix if "⟦prior⟧" in fix else f"{fix} given with ⟦prior⟧") from None
    return Prior(T, *s.prior_weights)
