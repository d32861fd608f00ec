"""Reader speed and memory: handeye's ``read_stream`` beside rosbags' ``AnyReader`` on the same MCAP.

Builds (in a temporary directory) MCAP files holding ``--poses`` PoseStamped messages on ``/pose``
(a 200 Hz simulated trajectory) interleaved with ``sensor_msgs/Image`` messages of ~100 KB on
``/camera/image`` — one file per ``--images`` count, so every chunk holds both topics. Each reader
then runs ``--repeat`` times in a fresh subprocess per file:

* handeye: ``read_stream(path, topic="/pose")`` → int64 stamps, positions, x-y-z-w quaternions;
* rosbags: ``AnyReader`` + ``deserialize`` of every PoseStamped, stamps and pose fields collected
  into the same (N, 8) array.

Reported: PoseStamped messages per second (best run, opening the file included), the ratio,
the child's peak RSS during the read and how far the read raised it above the RSS after the
imports (Linux only: the peak is reset through /proc/self/clear_refs before the read and read
from VmHWM after it). Both readers' arrays are compared. Usage::

    python benchmarks/readers.py [--poses 200000] [--images 300 3000] [--repeat 3]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

IMAGE_BYTES = 100_000
READERS = {"handeye": "handeye read_stream", "anyreader": "rosbags AnyReader"}


def build(path: Path, n_poses: int, n_images: int) -> None:
    """An MCAP with ``n_poses`` PoseStamped on /pose and ``n_images`` ~100 KB Images on /camera/image."""
    from _logs import POSE, ROS2_STORE, Channel, pose_channel, records, write_mcap

    from handeye_cli.simulation import Rig, simulate_rig

    rate = 200.0
    a, _ = simulate_rig(Rig(np.eye(4)), duration_s=n_poses / rate, rate_a=rate, rate_b=1.0, seed=1)
    T = ROS2_STORE.types
    image = T["sensor_msgs/msg/Image"](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="cam"),
        height=100, width=IMAGE_BYTES // 100, encoding="mono8", is_bigendian=0, step=IMAGE_BYTES // 100,
        data=np.random.default_rng(0).integers(0, 255, IMAGE_BYTES, dtype=np.uint8))
    raw = bytes(ROS2_STORE.serialize_cdr(image, "sensor_msgs/msg/Image"))
    t = np.linspace(a.stamps_ns[0], a.stamps_ns[-1], n_images).astype(np.int64)
    write_mcap(path, [pose_channel("/pose", POSE, records(a, "map", "")),
                      Channel("/camera/image", "sensor_msgs/msg/Image", [(int(ti), raw) for ti in t])],
               compression="none")


def _status_mb(key: str) -> float:
    """``VmRSS`` (current) or ``VmHWM`` (peak) resident memory from /proc/self/status [MB]."""
    line = next(ln for ln in Path("/proc/self/status").read_text().splitlines() if ln.startswith(key + ":"))
    return int(line.split()[1]) / 1024


def _reset_peak() -> None:
    """Reset VmHWM to the current RSS, so the peak that follows is the read's (Linux >= 4.0)."""
    Path("/proc/self/clear_refs").write_text("5")


def child(reader: str, path: str) -> None:
    """Read /pose once and print {n, seconds, rss_base_mb, rss_peak_mb, checksum} as JSON."""
    from rosbags.highlevel import AnyReader

    from handeye_cli.io import read_stream

    _reset_peak()
    base = _status_mb("VmRSS")
    t0 = time.perf_counter()
    if reader == "handeye":
        s = read_stream(path, topic="/pose")
        arr = np.column_stack([s.stamps_ns.astype(np.float64), s.xyz, s.quat_xyzw])
        stamps = s.stamps_ns
    else:
        rows = []
        with AnyReader([Path(path)]) as r:
            for conn, _, raw in r.messages(connections=[c for c in r.connections if c.topic == "/pose"]):
                m = r.deserialize(raw, conn.msgtype)
                p, q = m.pose.position, m.pose.orientation
                rows.append((m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec,
                             p.x, p.y, p.z, q.x, q.y, q.z, q.w))
        stamps = np.array([row[0] for row in rows], dtype=np.int64)
        arr = np.array(rows, dtype=np.float64)
    seconds = time.perf_counter() - t0
    order = np.argsort(stamps, kind="stable")
    print(json.dumps({"n": len(arr), "seconds": seconds, "rss_base_mb": base, "rss_peak_mb": _status_mb("VmHWM"),
                      "stamps": int(stamps.sum()), "values": arr[order, 1:].round(9).sum(axis=0).tolist()}))


def run(reader: str, path: Path, repeat: int) -> dict:
    """Best-of-``repeat`` result of ``child`` in fresh interpreters (highest peak RSS kept)."""
    runs = []
    for _ in range(repeat):
        out = subprocess.run([sys.executable, __file__, "--child", reader, str(path)],
                             capture_output=True, text=True, check=True)
        runs.append(json.loads(out.stdout))
    best = min(runs, key=lambda r: r["seconds"])
    return {**best, "rss_peak_mb": max(r["rss_peak_mb"] for r in runs)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--poses", type=int, default=200_000)
    ap.add_argument("--images", type=int, nargs="+", default=[300, 3000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--child", nargs=2, metavar=("READER", "PATH"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child)
        return
    print(f"python {sys.version.split()[0]}, {args.poses:,} PoseStamped per file, best of {args.repeat} "
          "runs in fresh processes\n")
    header = f"{'file':>9} {'reader':<20} {'msgs/s':>9} {'time [s]':>9} {'peak RSS [MB]':>14} {'read raised RSS [MB]':>21}"
    rows, results = [header, "-" * len(header)], {}
    with tempfile.TemporaryDirectory(prefix="handeye-bench-") as tmp:
        for k in args.images:
            path = Path(tmp) / f"poses_images_{k}.mcap"
            build(path, args.poses, k)
            size = f"{path.stat().st_size / 1e6:.0f} MB"
            res = {r: run(r, path, args.repeat) for r in READERS}
            results[k] = res
            for r, v in res.items():
                rows.append(f"{size:>9} {READERS[r]:<20} {v['n'] / v['seconds']:>9,.0f} {v['seconds']:>9.2f} "
                            f"{v['rss_peak_mb']:>14.0f} {v['rss_peak_mb'] - v['rss_base_mb']:>21.0f}")
            h, a = res["handeye"], res["anyreader"]
            same = h["n"] == a["n"] and h["stamps"] == a["stamps"] and np.allclose(h["values"], a["values"],
                                                                                    rtol=0, atol=1e-6)
            rows.append(f"{'':>9} ratio handeye / AnyReader: {a['seconds'] / h['seconds']:.2f}x "
                        f"({k:,} images of {IMAGE_BYTES // 1000} KB; same poses: {'yes' if same else 'NO'})")
    print("\n".join(rows))
    lo, hi = min(args.images), max(args.images)
    if lo != hi:
        growth = [results[k]["handeye"]["rss_peak_mb"] - results[k]["handeye"]["rss_base_mb"] for k in (lo, hi)]
        print(f"\nhandeye: {hi / lo:.0f}x more non-pose data changed the RSS raised by the read from "
              f"{growth[0]:.0f} MB to {growth[1]:.0f} MB")


if __name__ == "__main__":
    main()
