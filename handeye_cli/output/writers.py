"""Where results go: stdout, a regular file (replaced atomically), or a FIFO or device written through.

``-`` (or no path) is stdout. A regular file is written to a temporary file in its folder and
renamed over the target, so a reader never sees half a result and a failure leaves the old file
as it was; it keeps the mode of the file it replaces (a new file gets 0666 less the umask). A
FIFO, a character device (``/dev/null``, ``/dev/stdout``) or any other non-regular file that the
user names (``-o``, ``--report``) is opened and written through: replacing it would destroy it.

A **symbolic link** is never written through to a regular file: a link to a regular file, a
dangling link, or a link to anything in a name handeye chose (``--output-dir``) is itself replaced
by the new file (the rename replaces the link, not its target; the new file gets a new file's
mode, not the target's), so a link planted in a shared folder cannot make handeye overwrite
another file. A link the user names to a FIFO or device (``/dev/stdout`` is one, to
``/proc/self/fd/1``) is written through, as the FIFO or device itself would be. In a name
handeye chose, a FIFO or device is replaced too (``through=False``): opening a planted FIFO
would block. The write-through open never creates or truncates, and a file it finds regular
after all (a link swapped in after the check) is refused. Every failure is a
:class:`~handeye_cli.errors.WriteError` naming the path and the flag that chose it; a failure to
write stdout (a full disk, a closed pipe) is one too, and stdout is then pointed at the null device
so that the interpreter's last flush does not fail again.
"""
from __future__ import annotations

import contextlib
import errno
import os
import stat
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

from ..errors import ConfigError, WriteError

__all__ = ["format_mismatch", "SUFFIXES", "output_format", "check_writable", "write_output", "write_stdout",
           "written_through", "replace_atomically", "write_all", "FULL"]

# a full disk, and a file-size limit (RLIMIT_FSIZE; SIGXFSZ ignored) that acts like one
FULL = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT)

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
                          f"name the file {', '.join(SUFFIXES)} or pass ⟦fmt⟧")
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
    return f"{name} is written as ⟦fmt='{fmt}'⟧, though its name says {said}"


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


def written_through(p: Path, through: bool = True) -> bool:
    """Whether ``p`` is written through (see the module docstring): a FIFO, device or socket, or a
    link to one, and ``through`` (the user named it); never a regular file, a link to one, a
    dangling link or a missing path."""
    if not through:
        return False
    try:
        mode = os.stat(p).st_mode                   # follows a link: what it leads to
    except OSError:
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


def _old_mode(p: Path) -> int | None:
    """The mode a replacement keeps: a regular file's own (not a link's target's), else None."""
    try:
        st = os.lstat(p)
    except OSError:
        return None
    return st.st_mode if stat.S_ISREG(st.st_mode) else None


def replace_atomically(p: Path, write: Callable[[int], None]) -> None:
    """Make ``p`` a new regular file holding what ``write(fd)`` writes: a temporary file in its
    folder renamed over ``p`` — over the link itself when ``p`` is a symbolic link, whose target is
    never opened. The replaced regular file's mode is kept (a new file: 0666 less the umask)."""
    old_mode = _old_mode(p)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    try:
        try:
            write(fd)
        finally:
            os.close(fd)
        # mkstemp creates 0600: keep the replaced file's mode, else give a new file the usual one
        os.chmod(tmp, stat.S_IMODE(old_mode) if old_mode is not None else 0o666 & ~_umask())
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_all(fd: int, data: bytes) -> None:
    """Write all of ``data`` to the file descriptor ``fd`` (``os.write`` may write less)."""
    while data:
        data = data[os.write(fd, data):]


def _replace_atomically(p: Path, text: str) -> None:
    replace_atomically(p, lambda fd: write_all(fd, text.encode("utf-8")))


def _write_through(p: Path, text: str) -> None:
    """Write into the FIFO or device ``p`` leads to: opened without creating or truncating, refused
    when what was opened is a regular file after all."""
    fd = os.open(p, os.O_WRONLY | os.O_NOCTTY)
    try:
        if stat.S_ISREG(os.fstat(fd).st_mode):
            raise OSError(errno.EEXIST, "it became a regular file while being opened")
        write_all(fd, text.encode("utf-8"))
    finally:
        os.close(fd)


def write_output(path: str | Path | None, text: str, flag: str = "-o", *, through: bool = True) -> None:
    """Write ``text`` to stdout (``None`` or ``-``), through to a FIFO or device, or atomically as
    a regular file (see the module docstring; ``through=False``: a name handeye chose, where nothing
    is written through). Raises WriteError (one line, naming ``flag``) on failure."""
    if _is_stdout(path):
        write_stdout(text)
        return
    p = Path(str(path))
    if through:
        check_writable(p, flag)
    try:
        if written_through(p, through):
            _write_through(p, text)
        else:
            _replace_atomically(p, text)
    except OSError as e:
        error = WriteError(f"cannot write ({e.strerror or e.__class__.__name__})", str(p),
                           f"choose another {flag} path")
        error.errno, error.strerror = e.errno, e.strerror
        raise error from None


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
