"""Format-independent reading of an open log: one pose topic, a TF frame pair, or an overview."""
from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import replace
from typing import Any

from ..errors import ConfigError, DataError, ReadError
from ..streams import PoseStream
from .common import PoseBuffer, corrupt_input, make_stream
from .inputs import valid_frame_id
from .mcap_fast import FastPoses
from .messages import POSE_TYPES, TF_TYPES, PoseRecord, UnsupportedContent
from .progress import progress
from .source import LogSource, TopicInfo
from .tf import TfTree

__all__ = ["read_requests", "inspect_source", "is_static_topic"]

_BATCH = 4096   # messages between progress-bar updates


def is_static_topic(topic: str) -> bool:
    """``/tf_static`` (or ``…/tf_static``) carries time-invariant transforms."""
    return topic.rsplit("/", 1)[-1] == "tf_static"


def _pose_topics(infos: list[TopicInfo]) -> str:
    rows = [f"{t.topic} ({t.msgtype})" for t in infos if t.msgtype in POSE_TYPES]
    return ", ".join(rows) or "none"


def _records(src: LogSource, infos: list[TopicInfo], label: str, time_source: str,
             quiet: bool) -> Iterator[tuple[str, list[PoseRecord]]]:
    """(topic, pose records) per message of ``infos``; stamps replaced by log time if asked."""
    if not infos:
        return
    counts = {t.topic: 0 for t in infos}
    n = 0
    with progress(sum(t.count for t in infos), label, quiet=quiet) as bar:
        for n, (topic, log_ns, raw, decode) in enumerate(src.read(list(counts)), 1):
            i = counts[topic]
            counts[topic] = i + 1
            try:
                recs = decode(raw)
            except UnsupportedContent as exc:
                raise ReadError(str(exc), f"{src.name}:{topic}, message {i}",
                                   "convert the topic to a supported pose message") from exc
            except Exception as exc:
                if not corrupt_input(exc):
                    raise
                raise ReadError(f"cannot decode message: {type(exc).__name__}: {exc}",
                                   f"{src.name}:{topic}, message {i}",
                                   "the message is corrupt or not of its declared type") from exc
            if time_source == "log":
                recs = [(log_ns, *r[1:]) for r in recs]
            yield topic, recs
            if n % _BATCH == 0:
                bar.update(_BATCH)
        bar.update(n % _BATCH)


Request = tuple[str | None, tuple[str, str] | None]   # (topic, None) or (None, (parent, child))


def _check_topic(src: LogSource, infos: list[TopicInfo], topic: str) -> None:
    info = next((t for t in infos if t.topic == topic), None)
    if info is None:
        raise ConfigError(f"unknown topic {topic!r}", src.name, f"pose topics in this file: {_pose_topics(infos)}")
    if info.msgtype not in POSE_TYPES:
        raise ReadError(f"unsupported message type {info.msgtype!r}", f"{src.name}:{topic}",
                           f"supported types: {', '.join(sorted(POSE_TYPES))}; "
                           f"pose topics in this file: {_pose_topics(infos)}")


def _truncation(src: LogSource, n: int) -> list[str]:
    """The source's warnings (``notes``) and, for a cut-off recording, how many messages (``n``) were recovered."""
    notes = list(getattr(src, "notes", ()))
    if getattr(src, "truncated", False):
        notes.append(f"recovered {n} messages from truncated {src.name}; the rest is lost")
    return notes


def _clip(name: str, n: int = 60) -> str:
    """``name`` for a message: a damaged log's frame id may be 256 kB long."""
    return name if len(name) <= n else f"{name[:n]}… ({len(name)} characters)"


