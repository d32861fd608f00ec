"""Fleet scale: `handeye calibrate` on hour-long and image-heavy logs, beside the least any reader must do.

Builds (in a temporary directory) zstd-chunked MCAP logs of a rig — a at 100 Hz and b at 30 Hz
(PoseStamped) plus ``/tf`` at 100 Hz — of each ``--minutes`` length, and one image-heavy log
(``--image-seconds`` of the same poses with ``--image-hz`` images of ``--image-mb`` MB
interleaved: distinct images of random pixels, which zstd cannot compress, like the issue's
1.96 GB log; ``--same-image`` repeats one image instead, which a 4 MB chunk compresses about
fivefold, so the limit is mostly start-up). For each log it prints, all measured in this run:

* the limit: Python start-up with numpy + scipy.linalg + scipy.spatial.transform (a fresh
  process) plus zstd-decompressing every chunk of the file (in-process, ``zstandard``), as the issue
  defines it; beside it, start-up with numpy alone (a default ``calibrate`` imports no scipy, so it
  can start faster than the limit's start-up);
* ``handeye calibrate`` as a user runs it (a fresh process): wall time, peak RSS, and the ratio
  to the limit; beside them the same in CPU time (user + system), the stable figure on a machine
  shared with other work (wall times there include waiting for a core);
* the same with every diagnostic (``--bootstrap 200 --robust --alpha auto --report``) and its
  ratio to the plain run;
* in-process stage timers (read, sync, gate, pairs, solve) of the default pipeline;
* the ratio of the longest to the shortest log's calibrate time, beside the ratio of their lengths.

    python benchmarks/scale.py [--minutes 10 60] [--image-seconds 80 --image-hz 20 --image-mb 1 --same-image]
                               [--repeat 2] [--keep DIR]

Each timing (the limit, the plain and the diagnostic calibrate runs) is the fastest of ``--repeat`` runs.
The processes run with Python's bytecode cache on (as an installed package has it; an environment
with ``PYTHONDONTWRITEBYTECODE`` would compile every handeye module on every start, 0.15 s), kept
in a temporary ``PYTHONPYCACHEPREFIX`` and written by one warm-up run before any timing.

``--keep DIR`` builds the logs in DIR and keeps them: a later run with the same DIR and the same
lengths reuses them (the name of each log holds its parameters).
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

CALIBRATE = ["calibrate", "--topic-a", "/a/pose", "--topic-b", "/b/pose", "-q", "--format", "json", "-o", "-"]
DIAGNOSTICS = ["--bootstrap", "200", "--robust", "--alpha", "auto"]


def build(path: Path, seconds: float, image_hz: float = 0.0, image_mb: float = 1.0, same_image: bool = False) -> None:
    """A rig log: /a/pose 100 Hz, /b/pose 30 Hz (PoseStamped), /tf 100 Hz, optional images
    (distinct ones, or one repeated with ``same_image``)."""
    from _logs import POSE, image_channel, pose_channel, records, write_mcap

    from handeye_cli.geometry import se3
    from handeye_cli.simulation import Rig, simulate_rig

    X = se3.from_xyz_quat(np.array([0.1, 0.25, -0.05]), np.array([0.2, 0.1, -0.3, 0.9]))
    a, b = simulate_rig(Rig(X, 0), duration_s=seconds, rate_a=100, rate_b=30, speed=0.5,
                        sigma_r=np.deg2rad(0.1), sigma_t=0.002, jumps=int(seconds // 60), seed=4)
    channels = [pose_channel("/a/pose", POSE, records(a, "world", "")),
                pose_channel("/b/pose", POSE, records(b, "odom", "")),
                pose_channel("/tf", "tf2_msgs/msg/TFMessage", records(a, "world", "base_link"))]
    if image_hz:
        channels.append(image_channel("/camera/image", int(a.stamps_ns[0]), int(a.stamps_ns[-1]), image_hz,
                                      int(image_mb * 1e6), distinct=not same_image))
    write_mcap(path, channels, chunk_size=4 * 1024 * 1024)


def built(path: Path, seconds: float, image_hz: float = 0.0, image_mb: float = 1.0, same_image: bool = False) -> None:
    """:func:`build` unless ``path`` exists (a kept log); written beside it, then renamed, so an
    interrupted build leaves no log to reuse."""
    if not path.exists():
        part = path.with_suffix(".part")
        build(part, seconds, image_hz, image_mb, same_image)
        part.rename(path)


class Run(NamedTuple):
    """One measured run: wall time [s], CPU time (user + system) [s], peak RSS [MB]."""

    wall: float
    cpu: float
    rss: float


def measured_code() -> Path:
    """The checkout whose handeye_cli this process imports (PYTHONPATH, else the installed one)."""
    import handeye_cli

    return Path(handeye_cli.__file__).resolve().parent.parent


ENV = dict(os.environ)   # the environment of the measured processes (see use_bytecode_cache)


def use_bytecode_cache(pycache: Path) -> None:
    """Let the measured processes cache bytecode under ``pycache``, and write it once."""
    ENV.pop("PYTHONDONTWRITEBYTECODE", None)
    ENV["PYTHONPYCACHEPREFIX"] = str(pycache)
    run_process([sys.executable, "-c", "import numpy, scipy.linalg, scipy.spatial.transform, handeye_cli.pipeline"])


def run_process(args: list[str]) -> Run:
    """One fresh process, run in the checkout of :func:`measured_code` so that it imports the same
    handeye_cli as this one (``python -m`` puts the working directory first on the path); the peak
    is its VmHWM, polled from /proc while it runs (rusage of reaped children would give the largest
    child so far); the CPU time is its own rusage (wait4)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=measured_code(), env=ENV)
    peak_kb = 0
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        try:
            text = Path(f"/proc/{proc.pid}/status").read_text()
            peak_kb = max(peak_kb, int(text.split("VmHWM:")[1].split()[0]))
        except (OSError, IndexError, ValueError):
            pass
        time.sleep(0.02)
    seconds = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(args)} failed: {proc.stderr.read().decode()[-2000:] if proc.stderr else ''}")
    return Run(seconds, usage.ru_utime + usage.ru_stime, peak_kb / 1024)


