"""The interface every log container (MCAP, ROS bags) offers to the generic log readers."""
from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Protocol

from .messages import PoseRecord

__all__ = ["TopicInfo", "LogSource", "Decoder"]

Decoder = Callable[[bytes], list[PoseRecord]]


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a log: message type (``pkg/msg/Type`` or ``foxglove.X``), encoding, count."""

    topic: str
    msgtype: str
    encoding: str
    count: int


class LogSource(Protocol):
    """An open log. ``name`` names it in messages (the file path)."""

    name: str

    def topics(self) -> list[TopicInfo]:
        """Every topic with its type and message count (from the index, without reading messages)."""

    def span(self) -> tuple[int, int] | None:
        """(first, last) log time [ns], or None when the log holds no messages."""

    def read(self, topics: Sequence[str]) -> Iterator[tuple[str, int, bytes, Decoder]]:
        """(topic, log_time_ns, raw message, decoder raw → pose records) for every message of
        ``topics`` (pose types only), in file or log-time order; HandEyeError on a corrupt container."""
