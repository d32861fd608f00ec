"""Inputs named by URL (``s3://bucket/key.mcap``, ``gs://…``, ``https://…``, ``memory://…``): the one
home of remote reading — opening through fsspec, bounded retries, byte counting, the download cache.

fsspec (and s3fs for S3: the extra ``remote``, ``pip install 'handeye-cli[remote]'``; gcsfs for gs://:
``[gcs]``) is imported only when a URL is read. Credentials and the endpoint come the standard way
(``AWS_ENDPOINT_URL``, ``AWS_ACCESS_KEY_ID``/``AWS_SECRET_ACCESS_KEY``, ``AWS_PROFILE`` …) or from the storage options
(``--storage-option KEY=VALUE``: fsspec's keyword arguments of the file system); neither is ever
written to a message, record or result: errors are handeye's own sentences, and a URL holding
credentials (``https://user:pass@host/…``) is refused.

An object is read by byte range (:class:`RemoteObject`): every request asks for exactly the bytes
its reader needs (at least :data:`_READAHEAD` for small reads), gets at most
``remote_retries`` tries of ``remote_timeout`` seconds each, and adds what it got to the
session's :attr:`Session.bytes_fetched` (and one to :attr:`Session.requests`). Detecting the
format asks for the object's size together with its first :data:`_READAHEAD` and last
:data:`_TAIL` bytes (one round trip: :meth:`Session.is_folder`). The MCAP reader reads the footer,
the summary and then only the chunks it needs; an indexed ROS 1 bag's reader
(:class:`.rosbag1_scan.Bag1Index`) its header, its index and then only the chunks it needs. Both
ask for chunks through :meth:`RemoteObject.ranges`, which joins ranges at most :data:`_GAP` apart
into one request of at most :data:`_SPAN` and keeps up to :data:`_PARALLEL` requests holding up to
:data:`_AHEAD` bytes under way at once, so memory holds a few chunks, never the object. A plain
http(s) object is read with the standard library's client (:class:`_Plain`), anything else
through fsspec. What cannot be read by range — text files, ROS 2
bags, a ROS 1 bag without a usable index, split ROS 1 bags, an MCAP without a summary (cut short,
or written without one) — is downloaded once to the session's cache (:meth:`Session.cached`): at
most :data:`CACHE_LIMIT` bytes, removed when the session ends and at exit, with a one-line note.
"""
from __future__ import annotations

import atexit
import bisect
import concurrent.futures
import contextlib
import os
import re
import shutil
import struct
import tempfile
import threading
import time
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from ..errors import ConfigError, ReadError
from ..untrusted import REMOTE_DEADLINE_S, REMOTE_RETRIES, REMOTE_TIMEOUT_S

__all__ = ["is_url", "Session", "session", "session_of", "current", "RemoteObject", "CACHE_LIMIT", "scrub"]

CACHE_LIMIT = 8 << 30
"""The most bytes [B] one session downloads to its cache (objects that cannot be read by range)."""
_READAHEAD = 4 << 10        # [B] the least a request asks for (small reads: headers, records of a summary)
_TAIL = 16 << 10            # [B] an object's last bytes, asked for with its size (an MCAP's footer and summary,
                            # a ROS 1 bag's index: the rest, if longer, in one more request)
_SPAN = 16 << 20            # [B] the most one request of adjacent chunks asks for
_GAP = 64 << 10             # [B] planned ranges this close are asked for in one request (the gap's bytes with them)
_PARALLEL = 16              # requests of one object's planned ranges under way at once, at most …
_AHEAD = 64 << 20           # [B] … holding at most this many bytes asked for ahead of the reader (or one span)
_HELD = 64 << 20            # [B] the most fetched bytes kept for re-reading (footer, summary, head)
_PIECE = 16 << 20           # [B] a download's request size
_CLIENTS = ("botocore", "aiobotocore", "aiohttp", "urllib3", "asyncio", "gcsfs", "google", "fsspec", "s3fs")
_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*://")
_FOOTER = 37                # Footer record (opcode 1 + length 8 + 8 + 8 + 4) + magic 8
_MCAP_MAGIC = b"\x89MCAP0\r\n"
_CREDENTIAL_ENV = ("AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY", "AWS_SESSION_TOKEN", "GOOGLE_APPLICATION_CREDENTIALS")
_FIX_CREDENTIALS = ("set AWS_ACCESS_KEY_ID / AWS_SECRET_ACCESS_KEY or AWS_PROFILE, or pass "
                    "--storage-option key=… --storage-option secret=…")


