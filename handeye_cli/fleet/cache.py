"""Per-input result files in ``--output-dir`` and the key that lets ``--skip-done`` reuse them.

A result file is named after its input: the normalised path with ``/`` → ``__`` (an absolute path
starts with ``__``), two-file inputs joined by ``+``, then the format's suffix (``.yaml``, ``.json``,
``.urdf``, ``.launch``, ``.launch.py``, ``.sh``, ``.kalibr.yaml``). That name is
kept only when it cannot be another input's: when a component of the path is ``..``, holds
``__``, ``+``, ``%`` or ``~``, starts or ends with ``_``, or the name would be long, the name gets
``~`` and 16 hex digits of the SHA-256 of the path(s) as given — the same on every run, so that
``--skip-done`` finds it. A YAML or JSON file holds the result document, the verdict when there
is one, and ``batch: {input, key, log_span_ns, seconds}``; the other formats cannot carry those,
so the result document and its ``batch`` entry go beside the file, in ``<file>.handeye.json``.
The key is the SHA-256 of the handeye version, the options, the stream selection and the content
of every input file (a ROS 2 bag directory: every file in it, by relative name), so a changed log,
option or version recomputes.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import stat
from pathlib import Path
from typing import Any

import yaml

from ..errors import WriteError
from ..output.formats import render_format
from ..output.writers import SUFFIXES, write_output
from ..untrusted import load_yaml
from ..version import __version__
from .engine import Job

__all__ = ["job_key", "result_path", "load_done", "store"]

_CHUNK = 1 << 20
_SUFFIX = {fmt: suffix for suffix, fmt in reversed(SUFFIXES.items())} | {"kalibr": ".kalibr.yaml",
                                                                                 "urdf-joint": ".joint.urdf"}
_SIDECAR = ".handeye.json"      # the result document and its batch key, beside a file of another format


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


_SEP = "__"
_MAX_NAME = 180            # bytes of a name kept whole (file names: ≤ 255 bytes); a longer one keeps its tail


def _plain(component: str) -> bool:
    """Whether a path component can be joined by ``__`` and split back unambiguously."""
    return (component not in ("", ".", "..") and _SEP not in component and not set("+%~") & set(component)
            and not component.startswith("_") and not component.endswith("_"))


def result_path(output_dir: str | Path, job: Job, fmt: str) -> Path:
    """Where ``--output-dir`` keeps the result of ``job`` (see the module docstring): distinct
    inputs get distinct names, the same input the same name."""
    parts, plain = [], True
    for p in job.input.paths:
        norm = os.path.normpath(p)
        components = norm.split(os.sep)
        absolute = norm.startswith(os.sep)
        plain = plain and all(map(_plain, components[1:] if absolute else components))
        parts.append(("" if not absolute else _SEP) + _SEP.join(c for c in components if c not in ("", ".", "..")))
    name = "+".join(parts)
    long = len(name.encode("utf-8", "surrogateescape")) > _MAX_NAME
    if not plain or long:
        digest = hashlib.sha256("\0".join(job.input.paths).encode("utf-8", "surrogateescape")).hexdigest()
        name = f"{name[-40:] if long else name}~{digest[:16]}"
    return Path(output_dir) / f"{name}{_SUFFIX[fmt]}"


def _cache_path(path: Path, fmt: str) -> Path:
    """The file that holds the result document with its batch key: the result file itself (YAML,
    JSON), else the one beside it."""
    return path if fmt in ("yaml", "json") else path.with_name(path.name + _SIDECAR)


def store(output_dir: Path, job: Job, record: dict[str, Any], key: str, fmt: str) -> Path:
    """Write a calibrated record as its result file in ``fmt`` (atomically), and its cache file
    beside it when ``fmt`` cannot carry the batch key; the result file's path. The names are
    handeye's, in a folder others may write to: whatever holds them (a planted link, a FIFO) is
    replaced, never written through (``write_output(through=False)``). When the cache file
    cannot be written, the result file just written is removed: a record says a file was written
    only when both were."""
    path = result_path(output_dir, job, fmt)
    meta = {k: record[k] for k in ("input", "log_span_ns", "seconds") if k in record}
    doc = {k: v for k, v in record.items()
           if k not in ("input", "status", "error", "result_file", "log_span_ns", "seconds")}
    cached: dict[str, Any] = {**doc, "batch": {**meta, "key": key}}
    if fmt not in ("yaml", "json"):
        write_output(path, render_format(doc, fmt), "--output-dir", through=False)
    try:
        write_output(_cache_path(path, fmt), render_format(cached, fmt if fmt in ("yaml", "json") else "json"),
                     "--output-dir", through=False)
    except WriteError:
        if fmt not in ("yaml", "json"):
            path.unlink(missing_ok=True)
        raise
    return path


def _own_file(path: Path) -> bool:
    """Whether ``path`` is a regular file itself (not a link planted to another file, not a FIFO)."""
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def _own_text(path: Path) -> str:
    """The text of the regular file ``path`` itself: opened without following a link and without
    blocking (a FIFO swapped in after :func:`_own_file`); OSError for anything but a regular file."""
    fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    with open(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise OSError(f"{path} is not a regular file")
        return f.read().decode("utf-8")


def load_done(output_dir: Path, job: Job, key: str, fmt: str) -> dict[str, Any] | None:
    """The record stored for ``job`` when it was computed with ``key`` (without its verdict), else None:
    a result or cache file that is not a regular file itself (a planted link, a FIFO) is not trusted."""
    path = result_path(output_dir, job, fmt)
    if not _own_file(path):
        return None
    try:
        doc = load_yaml(_own_text(_cache_path(path, fmt)))      # a shared folder: no aliases, bounded depth
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return None
    meta = doc.get("batch") if isinstance(doc, dict) else None
    if not isinstance(meta, dict) or meta.get("key") != key:
        return None
    body = {k: v for k, v in doc.items() if k not in ("batch", "verdict")}
    return {"input": meta["input"], "status": "ok", **body, "log_span_ns": meta.get("log_span_ns"),
            "seconds": meta.get("seconds", 0.0)}
