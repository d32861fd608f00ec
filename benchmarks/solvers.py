"""Solver speed and the paper's Table 1 (upper part), measured in one run on this machine.

Prints (1) the median wall time of one ``handeye_cli.solve`` call per method — validation and
building the matrices included — for N = 100 (the paper's setting), 1,000 and 10,000 motions,
with its ratio to ``daniilidis`` measured in the same run; (2) the relative cost excess
``(c - c_dqopt) / (c + c_dqopt)`` of each approximation over dqopt on synthetic problems with
the paper's noise (σr = 0.57°, σt = 1 cm, random scenario, N = 100); (3) the time of the optimality
certificate (``solvers/certificate.py``) beside a dqopt solve of N = 100 motions.

    python benchmarks/solvers.py [--problems 1000] [--repeats 200]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from handeye_cli.simulation import motion_pairs, random_transform
from handeye_cli.solvers import METHODS, solve
from handeye_cli.solvers.certificate import certify

SIGMA_R, SIGMA_T = np.deg2rad(0.57), 0.01
PAPER_US = {"dqopt": 299, "dq2ndord": 155, "daniilidis": 92, "dqconvrlx": 77, "dq2steps": 63}
PAPER_EXCESS = {"dq2ndord": 6.6e-10, "dqconvrlx": 2.7e-5, "dq2steps": 8.4e-3}


def median_time(A: np.ndarray, B: np.ndarray, method: str, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        solve(A, B, method=method)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def timing(repeats: int) -> None:
    print("== time per solve (median; validation + matrices + solve), ratio to daniilidis in this run ==")
    rng = np.random.default_rng(0)
    X = random_transform(rng)
    sizes = (100, 1_000, 10_000)
    print(f"{'method':<11}" + "".join(f"{'N=' + str(n):>22}" for n in sizes) + f"{'paper N=100':>14}")
    rows = {}
    for n in sizes:
        A, B = motion_pairs(n, X, rng, sigma_r=SIGMA_R, sigma_t=SIGMA_T)
        reps = max(15, repeats * 100 // n)
        for m in METHODS:
            solve(A, B, method=m)                       # warm-up
        # Interleave methods so that machine load affects them alike.
        t = {m: [] for m in METHODS}
        for _ in range(3):
            for m in METHODS:
                t[m].append(median_time(A, B, m, max(1, reps // 3)))
        for m in METHODS:
            rows.setdefault(m, {})[n] = float(np.median(t[m]))
    for m in METHODS:
        cells = ""
        for n in sizes:
            sec = rows[m][n]
            ratio = sec / rows["daniilidis"][n]
            cells += f"{sec * 1e6:>12.0f} µs ×{ratio:>5.2f}" if n < 10_000 else f"{sec * 1e3:>12.2f} ms ×{ratio:>5.2f}"
        paper = f"{PAPER_US[m]} µs" if m in PAPER_US else "-"
        print(f"{m:<11}{cells}{paper:>14}")
    per = {n: rows["dqopt"][n] / n * 1e6 for n in sizes}
    print("dqopt µs per motion: " + ", ".join(f"N={n}: {v:.2f}" for n, v in per.items()) +
          "  (linear growth: roughly constant per motion once fixed costs are amortised)")
    print(f"paper: dqopt/daniilidis = {PAPER_US['dqopt'] / PAPER_US['daniilidis']:.2f}; "
          f"here at N=100: {rows['dqopt'][100] / rows['daniilidis'][100]:.2f}")


def table1(problems: int) -> None:
    print(f"\n== Table 1 (upper): relative cost excess over dqopt, {problems} problems, N=100, "
          f"σr=0.57°, σt=1 cm ==")
    excess = {m: [] for m in ("dq2ndord", "dqconvrlx", "dq2steps", "dqitr", "daniilidis")}
    unconverged = 0
    for seed in range(problems):
        rng = np.random.default_rng(10_000 + seed)
        A, B = motion_pairs(100, random_transform(rng), rng, sigma_r=SIGMA_R, sigma_t=SIGMA_T)
        c0 = solve(A, B).cost
        for m in excess:
            r = solve(A, B, method=m)
            unconverged += m == "dqitr" and not r.converged
            excess[m].append((r.cost - c0) / (r.cost + c0))
    print(f"{'method':<11}{'mean':>11}{'std':>11}{'min':>11}{'max':>11}{'paper mean':>12}")
    for m, e in excess.items():
        e = np.asarray(e)
        paper = f"{PAPER_EXCESS[m]:.1e}" if m in PAPER_EXCESS else "-"
        print(f"{m:<11}{e.mean():>11.2e}{e.std():>11.2e}{e.min():>11.2e}{e.max():>11.2e}{paper:>12}")
    print(f"dqitr did not converge on {unconverged} of {problems} problems; "
          "min < 0 would mean a method beat the optimum (it must be ≥ -1e-12, rounding).")


def certificate_cost(repeats: int) -> None:
    print("\n== optimality certificate: time beside a dqopt solve, N=100 (medians, interleaved) ==")
    rng = np.random.default_rng(1)
    A, B = motion_pairs(100, random_transform(rng), rng, sigma_r=SIGMA_R, sigma_t=SIGMA_T)
    sol = solve(A, B)
    assert sol.problem is not None and sol.dual_quaternion is not None
    problem, (q, qd) = sol.problem, sol.dual_quaternion
    t_solve, t_cert = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        solve(A, B)
        t1 = time.perf_counter()
        certify(problem, q, qd)
        t_cert.append(time.perf_counter() - t1)
        t_solve.append(t1 - t0)
    s, c = float(np.median(t_solve)), float(np.median(t_cert))
    print(f"dqopt solve {s * 1e6:.0f} µs, certificate {c * 1e6:.1f} µs: +{100 * c / s:.1f} % "
          f"(certified: {sol.certificate.certified if sol.certificate else None})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--problems", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=200)
    args = ap.parse_args()
    timing(args.repeats)
    table1(args.problems)
    certificate_cost(args.repeats * 10)


if __name__ == "__main__":
    main()