def _topic_stream(src: LogSource, topic: str, buf: PoseBuffer | FastPoses, time_source: str) -> PoseStream:
    source = f"{src.name}:{topic}"
    if len(buf.pairs) > 1:
        pairs = ", ".join(f"{_clip(p) or '?'}->{_clip(c) or '?'}" for p, c in list(buf.pairs)[:8])
        raise DataError(f"topic carries poses of several frame pairs ({pairs})", source,
                        "select one pair as a TF chain, the parent first: ⟦stream_a='tf:PARENT,CHILD'⟧")
    frame, child = next(iter(buf.pairs), ("", ""))
    stamps, xyz, quat = buf.arrays()
    truncated = getattr(src, "truncated", False)
    return make_stream(stamps, xyz, quat, source=source, frame_id=frame, child_frame_id=child or valid_frame_id(topic),
                       time_source=time_source, where=lambda i: f"message {i}", warnings=_truncation(src, len(buf)),
                       recovered_truncated=len(buf) if truncated else 0)


def _read_topics(src: LogSource, infos: list[TopicInfo], wanted: set[str], tf_topics: set[str], time_source: str,
                 quiet: bool) -> tuple[dict[str, PoseBuffer | FastPoses], TfTree, int, dict[str, set[tuple[str, str]]]]:
    """One pass over the ``wanted`` pose topics and the ``tf_topics``: (the poses of each wanted
    topic, the TF tree, how many TF messages were read, the (parent, child) pairs each TF topic
    carries). Topics the source's fast path decodes (``read_fast``, MCAP) come as arrays; the
    rest message by message."""
    label = "reading " + ", ".join(sorted(wanted) + (["TF"] if tf_topics else []))
    fast: dict[str, FastPoses] = {}
    if hasattr(src, "read_fast") and wanted | tf_topics:
        todo = [t for t in infos if t.topic in wanted | tf_topics]
        with progress(sum(t.count for t in todo), label, quiet=quiet) as bar:
            fast = src.read_fast(sorted(wanted | tf_topics), time_source)
            bar.update(sum(t.count for t in todo if t.topic in fast))
    poses: dict[str, PoseBuffer | FastPoses] = {t: fast[t] for t in wanted & fast.keys()}
    buffers = {topic: PoseBuffer() for topic in wanted - fast.keys()}
    tree = TfTree(src.name)
    pairs: dict[str, set[tuple[str, str]]] = {t: set() for t in tf_topics}
    tf_messages = 0
    for topic in tf_topics & fast.keys():
        pairs[topic].update(fast[topic].pair_names)
        tf_messages += len(fast[topic])
        for k, (parent, child) in enumerate(fast[topic].pair_names):
            tree.add_arrays(parent, child, *fast[topic].of_pair(k), static=is_static_topic(topic))
    slow = [t for t in infos if t.topic in (wanted | tf_topics) - fast.keys()]
    for topic, recs in _records(src, slow, label, time_source, quiet):
        if topic in buffers:
            buffers[topic].add(recs)
        if topic in tf_topics:
            tf_messages += 1
            tree.add(recs, static=is_static_topic(topic))
            pairs[topic].update((r[1], r[2]) for r in recs)
    return {**poses, **buffers}, tree, tf_messages, pairs


def read_requests(src: LogSource, requests: Sequence[Request], *, time_source: str = "header",
                  quiet: bool = True) -> list[PoseStream]:
    """Several pose streams of one log in a single pass over it, one per request: ``(topic, None)``
    reads the poses ``T_frame_child`` on a pose topic (child = child_frame_id, else the topic
    name as a valid frame id); ``(None, (parent, child))`` resolves ``T_parent_child(t)`` through
    the TF topics (TFMessage, Foxglove FrameTransform(s))."""
    infos = src.topics()
    wanted = {topic for topic, _ in requests if topic is not None}
    for topic in dict.fromkeys(topic for topic, _ in requests if topic is not None):    # in the order asked
        _check_topic(src, infos, topic)
    tf_topics = set()
    if any(frames is not None for _, frames in requests):
        tf_topics = {t.topic for t in infos if t.msgtype in TF_TYPES}
        if not tf_topics:
            raise DataError("no TF topics (/tf, /tf_static) in this file", src.name,
                            f"read a pose topic instead; pose topics: {_pose_topics(infos)}")
    poses, tree, tf_messages, _ = _read_topics(src, infos, wanted, tf_topics, time_source, quiet)
    streams = []
    for name, frames in requests:
        if name is not None:
            streams.append(_topic_stream(src, name, poses[name], time_source))
            continue
        assert frames is not None
        s = tree.lookup(*frames, time_source=time_source)
        streams.append(replace(s, warnings=(*_truncation(src, tf_messages), *s.warnings),
                               recovered_truncated=tf_messages if getattr(src, "truncated", False) else 0))
    return streams


