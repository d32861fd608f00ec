"""Reading logs from object storage by byte range against downloading them first (issue 23).

Writes an image-heavy MCAP (≥ 200 MB, ≥ 95 % image bytes, in /tmp) in two layouts — poses in their
own chunks (the writer flushed around them), and poses interleaved with images in every chunk —,
serves it with moto's S3 server on 127.0.0.1 and prints, for each: bytes fetched ÷ file size, the
lower bound from the file's own chunk index (footer + summary + the chunks holding the poses with
their message indexes) ÷ file size, fetched ÷ bound, the time of ``calibrate s3://…`` against
download-then-read (one GET of the whole object, then calibrate the local file) and the peak
resident memory of the reading process. Then ``batch --jobs 2`` over 100 remote logs against the
same logs on local disk, in logs per second.

    python benchmarks/remote.py [--mb 200] [--logs 100]
"""
from __future__ import annotations

import argparse
import contextlib
import http.server
import logging
import os
import re
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
POSE_SCHEMA = b"std_msgs/Header header\ngeometry_msgs/Pose pose\n"
TOPICS = ["--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose"]
START = 1_700_000_000_000_000_000   # [ns] the logs' first stamp


def _pose_cdr(stamp_ns: int, frame: bytes, xyz: np.ndarray, q: np.ndarray) -> bytes:
    """A little-endian CDR geometry_msgs/PoseStamped."""
    name = frame + b"\0"
    body = struct.pack("<iII", stamp_ns // 1_000_000_000, stamp_ns % 1_000_000_000, len(name)) + name
    body += b"\0" * (-len(body) % 8)
    return b"\0\1\0\0" + body + struct.pack("<7d", *xyz, *q)


def _motion(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions [m] and x-y-z-w quaternions of a smooth, well-excited camera path at times ``t`` [s]."""
    from scipy.spatial.transform import Rotation

    rot = Rotation.from_rotvec(np.c_[0.6 * np.sin(0.9 * t), 0.5 * np.sin(0.7 * t + 1), 0.8 * np.sin(0.5 * t + 2)])
    xyz = np.c_[np.sin(0.3 * t), np.cos(0.4 * t), 0.2 * np.sin(0.6 * t)]
    return xyz, rot.as_quat()


def _scene(seconds: float, own_chunks: bool, image_hz: float, pose_hz: float) -> tuple[list[tuple[int, int, int]], Any]:
    """(events (stamp [ns], 0 pose | 1 image, index) in write order, (xyz0, q0, xyz1, q1) of the pose
    topics /cam0/pose and /cam1/pose = cam0 · X). ``own_chunks``: every second's poses come before that
    second's images (the writers end a chunk around them); else poses and images interleave in time."""
    from scipy.spatial.transform import Rotation

    X_rot, X_t = Rotation.from_rotvec([0.1, -0.2, 0.3]), np.array([0.1, 0.05, -0.02])
    t_pose = np.arange(0, seconds, 1 / pose_hz)
    xyz0, q0 = _motion(t_pose)
    xyz1 = xyz0 + Rotation.from_quat(q0).apply(X_t)
    q1 = (Rotation.from_quat(q0) * X_rot).as_quat()
    events = [(int(s * 1e9) + START, 0, k) for k, s in enumerate(t_pose)]
    events += [(int(s * 1e9) + START, 1, k) for k, s in enumerate(np.arange(0, seconds, 1 / image_hz))]
    events.sort(key=(lambda e: (int((e[0] - START) // 1e9), e[1], e[0])) if own_chunks else None)
    return events, (xyz0, q0, xyz1, q1)


def _ends_chunk(events: list[tuple[int, int, int]], i: int) -> bool:
    """Whether the poses' chunk ends after event ``i`` (the last pose of its second, poses in own chunks)."""
    second = (events[i][0] - START) // 1_000_000_000
    return events[i][1] == 0 and (i + 1 == len(events) or events[i + 1][1] == 1
                                  or (events[i + 1][0] - START) // 1_000_000_000 != second)


def write_image_log(path: Path, *, seconds: float, image_bytes: int, own_chunks: bool, image_hz: float = 10.0,
                    pose_hz: float = 50.0, seed: int = 0) -> Path:
    """An MCAP with one camera topic of random (incompressible) images and two PoseStamped topics
    (:func:`_scene`); ``own_chunks``: every second of poses is flushed into a chunk of its own."""
    from mcap.writer import Writer

    rng = np.random.default_rng(seed)
    events, (xyz0, q0, xyz1, q1) = _scene(seconds, own_chunks, image_hz, pose_hz)
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=1 << 20)
        w.start(profile="ros2")
        pose = w.register_schema("geometry_msgs/msg/PoseStamped", "ros2msg", POSE_SCHEMA)
        image = w.register_schema("sensor_msgs/msg/CompressedImage", "ros2msg", b"uint8[] data\n")
        cam0 = w.register_channel("/cam0/pose", "cdr", pose)
        cam1 = w.register_channel("/cam1/pose", "cdr", pose)
        img = w.register_channel("/camera/image", "cdr", image)
        for i, (stamp, kind, k) in enumerate(events):
            if own_chunks and kind == 0 and (i == 0 or events[i - 1][1] == 1):
                w.flush()           # this second's poses start a chunk
            if kind == 0:
                w.add_message(cam0, stamp, _pose_cdr(stamp, b"world", xyz0[k], q0[k]), stamp)
                w.add_message(cam1, stamp, _pose_cdr(stamp, b"world", xyz1[k], q1[k]), stamp)
            else:
                w.add_message(img, stamp, b"\0\1\0\0" + rng.bytes(image_bytes), stamp)
            if own_chunks and _ends_chunk(events, i):
                w.flush()           # … and end it before its images
        w.finish()
    return path


def _ros1_header(stamp_ns: int, frame: bytes) -> bytes:
    return struct.pack("<III", 0, stamp_ns // 1_000_000_000, stamp_ns % 1_000_000_000) + struct.pack(
        "<I", len(frame)) + frame


def write_image_bag(path: Path, *, seconds: float, image_bytes: int, own_chunks: bool, image_hz: float = 10.0,
                    pose_hz: float = 50.0, seed: int = 0) -> Path:
    """The ROS 1 bag of :func:`write_image_log` (uncompressed chunks): images are
    sensor_msgs/CompressedImage, a chunk each; ``own_chunks``: every second of poses in a chunk of its own."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    rng = np.random.default_rng(seed)
    events, (xyz0, q0, xyz1, q1) = _scene(seconds, own_chunks, image_hz, pose_hz)
    with Writer(path) as w:
        cam0, cam1 = (w.add_connection(t, "geometry_msgs/msg/PoseStamped", typestore=store)
                      for t in ("/cam0/pose", "/cam1/pose"))
        img = w.add_connection("/camera/image", "sensor_msgs/msg/CompressedImage", typestore=store)
        for i, (stamp, kind, k) in enumerate(events):
            if kind == 0:
                w.chunk_threshold = 1 << 30
                w.write(cam0, stamp, _ros1_header(stamp, b"world") + struct.pack("<7d", *xyz0[k], *q0[k]))
                w.chunk_threshold = 0 if own_chunks and _ends_chunk(events, i) else 1 << 20
                w.write(cam1, stamp, _ros1_header(stamp, b"world") + struct.pack("<7d", *xyz1[k], *q1[k]))
            else:
                w.chunk_threshold = 0 if own_chunks else 1 << 20
                w.write(img, stamp, _ros1_header(stamp, b"") + struct.pack("<I", 4) + b"jpeg"
                        + struct.pack("<I", image_bytes) + rng.bytes(image_bytes))
    return path


def lower_bound(path: Path) -> int:
    """Footer + summary + the pose chunks with their message indexes [B]."""
    from mcap.reader import make_reader

    size = path.stat().st_size
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
        f.seek(size - 37 + 9)
        summary_start = int.from_bytes(f.read(8), "little")
    assert summary is not None and summary.statistics is not None
    wanted = {cid for cid, ch in summary.channels.items() if ch.topic.endswith("/pose")}
    chunks = sum(ix.chunk_length + ix.message_index_length for ix in summary.chunk_indexes
                 if wanted & set(ix.message_index_offsets))
    return size - summary_start + chunks


def lower_bound_bag(path: Path, topics: tuple[str, ...] = ("/cam0/pose", "/cam1/pose")) -> int:
    """The ROS 1 bag's magic and header record (without its padding) + its index (connections, chunk
    infos) + the chunks holding ``topics``, each with the index data records after it (up to the next chunk) [B]."""
    from rosbags.rosbag1 import Reader

    data = path.read_bytes()
    at = data.index(b"index_pos=") + len(b"index_pos=")
    (index_pos,) = struct.unpack_from("<Q", data, at)
    (head_len,) = struct.unpack_from("<I", data, 13)
    with Reader(path) as bag:
        wanted = {c.id for c in bag.connections if c.topic in topics}
        starts = sorted(info.pos for info in bag.chunk_infos)
        ends = dict(zip(starts, [*starts[1:], index_pos], strict=True))
        chunks = sum(ends[info.pos] - info.pos for info in bag.chunk_infos if wanted & set(info.connection_counts))
    return int(13 + 8 + head_len + len(data) - index_pos + chunks)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class RangeHandler(http.server.BaseHTTPRequestHandler):
    """Files of the server's folder over plain HTTP, answering ``Range: bytes=a-b`` (and the suffix
    ``bytes=-n``) with 206 and just those bytes (a request costs its bytes, not the object's: unlike
    moto, which reads the whole object for every request). The server's ``log`` gets (method, range,
    requests under way when this one arrived) of every request."""

    def _target(self) -> tuple[Path, int, int] | None:
        server: Any = self.server
        with server.lock:
            server.active += 1
            server.log.append((self.command, self.headers.get("Range"), server.active))
        try:
            time.sleep(server.latency)
            return self._answer(Path(server.root) / self.path.lstrip("/"))
        finally:
            with server.lock:
                server.active -= 1

    def _answer(self, path: Path) -> tuple[Path, int, int] | None:
        if not path.is_file():
            self.send_error(404)
            return None
        size = path.stat().st_size
        asked = re.fullmatch(r"bytes=(\d*)-(\d*)", self.headers.get("Range", ""))
        if asked and not asked[1]:
            start, stop = max(0, size - int(asked[2])), size
        else:
            start, stop = (int(asked[1]), min(size, int(asked[2] or size - 1) + 1)) if asked else (0, size)
        self.send_response(206 if asked else 200)
        self.send_header("Content-Type", "application/octet-stream")
        self.send_header("Content-Length", str(stop - start))
        self.send_header("Accept-Ranges", "bytes")
        if asked:
            self.send_header("Content-Range", f"bytes {start}-{stop - 1}/{size}")
        self.end_headers()
        return path, start, stop

    def do_HEAD(self) -> None:
        self._target()

    def do_GET(self) -> None:
        target = self._target()
        if target is None:
            return
        path, start, stop = target
        with open(path, "rb") as f, contextlib.suppress(ConnectionError):
            f.seek(start)
            rate = float(self.server.bandwidth)       # type: ignore[attr-defined]  # set by http_server
            while start < stop and (piece := f.read(min(1 << 20, stop - start))):
                self.wfile.write(piece)
                start += len(piece)
                if rate > 0:                                     # one connection's throughput [B/s]
                    time.sleep(len(piece) / rate)

    def log_message(self, *args: object) -> None:
        pass


@contextlib.contextmanager
def http_server(root: Path, latency: float = 0.0, handler: type[RangeHandler] = RangeHandler,
                bandwidth: float = 0.0) -> Iterator[http.server.ThreadingHTTPServer]:
    """The files in ``root`` served on 127.0.0.1 (by ``handler``: :class:`RangeHandler`), each answer
    ``latency`` [s] late and each connection's body at most ``bandwidth`` [B/s] (0: as fast as the loopback
    goes) (tests/io/test_remote.py serves with it too); shut down and its socket closed on exit (a socket left
    open is a ResourceWarning wherever its last reference goes, in another test)."""
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    server.daemon_threads = True
    server.root = str(root)                 # type: ignore[attr-defined]
    server.latency = latency                # type: ignore[attr-defined]
    server.bandwidth = bandwidth            # type: ignore[attr-defined]
    server.lock, server.active, server.log = threading.Lock(), 0, []     # type: ignore[attr-defined]
    serving = threading.Thread(target=server.serve_forever, daemon=True)
    serving.start()
    try:
        yield server
    finally:
        server.shutdown()
        serving.join()
        server.server_close()


def _run(args: list[str], env: dict[str, str]) -> tuple[float, dict[str, Any], int, int]:
    """(wall time [s], the result document, peak RSS [kB], range requests answered) of ``handeye ARGS``."""
    probe = ("import sys\nfrom handeye_cli.cli import main\nfrom handeye_cli.io import remote\nasked = []\n"
             "fetch = remote.RemoteObject.fetch\n"
             "remote.RemoteObject.fetch = lambda self, a, b: asked.append(b - a) or fetch(self, a, b)\n"
             "code = 0\ntry:\n    main(sys.argv[1:])\n"
             "except SystemExit as e:\n    code = e.code or 0\n"
             "hwm = [l for l in open('/proc/self/status') if l.startswith('VmHWM')][0].split()[1]\n"
             "sys.stderr.write('\\nREQUESTS %d\\nRSS %s\\n' % (len(asked), hwm))\n"
             "sys.exit(code)\n")
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", probe, *args], env=env, capture_output=True, text=True, check=True)
    seconds = time.perf_counter() - start
    rss = int(out.stderr.rsplit("RSS ", 1)[1])
    requests = int(out.stderr.rsplit("REQUESTS ", 1)[1].split()[0])
    import yaml

    return seconds, yaml.safe_load(out.stdout) if args[0] == "calibrate" else {}, rss, requests


def _case(name: str, path: Path, bound: int, urls: dict[str, str], downloads: dict[str, Any],
          env: dict[str, str], t_request: dict[str, float]) -> None:
    """Print one log's figures: by range from each server against download-then-read from the same
    server (each way of downloading), all measured here."""
    size = path.stat().st_size
    local = path.with_name("downloaded" + path.suffix)
    t_read, doc_local, rss_local, _ = _run(["calibrate", str(path), *TOPICS, "-q"], env)
    print(f"{name}: {size / 1e6:.0f} MB; lower bound by its own index {bound / size:.4f} of the file; "
          f"local read {t_read:.2f} s, peak RSS {rss_local / 1e3:.0f} MB")
    for server, url in urls.items():
        t_range, doc, rss, requests = _run(["calibrate", url, *TOPICS, "-q"], env)
        fetched = int(doc["inputs"]["bytes_fetched"])
        assert doc["matrix"] == doc_local["matrix"], "the remote and the local calibrations differ"
        from handeye_cli.io import read_log_streams
        from handeye_cli.io.remote import session

        start = time.perf_counter()
        with session((), 30.0, 3):
            read_log_streams(url, [("/cam0/pose", None), ("/cam1/pose", None)])
        t_streams = time.perf_counter() - start
        print(f"  {server}: fetched/size {fetched / size:.4f}, fetched/bound {fetched / bound:.3f}, "
              f"{requests} range requests ({t_request[server] * 1e3:.0f} ms each for 1 byte of this object); "
              f"by range {t_range:.2f} s, of which reading the two streams {t_streams:.2f} s (in this process, "
              f"imports done); peak RSS {rss / 1e3:.0f} MB")
        for how, download in downloads[server].items():
            start = time.perf_counter()
            download(url, local)
            t_get = time.perf_counter() - start
            t_local, _, _, _ = _run(["calibrate", str(local), *TOPICS, "-q"], env)
            local.unlink()
            print(f"    vs download ({how}) then read: {t_get:.2f} + {t_local:.2f} = {t_get + t_local:.2f} s: "
                  f"ratio {t_range / (t_get + t_local):.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mb", type=float, default=200.0, help="size of each image-heavy log [MB]")
    parser.add_argument("--logs", type=int, default=100, help="logs in the batch comparison")
    parser.add_argument("--latency-ms", type=float, default=30.0,
                        help="the plain HTTP server's delay before each answer [ms] (an object store's first byte)")
    parser.add_argument("--bandwidth-mb-s", type=float, default=0.0,
                        help="the plain HTTP server's throughput per connection [MB/s] (0: the loopback's, several "
                             "hundred MB/s; an object store serves one connection about 50-100 MB/s)")
    args = parser.parse_args()
    logging.getLogger("werkzeug").setLevel(logging.ERROR)      # moto's server: no line per request
    import boto3
    from moto.server import ThreadedMotoServer

    port = _free_port()
    server = ThreadedMotoServer(ip_address="127.0.0.1", port=port, verbose=False)
    server.start()
    endpoint = f"http://127.0.0.1:{port}"
    env = {**os.environ, "AWS_ENDPOINT_URL": endpoint, "AWS_ACCESS_KEY_ID": "bench", "AWS_SECRET_ACCESS_KEY": "bench",
           "AWS_DEFAULT_REGION": "us-east-1", "PYTHONPATH": str(ROOT)}
    os.environ.update({k: env[k] for k in ("AWS_ENDPOINT_URL", "AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY",
                                           "AWS_DEFAULT_REGION")})
    s3 = boto3.client("s3", endpoint_url=endpoint)
    s3.create_bucket(Bucket="bench")
    tmp = Path(tempfile.mkdtemp(prefix="handeye-bench-remote-"))
    served = tmp / "served"
    served.mkdir()
    closing = contextlib.ExitStack()             # the plain HTTP server, shut down and closed at the end
    web = closing.enter_context(http_server(served, args.latency_ms / 1e3, bandwidth=args.bandwidth_mb_s * 1e6))
    base = f"http://127.0.0.1:{web.server_address[1]}"

    def one_get(url: str, to: Path) -> None:
        key = url.split("/", 3)[3]
        with open(to, "wb") as f:
            shutil.copyfileobj(s3.get_object(Bucket="bench", Key=key)["Body"], f, 1 << 20)

    def http_get(url: str, to: Path) -> None:
        with urllib.request.urlopen(url) as r, open(to, "wb") as f:
            shutil.copyfileobj(r, f, 1 << 20)

    downloads = {"moto S3": {"one GET": one_get,
                             "boto3 download_file, as `aws s3 cp`": lambda u, to: s3.download_file(
                                 "bench", u.split("/", 3)[3], str(to))},
                 "plain HTTP range server": {"one GET": http_get}}
    for probe in ("import fsspec, aiohttp", "import s3fs", "import handeye_cli.cli"):
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", probe], env=env, check=True)
        print(f"start-up: python -c {probe!r}: {time.perf_counter() - start:.2f} s")
    try:
        image_bytes, image_hz = 1_000_000, 10.0
        seconds = args.mb * 1e6 / (image_bytes * image_hz)
        print(f"load average: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} (1, 5 min); {os.cpu_count()} cores")
        print("moto's server reads the whole object for every request (FakeKey.value, under a lock), so its "
              "requests cost in proportion to the object, not to the bytes asked, and do not overlap; the plain "
              f"HTTP server reads only the bytes asked, as object stores do, answering {args.latency_ms:g} ms late"
              + (f", {args.bandwidth_mb_s:g} MB/s a connection" if args.bandwidth_mb_s else ""))
        for fmt, own in (("mcap", True), ("mcap", False), ("bag", True), ("bag", False)):
            layout = "poses in own chunks" if own else "poses interleaved in every chunk"
            write = write_image_log if fmt == "mcap" else write_image_bag
            path = write(served / f"img_{int(own)}.{fmt}", seconds=seconds, image_bytes=image_bytes,
                         own_chunks=own, image_hz=image_hz)
            bound = lower_bound(path) if fmt == "mcap" else lower_bound_bag(path)
            s3.upload_file(str(path), "bench", path.name)
            urls = {"moto S3": f"s3://bench/{path.name}", "plain HTTP range server": f"{base}/{path.name}"}
            t_request = {}
            for name, url in urls.items():
                start = time.perf_counter()
                for k in range(3):
                    if name == "moto S3":
                        s3.get_object(Bucket="bench", Key=path.name, Range=f"bytes={k}-{k}")["Body"].read()
                    else:
                        urllib.request.urlopen(urllib.request.Request(url, headers={"Range": f"bytes={k}-{k}"})).read()
                t_request[name] = (time.perf_counter() - start) / 3
            _case(f"{'MCAP' if fmt == 'mcap' else 'ROS 1 bag'}, {layout}", path, bound, urls, downloads, env,
                  t_request)
            s3.delete_object(Bucket="bench", Key=path.name)
            path.unlink()
        # batch over many small remote logs against the same logs on disk
        logs = tmp / "logs"
        logs.mkdir()
        for k in range(args.logs):
            write_image_log(logs / f"log{k:03d}.mcap", seconds=12, image_bytes=20_000, own_chunks=True, seed=k)
            s3.upload_file(str(logs / f"log{k:03d}.mcap"), "bench", f"fleet/log{k:03d}.mcap")
        t_local, _, _, _ = _run(["batch", str(logs), *TOPICS, "-q", "--jobs", "2"], env)
        t_remote, _, _, _ = _run(["batch", "s3://bench/fleet/", *TOPICS, "-q", "--jobs", "2"], env)
        print(f"batch --jobs 2 over {args.logs} logs: remote {args.logs / t_remote:.1f} logs/s, local "
              f"{args.logs / t_local:.1f} logs/s (remote/local {t_local / t_remote:.2f}); load average "
              f"{os.getloadavg()[0]:.2f}")
    finally:
        shutil.rmtree(tmp, True)
        closing.close()
        server.stop()


if __name__ == "__main__":
    main()
