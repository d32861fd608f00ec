"""Automatic α against the best α of a sweep, on the paper's synthetic scenarios (appendix D.2).

Per scenario (random, line, circle; N = 100 pairs, σr = 0.57°, σt = 1 cm, the paper's jitter
on line/circle) and trial, in the same run: dqopt at every α of the paper's sweep (25 values,
log-spaced 10⁻² … 10^1.7 [1/m]), at ``auto_alpha`` (sandwich-predicted error), at
``residual_ratio_alpha`` (σ_rot/σ_trans from residuals, iterated twice) and at the default α = 1.
Prints the mean rotation [deg] and translation [cm] errors over the trials (the paper picks α
by the mean), the best sweep α for each, and each method's ratio to the sweep best
(target ≤ 1.2 for both errors). The paper's Table 2 DQOpt medians are quoted for orientation.

    python benchmarks/alpha.py [--trials 60] [--pairs 100]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from handeye_cli.analysis import auto_alpha, extrinsic_error, residual_ratio_alpha
from handeye_cli.simulation import motion_pairs, random_transform
from handeye_cli.solvers import solve

SIGMA_R, SIGMA_T = np.deg2rad(0.57), 0.01
SWEEP = np.logspace(-2.0, 1.7, 25)
PAPER = {"random": "0.0523° / 0.186 cm", "circle": "6.29° / 42.5 cm", "line": "8.31° / 45.3 cm"}


def run(scenario: str, trials: int, n: int) -> None:
    sweep = np.zeros((len(SWEEP), 2))
    rows = {"auto (sandwich)": np.zeros(2), "residual ratio": np.zeros(2), "alpha = 1": np.zeros(2)}
    chosen, t_auto = [], 0.0
    for seed in range(trials):
        rng = np.random.default_rng(seed)
        X = random_transform(rng)
        A, B = motion_pairs(n, X, rng, scenario, SIGMA_R, SIGMA_T)
        sweep += [extrinsic_error(solve(A, B, alpha=a).matrix, X) for a in SWEEP]
        t0 = time.perf_counter()
        a_auto = auto_alpha(A, B).alpha
        t_auto += time.perf_counter() - t0
        a_rr = residual_ratio_alpha(A, B).alpha
        chosen.append((a_auto, a_rr))
        for name, a in zip(rows, (a_auto, a_rr, 1.0), strict=True):
            rows[name] += extrinsic_error(solve(A, B, alpha=a).matrix, X)
    sweep /= trials
    best = sweep.min(axis=0)
    arg = sweep.argmin(axis=0)
    med = np.median(chosen, axis=0)
    print(f"\n{scenario}: sweep best rot {best[0]:.4f}° at α={SWEEP[arg[0]]:.3g}, "
          f"trans {100 * best[1]:.3f} cm at α={SWEEP[arg[1]]:.3g}   (paper DQOpt medians: {PAPER[scenario]})")
    for name, err in rows.items():
        e = err / trials
        alpha = {"auto (sandwich)": f"median α {med[0]:.3g}", "residual ratio": f"median α {med[1]:.3g}",
                 "alpha = 1": "α 1"}[name]
        print(f"  {name:<16} rot {e[0]:8.4f}°  trans {100 * e[1]:7.3f} cm   ratio to best  rot {e[0] / best[0]:5.3f}"
              f"  trans {e[1] / best[1]:5.3f}   ({alpha})")
    print(f"  auto_alpha time {1e3 * t_auto / trials:.0f} ms per call")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=60)
    ap.add_argument("--pairs", type=int, default=100)
    args = ap.parse_args()
    print(f"mean errors over {args.trials} trials, N={args.pairs}; target: auto within 1.2x of the sweep best")
    for scenario in ("random", "line", "circle"):
        run(scenario, args.trials, args.pairs)


if __name__ == "__main__":
    main()