def best(runs: list[Run]) -> Run:
    """The fastest of repeated runs (wall and CPU each at its least, the RSS of the fastest by wall):
    on a shared machine, other processes only ever add time."""
    fastest = min(runs, key=lambda r: r.wall)
    return Run(fastest.wall, min(r.cpu for r in runs), fastest.rss)


def decompress_every_chunk(path: Path) -> int:
    """zstd-decompress every chunk of ``path`` the cheapest way a reader can: the file mapped (not
    copied), each chunk (found by the summary's chunk index) into one reused buffer (no allocation,
    so no page faults per chunk: a fresh 5 MB buffer per chunk was up to 7x slower on this VM).
    Returns the bytes decompressed."""
    import mmap
    import struct

    import zstandard
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    buf, total = bytearray(max(c.uncompressed_size for c in chunks)), 0
    with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as mm, memoryview(mm) as view:
        for c in chunks:
            at = c.chunk_start_offset + 1 + 8 + 8 + 8 + 8 + 4           # opcode, length, times, size, CRC
            n = struct.unpack_from("<I", view, at)[0]
            size = struct.unpack_from("<Q", view, at + 4 + n)[0]
            data = view[at + 12 + n:at + 12 + n + size]
            if c.compression == "zstd":
                with zstandard.ZstdDecompressor().stream_reader(data, read_size=size) as reader:
                    out = memoryview(buf)[:c.uncompressed_size]
                    while out and (got := reader.readinto(out)):
                        out, total = out[got:], total + got
            data.release()
    return total


def limit(path: Path, repeat: int) -> tuple[Run, Run, Run]:
    """(start-up, decompression of every chunk), each the best of ``repeat`` — the least any reader must do
    as the issue defines it — and, for reference, start-up with numpy alone (a default calibrate imports no scipy)."""
    startup = best([run_process([sys.executable, "-c", "import numpy, scipy.linalg, scipy.spatial.transform"])
                    for _ in range(repeat)])
    numpy_only = best([run_process([sys.executable, "-c", "import numpy"]) for _ in range(repeat)])
    runs = []
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        decompress_every_chunk(path)
        runs.append(Run(time.perf_counter() - t0, time.process_time() - c0, 0.0))
    return startup, best(runs), numpy_only


