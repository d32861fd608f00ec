"""Verification at the speed of reading: `handeye calibrate` (default flags) on generated logs, beside the
limit measured in the same run.

Builds, in a temporary directory, zstd-chunked ROS 2 MCAPs of a simulated rigid rig (PoseStamped payloads
packed with ``struct``, checked byte for byte against rosbags' serialiser by ``benchmarks/readers.py``):

* 10 and 60 minutes: ``/cam0/pose`` at 100 Hz, ``/cam1/pose`` at 30 Hz (37 ms clock offset, tracking noise
  0.1° / 2 mm, ten tracking jumps) and a ``/tf`` TFMessage at 100 Hz that calibrate does not read;
* 1 minute, image-heavy: the same poses beside a 30 Hz ``/camera/image`` of raw 640 × 480 mono8 frames
  (a ramp plus noise, eight distinct ones, zstd compresses them about 2×: images ≈ 99.8 % of the bytes).

Each command runs in a fresh interpreter (fastest of ``--repeat``; peak RSS from ``wait4``, the largest of
the repeats). The limit of a log is Python starting with numpy and scipy imported plus the zstd
decompression of every chunk of that log (``benchmarks/readers.py``'s floor). Printed per log: calibrate's
wall time, its ratio to the limit, its peak RSS; then, from one profiled in-process run, each default
stage's share of calibrate's time; and the ratio of the 60-minute to the 10-minute calibrate.
Goals (issue 34): ≤ 4× the limit and ≤ 250 MB at 60 minutes, ≤ 1.3× on the image-heavy log, ≤ 6.5× from
10 to 60 minutes.

    python benchmarks/speed.py [--repeat 3] [--minutes 10 60]
"""
from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "benchmarks")]

GOAL_RATIO, GOAL_RSS_MB, GOAL_IMAGES, GOAL_GROWTH = 4.0, 250.0, 1.3, 6.5
TOPICS = ("/cam0/pose", "/cam1/pose")
STAGES = (   # (label, function names whose cumulative time is the stage's; the first that is found)
    ("read", ("read_streams",)),
    ("time offset", ("_time_offset",)),
    ("sync + gates + pairs", ("pairs_of",)),
    ("fit-test noise", ("sample_noise",)),
    ("solve", ("solve",)),
    ("observability", ("assess_observability",)),
    ("inversion check", ("check_inversion",)),
    ("quaternion order check", ("contradicted_order",)),
)


def build(path: Path, minutes: float, images: bool = False) -> None:
    """The rig's MCAP (see the module docstring)."""
    from _logs import POSE, ROS2_STORE, TF
    from mcap.writer import CompressionType, Writer
    from readers import pose_stamped, tf_message

    from handeye_cli.geometry import se3
    from handeye_cli.simulation import Rig, simulate_rig

    X = se3.from_xyz_quat(np.array([0.1, 0.25, -0.05]), np.array([0.2, 0.1, -0.3, 0.9]))
    a, b = simulate_rig(Rig(X, 37_000_000), duration_s=60 * minutes, rate_a=100, rate_b=30, speed=0.5,
                        sigma_r=np.deg2rad(0.1), sigma_t=0.002, jumps=10, seed=4)
    rows: list[tuple[int, str, bytes]] = []
    for topic, s in zip(TOPICS, (a, b), strict=True):
        v = np.c_[s.xyz, s.quat_xyzw].tolist()
        rows += [(int(t), topic, pose_stamped(int(t), b"map", tuple(x))) for t, x in zip(s.stamps_ns.tolist(), v,
                                                                                         strict=True)]
    if images:
        rng = np.random.default_rng(0)
        ramp = np.add.outer(np.arange(480), np.arange(640)).astype(np.uint8)       # 640 x 480 mono8
        frames = [(ramp + rng.integers(0, 32, ramp.shape, dtype=np.uint8)).tobytes() for _ in range(8)]
        head = b"\x00\x01\x00\x00"     # the bytes of an image: calibrate reads only the pose topics
        for k, t in enumerate(range(int(a.stamps_ns[0]), int(a.stamps_ns[-1]), 33_333_333)):
            rows.append((t, "/camera/image", head + frames[k % 8]))
    else:
        v = np.c_[a.xyz, a.quat_xyzw].tolist()
        rows += [(int(t), "/tf", tf_message(int(t), b"world", b"base", tuple(x)))
                 for t, x in zip(a.stamps_ns.tolist(), v, strict=True)]
    rows.sort(key=lambda r: r[0])
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD, chunk_size=1024 * 1024)
        w.start(profile="ros2", library="benchmarks/speed.py")
        ids = {}
        for topic, msgtype in ((TOPICS[0], POSE), (TOPICS[1], POSE), ("/tf", TF),
                               ("/camera/image", "sensor_msgs/msg/Image")):
            text, _ = ROS2_STORE.generate_msgdef(msgtype, ros_version=2)
            ids[topic] = w.register_channel(topic, "cdr", w.register_schema(msgtype, "ros2msg", text.encode()))
        for seq, (t, topic, data) in enumerate(rows):
            w.add_message(ids[topic], log_time=t, data=data, publish_time=t, sequence=seq)
        w.finish()


