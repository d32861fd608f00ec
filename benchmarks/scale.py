"""Fleet scale: `handeye calibrate` on hour-long and image-heavy logs, beside the least any reader must do.

Builds (in a temporary directory) zstd-chunked MCAP logs of a rig — a at 100 Hz and b at 30 Hz
(PoseStamped) plus ``/tf`` at 100 Hz — of each ``--minutes`` length, and one image-heavy log
(``--image-seconds`` of the same poses with ``--image-hz`` images of ``--image-mb`` MB
interleaved). For each log it prints, all measured in this run:

* the limit: Python start-up with numpy + scipy.linalg + scipy.spatial.transform (a fresh
  process) plus zstd-decompressing every chunk of the file (in-process, ``zstandard``);
* ``handeye calibrate`` as a user runs it (a fresh process, the faster of two runs): wall time,
  peak RSS, and the ratio to the limit;
* the same with every diagnostic (``--bootstrap 200 --robust --alpha auto --report``) and its
  ratio to the plain run, in wall time and in CPU time (user + system, which a loaded machine
  does not inflate);
* in-process stage timers (read, sync, gate, pairs, solve) of the default pipeline;
* the ratio of the longest to the shortest log's calibrate time, beside the ratio of their lengths.

    python benchmarks/scale.py [--minutes 10 60] [--image-seconds 80 --image-hz 20 --image-mb 1] [--keep DIR]

``--keep DIR`` builds the logs in DIR and keeps them; a later run with the same DIR reuses each
log already there (its name says its length, rates and image settings) instead of building it.
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

CALIBRATE = ["calibrate", "--topic-a", "/a/pose", "--topic-b", "/b/pose", "-q", "--format", "json", "-o", "-"]
DIAGNOSTICS = ["--bootstrap", "200", "--robust", "--alpha", "auto"]


def build(path: Path, seconds: float, image_hz: float = 0.0, image_mb: float = 1.0) -> None:
    """A rig log: /a/pose 100 Hz, /b/pose 30 Hz (PoseStamped), /tf 100 Hz, optional images."""
    from _logs import POSE, ROS2_STORE, Channel, pose_channel, records, write_mcap

    from handeye_cli import se3
    from handeye_cli.simulation import Rig, simulate_rig

    X = se3.from_xyz_quat(np.array([0.1, 0.25, -0.05]), np.array([0.2, 0.1, -0.3, 0.9]))
    a, b = simulate_rig(Rig(X, 0), duration_s=seconds, rate_a=100, rate_b=30, speed=0.5,
                        sigma_r=np.deg2rad(0.1), sigma_t=0.002, jumps=int(seconds // 60), seed=4)
    channels = [pose_channel("/a/pose", POSE, records(a, "world", "")),
                pose_channel("/b/pose", POSE, records(b, "odom", "")),
                pose_channel("/tf", "tf2_msgs/msg/TFMessage", records(a, "world", "base_link"))]
    if image_hz:
        T = ROS2_STORE.types
        n_bytes = int(image_mb * 1e6)
        image = T["sensor_msgs/msg/Image"](
            header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="cam"),
            height=1000, width=n_bytes // 1000, encoding="mono8", is_bigendian=0, step=n_bytes // 1000,
            data=np.random.default_rng(0).integers(0, 255, n_bytes // 1000 * 1000, dtype=np.uint8))
        raw = bytes(ROS2_STORE.serialize_cdr(image, "sensor_msgs/msg/Image"))
        t = np.arange(a.stamps_ns[0], a.stamps_ns[-1], int(1e9 / image_hz), dtype=np.int64)
        channels.append(Channel("/camera/image", "sensor_msgs/msg/Image", [(int(ti), raw) for ti in t]))
    write_mcap(path, channels, chunk_size=4 * 1024 * 1024)


def run_process(args: list[str]) -> tuple[float, float, float]:
    """(wall time [s], peak RSS [MB], CPU time [s]) of one fresh process; the peak is its VmHWM, polled
    from /proc while it runs (rusage of reaped children would give the largest child so far); the CPU
    time (user + system) is the change in the reaped children's, which does not grow with the load of
    other processes as the wall time does."""
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    peak_kb = 0
    while proc.poll() is None:
        try:
            status = Path(f"/proc/{proc.pid}/status").read_text()
            peak_kb = max(peak_kb, int(status.split("VmHWM:")[1].split()[0]))
        except (OSError, IndexError, ValueError):
            pass
        time.sleep(0.02)
    seconds = time.perf_counter() - t0
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(args)} failed: {proc.stderr.read().decode()[-2000:] if proc.stderr else ''}")
    return seconds, peak_kb / 1024, cpu1.ru_utime + cpu1.ru_stime - cpu0.ru_utime - cpu0.ru_stime


def limit(path: Path) -> tuple[float, float, float]:
    """(start-up [s], decompression of every chunk [s], their sum) — the least any reader must do."""
    import zstandard
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader

    startup, _, _ = run_process([sys.executable, "-c", "import numpy, scipy.linalg, scipy.spatial.transform"])
    dctx = zstandard.ZstdDecompressor()
    t0 = time.perf_counter()
    with open(path, "rb") as f:
        for record in StreamReader(f, skip_magic=False, emit_chunks=True).records:
            if isinstance(record, Chunk) and record.compression == "zstd":
                dctx.decompress(record.data, max_output_size=record.uncompressed_size)
    decompress = time.perf_counter() - t0
    return startup, decompress, startup + decompress


def stage_times(path: Path) -> dict[str, float]:
    """In-process timers of the default pipeline's stages [s]."""
    from handeye_cli.options import Options
    from handeye_cli.pipeline import StreamSpec, pairs_of, read_streams
    from handeye_cli.solvers import solve

    opts, times = Options(), {}
    t0 = time.perf_counter()
    a, b = read_streams(StreamSpec(str(path), "/a/pose"), StreamSpec(str(path), "/b/pose"), opts)
    times["read"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    pairs = pairs_of(a, b, opts, 0, None)[1]
    times["sync + gates + pairs"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    solve(pairs.A, pairs.B)
    times["solve"] = time.perf_counter() - t0
    return times


def measure(path: Path, label: str, report_dir: Path) -> float:
    """Print the limit, the CLI runs and the stage timers of one log; return the plain run's time."""
    size = path.stat().st_size / 1e6
    startup, decompress, floor = limit(path)
    cmd = [sys.executable, "-m", "handeye_cli", *CALIBRATE[:1], str(path), *CALIBRATE[1:]]
    plain, rss, cpu = min((run_process(cmd) for _ in range(2)), key=lambda r: r[0])
    diag_cmd = [*cmd, *DIAGNOSTICS, "--report", str(report_dir / f"{path.stem}.html")]
    diag, diag_rss, diag_cpu = min((run_process(diag_cmd) for _ in range(2)), key=lambda r: r[0])   # as plain
    stages = stage_times(path)
    print(f"\n{label}: {size:.0f} MB")
    print(f"  limit: start-up {startup:.2f} s + decompress every chunk {decompress:.2f} s = {floor:.2f} s")
    print(f"  calibrate           {plain:7.2f} s  peak RSS {rss:6.0f} MB  ratio to the limit {plain / floor:5.2f}x"
          f"  (CPU {cpu:.2f} s)")
    print(f"  + every diagnostic  {diag:7.2f} s  peak RSS {diag_rss:6.0f} MB  ratio to the plain run "
          f"{diag / plain:5.2f}x  (CPU {diag_cpu:.2f} s, ratio {diag_cpu / cpu:.2f}x)")
    print("  stages (in-process): " + ", ".join(f"{k} {v:.2f} s" for k, v in stages.items()))
    return plain


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, nargs="+", default=[10.0, 60.0])
    ap.add_argument("--image-seconds", type=float, default=80.0)
    ap.add_argument("--image-hz", type=float, default=20.0)
    ap.add_argument("--image-mb", type=float, default=1.0)
    ap.add_argument("--keep", type=Path, metavar="DIR", help="build the logs in DIR, keep them, and reuse those there")
    args = ap.parse_args()
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} cores")
    times = {}
    with tempfile.TemporaryDirectory(prefix="handeye-scale-") as tmp:
        d = Path(tmp)
        logs = d if args.keep is None else args.keep
        logs.mkdir(parents=True, exist_ok=True)

        def log(name: str, seconds: float, *image: float) -> Path:
            """The log ``name`` in the logs' directory, built unless kept from an earlier run."""
            path = logs / name
            if not path.exists():
                part = path.with_name(name + ".part")        # an interrupted build leaves no log to reuse
                build(part, seconds, *image)
                part.replace(path)
            return path

        for minutes in args.minutes:
            path = log(f"poses_{minutes:g}min.mcap", 60 * minutes)
            times[minutes] = measure(path, f"{minutes:g}-min pose log (100 + 30 Hz PoseStamped, /tf 100 Hz)", d)
            if args.keep is None:
                path.unlink()
        if args.image_seconds > 0:
            path = log(f"images_{args.image_seconds:g}s_{args.image_hz:g}hz_{args.image_mb:g}mb.mcap",
                       args.image_seconds, args.image_hz, args.image_mb)
            measure(path, f"{args.image_seconds:g}-s log with {args.image_hz:g} Hz images of {args.image_mb:g} MB", d)
    if len(times) > 1:
        lo, hi = min(times), max(times)
        print(f"\n{hi:g}-min / {lo:g}-min calibrate time: {times[hi] / times[lo]:.2f} (lengths {hi / lo:.1f}x)")


if __name__ == "__main__":
    main()