def is_url(path: object) -> bool:
    """Whether ``path`` is a URL (``scheme://…``) rather than a local path."""
    return isinstance(path, str) and bool(_URL.match(path))


def scrub(text: str, storage_options: Sequence[tuple[str, str]] = ()) -> str:
    """``text`` with every credential the environment or ``storage_options`` holds replaced by ``***``."""
    secrets = [os.environ.get(k, "") for k in _CREDENTIAL_ENV] + [v for _, v in storage_options]
    for secret in sorted({s for s in secrets if len(s) >= 4}, key=len, reverse=True):
        text = text.replace(secret, "***")
    return text


@dataclass
class Session:
    """The remote reading of one calibration (or one ``inspect``, one batch discovery): its settings,
    the objects opened (by URL, so detecting a format and reading it share their fetched bytes), the
    bytes fetched [B] and the downloads cached."""

    storage_options: tuple[tuple[str, str], ...]
    timeout: float              # [s] per request (``remote_timeout``)
    retries: int                # tries per request (``remote_retries``)
    deadline: float = REMOTE_DEADLINE_S     # [s] an object without an answered request (``remote_deadline``)
    bytes_fetched: int = 0
    requests: int = 0               # range requests answered (what benchmarks/remote.py reports)
    urls: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    _objects: dict[str, RemoteObject] = field(default_factory=dict)
    _folders: dict[str, bool] = field(default_factory=dict)
    _infos: dict[str, dict[str, Any]] = field(default_factory=dict)      # the file system's info, by URL
    _early: dict[str, list[concurrent.futures.Future[bytes | None]]] = field(default_factory=dict)
    _pool: concurrent.futures.ThreadPoolExecutor | None = None          # the requests sent with an info
    _cache: Path | None = None
    _cached: dict[str, Path] = field(default_factory=dict)
    _cached_bytes: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock)   # the counts, added to from a Ranges pool
    _stalls: dict[str, list[Any]] = field(default_factory=dict)     # URL → [clock start [s] or None, tries since]

    def count(self, n: int) -> None:
        """Count one request answered with ``n`` bytes [B] (safe from the threads of :class:`Ranges`)."""
        with self._lock:
            self.bytes_fetched += n
            self.requests += 1

    def fs(self, url: str, listing: bool = False) -> tuple[Any, str]:
        """(the fsspec file system of ``url``, its path there), with the timeouts and retries of this
        session; for reading a plain http(s) object (no storage options, not ``listing`` a folder
        page) the standard library's client instead (:class:`_Plain`)."""
        if urlsplit(url).password is not None or "@" in urlsplit(url).netloc:
            raise ConfigError("a URL holding credentials is refused", scrub(url.split("@", 1)[-1]),
                              "pass credentials through the environment or --storage-option")
        if not listing and not self.storage_options and url.split("://", 1)[0].lower() in ("http", "https"):
            return _Plain(self.timeout), url
        try:
            import fsspec  # type: ignore[import-untyped]
            from fsspec.core import split_protocol  # type: ignore[import-untyped]
        except ImportError as exc:
            raise ConfigError("reading URLs needs fsspec", url,
                              "pip install 'handeye-cli[remote]' (in a checkout: pip install '.[remote]')") from exc
        protocol, _ = split_protocol(url)
        options: dict[str, Any] = dict(self.storage_options)
        if protocol in ("s3", "s3a"):
            options.setdefault("config_kwargs", {"connect_timeout": self.timeout, "read_timeout": self.timeout,
                                                 "retries": {"max_attempts": 1},
                                                 "max_pool_connections": _PARALLEL + 2})
        elif protocol in ("http", "https"):
            import aiohttp  # the http(s) file system's client

            options.setdefault("client_kwargs", {"timeout": aiohttp.ClientTimeout(total=self.timeout)})
        try:
            fs = fsspec.filesystem(protocol, **options)
        except ImportError as exc:
            raise ConfigError(f"no file system for {protocol}:// installed: {exc.name or exc}", url,
                              "pip install 'handeye-cli[remote]' (s3://, https://) or 'handeye-cli[gcs]' (gs://); "
                              "in a checkout: pip install '.[remote]' or '.[gcs]'") from exc
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"bad storage options for {protocol}://: {type(exc).__name__}",
                              "--storage-option", "pass the keyword arguments of the fsspec file system") from exc
        return fs, fs._strip_protocol(url)

    def _left(self, url: str, what: str, start: bool = False) -> float:
        """The seconds [s] left of the :attr:`deadline` of the object ``url``: what its clock, running
        since the first try after its last answered request, has not used (``start``: a try starts, the
        clock with it unless it runs, and is counted); a one-line ReadError once nothing is left."""
        with self._lock:
            stall = self._stalls.setdefault(url, [None, 0])
            now = time.monotonic()
            if stall[0] is None:
                if not start:
                    return self.deadline
                stall[0] = now
            left = float(self.deadline - (now - stall[0]))
            if left <= 0:
                tried = f"{stall[1]} request{'s' * (stall[1] != 1)} tried"
                raise ReadError(f"{what}: no progress for {self.deadline:g} s ({tried})", url,
                                "check the endpoint (AWS_ENDPOINT_URL) and the network, or raise "
                                "--remote-deadline SECONDS")
            stall[1] += start
        return left

    def _answered(self, url: str) -> None:
        """A request of ``url`` was answered: the object's clock stops (the next try starts it anew)."""
        with self._lock:
            self._stalls[url] = [None, 0]

    def call(self, url: str, what: str, fn: Any, *args: Any, tries: int | None = None) -> Any:
        """``fn(*args)`` tried up to ``tries`` (default :attr:`retries`) times; a one-line ReadError
        naming ``url`` when the object is missing, access is denied, every try failed or overran
        :attr:`timeout`, or the object went :attr:`deadline` seconds without an answered request (its
        clock runs from the first try after its last answer, whichever request of it that was: each try
        is cut at what is left, so a stalled object fails in :attr:`deadline` seconds, a large one that
        keeps answering never)."""
        tries = self.retries if tries is None else tries
        for attempt in range(1, tries + 1):
            limit = min(self.timeout * 2 + 1, self._left(url, what, start=True))     # [s] this try's
            try:
                result = _within(limit, fn, *args)
                self._answered(url)
                return result
            except FileNotFoundError as exc:
                raise ReadError("no such object", url, "check the bucket, the key and the endpoint "
                                "(AWS_ENDPOINT_URL)") from exc
            except PermissionError as exc:
                raise ReadError("access denied: the credentials are wrong or lack permission", url,
                                _FIX_CREDENTIALS) from exc
            except (OSError, TimeoutError, _Overran) as exc:
                error: BaseException = exc
            except Exception as exc:    # the file systems' own errors (botocore, aiohttp) beside OSError
                if type(exc).__name__ in ("NoCredentialsError", "PartialCredentialsError"):
                    raise ReadError("no credentials found", url, _FIX_CREDENTIALS) from exc
                if not type(exc).__module__.startswith(_CLIENTS):
                    raise
                error = exc
            left = self._left(url, what)     # the deadline's line once spent, whatever tries are left
            if attempt < tries:
                time.sleep(min(2.0, 0.1 * 2 ** attempt, left))
        raise ReadError(f"{what} failed {tries} times ({_kind(error)}; {self.timeout:g} s each)", url,
                        "check the endpoint (AWS_ENDPOINT_URL) and the network, or raise --remote-timeout SECONDS / "
                        "--remote-retries N") from error

    def open(self, url: str) -> RemoteObject:
        """The object at ``url`` (its size asked once; opened once per session), holding the first and
        last bytes asked for with its size (:meth:`is_folder` with ``read_ahead``)."""
        if url not in self._objects:
            fs, path = self.fs(url)
            info = self._info(url, read_ahead=False)
            if info.get("type") == "directory":
                raise ReadError("a folder, not an object", url, "name an object, or give the folder to "
                                "handeye batch")
            obj = RemoteObject(self, url, fs, path, int(info["size"]))
            for start, asked in zip((0, -_TAIL), self._early.pop(url, []), strict=False):
                data = asked.result()
                if data and len(data) <= max(-start, _READAHEAD, 1) or data and len(data) == obj.size:
                    obj.hold(start if start >= 0 else obj.size - len(data), data)
            self._objects[url] = obj
            self.urls.append(url)
        return self._objects[url]

    def is_folder(self, url: str, read_ahead: bool = False) -> bool:
        """Whether ``url`` names a folder (a prefix holding objects) rather than an object (asked once
        a session: detecting the format and opening the input share the answer). An http(s) URL names
        a folder (a listing page) only if it ends with ``/``. ``read_ahead``: an object's first
        :data:`_READAHEAD` and last :data:`_TAIL` bytes are asked for together with its size, in one
        round trip (see :meth:`_info`)."""
        if url not in self._folders:
            if url.split("://", 1)[0].lower() in ("http", "https"):
                if url.endswith("/"):
                    fs, path = self.fs(url, listing=True)
                    self._folders[url] = bool(self.call(url, "listing", fs.isdir, path))
                else:
                    self._folders[url] = self._info(url, read_ahead)["type"] == "directory"
            else:
                self._folders[url] = self._info(url, read_ahead and not url.endswith("/"))["type"] == "directory"
        return self._folders[url]

    def _info(self, url: str, read_ahead: bool) -> dict[str, Any]:
        """The file system's info on ``url`` (``size`` [B], ``type``), asked once a session. With
        ``read_ahead`` the object's first :data:`_READAHEAD` bytes (what detecting its format reads) and
        its last :data:`_TAIL` (an MCAP's footer and summary, a ROS 1 bag's index) are asked for at the
        same time, one try each, kept for :meth:`open`: one round trip where there were three."""
        if url not in self._infos:
            fs, path = self.fs(url)
            if read_ahead:
                if self._pool is None:
                    self._pool = concurrent.futures.ThreadPoolExecutor(2, thread_name_prefix="handeye-ahead")
                self._early[url] = [self._pool.submit(self._read_ahead, fs, path, url, start, stop)
                                    for start, stop in ((0, _READAHEAD), (-_TAIL, None))]
            self._infos[url] = self.call(url, "asking its size", fs.info, path)
        return self._infos[url]

    def _read_ahead(self, fs: Any, path: str, url: str, start: int, stop: int | None) -> bytes | None:
        """The bytes ``[start, stop)`` (``start`` < 0: the last ``-start``) in one try, counted; None if
        the request failed (the ReadError of :meth:`call`: missing, denied, the network; the reader asks
        again, with retries, and reports what is wrong). Any other exception is not a failed request but a
        bug: it propagates (through :meth:`open`, which waits for this)."""
        try:
            data: bytes = self.call(url, "reading ahead", lambda: fs.cat_file(path, start=start, end=stop), tries=1)
        except ReadError:    # call turned the client's error into its one line: the reader's request says it
            return None
        self.count(len(data))
        return data

    def listing(self, url: str, pattern: bool = False) -> list[tuple[str, bool]]:
        """(URL, whether a folder) of the objects under the folder ``url`` (recursively), or of what
        the glob ``url`` matches (``pattern``), sorted."""
        fs, path = self.fs(url, listing=True)
        found = self.call(url, "listing", lambda: (fs.glob if pattern else fs.find)(path, detail=True))
        protocol = url.split("://", 1)[0]
        return sorted((name if is_url(name) else f"{protocol}://{name}" if protocol != "memory" else f"memory://{name}",
                       info.get("type") == "directory") for name, info in found.items())

    def cached(self, url: str, why: str) -> Path:
        """A local copy of the object (or folder) at ``url``, keeping its name, downloaded once to this
        session's cache, with a note saying so and ``why``; ReadError past :data:`CACHE_LIMIT`."""
        if url in self._cached:
            return self._cached[url]
        if self._cache is None:
            self._cache = Path(tempfile.mkdtemp(prefix="handeye-remote-"))
            atexit.register(shutil.rmtree, self._cache, True)
        folder = self._cache / str(len(self._cached))
        folder.mkdir()
        target = folder / (urlsplit(url).path.rstrip("/").rsplit("/", 1)[-1] or "object")
        if self.is_folder(url):
            base = url.rstrip("/")
            target.mkdir()
            for name, _ in self.listing(url):
                rel = name[len(base):].lstrip("/")
                if not rel or ".." in rel.split("/"):
                    continue
                (target / rel).parent.mkdir(parents=True, exist_ok=True)
                self._download(self.open(name), target / rel)
        else:
            self._download(self.open(url), target)
        self._cached[url] = target
        self.notes.append(f"{url}: {why}; downloaded it whole to a temporary cache (removed at exit)")
        return target

    def _download(self, obj: RemoteObject, target: Path) -> None:
        if self._cached_bytes + obj.size > CACHE_LIMIT:
            raise ReadError(f"the download cache would exceed {CACHE_LIMIT >> 20} MiB "
                            "(handeye_cli.io.remote.CACHE_LIMIT)", obj.url,
                            "download the object and pass its local path")
        self._cached_bytes += obj.size
        pieces = [(start, min(_PIECE, obj.size - start)) for start in range(0, obj.size, _PIECE)]
        with open(target, "wb") as f, obj.ranges(pieces) as ranges:     # several pieces under way at once
            for start, n in pieces:
                f.write(ranges.view(start, n))

    def close(self) -> None:
        """Remove this session's downloads; requests read ahead and never used are dropped."""
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
        if self._cache is not None:
            shutil.rmtree(self._cache, True)
            self._cache = None
        self._cached.clear()


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


