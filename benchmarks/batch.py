"""`handeye batch` on a generated fleet: --jobs 1 against --jobs 2 and what limits the ratio, batch
against one `handeye calibrate` process per log, and the peak memory of 100 against 1,000 inputs.

Writes N short logs (MCAP, ROS 1 bag, ROS 2 bags, TUM pairs; --duration s of a 30 Hz / 20 Hz rig
each) and prints, from one run: the wall time of `handeye batch DIR --jobs 1` and `--jobs 2` (whole
CLI processes, start-up included), their ratio, the time of N separate `handeye calibrate`
processes, the per-log overhead of those over the batch, and the bare start-up of `handeye
--version`. Each figure is the median of --repeat runs. Then what bounds the ratio: the serial part
(start-up and discovery, which jobs cannot share), a worker's start (fork), the library's import
(the calibration run and the log readers, imported by each worker, the workers at once: part of
their first jobs, not of the serial part, which is measured as the time from the command's start to
its first worker's fork), pickling a job and a record, and the parent's work per record (verdict,
JSON, an fsync'd append, overlapped with the workers' next jobs), with the ratio Amdahl's law allows
from them. That bound counts the library's import once, as --jobs 1 pays it: --jobs 2 pays it in
both workers at once, which is what keeps the measured ratio below it.
The load average is printed at the start and the end: other processes on the machine cut the ratio.

--memory instead runs `batch --jobs 1 -o records.jsonl` (all in one process) over 100 and 1,000
copies of a 10-s TUM pair from sample_data/ and prints each run's peak RSS.

    python benchmarks/batch.py [--logs 24] [--duration 12] [--repeat 3] [--memory]
"""
from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import pickle
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
FIRST_FORK = """
import sys, time
from handeye_cli.cli import main
from handeye_cli.fleet import engine
start = engine._Worker.__init__
def first(self, context):
    if not hasattr(engine, "forked_at"):
        engine.forked_at = time.perf_counter()
        sys.stderr.write(f"first_fork_s {engine.forked_at}\\n")
    start(self, context)
engine._Worker.__init__ = first
main(sys.argv[1:])
"""
MAXRSS = """
import atexit, resource, sys
atexit.register(lambda: sys.stderr.write(f"maxrss_kb {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}\\n"))
from handeye_cli.cli import main
main(sys.argv[1:])
"""


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


def _median_s(fn, repeat: int = 200) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def _echo(conn) -> None:
    conn.send(conn.recv())


def _fork_s() -> float:
    """Wall time [s] of starting a forked worker and one round trip through its pipe."""
    ctx = multiprocessing.get_context("fork")

    def once() -> None:
        ours, theirs = ctx.Pipe()
        p = ctx.Process(target=_echo, args=(theirs,))
        p.start()
        ours.send(1)
        ours.recv()
        p.join()
    return _median_s(once, 10)


def _first_fork_s(args: list[str], repeat: int = 1) -> float:
    """Median wall time [s] from starting ``handeye ARGS`` (a ``--jobs 2`` batch) to its first worker's
    fork: the serial part, start-up, discovery and the import of the library included."""
    times = []
    for _ in range(repeat):     # perf_counter is the system's monotonic clock: one across processes
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-c", FIRST_FORK, *args], capture_output=True, text=True, check=True)
        times.append(float(proc.stderr.split("first_fork_s ")[1].split()[0]) - t0)
    return statistics.median(times)


def _import_s() -> float:
    code = "import time; t = time.perf_counter(); import handeye_cli.calibration.run; print(time.perf_counter() - t)"
    return statistics.median(float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                                  check=True).stdout) for _ in range(3))


def limits(root: Path, records: list[dict]) -> dict[str, float]:
    """Per-job costs [s] outside the calibration itself (see the module docstring)."""
    from handeye_cli.fleet import BatchSettings, Job, Streams, discover
    from handeye_cli.fleet.batch import _judge, record_line
    from handeye_cli.fleet.journal import Journal
    from handeye_cli.options import Options

    job = Job(discover([str(root)])[0], Streams(*TOPICS[1::2]), Options())
    record = max(records, key=lambda r: len(json.dumps(r)))
    settings = BatchSettings()
    with tempfile.TemporaryDirectory() as tmp:
        journal = Journal(Path(tmp) / "r.jsonl", False, print)
        parent = _median_s(lambda: journal.append(record_line(_judge(dict(record), settings))))
        journal.close()
    return {"fork": _fork_s(), "import": _import_s(),
            "pickle": _median_s(lambda: pickle.loads(pickle.dumps(job))) +
            _median_s(lambda: pickle.loads(pickle.dumps(record))),
            "record_kb": len(pickle.dumps(record)) / 1024, "parent": parent}


