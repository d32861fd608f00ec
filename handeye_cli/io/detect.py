"""Which format a path holds, decided by content (magic bytes, header line), not by suffix."""
from __future__ import annotations

import re
from pathlib import Path

from ..errors import ReadError
from .formats import LOG_FORMATS, LOG_SUFFIXES, MAGIC_BYTES, by_magic, by_suffix
from .inputs import existing, is_stream, read_head
from .remote import current, is_url

__all__ = ["LOG_FORMATS", "LOG_SUFFIXES", "detect_format", "existing"]

_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$|^[+-]?(nan|inf)$", re.IGNORECASE)
_EUROC_HEADER = re.compile(r"p_RS_R_x|q_RS_w", re.IGNORECASE)
_PAIRS_HEADER = re.compile(r"^#?\s*ax\s*,\s*ay\s*,\s*az\s*,\s*aqx\b", re.IGNORECASE)
_YAML_LINE = re.compile(r"^(---|%YAML|[A-Za-z_][\w.\-]*:(\s|$))")
_HEAD_BYTES = 65536
_SUPPORTED = "pass a log (MCAP, ROS 1 .bag, ROS 2 bag) or a TUM / EuRoC / CSV trajectory"


def _not_a_stream(name: str, what: str, fix: str = _SUPPORTED) -> ReadError:
    return ReadError(f"{what}, not a pose stream", name, fix)


def _classify_header(name: str, suffix: str, line: str) -> str:
    """``csv`` for a CSV header row; a ReadError saying what the file is for anything else."""
    if _PAIRS_HEADER.match(line):
        raise _not_a_stream(name, "a motion-pairs file (ax, ay, az, aqx, …)", f"use `handeye solve {name}`")
    if line.startswith("rosbag2_bagfile_information:"):
        folder = str(Path(name).parent)
        raise _not_a_stream(name, "a ROS 2 bag's metadata.yaml", f"pass the bag's folder: {folder}")
    if suffix in (".yaml", ".yml") or _YAML_LINE.match(line):
        raise _not_a_stream(name, "a YAML file", "pass a configuration with ⟦config_file⟧; " + _SUPPORTED)
    if line.count(",") >= 7:
        return "csv"
    kind = ("a Markdown/text document" if suffix in (".md", ".rst", ".txt")
            else "text that is neither numbers nor a CSV header")
    raise _not_a_stream(f"{name}, first data line {line[:60]!r}", kind)


def text_format(name: str, suffix: str, head: bytes) -> str:
    """``tum``, ``euroc`` or ``csv`` from the first bytes of a text file (ReadError if it is not a
    pose table: binary, YAML, a motion-pairs file, prose)."""
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(head) - 4:       # not just a character cut at the end of the head
            raise ReadError("unrecognised file format (binary, but not MCAP, ROS bag or SQLite)", name,
                            "supported: MCAP, ROS 1 .bag, ROS 2 bag (dir/.db3/.mcap), "
                            "TUM, EuRoC CSV, CSV with header") from exc
        text = head[:exc.start].decode("utf-8")
    lines = text.splitlines()
    for i, line in enumerate(lines):
        s = line.strip()
        if not s or (i == len(lines) - 1 and len(head) == _HEAD_BYTES):
            continue
        if s.startswith("#"):
            if _EUROC_HEADER.search(s):
                return "euroc"
            if _PAIRS_HEADER.match(s):
                return _classify_header(name, suffix, s)
            continue
        fields = [x for x in re.split(r"[,\s]+", s) if x]
        if not all(_NUMBER.match(x) for x in fields):
            return _classify_header(name, suffix, s)
        # EuRoC: comma separated, integer nanosecond stamp; TUM: seconds, usually "t.fff"
        if "," in s and fields[0].lstrip("+-").isdigit() and len(fields) >= 8:
            return "euroc"
        return "tum"
    raise ReadError("empty file: no data lines", name, "check the file")


def _remote_format(url: str) -> str:
    """The format of the object (or folder) at ``url``: a log by its first bytes (one small range
    request); a folder holding a ROS 2 bag; text from its local copy (text is read whole anyway)."""
    session = current()
    if session.is_folder(url, read_ahead=True):     # with its first and last bytes, which the readers use
        names = [name for name, _ in session.listing(url)]
        if any(n.endswith(("/metadata.yaml", ".db3", ".mcap")) for n in names):
            return "rosbag2"
        raise ReadError("folder is not a ROS 2 bag (no metadata.yaml)", url,
                        "pass a bag folder, an MCAP, a .bag or a text trajectory object")
    head = session.open(url).read_at(0, MAGIC_BYTES)
    if (log := by_magic(head)) is not None:
        return log.name
    if not head:
        raise ReadError("empty object (0 bytes)", url, "the recording or its upload failed; check the object")
    suffix = Path(url.split("?", 1)[0]).suffix.lower()
    if (named := by_suffix(suffix)) is not None:
        raise ReadError(f"not a valid {named.title} file: wrong magic bytes {head[:8]!r}", url,
                        "the object is damaged or misnamed")
    local = session.cached(url, "a text file is read whole")
    return text_format(url, suffix, read_head(local, _HEAD_BYTES))


def detect_format(path: str | Path) -> str:
    """One of ``mcap``, ``rosbag1``, ``rosbag2``, ``tum``, ``euroc``, ``csv``.

    A directory with ``metadata.yaml`` (or only a ``.db3`` / ``.mcap`` storage file) is a ROS 2
    bag; files are recognised by their magic bytes (MCAP, ``#ROSBAG V2.0``, SQLite = bare rosbag2
    ``.db3``; a ``.mcap``/``.bag``/``.db3`` without its magic is an error, not text); anything else
    is text: EuRoC (``p_RS_R_x``/``q_RS_w`` header, or comma-separated rows starting with an
    integer nanosecond stamp), generic CSV (a header row with 8+ columns) or TUM. ``-`` (stdin)
    and pipes are read once (see :mod:`.inputs`); a URL is asked for its first bytes (see
    :mod:`.remote`). A YAML, motion-pairs or prose file is a
    ReadError that says what it is.
    """
    if is_url(path):
        return _remote_format(str(path))
    p = existing(path)
    if p.is_dir():
        if (p / "metadata.yaml").is_file() or any(p.glob("*.db3")) or any(p.glob("*.mcap")):
            return "rosbag2"
        raise ReadError("directory is not a ROS 2 bag (no metadata.yaml)", str(p),
                        "pass a bag directory, an MCAP, a .bag or a text trajectory file")
    try:
        head = read_head(path, _HEAD_BYTES)
    except OSError as exc:
        raise ReadError(f"cannot open file: {exc.strerror or exc}", str(p), "check permissions") from exc
    if (log := by_magic(head)) is not None:
        return log.name
    if not head:
        raise ReadError("empty file (0 bytes)", str(path), "the recording or export failed; check the file")
    suffix = "" if is_stream(path) else p.suffix.lower()
    if (named := by_suffix(suffix)) is not None:
        raise ReadError(f"not a valid {named.title} file: wrong magic bytes {head[:8]!r}",
                        str(p), "the file is damaged or misnamed; check it with `handeye inspect FILE`")
    return text_format(str(path), suffix, head)
