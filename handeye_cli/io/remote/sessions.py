"""The remote reading of one calibration (:class:`Session`: settings, bounded retries, the per-object deadline,
byte counting, the download cache), the session of a context (:func:`session`, :func:`session_of`,
:func:`current`), and what a URL is (:func:`is_url`, :func:`scrub`)."""
from __future__ import annotations

import atexit
import concurrent.futures
import contextlib
import os
import re
import shutil
import tempfile
import threading
import time
from collections.abc import Iterator, Sequence
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from ...errors import ConfigError, ReadError
from ...untrusted import REMOTE_DEADLINE_S, REMOTE_RETRIES, REMOTE_TIMEOUT_S
from .http import _kind, _Overran, _Plain, _within
from .objects import _READAHEAD, _TAIL, RemoteObject
from .ranges import _PARALLEL

CACHE_LIMIT = 8 << 30
"""The most bytes [B] one session downloads to its cache (objects that cannot be read by range)."""
_PIECE = 16 << 20           # [B] a download's request size
_CLIENTS = ("botocore", "aiobotocore", "aiohttp", "urllib3", "asyncio", "gcsfs", "google", "fsspec", "s3fs")
_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*://")
_CREDENTIAL_ENV = ("AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY", "AWS_SESSION_TOKEN", "GOOGLE_APPLICATION_CREDENTIALS")
_FIX_CREDENTIALS = ("set AWS_ACCESS_KEY_ID / AWS_SECRET_ACCESS_KEY or AWS_PROFILE, or pass "
                    "⟦storage_option='key=…'⟧ ⟦storage_option='secret=…'⟧")


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
                              "pass credentials through the environment or ⟦storage_option⟧")
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
                              "storage_option", "pass the keyword arguments of the fsspec file system") from exc
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
                                "⟦remote_deadline=SECONDS⟧")
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
                        "check the endpoint (AWS_ENDPOINT_URL) and the network, or raise ⟦remote_timeout=SECONDS⟧ / "
                        "⟦remote_retries=N⟧") from error

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