def stage_times(path: Path) -> dict[str, float]:
    """In-process timers of the default pipeline's stages [s]."""
    from handeye_cli.calibration import StreamSpec, pairs_of, read_streams
    from handeye_cli.options import Options
    from handeye_cli.solvers import solve

    opts, times = Options(), {}
    t0 = time.perf_counter()
    a, b = read_streams([StreamSpec(str(path), "/a/pose"), StreamSpec(str(path), "/b/pose")], opts)
    times["read"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    pairs = pairs_of(a, b, opts, 0, None).pairs
    times["sync + gates + pairs"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    solve(pairs.A, pairs.B)
    times["solve"] = time.perf_counter() - t0
    return times


def measure(path: Path, label: str, report_dir: Path, repeat: int) -> float:
    """Print the limit, the CLI runs and the stage timers of one log; return the plain run's wall time [s]."""
    size = path.stat().st_size / 1e6
    startup, decompress, numpy_only = limit(path, repeat)
    floor = Run(startup.wall + decompress.wall, startup.cpu + decompress.cpu, 0.0)
    cmd = [sys.executable, "-m", "handeye_cli", *CALIBRATE[:1], str(path), *CALIBRATE[1:]]
    plain = best([run_process(cmd) for _ in range(repeat)])
    diag = best([run_process([*cmd, *DIAGNOSTICS, "--report", str(report_dir / f"{path.stem}.html")])
                 for _ in range(repeat)])
    stages = stage_times(path)
    print(f"\n{label}: {size:.0f} MB")
    print(f"  limit: start-up {startup.wall:.2f} s + decompress every chunk {decompress.wall:.2f} s = "
          f"{floor.wall:.2f} s  (CPU {startup.cpu:.2f} + {decompress.cpu:.2f} = {floor.cpu:.2f} s); "
          f"start-up with numpy alone {numpy_only.wall:.2f} s")
    print(f"  calibrate           {plain.wall:7.2f} s  peak RSS {plain.rss:6.0f} MB  ratio to the limit "
          f"{plain.wall / floor.wall:5.2f}x  (CPU {plain.cpu:.2f} s, {plain.cpu / floor.cpu:5.2f}x)")
    print(f"  + every diagnostic  {diag.wall:7.2f} s  peak RSS {diag.rss:6.0f} MB  ratio to the plain run "
          f"{diag.wall / plain.wall:5.2f}x  (CPU {diag.cpu:.2f} s, {diag.cpu / plain.cpu:5.2f}x)")
    print("  stages (in-process): " + ", ".join(f"{k} {v:.2f} s" for k, v in stages.items()))
    return plain.wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, nargs="*", default=[10.0, 60.0],
                    help="pose logs (none: the image log only)")
    ap.add_argument("--image-seconds", type=float, default=80.0)
    ap.add_argument("--image-hz", type=float, default=20.0)
    ap.add_argument("--image-mb", type=float, default=1.0)
    ap.add_argument("--same-image", action="store_true", help="repeat one image (compressible), not distinct ones")
    ap.add_argument("--repeat", type=int, default=2, help="runs of each timing, the fastest kept")
    ap.add_argument("--keep", type=Path, help="build the logs here, keep them and reuse the ones already there")
    args = ap.parse_args()
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} cores, handeye_cli of {measured_code()}")
    times = {}
    with tempfile.TemporaryDirectory(prefix="handeye-scale-") as tmp:
        d = (args.keep or Path(tmp)).resolve()
        d.mkdir(parents=True, exist_ok=True)
        use_bytecode_cache(Path(tmp) / "pycache")
        for minutes in args.minutes:
            path = d / f"poses_{minutes:g}min.mcap"
            built(path, 60 * minutes)
            times[minutes] = measure(path, f"{minutes:g}-min pose log (100 + 30 Hz PoseStamped, /tf 100 Hz)", d,
                                     args.repeat)
            if not args.keep:
                path.unlink()
        if args.image_seconds > 0:
            kind = "same" if args.same_image else "distinct"
            path = d / f"images_{args.image_seconds:g}s_{args.image_hz:g}hz_{args.image_mb:g}mb_{kind}.mcap"
            built(path, args.image_seconds, args.image_hz, args.image_mb, args.same_image)
            measure(path, f"{args.image_seconds:g}-s log with {args.image_hz:g} Hz {kind} images of "
                    f"{args.image_mb:g} MB", d, args.repeat)
    if len(times) > 1:
        lo, hi = min(times), max(times)
        print(f"\n{hi:g}-min / {lo:g}-min calibrate time: {times[hi] / times[lo]:.2f} (lengths {hi / lo:.1f}x)")


if __name__ == "__main__":
    main()
