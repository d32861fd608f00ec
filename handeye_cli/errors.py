"""The exceptions handeye raises for bad input, one subclass per kind of failure.

Every user-facing failure is a :class:`HandEyeError`: a ``ValueError`` subclass whose message has
the form ``<what> (<where>): <how to fix>``, so the CLI prints it as one line and exits with
code 2 (a line break or other unprintable character of a name taken from a file is written as its
escape, :func:`one_line`). Callers that fall back on a failure catch the precise subclass:

* :class:`ConfigError` — an option or configuration value is invalid;
* :class:`ReadError` — a file is missing, unreadable, damaged or of the wrong kind;
* :class:`DataError` — the data were read but cannot be calibrated (empty stream, no time
  overlap, no sample passes a gate), with the subclasses :class:`TooFewPairsError` and
  :class:`UnderdeterminedError` (the motions cannot determine the extrinsic) and
  :class:`FitRejectedError` (the residuals at the solution do not fit a rigid rig);
* :class:`WriteError` — a result or report could not be written.
"""
from __future__ import annotations

import re
from collections.abc import Callable
from typing import TypeVar, cast

_T = TypeVar("_T")

__all__ = ["one_line", "option", "as_keywords", "as_flags", "worded", "KEYWORD_FLAGS", "HandEyeError", "ConfigError",
           "ReadError", "DataError", "TooFewPairsError", "UnderdeterminedError", "FitRejectedError", "WriteError"]


class HandEyeError(ValueError):
    """Bad input or an unsolvable problem, with a message that says how to fix it.

    Parameters
    ----------
    what:
        What is wrong, e.g. ``"unknown topic '/pose'"``.
    where:
        The file, topic, line or argument it concerns (may be empty).
    fix:
        How the user can fix it (may be empty).

    Examples
    --------
    >>> from handeye_cli.errors import ConfigError, HandEyeError
    >>> e = ConfigError("bad value 'fast'", "max_dt", "give a number of seconds > 0")
    >>> str(e)                                   # what the CLI prints after "error: "
    "bad value 'fast' (max_dt): give a number of seconds > 0"
    >>> isinstance(e, HandEyeError), isinstance(e, ValueError), e.where
    (True, True, 'max_dt')
    """

    def __init__(self, what: str, where: str = "", fix: str = "") -> None:
        self.what, self.where, self.fix = what, where, fix
        super().__init__(self.line(as_keywords))

    def line(self, words: Callable[[str], str] | None = None) -> str:
        """The message in one line, the options it names in ``words``: :func:`as_keywords` (``str(error)``,
        the Python API's), :func:`as_flags` (the command line's), or None to keep them marked (for a message
        or document that quotes it and is worded as a whole later). ``what``, ``where`` and ``fix`` keep the
        options marked (:func:`option`), so that a message built from another's parts is worded once."""
        text = self.what
        if self.where:
            text += f" ({self.where})"
        if self.fix:
            text += f": {self.fix}"
        return one_line(text if words is None else words(text))


def one_line(text: str) -> str:
    """``text`` with every unprintable character (line breaks, U+2028, NUL, terminal escapes) written as
    its escape sequence: names taken from a log or file cannot break the one-line message."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text)


class ConfigError(HandEyeError):
    """An invalid option: a configuration file, command-line flag or keyword argument."""


class ReadError(HandEyeError):
    """An input that cannot be read: missing, empty, damaged, or not of a supported kind."""


class DataError(HandEyeError):
    """Data that were read but cannot be calibrated (no overlap, empty stream, gates drop everything)."""


class TooFewPairsError(DataError):
    """Too few motion pairs are left after sync, gates and pair selection."""


class UnderdeterminedError(DataError):
    """The motions cannot determine the extrinsic (a family of solutions fits them exactly)."""


class FitRejectedError(DataError):
    """The solution's residuals are far larger than the streams' own noise predicts for a rigid rig
    (see :mod:`handeye_cli.analysis.fit_test`): wrong units, quaternion order, inversion, frames,
    clock, scale, outliers, or streams that are not rigidly attached."""


class WriteError(HandEyeError):
    """A result, report or other output could not be written; ``errno`` and ``strerror`` are the
    operating system's when it refused (a full disk: ``ENOSPC``), else None."""

    errno: int | None = None
    strerror: str | None = None


