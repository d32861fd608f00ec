"""MCAP files. ``mcap`` reads the summary (topics, types, counts) of every file.

Messages of a pure ROS 2 file (profile ``ros2``, CDR channels, ``ros2msg``/``ros2idl`` schemas —
a bare rosbag2 ``.mcap``) are read through rosbags' AnyReader, whose MCAP parser is ~2x faster
than ``mcap``'s pure-Python record parsing (measured by ``benchmarks/readers.py``). Anything else
(Foxglove JSON channels, ROS 1 profile, mixed encodings), or a ROS 2 file AnyReader refuses, is
read with ``mcap``, decoding CDR / ROS 1 with a rosbags typestore built from the file's schemas
and JSON with ``json``. Either way only the chunks holding the selected topics are read, in
file order (stamps are sorted afterwards).
"""
from __future__ import annotations

import json
from collections import defaultdict
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, BinaryIO

from mcap.reader import SeekingReader, make_reader
from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

from ..errors import HandEyeError
from .common import unreadable
from .messages import normalize_type, pose_decoder
from .rosbag_reader import BagSource
from .source import Decoder, TopicInfo

__all__ = ["McapSource"]

_IDL_SEP = "=" * 80 + "\n"
_RECOVER = "if the recording was cut off, repair it with `mcap recover FILE -o fixed.mcap`"
_ROS2_SCHEMAS = ("ros2msg", "ros2idl", "omgidl")


class McapSource:
    """An open MCAP file (use as a context manager). Message types are normalised to ``pkg/msg/T``."""

    def __init__(self, path: Path) -> None:
        self.name = str(path)
        self._file: BinaryIO = open(path, "rb")
        try:
            with unreadable(self.name, _RECOVER):
                self._reader = make_reader(self._file)
                summary = self._reader.get_summary() if isinstance(self._reader, SeekingReader) else None
                profile = self._reader.get_header().profile
            if summary is None or summary.statistics is None:
                raise HandEyeError("MCAP file has no summary section (unfinished or truncated recording?)",
                                   self.name, _RECOVER)
        except BaseException:
            self._file.close()
            raise
        self._summary = summary
        self._path = path
        self._bag: BagSource | None = None      # AnyReader on this file, opened by the first read()
        self._ros2 = (profile == "ros2"
                      and all(ch.message_encoding == "cdr" for ch in summary.channels.values())
                      and all(sc.encoding in _ROS2_SCHEMAS for sc in summary.schemas.values()))

    def __enter__(self) -> McapSource:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._bag is not None:
            self._bag.__exit__(*exc)
        self._file.close()

    def _schema_name(self, channel: Any) -> str:
        schema = self._summary.schemas.get(channel.schema_id)
        return normalize_type(schema.name) if schema is not None else ""

    def topics(self) -> list[TopicInfo]:
        counts = self._summary.statistics.channel_message_counts
        by_topic: dict[str, list] = defaultdict(list)
        for cid, ch in self._summary.channels.items():
            by_topic[ch.topic].append((self._schema_name(ch), ch.message_encoding, counts.get(cid, 0)))
        return [TopicInfo(topic, rows[0][0], rows[0][1], sum(r[2] for r in rows))
                for topic, rows in by_topic.items()]

    def span(self) -> tuple[int, int] | None:
        st = self._summary.statistics
        return (st.message_start_time, st.message_end_time) if st.message_count else None

    def _decoder(self, channel: Any) -> Decoder:
        schema = self._summary.schemas.get(channel.schema_id)
        name = self._schema_name(channel)
        enc = channel.message_encoding
        if enc == "json":
            return pose_decoder(name, json.loads)
        if enc not in ("cdr", "ros1") or schema is None:
            raise HandEyeError(f"unsupported message encoding {enc!r}", f"{self.name}:{channel.topic}",
                               "handeye reads CDR, ROS 1 and JSON channels")
        store = get_typestore(Stores.EMPTY)
        text = schema.data.decode()
        if schema.encoding == "ros2idl":
            blocks = text.split(_IDL_SEP)[1:] if text.startswith(f"{_IDL_SEP}IDL: ") else [f"\n{text}"]
            for block in blocks:
                store.register(get_types_from_idl(block.split("\n", 1)[1]))
        else:
            store.register(get_types_from_msg(text, name))
        if enc == "cdr":
            return pose_decoder(name, lambda b: store.deserialize_cdr(b, name), cdr=True)
        return pose_decoder(name, lambda b: store.deserialize_ros1(b, name))

    def read(self, topics: Sequence[str]) -> Iterator[tuple[str, int, bytes, Decoder]]:
        if self._ros2 and self._bag is None:
            try:
                self._bag = BagSource([self._path], "mcap")
            except HandEyeError:        # e.g. a schema rosbags cannot parse: use mcap below
                self._ros2 = False
        if self._bag is not None:
            yield from self._bag.read(topics)
            return
        decoders: dict[int, Decoder] = {}
        with unreadable(self.name):
            for cid, ch in self._summary.channels.items():
                if ch.topic in topics:
                    decoders[cid] = self._decoder(ch)
            self._file.seek(0)
            for _, channel, message in self._reader.iter_messages(topics=list(topics),
                                                                  log_time_order=False):
                yield channel.topic, message.log_time, message.data, decoders[channel.id]