_SESSION: ContextVar[Session | None] = ContextVar("handeye_remote_session", default=None)



@contextlib.contextmanager
def session(storage_options: Sequence[tuple[str, str]], timeout: float, retries: int,
            deadline: float = REMOTE_DEADLINE_S) -> Iterator[Session]:
    """A :class:`Session` that the readers in this context use (the read options ``storage_option``,
    ``remote_timeout``, ``remote_retries``, ``remote_deadline``); its downloads are removed at its end."""
    s = Session(tuple(storage_options), timeout, retries, deadline)
    token = _SESSION.set(s)
    try:
        yield s
    finally:
        _SESSION.reset(token)
        s.close()


def session_of(read: Any) -> contextlib.AbstractContextManager[Session]:
    """:func:`session` with the settings of the read options ``read`` (a :class:`handeye_cli.options.ReadOptions`)."""
    return session(read.storage_option, read.remote_timeout, read.remote_retries, read.remote_deadline)


def current() -> Session:
    """The session of this context, or one with the default read options lasting for the context
    (a reader called outside :func:`handeye_cli.calibrate_files` and the commands)."""
    s = _SESSION.get()
    if s is None:
        s = Session((), REMOTE_TIMEOUT_S, REMOTE_RETRIES, REMOTE_DEADLINE_S)
        _SESSION.set(s)
    return s


