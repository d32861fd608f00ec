"""Per-input result files in ``--output-dir`` and the key that lets ``--skip-done`` reuse them.

A result file is named after its input (the normalised path with ``/`` → ``__``, two-file inputs
joined by ``+``; ``.yaml`` or ``.json``) and holds the result document, the verdict when there is
one, and ``batch: {input, key, log_span_ns, seconds}``. The key is the SHA-256 of the handeye
version, the options, the stream selection and the content of every input file (a ROS 2 bag
directory: every file in it, by relative name), so a changed log, option or version recomputes.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from pathlib import Path
from typing import Any

import yaml

from .. import __version__
from ..output.document import render
from ..output.writers import write_output
from .engine import Job

__all__ = ["job_key", "result_path", "load_done", "store"]

_CHUNK = 1 << 20


def _hash_file(h: Any, path: Path) -> None:
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)


def _canonical(value: Any) -> Any:
    """Options (dataclasses, dicts, tuples) as JSON-able data with a stable order."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return _canonical(dataclasses.asdict(value))
    if isinstance(value, dict):
        return {str(k): _canonical(v) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    return value if isinstance(value, (str, int, float, bool, type(None))) else repr(value)


def job_key(job: Job) -> str:
    """SHA-256 (hex) of version, options, streams and the input files' content."""
    h = hashlib.sha256()
    h.update(json.dumps([__version__, _canonical(job.options), _canonical(job.streams)]).encode())
    for p in map(Path, job.input.paths):
        files = sorted(f for f in p.rglob("*") if f.is_file()) if p.is_dir() else [p]
        for f in files:
            h.update(str(f.relative_to(p) if p.is_dir() else f.name).encode() + b"\0")
            _hash_file(h, f)
    return h.hexdigest()


def result_path(output_dir: str | Path, job: Job, fmt: str) -> Path:
    """Where ``--output-dir`` keeps the result of ``job`` (see the module docstring)."""
    parts = []
    for p in job.input.paths:
        norm = os.path.normpath(p).lstrip(os.sep)
        parts.append("__".join(s for s in norm.split(os.sep) if s not in ("", ".", "..")))
    return Path(output_dir) / f"{'+'.join(parts)}.{fmt}"


def store(path: Path, record: dict[str, Any], key: str, fmt: str) -> None:
    """Write a calibrated record as its result file (atomically)."""
    meta = {k: record[k] for k in ("input", "log_span_ns", "seconds") if k in record}
    doc = {k: v for k, v in record.items() if k not in ("input", "status", "error", "log_span_ns", "seconds")}
    write_output(path, render({**doc, "batch": {**meta, "key": key}}, fmt), "--output-dir")


def load_done(path: Path, key: str) -> dict[str, Any] | None:
    """The record stored at ``path`` when it was computed with ``key`` (without its verdict), else None."""
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return None
    meta = doc.get("batch") if isinstance(doc, dict) else None
    if not isinstance(meta, dict) or meta.get("key") != key:
        return None
    body = {k: v for k, v in doc.items() if k not in ("batch", "verdict")}
    return {"input": meta["input"], "status": "ok", **body, "log_span_ns": meta.get("log_span_ns"),
            "seconds": meta.get("seconds", 0.0)}
