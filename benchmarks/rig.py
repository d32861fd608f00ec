"""Whole-rig calibration: joint vs pairwise accuracy per sensor, and one read vs three pairwise runs.

1. Accuracy: simulated 4-sensor rigs (30/20/10/50 Hz, 0.2–0.5° / 2–5 mm noise, clock offsets
   given), over ``--seeds`` seeds: without tracking gaps; with gaps (cam0 2–9 s, cam1 9–15 s, lidar
   15–21 s of 30 s); with those gaps and drifting lidar and wheels odometry. Per sensor: RMS error
   of the joint estimate, of the direct pairwise result ``T_ref_k`` and of the best chain of
   pairwise results (chosen in hindsight: the chain with the smallest RMS, separately for rotation
   and translation), rotation [deg] / translation [mm], the ratios joint / best chain with the
   p-value of the paired test that the joint is worse than that chain (exact one-sided Wilcoxon
   signed-rank on the per-seed error differences, as tests/rig/test_rig.py) and the ratio's standard
   error (paired bootstrap of the seeds), the RMS error the joint's noise model predicts (root of
   the mean predicted variance) and the model's joint / direct pair: where the model expects a gain
   of a few per cent, 20 seeds cannot resolve it (a ratio of 1.03 ± 0.04 is no loss).
2. Bad-stream naming: over the same seeds, with gaps (and drift): how often a clean rig names a
   stream, and how often a rig with one bad stream (cam1, lidar or wheels by turn; translations
   × 0.8, its given clock offset 30 ms wrong, or its mount slipping 1° / 5 mm mid-log: see
   ``handeye_cli.rig.simulate.with_fault``) names the right one; the χ² of the pairwise estimates
   (median p-value of the clean rigs).
3. Time: a 4-stream, ``--minutes``-minute MCAP (PoseStamped ×3 + TF), auto clock offsets:
   ``handeye rig`` (the log read once, 6 pairs, joint) against one ``calibrate`` of two of its
   streams (cam0-cam1; the ratio rig / one calibrate) and 3 separate ``calibrate`` runs of the
   reference against each sensor — in one warm process (imports done first; the reads alone too;
   the rig's stages: clock offsets, pairwise solves, joint), and as command lines (what a user
   runs: each ``handeye`` process starts, imports and reads once). Every time is the fastest of
   ``--repeat`` runs, the rig's and the calibrate's interleaved (other load slows single runs by up
   to 2×); the load average is printed beside it, and the warm runs' CPU time (steadier under load).

    python benchmarks/rig.py [--seeds 20] [--minutes 10] [--repeat 3] [--skip-accuracy] [--skip-detection]
                             [--skip-time]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

GAPS = (((2.0, 9.0),), ((9.0, 15.0),), ((15.0, 21.0),), ())
DEG = np.deg2rad(1.0)
OFFSETS_NS = (0, 15_000_000, -40_000_000, 70_000_000)
STREAMS = ("cam0=/cam0/pose", "cam1=/cam1/pose", "lidar=/lidar/pose", "wheels=tf:odom,wheels")


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
    """Rotation [deg] and translation [mm] error."""
    from handeye_cli.analysis import extrinsic_error

    rot, trans = extrinsic_error(X, truth)
    return np.array([rot, 1e3 * trans])


def chains(res, k: int) -> dict[tuple[int, ...], np.ndarray]:
    from handeye_cli.rig.graph import chains as chain_transforms

    return chain_transforms({(e.j, e.k): e.matrix for e in res.edges}, len(res.names), k)


def _rms(values: list[np.ndarray]) -> np.ndarray:
    return np.asarray(np.sqrt(np.mean(np.square(values), axis=0)))


def _ratio_se(joint: np.ndarray, chain: np.ndarray, draws: int = 2000) -> float:
    """Standard error of RMS(joint) ÷ RMS(chain) over the seeds (paired bootstrap of the seeds)."""
    rng = np.random.default_rng(0)
    pick = rng.integers(0, len(joint), size=(draws, len(joint)))
    return float(np.std(np.sqrt(np.mean(joint[pick] ** 2, axis=1) / np.mean(chain[pick] ** 2, axis=1)), ddof=1))


def accuracy(seeds: int, gaps: bool, drift: bool) -> None:
    from _util import signed_rank_p

    from handeye_cli.rig import RigOptions, calibrate_rig
    from handeye_cli.rig.simulate import simulate_streams

    offsets = {"cam1": OFFSETS_NS[1] / 1e9, "lidar": OFFSETS_NS[2] / 1e9, "wheels": OFFSETS_NS[3] / 1e9}
    joint: dict[int, list] = {}
    predicted: dict[int, list] = {}
    direct: dict[int, list] = {}
    chain: dict[tuple[int, tuple[int, ...]], list] = {}
    for seed in range(seeds):
        sims = sensors(seed, gaps, drift)
        res = calibrate_rig(simulate_streams(sims, duration_s=30, seed=seed), RigOptions(time_offsets=offsets))
        for k in range(1, 4):
            joint.setdefault(k, []).append(errors(res.matrices[k], sims[k].T_ref_k))
            cov = res.covariances[k]
            predicted.setdefault(k, []).append([np.trace(cov[:3, :3]) / DEG ** 2, 1e6 * np.trace(cov[3:, 3:])])
            e = 6 * [(d.j, d.k) for d in res.edges].index((0, k))
            edge = res.problem.covariance[e:e + 6, e:e + 6]
            direct.setdefault(k, []).append([np.trace(edge[:3, :3]) / DEG ** 2, 1e6 * np.trace(edge[3:, 3:])])
            for path, X in chains(res, k).items():
                chain.setdefault((k, path), []).append(errors(X, sims[k].T_ref_k))
    what = ("with tracking gaps" if gaps else "without tracking gaps") + (" and drift" if drift else "")
    print(f"\naccuracy over {seeds} seeds, 30 s, {what} (RMS rotation deg / translation mm):")
    for k, name in enumerate(("cam1", "lidar", "wheels"), 1):
        mine = {path: _rms(v) for (kk, path), v in chain.items() if kk == k}
        best = [min(mine, key=lambda p, c=c: mine[p][c]) for c in (0, 1)]
        j = _rms(joint[k])
        pred = np.sqrt(np.mean(predicted[k], axis=0))
        best_rms = np.array([mine[best[0]][0], mine[best[1]][1]])
        ratio = j / best_rms
        p = [signed_rank_p(np.array(joint[k])[:, c] - np.array(chain[(k, best[c])])[:, c]) for c in (0, 1)]
        se = [_ratio_se(np.array(joint[k])[:, c], np.array(chain[(k, best[c])])[:, c]) for c in (0, 1)]
        model = np.sqrt(np.mean(predicted[k], axis=0) / np.mean(direct[k], axis=0))
        print(f"  {name:<7} joint {j[0]:.4f}° / {j[1]:.3f} mm (model {pred[0]:.4f}° / {pred[1]:.3f} mm)   "
              f"direct {mine[(0, k)][0]:.4f}° / {mine[(0, k)][1]:.3f} mm   best chain "
              f"{'→'.join(map(str, best[0]))} {best_rms[0]:.4f}° / {'→'.join(map(str, best[1]))} {best_rms[1]:.3f} mm"
              f"   joint/best {ratio[0]:.3f} ± {se[0]:.3f} / {ratio[1]:.3f} ± {se[1]:.3f} (p joint worse "
              f"{p[0]:.2g} / {p[1]:.2g}; model joint/direct {model[0]:.3f} / {model[1]:.3f})")


def detection(seeds: int) -> None:
    from handeye_cli.rig import RigOptions, calibrate_rig
    from handeye_cli.rig.joint import CONSISTENCY_P_VALUE
    from handeye_cli.rig.simulate import FAULTS, simulate_streams, with_fault

    offsets = {"cam1": OFFSETS_NS[1] / 1e9, "lidar": OFFSETS_NS[2] / 1e9, "wheels": OFFSETS_NS[3] / 1e9}
    print(f"\nbad-stream naming over {seeds} seeds, 30 s, with tracking gaps (p < {CONSISTENCY_P_VALUE:g}):")
    for drift in (False, True):
        named, p_values = 0, []
        for seed in range(seeds):
            res = calibrate_rig(simulate_streams(sensors(seed, True, drift), duration_s=30, seed=seed),
                                RigOptions(time_offsets=offsets))
            named += res.consistency.suspect is not None
            p_values.append(res.consistency.p_value)
        print(f"  clean{' and drifting' if drift else ''}: a stream named on {named}/{seeds}, "
              f"median p {np.median(p_values):.2f}")
    for fault in FAULTS:
        right, wrong = 0, 0
        for seed in range(seeds):
            bad = 1 + seed % 3
            sims, error = with_fault(sensors(seed, True, True), bad, fault, np.random.default_rng(1000 + seed))
            given = {**offsets, sims[bad].name: offsets[sims[bad].name] + error}
            res = calibrate_rig(simulate_streams(sims, duration_s=30, seed=seed), RigOptions(time_offsets=given))
            right += res.consistency.suspect == bad
            wrong += res.consistency.suspect not in (None, bad)
        print(f"  {fault:<6} (drifting): the bad stream named on {right}/{seeds}, another on {wrong}")


def _write_log(path: Path, minutes: float) -> tuple[list, dict]:
    from _logs import POSE, TF, pose_channel, records, write_mcap

    from handeye_cli.rig.simulate import simulate_streams

    sims = sensors(0, gaps=False, drift=True)
    streams = simulate_streams(sims, duration_s=60 * minutes, seed=0)
    names, topics = ("cam0", "cam1", "lidar"), ["/cam0/pose", "/cam1/pose", "/lidar/pose"]
    channels = [pose_channel(t, POSE, records(streams[n], f"w_{n}", n)) for t, n in zip(topics, names, strict=True)]
    write_mcap(path, [*channels, pose_channel("/tf", TF, records(streams["wheels"], "odom", "wheels"))])
    return sims, streams


def _cli(args: list[str]) -> float:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "handeye_cli", *args], check=True, env=env, capture_output=True)
    return time.perf_counter() - t0


def _fastest(runs: list[tuple[str, Callable[[], object]]], repeat: int) -> tuple[dict[str, float], dict[str, float]]:
    """The fastest of ``repeat`` timings [s] of each named call, the calls interleaved: wall-clock time, and the
    process's CPU time (every thread's; steadier under other load, which slows the wall clock by up to 2×)."""
    best = {name: float("inf") for name, _ in runs}
    cpu = dict(best)
    for _ in range(repeat):
        for name, call in runs:
            t0, c0 = time.perf_counter(), time.process_time()
            call()
            best[name] = min(best[name], time.perf_counter() - t0)
            cpu[name] = min(cpu[name], time.process_time() - c0)
    return best, cpu


def timing(minutes: float, repeat: int) -> None:
    from handeye_cli.calibration import calibrate_files
    from handeye_cli.io import read_log_streams
    from handeye_cli.options import Options
    from handeye_cli.rig import RigOptions, calibrate_rig_files, parse_stream, read_rig
    from handeye_cli.rig.pairwise import clock_offsets, solve_edges
    from handeye_cli.stages import timeoffset  # noqa: F401  (scipy.signal: imported before any timing)

    with tempfile.TemporaryDirectory() as d:
        log = Path(d) / "rig4.mcap"
        sims, streams = _write_log(log, minutes)
        specs = [parse_stream(s) for s in STREAMS]
        read_rig(str(log), specs[:2])                                  # warm: readers, page cache
        read = list(read_rig(str(log), specs).values())
        offsets = clock_offsets(read, 0, {}, Options())
        out = ["-q", "-o", str(Path(d) / "out.yaml")]
        rig_cli = ["rig", str(log), *[a for s in STREAMS for a in ("--stream", s)], *out]
        one_cli = ["calibrate", str(log), "--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose", "--time-offset",
                   "auto", *out]
        t, cpu = _fastest([
            ("read one", lambda: read_rig(str(log), specs)),
            ("read three", lambda: [read_log_streams(log, [("/cam0/pose", None), (spec.topic, spec.frames)])
                                    for spec in specs[1:]]),
            ("rig", lambda: calibrate_rig_files(str(log), specs, RigOptions())),
            ("one", lambda: calibrate_files(log, topic_a="/cam0/pose", topic_b="/cam1/pose", time_offset="auto")),
            ("offsets", lambda: clock_offsets(read, 0, {}, Options())),
            ("edges", lambda: solve_edges(read, [s.name for s in specs], offsets, Options())),
            ("pairs", lambda: [calibrate_files(log, topic_a="/cam0/pose", topic_b=spec.topic, frames_b=spec.frames,
                                               time_offset="auto") for spec in specs[1:]]),
            ("rig cli", lambda: _cli(rig_cli)),
            ("one cli", lambda: _cli(one_cli)),
        ], repeat)
        cli_pairs = [_cli(["calibrate", str(log), "--topic-a", "/cam0/pose",
                           *(["--topic-b", spec.topic] if spec.topic else ["--frames-b", *spec.frames]),
                           "--time-offset", "auto", *out]) for spec in specs[1:]]
        res = calibrate_rig_files(str(log), specs, RigOptions())
        size = log.stat().st_size / 1e6
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"\ntime, {minutes:g}-minute 4-stream MCAP ({size:.1f} MB, {sum(map(len, streams.values()))} poses), "
          f"auto clock offsets, fastest of {repeat}, load average {load} (1, 5, 15 min); one warm process:")
    print(f"  read:      one pass of all 4 streams {t['read one']:.2f} s   vs 3 passes of 2 streams "
          f"{t['read three']:.2f} s")
    print(f"  calibrate: handeye rig (6 pairs, joint) {t['rig']:.2f} s   vs one calibrate cam0-cam1 {t['one']:.2f} s: "
          f"rig / one calibrate {t['rig'] / t['one']:.2f}   (3 pairwise calibrate runs {t['pairs']:.2f} s)")
    print(f"             in CPU time rig {cpu['rig']:.2f} s vs one calibrate {cpu['one']:.2f} s: rig / one calibrate "
          f"{cpu['rig'] / cpu['one']:.2f}")
    print(f"  rig stages: 3 clock offsets {t['offsets']:.2f} s, 6 pairwise solves {t['edges']:.2f} s, "
          f"read + noise model + joint + rest {max(t['rig'] - t['offsets'] - t['edges'], 0.0):.2f} s")
    print(f"  command lines: handeye rig {t['rig cli']:.2f} s   vs handeye calibrate cam0-cam1 --time-offset auto "
          f"{t['one cli']:.2f} s: rig / one calibrate {t['rig cli'] / t['one cli']:.2f}   "
          f"(3 of them, once each, {sum(cli_pairs):.2f} s)")
    print("  joint errors:", ", ".join(f"{n} {errors(res.matrices[k], sims[k].T_ref_k)[0]:.3f}° / "
                                       f"{errors(res.matrices[k], sims[k].T_ref_k)[1]:.2f} mm"
                                       for k, n in enumerate(res.names) if k))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--skip-accuracy", action="store_true")
    ap.add_argument("--skip-detection", action="store_true")
    ap.add_argument("--skip-time", action="store_true")
    args = ap.parse_args()
    if not args.skip_accuracy:
        accuracy(args.seeds, gaps=False, drift=False)
        accuracy(args.seeds, gaps=True, drift=False)
        accuracy(args.seeds, gaps=True, drift=True)
    if not args.skip_detection:
        detection(args.seeds)
    if not args.skip_time:
        timing(args.minutes, args.repeat)


if __name__ == "__main__":
    main()