def _limit_child(path: str) -> None:
    """Python with numpy and scipy imported, then every chunk of ``path`` decompressed."""
    import scipy.linalg  # noqa: F401 - part of the limit: a numpy + scipy program starting
    from readers import _decompress_all
    _decompress_all(path)


# A program's peak RSS as it exits: VmHWM of its own memory map (the rusage of a fork + exec also counts the
# benchmark's pages the child had before its exec).
_PEAK = ("import atexit, runpy, sys; atexit.register(lambda: sys.stderr.write(next(ln for ln in "
         "open('/proc/self/status') if ln.startswith('VmHWM')))); sys.argv = sys.argv[1:]; "
         "runpy.run_path(sys.argv[0], run_name='__main__') if sys.argv[0].endswith('.py') else "
         "runpy.run_module(sys.argv[0], run_name='__main__', alter_sys=True)")


def timed(cmd: list[str]) -> tuple[float, float]:
    """(wall seconds, peak RSS [MB]) of one fresh process running ``cmd`` (a module or script and its
    arguments)."""
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _PEAK, *cmd], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          text=True)
    sec = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed: {proc.stderr}")
    peak = [ln for ln in proc.stderr.splitlines() if ln.startswith("VmHWM")]
    return sec, int(peak[-1].split()[1]) / 1024


def best(cmd: list[str], repeat: int) -> tuple[float, float]:
    runs = [timed(cmd) for _ in range(repeat)]
    return min(r[0] for r in runs), max(r[1] for r in runs)


def calibrate_cmd(log: Path) -> list[str]:
    return ["handeye_cli", "calibrate", str(log), "--topic-a", TOPICS[0],
            "--topic-b", TOPICS[1], "-q", "--format", "json"]


def shares(log: Path) -> list[tuple[str, float]]:
    """Each stage's share of one profiled in-process calibrate (cumulative time of its function)."""
    from handeye_cli import calibrate_files

    prof = cProfile.Profile()
    prof.enable()
    calibrate_files(log, topic_a=TOPICS[0], topic_b=TOPICS[1])
    prof.disable()
    stats = pstats.Stats(prof).stats      # type: ignore[attr-defined]
    total = max(ct for (_, _, name), (_, _, _, ct, _) in stats.items() if name == "calibrate_files")
    out = []
    for label, names in STAGES:
        cum = [ct for (_, _, name), (_, _, _, ct, _) in stats.items() if name in names]
        out.append((label, max(cum) / total if cum else 0.0))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--minutes", type=float, nargs="+", default=[10.0, 60.0])
    ap.add_argument("--limit-child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.limit_child:
        _limit_child(args.limit_child)
        return
    print(f"load average {os.getloadavg()[0]:.2f}; python {sys.version.split()[0]}; fastest of {args.repeat} "
          "fresh processes")
    logs = [(f"{m:g} min", m, False) for m in args.minutes] + [("1 min, image-heavy", 1.0, True)]
    times: dict[str, float] = {}
    verdicts = []
    with tempfile.TemporaryDirectory(prefix="handeye-speed-") as tmp:
        for label, minutes, images in logs:
            log = Path(tmp) / f"{label.replace(' ', '_').replace(',', '')}.mcap"
            build(log, minutes, images)
            limit, _ = best([__file__, "--limit-child", str(log)], args.repeat)
            sec, rss = best(calibrate_cmd(log), args.repeat)
            times[label] = sec
            ratio = sec / limit
            print(f"\n{label}: {log.stat().st_size / 1e6:.0f} MB; limit (start-up + zstd of every chunk) "
                  f"{limit:.2f} s; calibrate {sec:.2f} s = {ratio:.2f}x the limit; peak RSS {rss:.0f} MB")
            print("  stage shares: " + ", ".join(f"{name} {100 * s:.0f} %" for name, s in shares(log)))
            if images:
                verdicts.append((f"image-heavy ≤ {GOAL_IMAGES}x", ratio <= GOAL_IMAGES))
            elif minutes >= 60:
                verdicts += [(f"60 min ≤ {GOAL_RATIO}x", ratio <= GOAL_RATIO),
                             (f"60 min ≤ {GOAL_RSS_MB:.0f} MB", rss <= GOAL_RSS_MB)]
    if "10 min" in times and "60 min" in times:
        growth = times["60 min"] / times["10 min"]
        print(f"\n60 min / 10 min: {growth:.2f}x")
        verdicts.append((f"10 → 60 min ≤ {GOAL_GROWTH}x", growth <= GOAL_GROWTH))
    print("\n" + "; ".join(f"{name}: {'yes' if ok else 'NO'}" for name, ok in verdicts))
    print(json.dumps({"load_average": os.getloadavg()[0]}))


if __name__ == "__main__":
    main()