#: the library's keywords whose flag is not the keyword dashed (``max_jump`` ↔ ``--max-jump``): the CLI's
#: ``_as_flags`` and :func:`as_flags` read this one table
KEYWORD_FLAGS = {"preset": "--preset", "config_file": "--config", "fmt": "--format", "streams": "--stream"}

#: an option named in a message: ``⟦key⟧``, or ``⟦key=value⟧`` with the value as the keyword argument's
#: (``⟦gate='off'⟧``, ``⟦invert_b=False⟧``, ``⟦max_pairs=N⟧``: an upper-case placeholder,
#: ``⟦frames_a=(PARENT, CHILD)⟧``)
_MENTION = re.compile(r"⟦([A-Za-z_*][A-Za-z0-9_*]*)(?:=([^⟦⟧]*))?⟧")


def option(key: str, value: object = None) -> str:
    """The option ``key`` named in a message, with ``value`` (None: the option itself), which the Python API
    says as a keyword (:func:`as_keywords`: ``max_pairs=N``) and the CLI as a flag (:func:`as_flags`:
    ``--max-pairs N``). A value is written as the keyword argument's: a bool or number as is, an upper-case
    placeholder (``N``, ``SECONDS``) bare, other text quoted, a tuple in parentheses. Messages written as
    literals carry the same marker directly, e.g. ``"widen ⟦max_dt⟧ or try ⟦pairs='all'⟧"``."""
    def shown(v: object) -> str:
        return v if isinstance(v, str) and v.isupper() else repr(v) if isinstance(v, str) else f"{v}"
    if value is None:
        return f"⟦{key}⟧"
    text = f"({', '.join(shown(v) for v in value)})" if isinstance(value, tuple) else shown(value)
    return f"⟦{key}={text}⟧"


def as_keywords(text: str) -> str:
    """``text`` in the Python API's words: each option it names (``⟦max_pairs=N⟧``) as the keyword
    argument (``max_pairs=N``)."""
    return _MENTION.sub(lambda m: m.group(0)[1:-1], text)


def as_flags(text: str) -> str:
    """``text`` in the command line's words: each option it names as its flag — ``⟦max_dt⟧`` and
    ``⟦robust=True⟧`` as ``--max-dt``, ``--robust``; ``⟦invert_b=False⟧`` as ``--no-invert-b``;
    ``⟦gate='off'⟧`` as ``--gate off``; ``⟦frames_a=(PARENT, CHILD)⟧`` as ``--frames-a PARENT CHILD``."""
    def flag(m: re.Match[str]) -> str:
        key, value = m.group(1), m.group(2)
        name = KEYWORD_FLAGS.get(key, "--" + key.replace("_", "-"))
        if value is None or value == "True":
            return name
        if value == "False":
            return "--no-" + name[2:]
        values = value[1:-1].split(", ") if value.startswith("(") and value.endswith(")") else [value]
        return " ".join([name, *(v[1:-1] if len(v) > 1 and v[0] == v[-1] and v[0] in "'\"" else v
                                 for v in values)])
    return _MENTION.sub(flag, text)


def worded(value: _T, words: Callable[[str], str]) -> _T:
    """``value`` (a document: dicts, lists, tuples, strings, numbers) with every string in ``words``
    (:func:`as_keywords` or :func:`as_flags`): how a result document leaves the library or the CLI."""
    if isinstance(value, str):
        return cast(_T, words(value))
    if isinstance(value, dict):
        return cast(_T, {k: worded(v, words) for k, v in value.items()})
    if isinstance(value, (list, tuple)):
        return cast(_T, type(value)(worded(v, words) for v in value))
    return value
