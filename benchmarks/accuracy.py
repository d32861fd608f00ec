"""Accuracy of the defaults against every fixed pair strategy and the best fixed α in hindsight.

Per scenario of :data:`handeye_cli.simulation.recordings.SCENARIOS` (drifting VIO on both
streams, VIO vs motion capture, motion capture vs a target camera, a continuous robot arm, a
200 Hz / 15 Hz rate mix, a clock offset with tracking jumps) and seed, in the same run:

* **defaults**: :func:`handeye_cli.calibrate` with no option but ``time_offset="auto"`` where the
  clocks differ — what ``handeye calibrate a b [--time-offset auto]`` does;
* every fixed strategy (keyframes, all capped at 2000 pairs, consecutive, stride:K) on the same
  synced and gated samples, solved with dqopt at each α of a grid (0.03 … 10 [1/m]);
* **park, same pairs**: the rotation-first solver on the defaults' pairs and weights (issue 19:
  the defaults' rotation must not lose to it by more than 1.2× on VIO against motion capture).

Printed per scenario: mean rotation [deg] and translation [mm] error vs truth over the seeds for
the defaults, each strategy at α = 1 and at its best α in hindsight, and the ratio default/best
where *best* is the lowest mean error of any (strategy, α) — separately for rotation and
translation (goal: ≤ 1.2 for both). The α chosen by the defaults and the noise model's verdict
(drifting / absolute) are shown too.

    python benchmarks/accuracy.py [--seeds 12] [--duration 60] [--scenarios vio-vio,arm]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from handeye_cli import calibrate
from handeye_cli.analysis import extrinsic_error
from handeye_cli.simulation.recordings import SCENARIOS, scenario
from handeye_cli.solvers import solve
from handeye_cli.stages.pairs import make_pairs

STRATEGIES = ("keyframes", "all", "consecutive", "stride:5", "stride:15", "stride:30", "stride:90")
ALPHAS = np.array([0.03, 0.1, 0.3, 1.0, 3.0, 10.0])


def run_seed(name: str, seed: int, duration: float) -> tuple[np.ndarray, np.ndarray, float, str, float, np.ndarray]:
    """(default error (2,), fixed errors (strategies, alphas, 2), default α, noise kind, default seconds,
    park's error on the defaults' pairs (2,))."""
    rec = scenario(name, seed, duration)
    t0 = time.perf_counter()
    cal = calibrate(rec.a, rec.b, time_offset="auto" if rec.rig.time_offset_ns else 0.0)
    seconds = time.perf_counter() - t0
    truth = rec.rig.T_a_b
    fixed = np.full((len(STRATEGIES), len(ALPHAS), 2), np.nan)
    for s, strategy in enumerate(STRATEGIES):
        pairs, _ = make_pairs(cal.synced, strategy)
        if len(pairs) < 3:
            continue
        for k, alpha in enumerate(ALPHAS):
            fixed[s, k] = extrinsic_error(solve(pairs.A, pairs.B, alpha=float(alpha)).matrix, truth)
    kind = cal.diagnostics.get("noise_model", {}).get("kind") or "-"
    park = extrinsic_error(solve(cal.pairs.A, cal.pairs.B, method="park", weights=cal.weights).matrix, truth)
    return np.array(extrinsic_error(cal.matrix, truth)), fixed, cal.solution.alpha, kind, seconds, np.array(park)


def report(name: str, default: np.ndarray, fixed: np.ndarray, alphas: list[float], kinds: list[str],
           seconds: float, park: np.ndarray) -> tuple[float, float, float]:
    """Print one scenario's table; return the ratios default/best (rotation, translation) and the
    defaults' rotation / park's on the same pairs."""
    best = np.nanmin(fixed.reshape(-1, 2), axis=0)
    where = [np.unravel_index(np.nanargmin(fixed[..., m]), fixed.shape[:2]) for m in range(2)]
    ratio = default / best
    print(f"\n{name}: {SCENARIOS[name][1]}")
    print(f"  {'defaults':<13} rot {default[0]:8.4f}°  trans {1e3 * default[1]:8.3f} mm   "
          f"(α median {np.median(alphas):.3g}, noise model: {max(set(kinds), key=kinds.count)}, "
          f"{seconds:.2f} s per calibrate)")
    for s, strategy in enumerate(STRATEGIES):
        e1 = fixed[s, int(np.flatnonzero(ALPHAS == 1.0)[0])]
        eb = np.nanmin(fixed[s], axis=0)
        print(f"  {strategy:<13} rot {e1[0]:8.4f}°  trans {1e3 * e1[1]:8.3f} mm   at best α: "
              f"rot {eb[0]:8.4f}°  trans {1e3 * eb[1]:8.3f} mm")
    print(f"  best in hindsight: rot {best[0]:.4f}° ({STRATEGIES[where[0][0]]}, α {ALPHAS[where[0][1]]:g}), "
          f"trans {1e3 * best[1]:.3f} mm ({STRATEGIES[where[1][0]]}, α {ALPHAS[where[1][1]]:g})")
    print(f"  park, same pairs rot {park[0]:8.4f}°  trans {1e3 * park[1]:8.3f} mm")
    print(f"  ratio defaults / best:  rot {ratio[0]:.2f}  trans {ratio[1]:.2f};  "
          f"rot defaults / park {default[0] / park[0]:.2f}")
    return float(ratio[0]), float(ratio[1]), float(default[0] / park[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=12)
    parser.add_argument("--duration", type=float, default=60.0, help="seconds per recording")
    parser.add_argument("--scenarios", default=",".join(SCENARIOS))
    args = parser.parse_args()
    t0 = time.perf_counter()
    worst = []
    for name in args.scenarios.split(","):
        runs = [run_seed(name, seed, args.duration) for seed in range(args.seeds)]
        default = np.mean([r[0] for r in runs], axis=0)
        fixed = np.mean([r[1] for r in runs], axis=0)
        worst.append((name, *report(name, default, fixed, [r[2] for r in runs], [r[3] for r in runs],
                                    float(np.mean([r[4] for r in runs])), np.mean([r[5] for r in runs], axis=0))))
    print("\nsummary (defaults / best fixed strategy and α in hindsight, and rotation / park on the same pairs; "
          "goal ≤ 1.2):")
    for name, rot, trans, park in worst:
        print(f"  {name:<17} rot {rot:5.2f}  trans {trans:5.2f}  rot/park {park:5.2f}  "
              f"{'ok' if max(rot, trans, park) <= 1.2 else 'MISSED'}")
    print(f"{args.seeds} seeds × {args.duration:g} s per scenario; total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
