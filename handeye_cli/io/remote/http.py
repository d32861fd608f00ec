"""The standard library's client for plain http(s) objects (:class:`_Plain`), and the wall-clock bound of one
request (:func:`_within`) with the word for what went wrong (:func:`_kind`): what :meth:`.sessions.Session.call`
tries and reports."""
from __future__ import annotations

import concurrent.futures
from typing import Any

from ...errors import ReadError


class _Plain:
    """The two calls an object's reading makes of its file system — ``info`` (its size) and
    ``cat_file`` (a byte range; ``start`` < 0: the last ``-start`` bytes) — for a plain http(s) URL,
    on the standard library's client: no aiohttp to import (0.3 s of every command), and a body read
    in one call (fsspec's http file system took 3-5 x as long as one GET for 200 MB of ranges from
    the loopback server of benchmarks/remote.py). No proxy from the environment, as fsspec's;
    storage options (headers, auth) and folder listings go through fsspec. Answers map to the errors
    :meth:`Session.call` knows: 404/410 FileNotFoundError, 401/403 PermissionError, no answer in
    ``timeout`` [s] TimeoutError, anything else OSError; a server that ignores ``Range`` (answers 200
    with the whole object) is a ReadError at once, never the wrong bytes."""

    def __init__(self, timeout: float) -> None:
        import urllib.request

        self._timeout = timeout
        self._opener = urllib.request.build_opener(urllib.request.ProxyHandler({}))

    def _open(self, url: str, method: str, headers: dict[str, str]) -> Any:
        import urllib.error
        import urllib.request

        try:
            return self._opener.open(urllib.request.Request(url, method=method, headers={
                "Accept-Encoding": "identity", **headers}), timeout=self._timeout)
        except urllib.error.HTTPError as exc:
            exc.close()
            if exc.code in (404, 410):
                raise FileNotFoundError(url) from None
            if exc.code in (401, 403):
                raise PermissionError(url) from None
            raise OSError(f"HTTP {exc.code}") from None
        except urllib.error.URLError as exc:
            if isinstance(exc.reason, TimeoutError):
                raise TimeoutError from None
            raise OSError(str(exc.reason)) from None

    def info(self, url: str) -> dict[str, Any]:
        with self._open(url, "HEAD", {}) as r:
            size = r.headers.get("Content-Length")
        if size is None:
            raise ReadError("the server does not say the object's size (no Content-Length)", url,
                            "download the object and pass its local path")
        return {"name": url, "size": int(size), "type": "file"}

    def cat_file(self, url: str, start: int = 0, end: int | None = None) -> bytes:
        import http.client

        asked = f"bytes=-{-start}" if start < 0 else f"bytes={start}-{'' if end is None else end - 1}"
        try:
            with self._open(url, "GET", {"Range": asked}) as r:
                n = int(r.headers.get("Content-Length", -1))
                whole = -start if start < 0 else end if start == 0 else -1     # the object, when no longer
                if r.status != 206 and not (r.status == 200 and n >= 0 and (whole is None or n <= whole)):
                    raise ReadError(f"the server ignores byte ranges (answered {r.status} to a Range request)",
                                    url, "serve the object where Range requests are answered, or download it "
                                    "and pass its local path")
                data: bytes = r.read()
        except http.client.HTTPException as exc:        # cut short: IncompleteRead, a bad status line
            raise OSError(type(exc).__name__) from None
        return data


class _Overran(Exception):
    """A request still running past its time limit."""


def _within(seconds: float, fn: Any, *args: Any) -> Any:
    """``fn(*args)``, or :class:`_Overran` after ``seconds`` (the file systems' own timeouts come
    first; this is the bound when one of them does not apply, e.g. a server that accepts and is silent)."""
    pool = concurrent.futures.ThreadPoolExecutor(1)
    try:
        return pool.submit(fn, *args).result(seconds)
    except concurrent.futures.TimeoutError as exc:
        raise _Overran from exc
    finally:
        pool.shutdown(wait=False)


def _kind(error: BaseException) -> str:
    if isinstance(error, (_Overran, TimeoutError)) or "timeout" in type(error).__name__.lower():
        return "no answer in time"
    return type(error).__name__
