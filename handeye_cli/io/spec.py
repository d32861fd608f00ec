"""Where a pose stream is read from: :class:`StreamSpec`, the one description of an input stream that
``calibrate``, ``rig`` and ``batch`` share (and :func:`handeye_cli.io.read_specs` reads)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["StreamSpec"]


@dataclass(frozen=True)
class StreamSpec:
    """One pose stream ``T_frame_child(t)`` to read.

    path: the file — a log (MCAP, ROS 1 bag, ROS 2 bag) or a text pose file (TUM, EuRoC, CSV); ``-``
        is stdin. ``None`` only in a rig's stream list, for "the rig's log".
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