def _rate(info: TopicInfo, span: tuple[int, int] | None, log_span_ns: int) -> tuple[float | None, str]:
    """(mean rate [Hz], over what): over the topic's own span from its first to its last message,
    ``(count − 1) / (last − first)``; None for a ``/tf_static`` topic (latched: its messages are
    published once, the rate means nothing) or a topic of one message or all at one stamp;
    over the log's span (``count / span``) when the log does not tell the topic's own."""
    if is_static_topic(info.topic):
        return None, "latched"
    if span is None:
        return (round(info.count / log_span_ns * 1e9, 3) if log_span_ns else None), "log"
    return (round((info.count - 1) / (span[1] - span[0]) * 1e9, 3) if span[1] > span[0] else None), "topic"


def inspect_source(src: LogSource, quiet: bool = True) -> dict[str, Any]:
    """Topics (type, encoding, count; ``first_ns``/``last_ns``, the topic's own span, and
    ``rate_hz`` over it, as :func:`_rate` says in ``rate_over`` — from the summary/index, no
    message read —; ``pose``: readable as one pose stream with ``read_requests``, for a TF topic
    only when it carries a single frame pair), the TF edges with exact counts from every TF
    message (``tf_messages``), and ``warnings``: what the file lost (cut off, chunks skipped) or
    how it was read (no index)."""
    infos = src.topics()
    span = src.span()
    duration = span[1] - span[0] if span else 0
    tf_topics = {t.topic for t in infos if t.msgtype in TF_TYPES}
    _, tree, _, tf_pairs = _read_topics(src, infos, set(), tf_topics, "header", quiet)
    own = src.topic_spans()

    def one_stream(t: TopicInfo) -> bool:
        return t.msgtype in POSE_TYPES and (t.topic not in tf_pairs or len(tf_pairs[t.topic]) == 1)

    topics = []
    for t in sorted(infos, key=lambda t: t.topic):
        rate, over = _rate(t, own.get(t.topic), duration)
        first, last = own.get(t.topic, (None, None))
        topics.append({"topic": t.topic, "type": t.msgtype, "encoding": t.encoding,
                       "count": t.count, "first_ns": first, "last_ns": last, "rate_hz": rate, "rate_over": over,
                       "pose": one_stream(t)})
    return {"start_ns": span[0] if span else None, "end_ns": span[1] if span else None,
            "duration_ns": duration, "topics": topics, "tf_frames": tree.edges(),
            "tf_messages": sum(t.count for t in infos if t.topic in tf_topics),
            "warnings": _losses(src)}


def _losses(src: LogSource) -> list[str]:
    """What an overview of ``src`` must say about the file: its readers' notes (no usable index,
    chunks skipped and their messages lost) and, for a file cut off, that the rest is lost."""
    notes = list(getattr(src, "notes", ()))
    if getattr(src, "truncated", False):
        span = src.span()
        read = f"{(span[1] - span[0]) / 1e9:.3f} s of messages are read up to the cut; " if span else ""
        notes.append(f"{src.name} is cut off (a crashed or interrupted recording): {read}whatever was recorded after "
                     "the cut is lost, and the counts, spans and rates are of what was read")
    return notes