class RemoteObject:
    """One object read by byte range: ``size`` [B]; what :meth:`read_at` fetched is kept (at most
    :data:`_HELD` bytes, oldest dropped first) so that re-reading a header or the summary costs nothing."""

    def __init__(self, owner: Session, url: str, fs: Any, path: str, size: int) -> None:
        self.session, self.url, self._fs, self._path, self.size = owner, url, fs, path, size
        self.name = url
        self._held: OrderedDict[int, bytes] = OrderedDict()

    def __str__(self) -> str:
        return self.url

    def fetch(self, start: int, stop: int) -> bytes:
        """The bytes ``[start, stop)`` in one request (fewer only if the object ends first), counted."""
        stop = min(stop, self.size)
        if stop <= start:
            return b""
        data: bytes = self.session.call(self.url, f"reading bytes {start}-{stop}",
                                        lambda: self._fs.cat_file(self._path, start=start, end=stop))
        self.session.count(len(data))
        return data

    def hold(self, start: int, data: bytes) -> None:
        """Keep ``data``, the object's bytes from ``start``, for re-reading (at most :data:`_HELD`: oldest out)."""
        self._held[start] = data
        while sum(map(len, self._held.values())) > _HELD and len(self._held) > 1:
            self._held.popitem(last=False)

    def held(self, start: int, n: int) -> memoryview | None:
        """The ``n`` bytes from ``start`` if one block held has them all, else None."""
        for s, d in self._held.items():
            if s <= start and start + n <= s + len(d):
                return memoryview(d)[start - s:start - s + n]
        return None

    def unheld(self, start: int, stop: int) -> tuple[int, int]:
        """The bytes ``[start, stop)`` less what blocks held give at either end (the object's first
        and last bytes, read ahead): ``(a, b)``, empty (``a == b``) if nothing is left."""
        a, b = start, stop
        for s, d in self._held.items():
            if s <= a < s + len(d):
                a = min(stop, s + len(d))
        for s, d in self._held.items():
            if s < b <= s + len(d):
                b = s
        return a, max(a, b)

    def read_at(self, pos: int, n: int) -> bytes:
        """``n`` bytes from ``pos`` (fewer at the end): from what is held, else one request of at least
        :data:`_READAHEAD` bytes."""
        out = bytearray()
        while n > 0 and pos < self.size:
            block = next(((s, d) for s, d in self._held.items() if s <= pos < s + len(d)), None)
            if block is None:
                nxt = min((s for s in self._held if s > pos), default=self.size)
                want = min(max(n, _READAHEAD), nxt - pos) if nxt - pos >= n else nxt - pos
                data = self.fetch(pos, pos + want)
                if not data:
                    break
                self.hold(pos, data)
                block = (pos, data)
            s, d = block
            piece = d[pos - s:pos - s + n]
            out += piece
            pos, n = pos + len(piece), n - len(piece)
        return bytes(out)

    def prefetch_summary(self) -> bool:
        """Hold the MCAP footer and the summary it points at (what the object's last bytes, held since
        it was opened, do not cover: in one request); whether there is a summary (False: no footer —
        cut short — or written without one)."""
        if self.size < len(_MCAP_MAGIC) + _FOOTER:
            return False
        tail = self.read_at(self.size - _FOOTER, _FOOTER)
        if tail[-8:] != _MCAP_MAGIC or tail[0] != 0x02:
            return False
        (summary_start,) = struct.unpack_from("<Q", tail, 9)
        if not 0 < summary_start < self.size - _FOOTER:
            return False
        self.read_at(summary_start, self.size - _FOOTER - summary_start)
        return True

    def file(self) -> RangeFile:
        """A seekable binary file object reading this object by range."""
        return RangeFile(self)

    def ranges(self, planned: Sequence[tuple[int, int]]) -> Ranges:
        """Views of the byte ranges ``planned`` [(start, length)], to be asked for in that order."""
        return Ranges(self, planned)


