"""Where a pose stream is read from: :class:`StreamSpec`, the one description of an input stream that
``calibrate``, ``rig`` and ``batch`` share (and :func:`handeye_cli.io.read_specs` reads), and
:func:`stream_source`, the one parser of the spelling every command and the Python API name a stream in:

* ``/topic`` — a pose-carrying topic of the log;
* ``tf:PARENT,CHILD`` — the TF chain PARENT→CHILD of the log (``/tf`` + ``/tf_static``), the parent first;
* ``FILE`` — a pose file of its own (TUM, EuRoC, CSV, or a log holding one stream); ``-`` is stdin.

``calibrate --stream-a SOURCE`` / ``batch --stream-a SOURCE`` / ``rig --stream NAME=SOURCE``, the keywords
``calibrate_files(stream_a=…)`` and ``calibrate_rig_files(…, ["NAME=SOURCE", …])``, and ``stream_a: SOURCE`` in
a batch's per-input file. ``--topic-a TOPIC`` (any topic name, with or without ``/``) and ``--frames-a PARENT
CHILD`` (keywords ``topic_a``, ``frames_a=(PARENT, CHILD)``) are synonyms parsed by the same function.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import ConfigError, option
from .remote import is_url

__all__ = ["SOURCE_FORMS", "StreamSpec", "stream_source"]

#: the spelling of a stream source, as errors and help texts show it
SOURCE_FORMS = "/topic, tf:PARENT,CHILD (the parent first) or FILE"


@dataclass(frozen=True)
class StreamSpec:
    """One pose stream ``T_frame_child(t)`` to read.

    path: the file — a log (MCAP, ROS 1 bag, ROS 2 bag) or a text pose file (TUM, EuRoC, CSV); ``-``
        is stdin. ``None`` for a source of "the log" the command reads (a topic or TF chain named before
        the log is known: :func:`stream_source`).
    topic: in a log, a pose-carrying topic; frames: in a log, a ``(parent, child)`` TF frame pair
        (exactly one of the two for a log, neither for a text file).
    name: the sensor's name where one is given (a rig's ``NAME=…``); else the frames name it.
    """

    path: str | None = None
    topic: str | None = None
    frames: tuple[str, str] | None = None
    name: str | None = None

    def describe(self) -> dict[str, Any]:
        """The result's ``inputs`` record of this stream: ``file``, and ``topic`` or ``frames``."""
        out: dict[str, Any] = {"file": self.path} if self.path else {}
        if self.topic:
            out["topic"] = self.topic
        if self.frames:
            out["frames"] = list(self.frames)
        return out


def _example(key: str) -> str:
    """A TF chain as the option ``key`` takes it (:func:`~handeye_cli.errors.option`: a flag on the command line,
    a keyword in Python)."""
    if key == "streams":
        return option("streams", "NAME=tf:odom,base_link")
    return option(key, ("odom", "base_link") if key.startswith("frames_") else "tf:odom,base_link")


def _tf_chain(frames: object, key: str, given: str, where: str) -> StreamSpec:
    """The TF chain ``frames`` = (PARENT, CHILD); ``given``: how the user wrote it, for the message."""
    if not (isinstance(frames, list | tuple) and len(frames) == 2 and all(isinstance(f, str) and f for f in frames)):
        raise ConfigError(f"bad TF chain {given!r}: it takes two frame names, PARENT CHILD", where,
                          f"name the parent first, then the child: {_example(key)}")
    for role, name in zip(("PARENT", "CHILD"), frames, strict=True):
        if name.startswith("-"):            # click gave the next flag as a frame (--frames-a base_link --topic-b …)
            raise ConfigError(f"bad TF chain {given!r}: it takes two frame names, PARENT CHILD; got {name!r} as {role}",
                              where,
                              f"give both frames, the parent first, e.g. {_example(key)}")
    return StreamSpec(frames=(frames[0], frames[1]))


def stream_source(key: str, source: str | StreamSpec | None = None, *, topic: object = None,
                  frames: object = None, where: str = "") -> StreamSpec | None:
    """The stream one command-line flag, keyword or per-input entry names (see the module docstring): at most one
    of ``source`` (the shared spelling; a :class:`StreamSpec` is taken as parsed), ``topic`` (``--topic-a``) and
    ``frames`` (``--frames-a PARENT CHILD``: a pair, or the string ``"PARENT CHILD"``); None when none is given.

    key: the option key the errors name (``stream_a``, a rig's ``streams``; the synonyms' ``topic_a`` and
    ``frames_a``), after ``where`` when it is given (a per-input file's ``FILE: PATTERN``). Returns a spec
    without a path for a topic or TF chain (of the log the command reads), with one for a file."""
    side = key.rpartition("_")[2] if key.startswith("stream_") else ""

    def at(k: str) -> str:
        return f"{where}: {k}" if where else k

    given = [k for k, v in ((key, source), (f"topic_{side}", topic), (f"frames_{side}", frames)) if v is not None]
    if len(given) > 1:
        raise ConfigError(f"stream {side or key} is named twice", at("/".join(given)),
                          f"give one of them ({key}: {SOURCE_FORMS})")
    if not given:
        return None
    if isinstance(source, StreamSpec):
        return source
    if frames is not None:
        pair = frames.split() if isinstance(frames, str) else frames
        shown = " ".join(map(str, pair)) if isinstance(pair, list | tuple) else repr(pair)
        return _tf_chain(pair, f"frames_{side}", shown, at(f"frames_{side}"))
    if topic is not None:
        if not isinstance(topic, str) or not topic.strip():
            raise ConfigError(f"{topic!r} is no topic name", at(f"topic_{side}"), "give a topic, e.g. /cam0/pose")
        return StreamSpec(topic=topic)
    text = source.strip() if isinstance(source, str) else source
    if not isinstance(text, str) or not text:
        raise ConfigError(f"{source!r} names no stream", at(key), f"write {SOURCE_FORMS}")
    if text.startswith("tf:"):
        return _tf_chain([f.strip() for f in text[3:].split(",")], key, text, at(key))
    if text == "-" or is_url(text) or Path(text).is_file():
        return StreamSpec(text)
    if text.startswith("/"):
        return StreamSpec(topic=text)
    raise ConfigError(f"{text!r} is neither a topic (/…), a TF chain (tf:PARENT,CHILD) nor an existing file", at(key),
                      f"check the path, start a topic with /, or name a TF chain parent first: {_example(key)}")
