"""Per-input options for a batch (``--per-input FILE``): a YAML mapping of glob patterns of input
paths to the options and streams that differ for the inputs they match, options by flat name as
in ``--config``, streams as ``topic_a``/``topic_b`` (a topic) or ``frames_a``/``frames_b`` (a TF
pair: ``[PARENT, CHILD]`` or ``"PARENT CHILD"``), so that one run covers a mixed fleet::

    "*/robot42/*": {time_offset: 0.02}
    "robot07*": {topic_b: /imu/pose}
    "logs/2026-11-03/*.bag": {gate: off, pairs: all, frames_a: [odom, base_link]}

An input matches a pattern when one of its paths does as a whole (:func:`fnmatch.fnmatch`, ``*``
also crosses ``/``), or, for a pattern without ``/``, when one of its paths' components does: so
``robot01*`` matches ``logs/robot01/rig1.bag`` and ``*.bag`` every bag wherever it is. Matching
entries apply in file order over the shared options (defaults < preset < --config < flags), so
the most specific entry goes last. Every entry is checked when the file is read: a bad option
fails the batch before it starts; a pattern that matches no input is warned about.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from fnmatch import fnmatch
from pathlib import Path, PurePath
from typing import Any

from ..config import read_config
from ..errors import ConfigError
from ..options import Options
from .discovery import BatchInput
from .engine import Streams

__all__ = ["Override", "read_overrides", "settings_for", "unmatched"]

_TOPICS = ("topic_a", "topic_b")
_FRAMES = ("frames_a", "frames_b")
_OTHER = {"topic_a": "frames_a", "frames_a": "topic_a", "topic_b": "frames_b", "frames_b": "topic_b"}


@dataclass(frozen=True)
class Override:
    """Options (``values``: flat name, value pairs) and streams (``streams``: ``topic_a`` … with
    checked values) for the inputs whose paths match ``pattern``."""

    pattern: str
    values: tuple[tuple[str, Any], ...]
    streams: tuple[tuple[str, Any], ...]
    where: str

    def matches(self, item: BatchInput) -> bool:
        """Whether one of the input's paths matches the pattern (see the module docstring)."""
        whole = any(fnmatch(p, self.pattern) for p in item.paths)
        return whole or ("/" not in self.pattern and
                         any(fnmatch(part, self.pattern) for p in item.paths for part in PurePath(p).parts))


def _stream(key: str, value: Any, where: str) -> Any:
    """A checked stream value: a topic name, or a (parent, child) frame pair."""
    if key in _TOPICS:
        if not isinstance(value, str) or not value.strip():
            raise ConfigError(f"{key} must be a topic name", where, f'write e.g. {key}: /cam0/pose')
        return value
    pair = value.split() if isinstance(value, str) else value
    if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(v, str) and v for v in pair)):
        raise ConfigError(f"{key} must be a TF frame pair PARENT CHILD", where, f"write e.g. {key}: [odom, imu_link]")
    return tuple(pair)


def read_overrides(path: str | Path) -> tuple[Override, ...]:
    """The entries of a per-input options file, each checked against the options' parsers."""
    out = []
    for pattern, values in read_config(path).items():
        where = f"{path}: {pattern}"
        if not isinstance(values, dict):
            raise ConfigError("each pattern needs a mapping of option: value", where,
                              'write e.g. "*/robot42/*": {time_offset: 0.02}')
        streams = tuple((k, _stream(k, v, where)) for k, v in values.items() if k in _TOPICS + _FRAMES)
        options = {k: v for k, v in values.items() if k not in _TOPICS + _FRAMES}
        Options.from_flat(Options(), where, **options)
        out.append(Override(str(pattern), tuple(options.items()), streams, where))
    return tuple(out)


def settings_for(item: BatchInput, streams: Streams, base: Options,
                 overrides: Sequence[Override]) -> tuple[Streams, Options]:
    """``streams`` and ``base`` with every matching override applied in order (a topic given for
    stream a replaces its frames, and the other way round)."""
    opts = base
    for o in overrides:
        if o.matches(item):
            opts = Options.from_flat(opts, o.where, **dict(o.values))
            for key, value in o.streams:
                streams = replace(streams, **{key: value, _OTHER[key]: None})
    return streams, opts


def unmatched(overrides: Sequence[Override], inputs: Sequence[BatchInput], warn: Callable[[str], None]) -> None:
    """Warn about each pattern that matches none of ``inputs`` (a typo would silently change nothing)."""
    for o in overrides:
        if not any(o.matches(i) for i in inputs):
            warn(f"{o.where}: the pattern matches none of the {len(inputs)} input(s); it changes nothing "
                 "(patterns match whole paths, or a component of one: check --per-input)")
