"""The interface every log container (MCAP, ROS bags) offers to the generic log readers."""
from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Protocol

from .messages import PoseRecord

__all__ = ["TopicInfo", "LogSource", "Decoder", "spans_by_topic"]

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

    def topic_spans(self) -> dict[str, tuple[int, int]]:
        """(first, last) log time [ns] of each topic the log's index tells without reading messages
        (a topic left out: the log does not say; ``inspect`` then rates it over the log's span)."""

    def read(self, topics: Sequence[str]) -> Iterator[tuple[str, int, bytes, Decoder]]:
        """(topic, log_time_ns, raw message, decoder raw → pose records) for every message of
        ``topics`` (pose types only), in file or log-time order; HandEyeError on a corrupt container."""


def spans_by_topic(spans: Iterable[tuple[str, tuple[int, int]]]) -> dict[str, tuple[int, int]]:
    """``(topic, (first, last))`` of several channels or connections → one (first, last) per topic."""
    out: dict[str, tuple[int, int]] = {}
    for topic, (lo, hi) in spans:
        old = out.get(topic, (lo, hi))
        out[topic] = (min(old[0], lo), max(old[1], hi))
    return out
