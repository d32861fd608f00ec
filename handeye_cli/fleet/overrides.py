"""Per-input options for a batch (``--per-input FILE``): a YAML mapping of glob patterns of input
paths to the options and streams that differ for the inputs they match, options by flat name as
in ``--config``, streams as ``stream_a``/``stream_b`` in the spelling every command shares (``/topic``,
``tf:PARENT,CHILD``, ``FILE``; :func:`~handeye_cli.io.spec.stream_source`), or its synonyms ``topic_a`` and
``frames_a`` (``[PARENT, CHILD]`` or ``"PARENT CHILD"``), so that one run covers a mixed fleet::

    "*/robot42/*": {time_offset: 0.02}
    "robot07*": {stream_b: /imu/pose}
    "logs/2026-11-03/*.bag": {gate: off, pairs: all, stream_a: "tf:odom,base_link"}

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
from ..io.spec import StreamSpec, stream_source
from ..options import Options
from .discovery import BatchInput
from .engine import Streams

__all__ = ["Override", "read_overrides", "settings_for", "unmatched"]

_STREAM_KEYS = {f"{kind}_{side}": (side, kind) for side in "ab" for kind in ("stream", "topic", "frames")}


@dataclass(frozen=True)
class Override:
    """Options (``values``: flat name, value pairs) and streams (``streams``: side ``a``/``b``, its parsed source)
    for the inputs whose paths match ``pattern``."""

    pattern: str
    values: tuple[tuple[str, Any], ...]
    streams: tuple[tuple[str, StreamSpec], ...]
    where: str

    def matches(self, item: BatchInput) -> bool:
        """Whether one of the input's paths matches the pattern (see the module docstring)."""
        whole = any(fnmatch(p, self.pattern) for p in item.paths)
        return whole or ("/" not in self.pattern and
                         any(fnmatch(part, self.pattern) for p in item.paths for part in PurePath(p).parts))


def _streams(values: dict[str, Any], where: str) -> tuple[tuple[str, StreamSpec], ...]:
    """The entry's streams, each parsed by the one parser of a stream source (at most one key per side)."""
    out = []
    for side in "ab":
        given = {kind: values[key] for key, (s, kind) in _STREAM_KEYS.items() if s == side and key in values}
        spec = stream_source(f"stream_{side}", given.get("stream"), topic=given.get("topic"),
                             frames=given.get("frames"), where=where)
        if spec is not None:
            out.append((side, spec))
    return tuple(out)


def read_overrides(path: str | Path) -> tuple[Override, ...]:
    """The entries of a per-input options file, each checked against the options' parsers."""
    out = []
    for pattern, values in read_config(path).items():
        where = f"{path}: {pattern}"
        if not isinstance(values, dict):
            raise ConfigError("each pattern needs a mapping of option: value", where,
                              'write e.g. "*/robot42/*": {time_offset: 0.02}')
        streams = _streams(values, where)
        options = {k: v for k, v in values.items() if k not in _STREAM_KEYS}
        Options.from_flat(Options(), where, **options)
        out.append(Override(str(pattern), tuple(options.items()), streams, where))
    return tuple(out)


def settings_for(item: BatchInput, streams: Streams, base: Options,
                 overrides: Sequence[Override]) -> tuple[Streams, Options]:
    """``streams`` and ``base`` with every matching override applied in order (a stream named replaces what
    named it before, in whichever spelling)."""
    opts = base
    for o in overrides:
        if o.matches(item):
            opts = Options.from_flat(opts, o.where, **dict(o.values))
            for side, spec in o.streams:
                streams = replace(streams, **{side: spec})
    return streams, opts


def unmatched(overrides: Sequence[Override], inputs: Sequence[BatchInput], warn: Callable[[str], None]) -> None:
    """Warn about each pattern that matches none of ``inputs`` (a typo would silently change nothing)."""
    for o in overrides:
        if not any(o.matches(i) for i in inputs):
            warn(f"{o.where}: the pattern matches none of the {len(inputs)} input(s); it changes nothing "
                 "(patterns match whole paths, or a component of one: check --per-input)")
