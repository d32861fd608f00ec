"""Where results go: stdout, a regular file (replaced atomically), or anything else written through.

``-`` (or no path) is stdout. A regular file is written to a temporary file in its folder and
renamed over the target, so a reader never sees half a result and a failure leaves the old file
as it was; it keeps the mode of the file it replaces (a new file gets 0666 less the umask). A
FIFO, a character device (``/dev/null``, ``/dev/stdout``) or any other non-regular file is
opened and written through: replacing it would destroy it. Every failure is a
:class:`~handeye_cli.errors.WriteError` naming the path and the flag that chose it; a failure to
write stdout (a full disk, a closed pipe) is one too, and stdout is then pointed at the null device
so that the interpreter's last flush does not fail again.
"""
from __future__ import annotations

import contextlib
import os
import stat
import sys
import tempfile
from pathlib import Path

from ..errors import ConfigError, WriteError

__all__ = ["format_mismatch", "SUFFIXES", "output_format", "check_writable", "write_output", "write_stdout"]

# File-name endings that choose the output format (see handeye_cli/output/formats.py); Kalibr YAML
# needs --format kalibr.
SUFFIXES = {".yaml": "yaml", ".yml": "yaml", ".json": "json", ".urdf": "urdf", ".launch.py": "ros2-launch",
            ".launch": "ros1-launch", ".sh": "tf-static"}


def _is_stdout(path: str | Path | None) -> bool:
    return path is None or str(path) == "-"


def output_format(path: str | Path | None, fmt: str | None, flag: str = "-o") -> str:
    """The output format: ``fmt`` if given, else the one the file's suffix names, else YAML.
    An unknown suffix is refused rather than silently written as YAML."""
    if fmt:
        return fmt
    if _is_stdout(path):
        return "yaml"
    name = Path(str(path)).name.lower()
    chosen = next((f for suffix, f in SUFFIXES.items() if name.endswith(suffix)), None)
    if chosen:
        return chosen
    if not Path(str(path)).exists() or Path(str(path)).is_file():
        raise ConfigError(f"cannot tell the output format from {str(path)!r}", flag,
                          f"name the file {', '.join(SUFFIXES)} or pass --format")
    return "yaml"    # a FIFO or device without a suffix: the default format


# what a suffix may hold: the format it names and its kin (a URDF joint snippet in .urdf, Kalibr's YAML in .yaml),
# and the XML or Python formats for a name ending .xml / .py (a ROS 2 launch file may be either)
_KIN = {"urdf": ("urdf", "urdf-joint"), "yaml": ("yaml", "kalibr"), ".xml": ("urdf", "urdf-joint", "ros1-launch"),
        ".py": ("ros2-launch",)}


def format_mismatch(path: str | Path | None, fmt: str | None) -> str | None:
    """A one-line warning when ``-o``'s name says another format than ``--format`` (``x.launch.xml`` holding
    Python), else None; stdout or a name of no known suffix is no mismatch."""
    if not fmt or _is_stdout(path):
        return None
    name = Path(str(path)).name
    named = next((f for suffix, f in SUFFIXES.items() if name.lower().endswith(suffix)), None)
    named = named or next((s for s in (".xml", ".py") if name.lower().endswith(s)), None)
    if named is None or fmt in _KIN.get(named, (named,)):
        return None
    said = named.lstrip(".").upper() if named.startswith(".") else named
    return f"{name} is written as --format {fmt}, though its name says {said}"


def check_writable(path: str | Path | None, flag: str) -> None:
    """Fail early — before any computation — when ``path`` cannot be written."""
    if _is_stdout(path):
        return
    p = Path(str(path))
    if p.exists() and not p.is_file():
        if p.is_dir():
            raise WriteError("the output path is a folder", str(p), f"give a file name to {flag}")
        return                                        # FIFO / device: written through
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        what = "is not a folder" if folder.exists() else "does not exist"
        raise WriteError(f"the output folder {what}", str(folder), f"create it or choose another {flag} path")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise WriteError("the output folder is not writable", str(folder), f"choose another {flag} path")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _replace_atomically(p: Path, text: str, old_mode: int | None) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        # mkstemp creates 0600: keep the replaced file's mode, else give a new file the usual one
        os.chmod(tmp, stat.S_IMODE(old_mode) if old_mode is not None else 0o666 & ~_umask())
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_output(path: str | Path | None, text: str, flag: str = "-o") -> None:
    """Write ``text`` to stdout (``None`` or ``-``), through to a non-regular file, or atomically
    to a regular file. Raises WriteError (one line, naming ``flag``) on failure."""
    if _is_stdout(path):
        write_stdout(text)
        return
    p = Path(str(path))
    check_writable(p, flag)
    try:
        mode = os.stat(p).st_mode if p.exists() else None
        if mode is not None and not stat.S_ISREG(mode):
            with open(p, "w", encoding="utf-8") as f:       # FIFO, device, /dev/stdout: write through
                f.write(text)
        else:
            _replace_atomically(p, text, mode)
    except OSError as e:
        raise WriteError(f"cannot write ({e.strerror or e.__class__.__name__})", str(p),
                         f"choose another {flag} path") from None


def write_stdout(text: str) -> None:
    """Write ``text`` to stdout and flush it. Raises WriteError (one line) when stdout cannot be
    written (``> /dev/full``, a closed pipe), after pointing it at the null device."""
    try:
        sys.stdout.write(text)
        sys.stdout.flush()
    except OSError as e:
        with contextlib.suppress(OSError, ValueError, AttributeError):  # what stays buffered must not fail
            null = os.open(os.devnull, os.O_WRONLY)                     # again at exit
            os.dup2(null, sys.stdout.fileno())
            os.close(null)
        raise WriteError("cannot write to stdout", e.strerror or type(e).__name__,
                         "free space where it goes, or redirect it elsewhere") from None
