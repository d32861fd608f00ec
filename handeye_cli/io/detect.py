"""Which format a path holds, decided by content (magic bytes, header line), not by suffix."""
from __future__ import annotations

import re
from pathlib import Path

from ..errors import HandEyeError

__all__ = ["FORMATS", "LOG_FORMATS", "detect_format", "existing"]

FORMATS = ("mcap", "rosbag1", "rosbag2", "tum", "euroc", "csv")
LOG_FORMATS = ("mcap", "rosbag1", "rosbag2")

_MAGIC = ((b"\x89MCAP0\r\n", "mcap"), (b"#ROSBAG V2.0", "rosbag1"), (b"SQLite format 3\x00", "rosbag2"))
_LOG_SUFFIXES = {".mcap": "MCAP", ".bag": "ROS 1 bag", ".db3": "ROS 2 SQLite bag"}
_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_EUROC_HEADER = re.compile(r"p_RS_R_x|q_RS_w", re.IGNORECASE)


def existing(path: str | Path) -> Path:
    """``path`` as a Path, or a HandEyeError if nothing is there."""
    p = Path(path)
    if not p.exists():
        raise HandEyeError("file not found", str(p), "check the path")
    return p


def _text_format(p: Path) -> str:
    try:
        with open(p, encoding="utf-8") as f:
            for line in f:
                s = line.strip()
                if not s:
                    continue
                if s.startswith("#"):
                    if _EUROC_HEADER.search(s):
                        return "euroc"
                    continue
                fields = [x for x in re.split(r"[,\s]+", s) if x]
                if not all(_NUMBER.match(x) for x in fields):
                    return "csv"
                # EuRoC: comma separated, integer nanosecond stamp; TUM: seconds, usually "t.fff"
                if "," in s and fields[0].lstrip("+-").isdigit() and len(fields) >= 8:
                    return "euroc"
                return "tum"
    except UnicodeDecodeError as exc:
        raise HandEyeError("unrecognised file format (binary, but not MCAP, ROS bag or SQLite)",
                           str(p), "supported: MCAP, ROS 1 .bag, ROS 2 bag (dir/.db3/.mcap), "
                                   "TUM, EuRoC CSV, CSV with header") from exc
    raise HandEyeError("empty file: no data lines", str(p), "check the file")


def detect_format(path: str | Path) -> str:
    """One of ``mcap``, ``rosbag1``, ``rosbag2``, ``tum``, ``euroc``, ``csv``.

    A directory with ``metadata.yaml`` is a ROS 2 bag; files are recognised by their magic
    bytes (MCAP, ``#ROSBAG V2.0``, SQLite = bare rosbag2 ``.db3``; a ``.mcap``/``.bag``/``.db3``
    without its magic is an error, not text); anything else is text:
    EuRoC (``p_RS_R_x``/``q_RS_w`` header, or comma-separated rows starting with an integer
    nanosecond stamp), generic CSV (a non-numeric header row) or TUM.
    """
    p = existing(path)
    if p.is_dir():
        if (p / "metadata.yaml").is_file():
            return "rosbag2"
        raise HandEyeError("directory is not a ROS 2 bag (no metadata.yaml)", str(p),
                           "pass a bag directory, an MCAP, a .bag or a text trajectory file")
    try:
        with open(p, "rb") as f:
            head = f.read(16)
    except OSError as exc:
        raise HandEyeError(f"cannot open file: {exc.strerror or exc}", str(p), "check permissions") from exc
    for magic, fmt in _MAGIC:
        if head.startswith(magic):
            return fmt
    if not head:
        raise HandEyeError("empty file (0 bytes)", str(p), "the recording or export failed; check the file")
    if p.suffix.lower() in _LOG_SUFFIXES:
        raise HandEyeError(f"not a valid {_LOG_SUFFIXES[p.suffix.lower()]} file: wrong magic bytes {head[:8]!r}",
                           str(p), "the file is damaged or misnamed; check it with `handeye inspect FILE`")
    return _text_format(p)