class RangeFile:
    """A read-only, seekable binary file on a :class:`RemoteObject` (reads never past its end)."""

    def __init__(self, obj: RemoteObject) -> None:
        self._obj, self._pos = obj, 0
        self.name = obj.url

    def read(self, n: int | None = -1) -> bytes:
        if n is None or n < 0:
            n = self._obj.size - self._pos
        data = self._obj.read_at(self._pos, n)
        self._pos += len(data)
        return data

    def readinto(self, buf: Any) -> int:
        data = self.read(len(buf))
        memoryview(buf).cast("B")[:len(data)] = data
        return len(data)

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        base = {os.SEEK_SET: 0, os.SEEK_CUR: self._pos, os.SEEK_END: self._obj.size}[whence]
        self._pos = max(0, base + offset)
        return self._pos

    def tell(self) -> int:
        return self._pos

    def seekable(self) -> bool:
        return True

    def readable(self) -> bool:
        return True

    def close(self) -> None:
        """Nothing to release: the object's held bytes belong to its session."""

    def __enter__(self) -> RangeFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Ranges:
    """Byte ranges of an object asked for in a planned order (use as a context manager): ranges at
    most :data:`_GAP` apart are fetched together, up to :data:`_SPAN` bytes a request; the spans
    after the one being read are asked for at once, on a small thread pool, while the reader works
    through it — at most :data:`_PARALLEL` requests holding at most :data:`_AHEAD` bytes (or one
    span) —, so that the requests' first-byte latencies overlap and fetching overlaps decoding; a
    span is dropped once the reader moves past it (memory holds the span being read and
    :data:`_AHEAD` bytes: a few chunks, never the object)."""

    def __init__(self, obj: RemoteObject, planned: Sequence[tuple[int, int]]) -> None:
        self._obj = obj
        self._spans: list[tuple[int, int]] = []
        for first, n in sorted(planned):
            start, stop = obj.unheld(first, min(first + n, obj.size))   # what was read ahead is not asked again
            last = self._spans[-1] if self._spans else None
            if start == stop:
                continue
            if last and start - last[1] <= _GAP and max(last[1], stop) - last[0] <= _SPAN:
                self._spans[-1] = (last[0], max(last[1], stop))
            else:
                self._spans.append((start, stop))
        self._starts = [a for a, _ in self._spans]
        self._span = (0, b"")
        self._pool: concurrent.futures.ThreadPoolExecutor | None = None
        self._asked: dict[int, concurrent.futures.Future[bytes]] = {}    # span number → its bytes
        self._next = 0                  # the next span to ask for

    def __enter__(self) -> Ranges:
        return self

    def __exit__(self, *exc: object) -> None:
        """Requests not yet sent are dropped; those under way are waited for (each bounded by the
        session's timeout), so that :attr:`Session.bytes_fetched` is complete."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
        self._asked.clear()

    def _ask(self, k: int) -> None:
        """Span ``k`` and those after it asked for, up to :data:`_PARALLEL` requests and :data:`_AHEAD`
        bytes [B] (at least span ``k``); earlier ones forgotten."""
        for old in [j for j in self._asked if j < k]:
            self._asked.pop(old).cancel()
        self._next = max(self._next, k)
        ahead = sum(self._spans[j][1] - self._spans[j][0] for j in self._asked)
        while self._next < len(self._spans) and len(self._asked) < _PARALLEL:
            start, stop = self._spans[self._next]
            if self._asked and ahead + stop - start > _AHEAD:
                break
            if self._pool is None:
                self._pool = concurrent.futures.ThreadPoolExecutor(_PARALLEL, thread_name_prefix="handeye-range")
            self._asked[self._next] = self._pool.submit(self._obj.fetch, start, stop)
            ahead += stop - start
            self._next += 1

    def view(self, start: int, n: int) -> memoryview:
        """The ``n`` bytes from ``start`` (fewer where the object ends)."""
        n = max(0, min(n, self._obj.size - start))
        s, data = self._span
        if s <= start and start + n <= s + len(data):
            return memoryview(data)[start - s:start - s + n]
        if (held := self._obj.held(start, n)) is not None:      # read ahead with the object's size
            return held
        a, b = self._obj.unheld(start, start + n)
        if not (s <= a and b <= s + len(data)):
            self._span = (0, b"")           # the previous span goes before the next arrives
            k = bisect.bisect_right(self._starts, a) - 1
            if k >= 0 and self._spans[k][0] <= a and b <= self._spans[k][1] and (k in self._asked or k >= self._next):
                self._ask(k)
                s, data = self._spans[k][0], self._asked.pop(k).result()
            else:                           # outside the plan (or read already): asked for alone
                s, data = a, self._obj.fetch(a, b)
            self._span = (s, data)
        if (a, b) == (start, start + n):
            return memoryview(data)[start - s:start - s + n]
        ends = self._obj.held(start, a - start), self._obj.held(b, start + n - b)     # read ahead: joined to it
        return memoryview(b"".join((ends[0] or b"", memoryview(data)[a - s:b - s], ends[1] or b"")))
