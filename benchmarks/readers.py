"""Reader speed and memory: handeye's MCAP fast path, rosbags' AnyReader, the bare cost of decompressing, and
the TUM text parser.

Builds (in a temporary directory, payloads packed with ``struct`` and checked byte for byte against rosbags'
serializer) a zstd-chunked ROS 2 MCAP of ``--minutes`` minutes: PoseStamped at 100 Hz on /a and 30 Hz on /b
and a TFMessage at 100 Hz on /tf (world → base), and a ``--tum-lines`` TUM file. Each measurement runs in a
fresh interpreter (best of ``--repeat``; start-up — importing handeye_cli.io — timed apart from the work):

* ``fast``: ``read_stream(log, topic="/a")`` (numpy fast path) and ``read_log_streams`` of /a, /b and the TF
  pair world→base (everything in the log);
* ``anyreader``: rosbags' ``AnyReader`` + ``deserialize`` of every /a message into the same arrays;
* ``decompress``: open the file, read its summary and decompress every chunk with ``zstandard`` — the floor
  any reader of this file pays;
* ``tum``: ``read_stream(file.tum)``.

Reported: start-up and work time (wall and CPU — on a shared machine CPU time is the stable figure), items
per CPU second, peak RSS (VmHWM; Linux), and the ratios: fast path / AnyReader on /a (goal ≥ 8x), whole read
/ (start-up + decompress every chunk). Usage::

    python benchmarks/readers.py [--minutes 60] [--tum-lines 1000000] [--repeat 3]
"""
from __future__ import annotations

import argparse
import json
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]      # this checkout's handeye_cli, not an installed one

_POSE = struct.Struct("<7d")


def _cdr_header(stamp: int, frame: bytes) -> bytes:
    """Time + frame_id string as they follow the 4-byte CDR encapsulation header."""
    return struct.pack("<iII", stamp // 10**9, stamp % 10**9, len(frame) + 1) + frame + b"\0"


def _pad(body: bytes, k: int) -> bytes:
    return body + bytes(-len(body) % k)


def pose_stamped(stamp: int, frame: bytes, v: tuple) -> bytes:
    return b"\x00\x01\x00\x00" + _pad(_cdr_header(stamp, frame), 8) + _POSE.pack(*v)


def tf_message(stamp: int, parent: bytes, child: bytes, v: tuple) -> bytes:
    body = _pad(struct.pack("<I", 1) + _cdr_header(stamp, parent), 4)
    body = _pad(body + struct.pack("<I", len(child) + 1) + child + b"\0", 8)
    return b"\x00\x01\x00\x00" + body + _POSE.pack(*v)


def _check_packing() -> None:
    """The struct-packed payloads equal rosbags' serialisation."""
    from _logs import POSE, ROS2_STORE, TF, ros_message
    r = (1700000000123456789, "map", "base", 1.0, 2.0, 3.0, 0.1, 0.2, 0.3, 0.9)
    for msgtype, packed in ((POSE, pose_stamped(r[0], b"map", r[3:])), (TF, tf_message(r[0], b"map", b"base", r[3:]))):
        assert packed == bytes(ROS2_STORE.serialize_cdr(ros_message(ROS2_STORE, msgtype, [r]), msgtype)), msgtype


def build_log(path: Path, minutes: float) -> int:
    """The 100 Hz + 30 Hz PoseStamped + 100 Hz /tf zstd MCAP; returns its message count."""
    from _logs import POSE, ROS2_STORE, TF
    from mcap.writer import CompressionType, Writer
    _check_packing()
    rng = np.random.default_rng(0)
    t0 = 1_700_000_000_000_000_000
    streams = []
    for topic, rate, msgtype in (("/a", 100, POSE), ("/b", 30, POSE), ("/tf", 100, TF)):
        n = int(minutes * 60 * rate)
        t = t0 + (np.arange(n) * (1e9 / rate)).astype(np.int64) + rng.integers(0, 1000, n)
        q = rng.normal(size=(n, 4))
        v = np.c_[rng.normal(size=(n, 3)), q / np.linalg.norm(q, axis=1)[:, None]]
        streams.append((topic, msgtype, t, v))
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD, chunk_size=1024 * 1024)
        w.start(profile="ros2", library="benchmarks/readers.py")
        ids = {}
        for topic, msgtype, _, _ in streams:
            text, _ = ROS2_STORE.generate_msgdef(msgtype, ros_version=2)
            ids[topic] = w.register_channel(topic, "cdr", w.register_schema(msgtype, "ros2msg", text.encode()))
        rows = sorted((int(t), k, i) for k, (_, _, ts, _) in enumerate(streams) for i, t in enumerate(ts.tolist()))
        for seq, (t, k, i) in enumerate(rows):
            topic, msgtype, _, v = streams[k]
            vals = tuple(v[i].tolist())
            data = pose_stamped(t, b"map", vals) if msgtype == POSE else tf_message(t, b"world", b"base", vals)
            w.add_message(ids[topic], log_time=t, data=data, publish_time=t, sequence=seq)
        w.finish()
    return len(rows)


def build_tum(path: Path, lines: int) -> None:
    """``lines`` TUM poses at 100 Hz, full-precision (repr) numbers, epoch stamps to the nanosecond."""
    rng = np.random.default_rng(1)
    t = 1_700_000_000_000_000_000 + np.arange(lines, dtype=np.int64) * 10_000_000 + rng.integers(0, 1000, lines)
    q = rng.normal(size=(lines, 4))
    v = np.c_[rng.normal(size=(lines, 3)), q / np.linalg.norm(q, axis=1)[:, None]]
    with open(path, "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n")
        for s, row in zip(t.tolist(), v.tolist(), strict=True):
            f.write(f"{s // 10**9}.{s % 10**9:09d} " + " ".join(map(repr, row)) + "\n")


