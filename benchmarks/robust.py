"""Outlier rejection: error of X with gross outliers among the pairs, against the outlier-free error.

Setup: the paper's random scenario (appendix D.2), σr = 0.57°, σt = 1 cm, N pairs; a fraction of
the pairs is replaced by gross outliers (A_i or B_i becomes a random motion: uniform rotation,
translation U(-1, 1)³ m). Per trial, measured in the same run:

* ``clean``   — dqopt on the outlier-free pairs (the reference error),
* ``plain``   — dqopt on the contaminated pairs (the baseline without --robust),
* ``robust``  — :func:`robust_solve` on the contaminated pairs,
* ``robust0`` — :func:`robust_solve` on the outlier-free pairs (cost of robustness on good data).

Prints median rotation error [deg] and translation error [mm] over the trials, the ratio
robust / clean (target ≤ 1.5; anchors: ETH RANSAC degrades 2.5×), outlier recall and the number
of good pairs lost, and the median time of one robust_solve call.

    python benchmarks/robust.py [--trials 50] [--pairs 100 1000] [--fractions 0.1 0.2 0.3]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from handeye_cli.analysis import extrinsic_error, robust_solve
from handeye_cli.simulation import motion_pairs, random_transform
from handeye_cli.solvers import solve

SIGMA_R, SIGMA_T = np.deg2rad(0.57), 0.01


def contaminate(A: np.ndarray, B: np.ndarray, fraction: float, rng: np.random.Generator):
    """Replace a fraction of the pairs: A_i or B_i (coin flip) becomes a random motion."""
    A, B = A.copy(), B.copy()
    bad = rng.choice(len(A), int(round(fraction * len(A))), replace=False)
    for i in bad:
        (A if rng.random() < 0.5 else B)[i] = random_transform(rng)
    return A, B, bad


def trial(seed: int, n: int, fraction: float) -> dict:
    rng = np.random.default_rng(seed)
    X = random_transform(rng)
    A, B = motion_pairs(n, X, rng, "random", SIGMA_R, SIGMA_T)
    Ac, Bc, bad = contaminate(A, B, fraction, rng)
    t0 = time.perf_counter()
    r = robust_solve(Ac, Bc, seed=seed)
    dt = time.perf_counter() - t0
    rejected = set(r.rejected.tolist())
    return {"clean": extrinsic_error(solve(A, B).matrix, X), "plain": extrinsic_error(solve(Ac, Bc).matrix, X),
            "robust": extrinsic_error(r.solution.matrix, X),
            "robust0": extrinsic_error(robust_solve(A, B, seed=seed).solution.matrix, X),
            "recall": len(rejected & set(bad.tolist())) / max(len(bad), 1),
            "lost": len(rejected - set(bad.tolist())), "time": dt}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=50)
    ap.add_argument("--pairs", type=int, nargs="+", default=[100, 1000])
    ap.add_argument("--fractions", type=float, nargs="+", default=[0.1, 0.2, 0.3])
    args = ap.parse_args()
    print(f"random scenario, σr=0.57°, σt=1 cm, {args.trials} trials; medians; errors rot [deg] / trans [mm]")
    head = (f"{'N':>5} {'outl':>5} | {'clean':>15} | {'plain dqopt':>15} | {'robust':>15} | {'robust, clean':>15}"
            f" | {'ratio rob/clean':>16} | {'recall':>6} {'lost':>5} | {'time':>7}")
    print(head)
    print("-" * len(head))
    for n in args.pairs:
        for frac in args.fractions:
            rows = [trial(1000 * n + s, n, frac) for s in range(args.trials)]
            med = {k: np.median([r[k] for r in rows], axis=0) for k in ("clean", "plain", "robust", "robust0")}
            ratio = med["robust"] / med["clean"]

            def fmt(e):
                return f"{e[0]:7.4f} / {1e3 * e[1]:5.2f}"
            print(f"{n:>5} {frac:>5.0%} | {fmt(med['clean'])} | {fmt(med['plain'])} | {fmt(med['robust'])} | "
                  f"{fmt(med['robust0'])} | {ratio[0]:6.3f} / {ratio[1]:6.3f} | "
                  f"{np.mean([r['recall'] for r in rows]):6.1%} {np.mean([r['lost'] for r in rows]):5.1f} | "
                  f"{1e3 * np.median([r['time'] for r in rows]):5.1f}ms")
    print("target: ratio rob/clean ≤ 1.5 (rotation and translation) at 10 % outliers")


if __name__ == "__main__":
    main()
