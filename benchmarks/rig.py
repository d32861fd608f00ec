"""Whole-rig calibration: joint vs pairwise accuracy per sensor, and one read vs three pairwise runs.

1. Accuracy: simulated 4-sensor rigs (30/20/10/50 Hz, 0.2–0.5° / 2–5 mm noise, clock offsets
   given), over ``--seeds`` seeds, with and without tracking gaps (cam0 2–9 s, cam1 9–15 s,
   lidar 15–21 s of 30 s). Per sensor: RMS error of the joint estimate, of the direct pairwise
   result ``T_ref_k`` and of the best chain of pairwise results (the chain with the smallest RMS),
   as rotation [deg], translation [mm] and the combined rotation [rad] + α · translation [m].
2. Time: a 4-stream, ``--minutes``-minute MCAP (PoseStamped ×3 + TF), auto clock offsets:
   ``handeye rig`` (the log read once, 6 pairs) against 3 separate ``calibrate`` runs of the
   reference against each sensor (the log read 3 times, 3 pairs), in one process; the reads alone too.

    python benchmarks/rig.py [--seeds 12] [--minutes 10]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

GAPS = (((2.0, 9.0),), ((9.0, 15.0),), ((15.0, 21.0),), ())
DEG = np.deg2rad(1.0)
OFFSETS_NS = (0, 15_000_000, -40_000_000, 70_000_000)


def sensors(seed: int, gaps: bool, drift: bool = False) -> list:
    from handeye_cli.rig.simulate import SimSensor
    from handeye_cli.simulation import random_transform

    rng = np.random.default_rng(seed)
    T = [np.eye(4)] + [random_transform(rng, 0.3) for _ in range(3)]
    d1 = (0, 0, 0.5 * DEG / 60, 0.01 / 60, 0, 0) if drift else (0.0,) * 6
    d2 = (0, 0, 1.0 * DEG / 60, 0.02 / 60, 0.01 / 60, 0) if drift else (0.0,) * 6
    out = [SimSensor("cam0", T[0], 30, 0.2 * DEG, 0.002),
           SimSensor("cam1", T[1], 20, 0.3 * DEG, 0.003, OFFSETS_NS[1]),
           SimSensor("lidar", T[2], 10, 0.1 * DEG, 0.002, OFFSETS_NS[2], drift=d1),
           SimSensor("wheels", T[3], 50, 0.5 * DEG, 0.005, OFFSETS_NS[3], drift=d2)]
    return [replace(s, gaps=g) for s, g in zip(out, GAPS, strict=True)] if gaps else out


def errors(X: np.ndarray, truth: np.ndarray) -> np.ndarray:
    from handeye_cli.analysis import extrinsic_error

    rot, trans = extrinsic_error(X, truth)
    return np.array([rot, 1e3 * trans, np.deg2rad(rot) + trans])


def chains(res, k: int) -> dict[tuple[int, ...], np.ndarray]:
    from handeye_cli.rig.graph import chains as chain_transforms

    return chain_transforms({(e.j, e.k): e.matrix for e in res.edges}, len(res.names), k)


def accuracy(seeds: int, gaps: bool) -> None:
    from handeye_cli.rig import RigOptions, calibrate_rig
    from handeye_cli.rig.simulate import simulate_streams

    offsets = {"cam1": OFFSETS_NS[1] / 1e9, "lidar": OFFSETS_NS[2] / 1e9, "wheels": OFFSETS_NS[3] / 1e9}
    joint: dict[int, list] = {}
    chain: dict[tuple[int, tuple[int, ...]], list] = {}
    for seed in range(seeds):
        sims = sensors(seed, gaps)
        res = calibrate_rig(simulate_streams(sims, duration_s=30, seed=seed), RigOptions(time_offsets=offsets))
        for k in range(1, 4):
            joint.setdefault(k, []).append(errors(res.matrices[k], sims[k].T_ref_k))
            for path, X in chains(res, k).items():
                chain.setdefault((k, path), []).append(errors(X, sims[k].T_ref_k))
    rms = {key: np.sqrt(np.mean(np.square(v), axis=0)) for key, v in {**joint, **chain}.items()}
    print(f"\naccuracy over {seeds} seeds, 30 s, {'with' if gaps else 'without'} tracking gaps "
          "(RMS: rotation deg / translation mm / rad + α·m):")
    for k, name in enumerate(("cam1", "lidar", "wheels"), 1):
        best = min((key for key in rms if isinstance(key, tuple) and key[0] == k), key=lambda key: rms[key][2])
        fmt = "{:.4f}° / {:.3f} mm / {:.3e}"
        print(f"  {name:<7} joint {fmt.format(*rms[k])}   direct {fmt.format(*rms[(k, (0, k))])}   "
              f"best chain {'→'.join(map(str, best[1]))} {fmt.format(*rms[best])}   "
              f"joint/best {rms[k][2] / rms[best][2]:.3f}")


def timing(minutes: float) -> None:
    from _logs import POSE, TF, pose_channel, records, write_mcap

    from handeye_cli.io import read_log_streams
    from handeye_cli.pipeline import calibrate_files
    from handeye_cli.rig import RigOptions, calibrate_rig_files, parse_stream, read_rig
    from handeye_cli.rig.simulate import simulate_streams

    sims = sensors(0, gaps=False, drift=True)
    streams = simulate_streams(sims, duration_s=60 * minutes, seed=0)
    topics = ["/cam0/pose", "/cam1/pose", "/lidar/pose"]
    with tempfile.TemporaryDirectory() as d:
        log = Path(d) / "rig4.mcap"
        names = ("cam0", "cam1", "lidar")
        channels = [pose_channel(t, POSE, records(streams[n], f"w_{n}", n)) for t, n in zip(topics, names, strict=True)]
        write_mcap(log, [*channels, pose_channel("/tf", TF, records(streams["wheels"], "odom", "wheels"))])
        specs = [parse_stream(s) for s in ("cam0=/cam0/pose", "cam1=/cam1/pose", "lidar=/lidar/pose",
                                           "wheels=tf:odom,wheels")]
        t0 = time.perf_counter()
        read_rig(str(log), specs)
        t_read_one = time.perf_counter() - t0
        t0 = time.perf_counter()
        for spec in specs[1:]:
            read_log_streams(log, [("/cam0/pose", None), (spec.topic, spec.frames)])
        t_read_three = time.perf_counter() - t0
        t0 = time.perf_counter()
        res = calibrate_rig_files(str(log), specs, RigOptions())
        t_rig = time.perf_counter() - t0
        t0 = time.perf_counter()
        for spec in specs[1:]:
            calibrate_files(log, topic_a="/cam0/pose", topic_b=spec.topic, frames_b=spec.frames, time_offset="auto")
        t_pairs = time.perf_counter() - t0
        size = log.stat().st_size / 1e6
    print(f"\ntime, {minutes:g}-minute 4-stream MCAP ({size:.1f} MB, {sum(map(len, streams.values()))} poses), "
          "auto clock offsets:")
    print(f"  read:      one pass of all 4 streams {t_read_one:.2f} s   vs 3 passes of 2 streams {t_read_three:.2f} s")
    print(f"  calibrate: handeye rig (6 pairs, joint) {t_rig:.2f} s   vs 3 pairwise calibrate runs {t_pairs:.2f} s")
    print("  joint errors:", ", ".join(f"{n} {errors(res.matrices[k], sims[k].T_ref_k)[0]:.3f}° / "
                                       f"{errors(res.matrices[k], sims[k].T_ref_k)[1]:.2f} mm"
                                       for k, n in enumerate(res.names) if k))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=12)
    ap.add_argument("--minutes", type=float, default=10.0)
    args = ap.parse_args()
    accuracy(args.seeds, gaps=False)
    accuracy(args.seeds, gaps=True)
    timing(args.minutes)


if __name__ == "__main__":
    main()