# --- children ---------------------------------------------------------------------------------
def _status_mb(key: str) -> float:
    """``VmRSS`` (current) or ``VmHWM`` (peak) resident memory from /proc/self/status [MB]."""
    line = next(ln for ln in Path("/proc/self/status").read_text().splitlines() if ln.startswith(key + ":"))
    return int(line.split()[1]) / 1024


def _decompress_all(path: str) -> int:
    import zstandard
    from mcap.reader import make_reader
    with open(path, "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
        total = 0
        for c in chunks:
            f.seek(c.chunk_start_offset + 9 + 28)
            n = int.from_bytes(f.read(4), "little")
            f.seek(n + 8, 1)
            total += len(zstandard.ZstdDecompressor().decompress(f.read(c.compressed_size),
                                                                  max_output_size=c.uncompressed_size))
    return total


def _anyreader(path: str) -> int:
    from rosbags.highlevel import AnyReader
    rows = []
    with AnyReader([Path(path)]) as r:
        for conn, _, raw in r.messages(connections=[c for c in r.connections if c.topic == "/a"]):
            m = r.deserialize(raw, conn.msgtype)
            p, q = m.pose.position, m.pose.orientation
            stamp = m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
            rows.append((stamp, p.x, p.y, p.z, q.x, q.y, q.z, q.w))
    return len(np.array(rows))


def child(kind: str, path: str) -> None:
    """One measurement: print {n, startup_s (imports), seconds (the work), cpu_s (the work's CPU time: user +
    system, stable on a shared machine), rss_peak_mb} as JSON. Every kind imports handeye_cli.io first, so
    ``startup_s`` is the same program start-up for all."""
    t0 = time.perf_counter()
    from rosbags.highlevel import AnyReader  # noqa: F401 - start-up of the AnyReader measurement

    from handeye_cli.io import read_log_streams, read_stream
    t1, c1 = time.perf_counter(), time.process_time()
    if kind == "decompress":
        n = _decompress_all(path)
    elif kind == "anyreader":
        n = _anyreader(path)
    elif kind == "fast":
        n = len(read_stream(path, topic="/a"))
    elif kind == "all":
        n = sum(map(len, read_log_streams(path, [("/a", None), ("/b", None), (None, ("world", "base"))])))
    else:
        n = len(read_stream(path))
    t2, c2 = time.perf_counter(), time.process_time()
    print(json.dumps({"n": n, "startup_s": t1 - t0, "seconds": t2 - t1, "cpu_s": c2 - c1,
                      "rss_peak_mb": _status_mb("VmHWM")}))


def run(kind: str, path: Path, repeat: int) -> dict:
    """Best-of-``repeat`` times of ``child`` in fresh interpreters (highest peak RSS kept)."""
    runs = [json.loads(subprocess.run([sys.executable, __file__, "--child", kind, str(path)], capture_output=True,
                                      text=True, check=True).stdout) for _ in range(repeat)]
    best = {key: min(r[key] for r in runs) for key in ("startup_s", "seconds", "cpu_s")}
    return {"n": runs[0]["n"], **best, "rss_peak_mb": max(r["rss_peak_mb"] for r in runs)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--tum-lines", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--child", nargs=2, metavar=("KIND", "PATH"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child)
        return
    with tempfile.TemporaryDirectory(prefix="handeye-bench-") as tmp:
        log, tum = Path(tmp) / "log.mcap", Path(tmp) / "poses.tum"
        total = build_log(log, args.minutes)
        build_tum(tum, args.tum_lines)
        print(f"python {sys.version.split()[0]}; {args.minutes:g}-min log: {total:,} messages, "
              f"{log.stat().st_size / 1e6:.0f} MB zstd; TUM: {args.tum_lines:,} lines, "
              f"{tum.stat().st_size / 1e6:.0f} MB; best of {args.repeat} fresh processes, start-up included\n")
        kinds = ("decompress", "fast", "all", "anyreader", "tum")
        res = {k: run(k, tum if k == "tum" else log, args.repeat) for k in kinds}
    labels = {"decompress": "start-up + decompress (bytes)", "fast": "handeye fast path, /a",
              "all": "handeye /a + /b + TF world->base", "anyreader": "rosbags AnyReader, /a", "tum": "handeye TUM"}
    print(f"{'measurement':<36} {'items':>10} {'start-up [s]':>12} {'work [s]':>9} {'work CPU [s]':>12} "
          f"{'items/CPU s':>12} {'peak RSS [MB]':>14}")
    for k, v in res.items():
        print(f"{labels[k]:<36} {v['n']:>10,} {v['startup_s']:>12.2f} {v['seconds']:>9.3f} {v['cpu_s']:>12.3f} "
              f"{v['n'] / v['cpu_s']:>12,.0f} {v['rss_peak_mb']:>14.0f}")
    fast, anyr = res["fast"], res["anyreader"]
    print(f"\nfast path vs AnyReader on /a: {anyr['cpu_s'] / fast['cpu_s']:.1f}x less CPU time, "
          f"{anyr['seconds'] / fast['seconds']:.1f}x less wall time (same {fast['n']:,} poses: "
          f"{'yes' if fast['n'] == anyr['n'] else 'NO'})")
    whole, floor = res["all"], res["decompress"]
    print("whole log (/a + /b + TF) vs start-up + decompress every chunk (wall): "
          f"{(whole['startup_s'] + whole['seconds']) / (floor['startup_s'] + floor['seconds']):.2f}x; "
          f"work only (CPU): {whole['cpu_s'] / floor['cpu_s']:.2f}x")

if __name__ == "__main__":
    main()
