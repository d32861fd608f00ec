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

__all__ = ["one_line", "in_keywords", "KEYWORD_FLAGS", "HandEyeError", "ConfigError", "ReadError", "DataError",
           "TooFewPairsError", "UnderdeterminedError", "FitRejectedError", "WriteError"]


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
        text = what
        if where:
            text += f" ({where})"
        if fix:
            text += f": {fix}"
        super().__init__(one_line(text))


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


#: the library's keywords whose flag is not the keyword dashed (``max_jump`` ↔ ``--max-jump``), both ways:
#: the CLI's ``_as_flags`` and :func:`in_keywords` read this one table
KEYWORD_FLAGS = {"preset": "--preset", "config_file": "--config", "fmt": "--format", "streams": "--stream"}
_KEYWORD_OF = {flag[2:]: key for key, flag in KEYWORD_FLAGS.items()}
_WORDS = {"to", "or", "and", "for", "with", "is", "the", "a", "an", "given", "instead", "first", "then", "on", "in",
          "if", "when", "as", "of", "that", "it", "at", "by", "from", "each", "too", "also", "alone", "only"}
_VALUE = re.compile(r"^/?[A-Za-z0-9_][A-Za-z0-9_.|*:/,=-]*$")     # a word, number, topic or stream source
# a flag and up to two words after it; a word is cut at , ; : ) but a stream source (tf:PARENT,CHILD) is whole
_FLAG = re.compile(r"--(no-)?([a-z][a-z0-9-]*)((?: (?![-])(?:[^\s,;:)]*tf:[^\s;:)]*[^\s,;:)]|[^\s,;:)]+)){0,2})")


def _keyword(m: re.Match[str]) -> str:
    negated, name, rest = m.group(1), m.group(2), m.group(3)
    key = _KEYWORD_OF.get(name, name.replace("-", "_"))
    values: list[str] = []
    for token in rest.split()[:2 if name.startswith("frames-") else 1]:     # --frames-a PARENT CHILD: two
        if token.lower() in _WORDS or not _VALUE.match(token):
            break
        values.append(token)
    tail = rest.split()[len(values):]
    if negated or not values:
        text = f"{key}={'False' if negated else 'True'}"
    else:
        shown = [v if v.isupper() or v.replace(".", "", 1).lstrip("-").isdigit() else repr(v) for v in values]
        text = f"{key}={shown[0]}" if len(shown) == 1 else f"{key}=({', '.join(shown)})"
    return " ".join([text, *tail])


def in_keywords(error: HandEyeError) -> HandEyeError:
    """``error`` in the Python API's words: each flag its fix names (``--gate paper``, ``--no-invert-b``,
    ``--frames-a PARENT CHILD``) written as the keyword argument (``gate='paper'``, ``invert_b=False``,
    ``frames_a=(PARENT, CHILD)``). The one place the library turns the command line's words into its own; the
    ``where`` part already names the option by its key."""
    fix = _FLAG.sub(_keyword, error.fix)
    return error if fix == error.fix else type(error)(error.what, error.where, fix)
