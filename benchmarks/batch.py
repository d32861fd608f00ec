"""`handeye batch` on a generated fleet: --jobs 1 against --jobs 2, and batch against one
`handeye calibrate` process per log (the start-up cost a batch amortises).

Writes N short logs (MCAP, ROS 1 bag, ROS 2 bags, TUM pairs; 12 s of a 30 Hz / 20 Hz rig each)
and prints, from one run: the wall time of `handeye batch DIR --jobs 1` and `--jobs 2` (whole
CLI processes, start-up included), their ratio, the time of N separate `handeye calibrate`
processes, the per-log overhead of those over the batch, and the bare start-up of `handeye
--version`. Each figure is the median of --repeat runs.

    python benchmarks/batch.py [--logs 24] [--repeat 3]
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

TOPICS = ["--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose"]


def _cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed(args: list[str], repeat: int) -> tuple[float, float, str]:
    """Median wall time and CPU time [s] (user + system, all processes) of ``repeat`` runs of
    ``handeye ARGS``, and the last stdout."""
    times, cpus, out = [], [], ""
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), _cpu()
        proc = subprocess.run([sys.executable, "-m", "handeye_cli", *args], capture_output=True, text=True)
        times.append(time.perf_counter() - t0)
        cpus.append(_cpu() - c0)
        if proc.returncode != 0:
            raise SystemExit(f"handeye {' '.join(args)} failed ({proc.returncode}): {proc.stderr}")
        out = proc.stdout
    return statistics.median(times), statistics.median(cpus), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--logs", type=int, default=24)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    from _fleet import make_fleet

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "logs"
        expected = make_fleet(root, n_good=args.logs, n_beyond=0, n_below=0, broken=False)
        inputs = [k for k, e in expected.items() if e.status == "ok"]
        batch = ["batch", str(root), *TOPICS, "-q"]
        load = os.getloadavg()[0]
        start = timed(["--version"], args.repeat)
        one = timed([*batch, "--jobs", "1"], args.repeat)
        two = timed([*batch, "--jobs", "2"], args.repeat)
        ok = sum(json.loads(line)["status"] == "ok" for line in one[2].splitlines())
        wall = cpu = 0.0
        for label in inputs:
            paths = label.split(" ")
            w, c, _ = timed(["calibrate", *paths, *([] if len(paths) == 2 else TOPICS), "-q"], 1)
            wall, cpu = wall + w, cpu + c
    n = len(inputs)
    print(f"{n} logs (12 s each, mixed MCAP / ROS 1 bag / ROS 2 bag / TUM), {ok} calibrated; median of "
          f"{args.repeat}; {os.cpu_count()} cores, load average {load:.1f} at the start")
    print("                                     wall [s]   CPU [s]   wall per log [ms]")
    for name, (w, c, _) in (("handeye --version (start-up)", start), ("batch --jobs 1", one), ("batch --jobs 2", two)):
        print(f"  {name:<32} {w:8.2f}  {c:8.2f}   {w / n * 1000 if 'batch' in name else w * 1000:8.0f}")
    print(f"  {n} x handeye calibrate{'':<12} {wall:8.2f}  {cpu:8.2f}   {wall / n * 1000:8.0f}")
    print(f"  ratio of wall times jobs1 / jobs2: {one[0] / two[0]:.2f}")
    print(f"  per-log overhead of separate processes over batch --jobs 1: {(wall - one[0]) / n * 1000:.0f} ms wall, "
          f"{(cpu - one[1]) / n * 1000:.0f} ms CPU")


if __name__ == "__main__":
    main()
