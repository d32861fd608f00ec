"""Benchmark of ``estimate_time_offset`` against the issue-4 target and the existing tools.

Each seeded trial simulates a rigid rig (:func:`handeye_cli.simulation.simulate_rig`): stream a at
100 Hz for ``--duration`` s, stream b at 30 Hz covering only a ``--b-duration`` s stretch of it (as
in the anchors' protocol, notes/anchors.md d3), both with absolute pose noise σ = ``--sigma-deg``
and ``--sigma-mm``, and b's clock ahead of a's by an offset drawn uniformly in ±``--max-offset`` s,
so most trials' raw time spans do not even overlap. No search window is given to the estimator.

Prints one row per trial (true offset [s], error [ms], the reported 1-σ [ms], peak correlation,
time per estimate [ms]) and a summary: median and max |error| [ms], the fraction within 1 ms,
the mean time per estimate, and the anchors' figures.

Run from the repository root: ``python benchmarks/timeoffset.py [--trials 25]``.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from handeye_cli.simulation import Rig, random_transform, simulate_rig
from handeye_cli.stages.timeoffset import estimate_time_offset

TARGET_MS = 1.0
ANCHORS = ("kinhec estimate_time_offset: <= 2 ms, only inside its default +-0.5 s search window",
           "ETH hand_eye_calibration calculate_time_offset: <= 44 ms (30 Hz vs 100 Hz)")


def trial(k: int, args: argparse.Namespace) -> tuple[float, float, float, float, float]:
    """One seeded trial: (true offset [s], error [ms], reported std [ms], correlation, time [s])."""
    rng = np.random.default_rng([args.seed, k])
    offset_ns = int(round(rng.uniform(-args.max_offset, args.max_offset) * 1e9))
    a, b = simulate_rig(Rig(random_transform(rng, 0.3), offset_ns), duration_s=args.duration, rate_a=100,
                        rate_b=30, sigma_r=np.deg2rad(args.sigma_deg), sigma_t=args.sigma_mm / 1e3,
                        seed=int(rng.integers(2**31)))
    start = b.stamps_ns[0] + int(rng.uniform(0, args.duration - args.b_duration) * 1e9)
    b = b.select((b.stamps_ns >= start) & (b.stamps_ns < start + int(args.b_duration * 1e9)))
    t = time.perf_counter()
    est = estimate_time_offset(a, b)
    elapsed = time.perf_counter() - t
    return offset_ns / 1e9, (est.offset_ns - offset_ns) / 1e6, est.std_ns / 1e6, est.correlation, elapsed


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=25)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--duration", type=float, default=60.0, help="stream a's length [s]")
    parser.add_argument("--b-duration", type=float, default=45.0, help="stream b's length [s]")
    parser.add_argument("--max-offset", type=float, default=300.0, help="offsets drawn in +-this [s]")
    parser.add_argument("--sigma-deg", type=float, default=0.1, help="rotation noise per pose [deg]")
    parser.add_argument("--sigma-mm", type=float, default=2.0, help="translation noise per pose [mm]")
    args = parser.parse_args(argv)

    print(f"time offset: a 100 Hz x {args.duration:g} s, b 30 Hz x {args.b_duration:g} s, noise "
          f"{args.sigma_deg:g} deg / {args.sigma_mm:g} mm, offsets uniform in +-{args.max_offset:g} s, "
          f"{args.trials} trials (seed {args.seed})")
    print(f"{'trial':>5} {'offset [s]':>12} {'error [ms]':>11} {'std [ms]':>9} {'corr':>6} {'time [ms]':>10}")
    rows = []
    for k in range(args.trials):
        rows.append(trial(k, args))
        offset, err, std, corr, elapsed = rows[-1]
        print(f"{k:5d} {offset:12.6f} {err:11.4f} {std:9.4f} {corr:6.3f} {elapsed * 1e3:10.1f}")
    errors = np.abs([r[1] for r in rows])
    within = float(np.mean(errors <= TARGET_MS))
    print(f"summary: median |error| {np.median(errors):.4f} ms, max |error| {errors.max():.4f} ms, "
          f"within {TARGET_MS:g} ms: {within:.0%}, mean time per estimate {np.mean([r[4] for r in rows]) * 1e3:.0f} ms")
    print(f"target (issue 4): <= {TARGET_MS:g} ms anywhere in +-300 s -> "
          f"{'met' if errors.max() <= TARGET_MS else 'MISSED'}")
    for anchor in ANCHORS:
        print(f"anchor: {anchor}")


if __name__ == "__main__":
    main()
