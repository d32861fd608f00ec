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
import os
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
POSE_SCHEMA = b"std_msgs/Header header\ngeometry_msgs/Pose pose\n"
TOPICS = ["--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose"]


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


def write_image_log(path: Path, *, seconds: float, image_bytes: int, own_chunks: bool, image_hz: float = 10.0,
                    pose_hz: float = 50.0, seed: int = 0) -> Path:
    """An MCAP with one camera topic of random (incompressible) images and two PoseStamped topics
    /cam0/pose, /cam1/pose = cam0 · X. ``own_chunks``: every second of poses is written and flushed
    into a chunk of its own before that second's images; else they interleave in time."""
    from mcap.writer import Writer
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    X_rot, X_t = Rotation.from_rotvec([0.1, -0.2, 0.3]), np.array([0.1, 0.05, -0.02])
    t_pose = np.arange(0, seconds, 1 / pose_hz)
    xyz0, q0 = _motion(t_pose)
    r1 = Rotation.from_quat(q0) * X_rot
    xyz1 = xyz0 + Rotation.from_quat(q0).apply(X_t)
    q1 = r1.as_quat()
    start = 1_700_000_000_000_000_000
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=1 << 20)
        w.start(profile="ros2")
        pose = w.register_schema("geometry_msgs/msg/PoseStamped", "ros2msg", POSE_SCHEMA)
        image = w.register_schema("sensor_msgs/msg/CompressedImage", "ros2msg", b"uint8[] data\n")
        cam0 = w.register_channel("/cam0/pose", "cdr", pose)
        cam1 = w.register_channel("/cam1/pose", "cdr", pose)
        img = w.register_channel("/camera/image", "cdr", image)
        events = [(int(s * 1e9) + start, 0, k) for k, s in enumerate(t_pose)]
        events += [(int(s * 1e9) + start, 1, k) for k, s in enumerate(np.arange(0, seconds, 1 / image_hz))]
        if own_chunks:
            events.sort(key=lambda e: (int((e[0] - start) // 1e9), e[1], e[0]))
        else:
            events.sort()
        last_second = -1
        for stamp, kind, k in events:
            second = int((stamp - start) // 1e9)
            if own_chunks and second != last_second:
                w.flush()
                last_second = second
            if kind == 0:
                w.add_message(cam0, stamp, _pose_cdr(stamp, b"world", xyz0[k], q0[k]), stamp)
                w.add_message(cam1, stamp, _pose_cdr(stamp, b"world", xyz1[k], q1[k]), stamp)
            else:
                w.add_message(img, stamp, b"\0\1\0\0" + rng.bytes(image_bytes), stamp)
            if own_chunks and kind == 0 and (stamp + int(1e9 / pose_hz) - start) // int(1e9) != second:
                w.flush()           # this second's poses end their chunk before its images
        w.finish()
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


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _run(args: list[str], env: dict[str, str]) -> tuple[float, dict[str, object], int]:
    """(wall time [s], the result document, peak RSS [kB] of the process) of ``handeye ARGS``."""
    probe = ("import sys\nfrom handeye_cli.cli import main\ncode = 0\ntry:\n    main(sys.argv[1:])\n"
             "except SystemExit as e:\n    code = e.code or 0\n"
             "hwm = [l for l in open('/proc/self/status') if l.startswith('VmHWM')][0].split()[1]\n"
             "sys.stderr.write('\\nRSS %s\\n' % hwm)\n"
             "sys.exit(code)\n")
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", probe, *args], env=env, capture_output=True, text=True, check=True)
    seconds = time.perf_counter() - start
    rss = int(out.stderr.rsplit("RSS ", 1)[1])
    import yaml

    return seconds, yaml.safe_load(out.stdout) if args[0] == "calibrate" else {}, rss


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mb", type=float, default=200.0, help="size of each image-heavy log [MB]")
    parser.add_argument("--logs", type=int, default=100, help="logs in the batch comparison")
    args = parser.parse_args()
    import boto3
    from moto.server import ThreadedMotoServer

    port = _free_port()
    server = ThreadedMotoServer(ip_address="127.0.0.1", port=port)
    server.start()
    endpoint = f"http://127.0.0.1:{port}"
    env = {**os.environ, "AWS_ENDPOINT_URL": endpoint, "AWS_ACCESS_KEY_ID": "bench", "AWS_SECRET_ACCESS_KEY": "bench",
           "AWS_DEFAULT_REGION": "us-east-1", "PYTHONPATH": str(ROOT)}
    os.environ.update({k: env[k] for k in ("AWS_ENDPOINT_URL", "AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY",
                                           "AWS_DEFAULT_REGION")})
    s3 = boto3.client("s3", endpoint_url=endpoint)
    s3.create_bucket(Bucket="bench")
    tmp = Path(tempfile.mkdtemp(prefix="handeye-bench-remote-"))
    try:
        image_bytes, image_hz = 1_000_000, 10.0
        seconds = args.mb * 1e6 / (image_bytes * image_hz)
        print(f"uptime: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} (1, 5 min load)")
        for own in (True, False):
            layout = "poses in own chunks" if own else "poses interleaved in every chunk"
            path = write_image_log(tmp / f"img_{int(own)}.mcap", seconds=seconds, image_bytes=image_bytes,
                                   own_chunks=own, image_hz=image_hz)
            size = path.stat().st_size
            bound = lower_bound(path)
            s3.upload_file(str(path), "bench", path.name)
            url = f"s3://bench/{path.name}"
            start = time.perf_counter()
            for k in range(3):
                s3.get_object(Bucket="bench", Key=path.name, Range=f"bytes={k}-{k}")["Body"].read()
            t_byte = (time.perf_counter() - start) / 3
            t_remote, doc, rss = _run(["calibrate", url, *TOPICS, "-q"], env)
            fetched = int(doc["inputs"]["bytes_fetched"])                 # type: ignore[index]
            start = time.perf_counter()
            local = tmp / "downloaded.mcap"
            s3.download_file("bench", path.name, str(local))
            t_get = time.perf_counter() - start
            t_local, doc_local, rss_local = _run(["calibrate", str(local), *TOPICS, "-q"], env)
            assert doc_local["matrix"] == doc["matrix"]
            local.unlink()
            print(f"{layout}: {size / 1e6:.0f} MB; fetched/size {fetched / size:.4f}; bound/size {bound / size:.4f}; "
                  f"fetched/bound {fetched / bound:.3f}; by range {t_remote:.2f} s vs download-then-read "
                  f"{t_get + t_local:.2f} s ({t_get:.2f} + {t_local:.2f}): ratio {t_remote / (t_get + t_local):.2f}; "
                  f"peak RSS {rss / 1e3:.0f} MB (local read {rss_local / 1e3:.0f} MB); "
                  f"the server answers a 1-byte range of this object in {t_byte:.3f} s")
            path.unlink()
        # batch over many small remote logs against the same logs on disk
        logs = tmp / "logs"
        logs.mkdir()
        for k in range(args.logs):
            write_image_log(logs / f"log{k:03d}.mcap", seconds=12, image_bytes=20_000, own_chunks=True, seed=k)
            s3.upload_file(str(logs / f"log{k:03d}.mcap"), "bench", f"fleet/log{k:03d}.mcap")
        t_local, _, _ = _run(["batch", str(logs), *TOPICS, "-q", "--jobs", "2"], env)
        t_remote, _, _ = _run(["batch", "s3://bench/fleet/", *TOPICS, "-q", "--jobs", "2"], env)
        print(f"batch --jobs 2 over {args.logs} logs: remote {args.logs / t_remote:.1f} logs/s, local "
              f"{args.logs / t_local:.1f} logs/s (remote/local {t_local / t_remote:.2f})")
    finally:
        shutil.rmtree(tmp, True)
        server.stop()


if __name__ == "__main__":
    main()