def memory(counts: tuple[int, ...]) -> None:
    a = (ROOT / "sample_data" / "rig_a.tum").read_text().splitlines(keepends=True)[:300]     # 10 s at 30 Hz
    b = (ROOT / "sample_data" / "rig_b.tum").read_text().splitlines(keepends=True)[:120]     # 10 s at 12 Hz
    print(f"peak RSS of batch --jobs 1 -o records.jsonl (one process) over copies of a 10-s TUM pair; "
          f"load average {os.getloadavg()[0]:.1f}")
    base = None
    for n in counts:
        with tempfile.TemporaryDirectory() as tmp:
            for k in range(n):
                folder = Path(tmp) / "logs" / f"robot{k:04d}"
                folder.mkdir(parents=True)
                (folder / "a.tum").write_text("".join(a))
                (folder / "b.tum").write_text("".join(b))
            t0 = time.perf_counter()
            proc = subprocess.run([sys.executable, "-c", MAXRSS, "batch", str(Path(tmp) / "logs"), "--jobs", "1",
                                   "-o", str(Path(tmp) / "records.jsonl"), "-q"], capture_output=True, text=True)
            wall = time.perf_counter() - t0
            lines = (Path(tmp) / "records.jsonl").read_text().splitlines()
        rss = int(proc.stderr.split("maxrss_kb ")[1].split()[0]) / 1024
        ok = sum(json.loads(line)["status"] == "ok" for line in lines)
        base = base or rss
        print(f"  {n:5d} inputs: {ok} ok of {len(lines)} records, {wall:6.1f} s, peak RSS {rss:6.1f} MB "
              f"({rss / base:.2f}x the {counts[0]}-input run)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--logs", type=int, default=24)
    ap.add_argument("--duration", type=float, default=12.0, help="seconds of each log")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--memory", action="store_true", help="peak RSS over 100 and 1,000 inputs instead")
    args = ap.parse_args()
    if args.memory:
        memory((100, 1000))
        return
    import _fleet

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "logs"
        real_write = _fleet.write_rig
        _fleet.write_rig = lambda folder, kind, X, seed, duration_s=args.duration: real_write(
            folder, kind, X, seed, duration_s)
        expected = _fleet.make_fleet(root, n_good=args.logs, n_beyond=0, n_below=0, broken=False)
        inputs = [k for k, e in expected.items() if e.status == "ok"]
        batch = ["batch", str(root), *TOPICS, "-q"]
        load = os.getloadavg()[0]
        start = timed(["--version"], args.repeat)
        one = timed([*batch, "--jobs", "1"], args.repeat)
        two = timed([*batch, "--jobs", "2"], args.repeat)
        load_end = os.getloadavg()[0]
        records = [json.loads(line) for line in one[2].splitlines()]
        ok = sum(r["status"] == "ok" for r in records)
        cost = limits(root / "robot00", records)
        first_fork = _first_fork_s([*batch, "--jobs", "2"])
        wall = cpu = 0.0
        for label in inputs[:8]:
            paths = label.split(" ")
            w, c, _ = timed(["calibrate", *paths, *([] if len(paths) == 2 else TOPICS), "-q"], 1)
            wall, cpu = wall + w, cpu + c
    n = len(inputs)
    print(f"{n} logs ({args.duration:g} s each, mixed MCAP / ROS 1 bag / ROS 2 bag / TUM), {ok} calibrated; median "
          f"of {args.repeat}; {os.cpu_count()} cores, load average {load:.1f} at the start, {load_end:.1f} at the end")
    print("                                     wall [s]   CPU [s]   wall per log [ms]")
    for name, (w, c, _) in (("handeye --version (start-up)", start), ("batch --jobs 1", one), ("batch --jobs 2", two)):
        print(f"  {name:<32} {w:8.2f}  {c:8.2f}   {w / n * 1000 if 'batch' in name else w * 1000:8.0f}")
    per = wall / 8
    print(f"  8 x handeye calibrate{'':<13} {wall:8.2f}  {cpu:8.2f}   {per * 1000:8.0f}")
    print(f"  ratio of wall times jobs1 / jobs2: {one[0] / two[0]:.2f}")
    print(f"  per-log overhead of separate processes over batch --jobs 1: {per * 1000 - one[0] / n * 1000:.0f} ms wall")
    serial = first_fork                     # start-up, discovery, the import before the workers fork
    work = (one[0] - serial) / n                         # one log's calibration, in one process
    # the parent's per-record work overlaps the workers' (they get their next job first), unless it is the larger
    bound = one[0] / (serial + n * max(work / 2, cost["parent"]) + 2 * cost["fork"])
    print("what limits --jobs 2:")
    print(f"  serial: {serial * 1000:.0f} ms from the command's start to its first worker's fork (start-up "
          f"{start[0] * 1000:.0f} ms of it, then the command's imports and discovery; the library, imported by each "
          f"worker, alone in a fresh interpreter: {cost['import'] * 1000:.0f} ms) = "
          f"{serial / one[0] * 100:.0f} % of the --jobs 1 wall time")
    print(f"  per worker: fork and first reply {cost['fork'] * 1000:.1f} ms (x2)")
    print(f"  per log: calibration {work * 1000:.0f} ms; pickling a job and its record ({cost['record_kb']:.1f} KB) "
          f"{cost['pickle'] * 1e6:.0f} us; the parent's verdict + JSON + fsync'd append {cost['parent'] * 1e6:.0f} us "
          "(while the workers run their next jobs)")
    print(f"  Amdahl bound from these: {bound:.2f}x (measured {one[0] / two[0]:.2f}x)")


if __name__ == "__main__":
    main()
