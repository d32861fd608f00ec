"""Rules for text handeye did not write: YAML files (configurations, results, nominals, priors) and
frame ids (from logs, nominals and the command line).

* :func:`load_yaml` is PyYAML's safe loader without aliases (a nest of them, "billion laughs",
  expands to gigabytes; no file of handeye's needs one) and with at most :data:`MAX_YAML_DEPTH`
  levels of nesting (the composer recurses per level: 50,000 levels would be a RecursionError).
  JSON is YAML, so JSON files go through it too.
* :func:`frame_id_problem` is the frame-id rule every stream, nominal and ``--name-a`` obeys:
  tf2's — no whitespace, no control or other unprintable characters (line and paragraph
  separators included), no quotes or backslash, at most :data:`MAX_FRAME_ID` characters.
* :func:`numbers_problem` is the rule for the numbers of a transform read from a file (nominals,
  priors, results read back): finite, and at most :data:`MAX_MAGNITUDE` (1e150) in absolute value,
  so that their squares (a norm, a residual, a verdict's distance) and sums of many of them stay
  finite: ``xyz="1e308 1e308 0"`` is refused where it is read, not met as an overflow later.

See the threat model in docs/design.md.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import yaml

__all__ = ["MAX_FRAME_ID", "MAX_MAGNITUDE", "MAX_YAML_DEPTH", "frame_id_problem", "load_yaml", "numbers_problem",
           "yaml_problem"]

MAX_YAML_DEPTH = 100
MAX_FRAME_ID = 256
MAX_MAGNITUDE = 1e150
"""The largest absolute value of a transform's number read from a file: its square, 1e300, and a sum of
many such squares stay below float64's 1.8e308 (a metre of translation beyond it is no extrinsic)."""
_QUOTES = "'\"`\\"


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader that refuses aliases and more than :data:`MAX_YAML_DEPTH` levels."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            mark = self.peek_event().start_mark    # type: ignore[no-untyped-call]  # PyYAML's stubs leave it untyped
            raise yaml.composer.ComposerError(None, None, "aliases (*name) are not allowed", mark)
        if self._depth >= MAX_YAML_DEPTH:
            mark = self.peek_event().start_mark    # type: ignore[no-untyped-call]
            raise yaml.composer.ComposerError(None, None, f"nested deeper than {MAX_YAML_DEPTH} levels", mark)
        self._depth += 1
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


def load_yaml(text: str) -> Any:
    """The YAML (or JSON) document ``text`` as plain Python values; ``yaml.YAMLError`` when it is not
    valid YAML, uses an alias or nests deeper than :data:`MAX_YAML_DEPTH` levels."""
    return yaml.load(text, Loader=_Loader)


def yaml_problem(error: yaml.YAMLError, where: str) -> tuple[str, str]:
    """``(what, where:line)`` of a :func:`load_yaml` failure, for a one-line error message."""
    mark = getattr(error, "problem_mark", None)
    problem = getattr(error, "problem", None) or "invalid YAML"
    return str(problem), f"{where}:{mark.line + 1}" if mark else where


def numbers_problem(values: Any) -> str | None:
    """Why the numbers ``values`` (an array) break the rule of :data:`MAX_MAGNITUDE`, or None when they keep it."""
    a = np.asarray(values, dtype=float)
    if not np.isfinite(a).all():
        return "it holds a non-finite number (NaN or inf)"
    if a.size and np.abs(a).max() > MAX_MAGNITUDE:
        return f"it holds {a.flat[np.abs(a).argmax()]:g}, beyond ±{MAX_MAGNITUDE:g} (its square would overflow)"
    return None


def frame_id_problem(name: str) -> str | None:
    """Why ``name`` breaks the frame-id rule (see the module docstring), or None when it keeps it.
    A leading ``/`` (ROS 1 style) is allowed: readers strip it."""
    if not name:
        return "it is empty"
    if len(name) > MAX_FRAME_ID:
        return f"it has {len(name)} characters (at most {MAX_FRAME_ID})"
    for c in name:
        if c.isspace() or not c.isprintable():
            return f"it holds the character {c!r}"
        if c in _QUOTES:
            return f"it holds the quote {c!r}"
    return None


REMOTE_TIMEOUT_S = 30.0
"""How long [s] one request to object storage may take before it is tried again (a store that stalls must not
hang a batch): the default of the ``remote_timeout`` option."""
REMOTE_RETRIES = 3
"""How many times a request to object storage is tried before the input fails: the default of ``remote_retries``."""
REMOTE_DEADLINE_S = 60.0
"""How long [s] one object may go without an answered request while its requests are tried (the clock starts with the
first try after its last answer, and an answer stops it: a large object that keeps answering is never cut), whatever
``remote_timeout`` x ``remote_retries`` allow: the default of the ``remote_deadline`` option."""
