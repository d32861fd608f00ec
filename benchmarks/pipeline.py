"""End to end: `handeye calibrate` on a 10-minute log, a at 100 Hz and b at 30 Hz (PoseStamped in MCAP).

Prints the wall time of whole CLI runs (Python start-up included) with the default settings and
with every diagnostic on (`--time-offset auto --robust --alpha auto --bootstrap 1000`), beside
the baseline measured in the same run: a run of `handeye inspect` on the same file (start-up plus
opening the log) and the bare read of both topics. Also prints the extrinsic error.

    python benchmarks/pipeline.py [--minutes 10]
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


def build(path: Path, minutes: float, X: np.ndarray, offset_ns: int) -> None:
    from _logs import POSE, pose_channel, records, write_mcap

    from handeye_cli.simulation import Rig, simulate_rig

    a, b = simulate_rig(Rig(X, offset_ns), duration_s=60 * minutes, rate_a=100, rate_b=30, speed=0.5,
                        sigma_r=np.deg2rad(0.1), sigma_t=0.002, jumps=10, seed=4)
    write_mcap(path, [pose_channel("/a/pose", POSE, records(a, "world", "")),
                      pose_channel("/b/pose", POSE, records(b, "odom", ""))])


def timed(args: list[str]) -> tuple[float, str]:
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "handeye_cli", *args], capture_output=True, text=True, check=True)
    return time.perf_counter() - t0, out.stdout


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--minutes", type=float, default=10.0)
    args = ap.parse_args()
    from handeye_cli.geometry import se3
    from handeye_cli.io import read_stream

    X = se3.from_xyz_quat(np.array([0.1, 0.25, -0.05]), np.array([0.2, 0.1, -0.3, 0.9]))
    with tempfile.TemporaryDirectory() as d:
        log = Path(d) / "log.mcap"
        build(log, args.minutes, X, offset_ns=0)
        print(f"log: {args.minutes:g} min, a 100 Hz + b 30 Hz PoseStamped, {log.stat().st_size / 1e6:.1f} MB")
        t0 = time.perf_counter()
        read_stream(log, topic="/a/pose"), read_stream(log, topic="/b/pose")
        t_read = time.perf_counter() - t0
        t_inspect, _ = timed(["inspect", str(log)])
        base = ["calibrate", str(log), "--topic-a", "/a/pose", "--topic-b", "/b/pose", "-q", "--format", "json"]
        rows = [("read both topics (in-process)", t_read, None), ("handeye inspect (CLI)", t_inspect, None)]
        for label, extra in (("handeye calibrate (defaults)", []),
                             ("… --time-offset auto --robust --alpha auto --bootstrap 1000",
                              ["--time-offset", "auto", "--robust", "--alpha", "auto", "--bootstrap", "1000"])):
            sec, out = timed(base + extra)
            doc = json.loads(out)
            M = np.array(doc["matrix"])
            err = (np.rad2deg(se3.rotation_angle(M[:3, :3].T @ X[:3, :3])), 1e3 * np.linalg.norm(M[:3, 3] - X[:3, 3]))
            rows.append((label, sec, err))
        for label, sec, err in rows:
            extra = f"   error {err[0]:.4f}° / {err[1]:.3f} mm" if err else ""
            print(f"{label:<62}{sec:7.2f} s   ×{sec / t_inspect:5.2f} inspect{extra}")


if __name__ == "__main__":
    main()
