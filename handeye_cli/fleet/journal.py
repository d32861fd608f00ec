"""The records file of a batch (``handeye batch -o records.jsonl``): JSON Lines appended one record
at a time, each written whole by one ``write`` and made durable (``fsync``) before the next input's
record, so that a batch ended by SIGINT, SIGTERM or SIGKILL leaves every record it emitted.

With ``--skip-done`` the file is the batch's journal: its intact records are kept and their inputs
not run again (error records too: delete a line to retry its input); a last line cut by a kill
mid-write (no newline at its end) is cut off, with a warning, and its input run again; the new
records are appended. A damaged line that ends in a newline is refused (exit 2): a kill does not
write one. Without ``--skip-done`` the file is started afresh.
"""
from __future__ import annotations

import os
import stat
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..errors import WriteError
from ..output.records import intact_records

__all__ = ["Journal"]

Record = dict[str, Any]


class Journal:
    """The records file at ``path``: :attr:`done` (input → record) holds what a resumed batch keeps."""

    def __init__(self, path: str | Path, resume: bool, warn: Callable[[str], None], flag: str = "--output") -> None:
        self.path, self.flag = Path(path), flag
        self.done: dict[str, Record] = {}
        self.regular = True
        try:
            self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_APPEND | (0 if resume else os.O_TRUNC), 0o666)
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
        data = (line + "\n").encode("utf-8")
        while data:
            data = data[self._call(os.write, data):]
        if self.regular:
            self._call(os.fsync)

    def close(self) -> None:
        os.close(self.fd)
