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

The package, by concept: :mod:`.sessions` (:class:`Session`: the settings, :meth:`Session.call`'s bounded
tries and per-object deadline, the counts, the download cache; :func:`session`, :func:`session_of`,
:func:`current`, :func:`is_url`, :func:`scrub`), :mod:`.objects` (:class:`RemoteObject`, ``RangeFile``,
:data:`_READAHEAD`, :data:`_TAIL`, :data:`_HELD`), :mod:`.ranges` (``Ranges`` and :data:`_SPAN`,
:data:`_GAP`, :data:`_PARALLEL`, :data:`_AHEAD`) and :mod:`.http` (:class:`_Plain`, the standard
library's client; the wall-clock guard of one try). This module re-exports the public names.
"""
from __future__ import annotations

from .objects import RemoteObject
from .sessions import CACHE_LIMIT, Session, current, is_url, scrub, session, session_of

__all__ = ["is_url", "Session", "session", "session_of", "current", "RemoteObject", "CACHE_LIMIT", "scrub"]
