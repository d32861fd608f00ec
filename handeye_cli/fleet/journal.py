"""The records file of a batch (``handeye batch -o records.jsonl``): JSON Lines appended one record
at a time, each written whole by one ``write`` and made durable (``fsync``) before the next input's
record, so that a batch ended by SIGINT, SIGTERM or SIGKILL leaves every record it emitted.

With ``--skip-done`` the file is the batch's journal: its intact records are kept and their inputs
not run again (error records too: delete a line to retry its input); a last line cut by a kill
mid-write (no newline at its end) is cut off, with a warning, and its input run again; the new
records are appended. A damaged line that ends in a newline is refused (exit 2): a kill does not
write one. Without ``--skip-done`` the file is started afresh.

A symbolic link at the path is never appended through (a link planted in a shared folder would
make the batch write into another file) nor read: it is replaced by a new, empty regular file (a
temporary file renamed over the link), so with ``--skip-done`` every input runs again, as a result
file that is a link is not trusted either; the path is then opened with ``O_NOFOLLOW``, so a link
planted again in between is one line (exit 2), not a write. Without ``--skip-done`` a regular file
is replaced by a new empty one the same way (not truncated in place: a hard link to it keeps its
content). A link to a FIFO or device
(``/dev/stdout``) is written through, as the FIFO or device itself is (see
:mod:`handeye_cli.output.writers`).
"""
from __future__ import annotations

import os
import stat
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..errors import WriteError
from ..output.records import intact_records
from ..output.writers import replace_atomically, write_all, written_through

__all__ = ["Journal"]

Record = dict[str, Any]


class Journal:
    """The records file at ``path``: :attr:`done` (input → record) holds what a resumed batch keeps."""

    def __init__(self, path: str | Path, resume: bool, warn: Callable[[str], None], flag: str = "--output") -> None:
        self.path, self.flag = Path(path), flag
        self.done: dict[str, Record] = {}
        self.regular = True
        through = written_through(self.path)
        try:
            if not through and (self.path.is_symlink() or not resume):    # a planted link's target is neither
                replace_atomically(self.path, lambda fd: None)                # read nor written; a fresh file is new
            flags = os.O_RDWR | os.O_CREAT | os.O_APPEND | (0 if resume else os.O_TRUNC)
            self.fd = os.open(self.path, flags | (0 if through else os.O_NOFOLLOW), 0o666)
        except OSError as e:
            raise WriteError(f"cannot open the records file ({e.strerror})", str(self.path),
                             f"choose another {flag} path") from None
        self.regular = stat.S_ISREG(os.fstat(self.fd).st_mode)      # a FIFO or /dev/null: no fsync, no resume
        if resume and self.regular:
            with open(self.fd, "rb", closefd=False) as f:
                records, end = intact_records(f.read(), str(self.path), warn)
            self.done = {r["input"]: r for r in records}
            self._call(os.ftruncate, end)

    def _call(self, fn: Callable[..., Any], *args: Any) -> Any:
        try:
            return fn(self.fd, *args)
        except OSError as e:
            raise WriteError(f"cannot write the records file ({e.strerror})", str(self.path),
                             f"free space there or choose another {self.flag} path") from None

    def append(self, line: str) -> None:
        """Append one record line (``line`` without its newline) and make it durable."""
        self._call(write_all, (line + "\n").encode("utf-8"))
        if self.regular:
            self._call(os.fsync)

    def close(self) -> None:
        os.close(self.fd)
