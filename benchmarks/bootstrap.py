"""Bootstrap uncertainty: speed, and coverage of the 95 % intervals against known truth.

(1) Speed: ``bootstrap(A, B, 1000)`` on 1,000 pairs (median of 3 runs) against the naive loop,
    measured in the same run: ``solve(A, B, weights=counts)`` per replicate (timed on 50
    replicates, scaled to 1,000).
(2) Coverage: per trial a new X and new pairs (the paper's random scenario, σr = 0.57°,
    σt = 1 cm); the fraction of trials whose 95 % interval contains the true value, per axis of
    the rotation perturbation (frame a) and of the translation. Also the RMS over the trials of
    the actual error divided by the bootstrap standard deviation (1 = calibrated; above 1 =
    optimistic), and the same for the sandwich covariance (``linear_covariance``).

(3) Pairs that share pose samples: a simulated rig (``simulate_rig``: 40 s, 30/12 Hz, absolute
    pose noise 0.2° / 2 mm) paired by the ``keyframes`` and ``consecutive`` strategies; coverage
    and RMS(error / std) of the pairs bootstrap against the samples (vertex) bootstrap
    (``samples=(pairs.i, pairs.j)``).

    python benchmarks/bootstrap.py [--trials 200] [--replicates 1000] [--pairs 40 100 1000] [--rigs 30]
"""
from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.spatial.transform import Rotation

from handeye_cli.analysis import bootstrap, linear_covariance
from handeye_cli.simulation import motion_pairs, random_transform
from handeye_cli.solvers import solve

SIGMA_R, SIGMA_T = np.deg2rad(0.57), 0.01


def speed() -> None:
    rng = np.random.default_rng(0)
    X = random_transform(rng)
    A, B = motion_pairs(1000, X, rng, "random", SIGMA_R, SIGMA_T)
    runs = []
    for k in range(3):
        t0 = time.perf_counter()
        bootstrap(A, B, 1000, seed=k)
        runs.append(time.perf_counter() - t0)
    counts = rng.multinomial(1000, np.full(1000, 1e-3), size=50)
    t0 = time.perf_counter()
    for c in counts:
        solve(A, B, weights=c)
    naive = (time.perf_counter() - t0) / 50 * 1000
    fast = float(np.median(runs))
    print("== speed: 1,000 replicates on 1,000 pairs ==")
    print(f"bootstrap(): {fast:.3f} s   naive solve(weights=counts) loop: {naive:.2f} s   "
          f"speed-up {naive / fast:.1f}x")


def coverage(n: int, trials: int, replicates: int) -> None:
    hits, errors, boot_std, cov_std = np.zeros(6), [], [], []
    t0 = time.perf_counter()
    for trial in range(trials):
        rng = np.random.default_rng(10_000 * n + trial)
        X = random_transform(rng)
        A, B = motion_pairs(n, X, rng, "random", SIGMA_R, SIGMA_T)
        b = bootstrap(A, B, replicates, seed=trial)
        r_in, t_in = b.contains(X)
        hits += np.r_[r_in, t_in]
        errors.append(np.r_[np.rad2deg(Rotation.from_matrix(X[:3, :3] @ b.matrix[:3, :3].T).as_rotvec()),
                            X[:3, 3] - b.matrix[:3, 3]])
        boot_std.append(np.r_[b.rotation_std_deg, b.translation_std_m])
        c = linear_covariance(A, B, b.matrix)
        cov_std.append(np.r_[c.rotation_std_deg, c.translation_std_m])
    errors = np.array(errors)
    cover = " ".join(f"{100 * h / trials:5.1f}" for h in hits)
    calib_b = " ".join(f"{v:5.2f}" for v in np.sqrt(np.mean((errors / np.array(boot_std)) ** 2, axis=0)))
    calib_c = " ".join(f"{v:5.2f}" for v in np.sqrt(np.mean((errors / np.array(cov_std)) ** 2, axis=0)))
    print(f"{n:>6} {trials:>6} | {cover} | {calib_b} | {calib_c} | {time.perf_counter() - t0:6.1f}s")


def rig_trial(seed: int, strategy: str, replicates: int) -> list[np.ndarray]:
    from handeye_cli.simulation import Rig, simulate_rig
    from handeye_cli.stages.pairs import make_pairs
    from handeye_cli.stages.sync import associate
    X = random_transform(np.random.default_rng(seed), 0.3)
    a, b = simulate_rig(Rig(X), duration_s=40, rate_a=30, rate_b=12, sigma_r=np.deg2rad(0.2), sigma_t=0.002,
                        seed=seed)
    pairs, _ = make_pairs(associate(a, b)[0], strategy, max_pairs=1000)
    out = []
    for samples in (None, (pairs.i, pairs.j)):
        b = bootstrap(pairs.A, pairs.B, replicates, seed=seed, samples=samples)
        err = np.r_[np.rad2deg(Rotation.from_matrix(X[:3, :3] @ b.matrix[:3, :3].T).as_rotvec()),
                    X[:3, 3] - b.matrix[:3, 3]]
        out.append(np.r_[np.concatenate(b.contains(X)), err / np.r_[b.rotation_std_deg, b.translation_std_m]])
    return out


def rigs(trials: int, replicates: int) -> None:
    print(f"\n== simulated rig, pairs sharing samples ({trials} rigs, {replicates} replicates) ==")
    print(f"{'strategy':<12} {'resample':<8} | {'coverage [%]':^35} | {'RMS(error / std)':^35}")
    for strategy in ("keyframes", "consecutive"):
        res = np.array([rig_trial(s, strategy, replicates) for s in range(trials)])     # (T, 2, 12)
        for k, name in enumerate(("pairs", "samples")):
            cover = " ".join(f"{100 * v:5.1f}" for v in res[:, k, :6].mean(axis=0))
            z = " ".join(f"{v:5.2f}" for v in np.sqrt(np.mean(res[:, k, 6:] ** 2, axis=0)))
            print(f"{strategy:<12} {name:<8} | {cover} | {z}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--replicates", type=int, default=1000)
    ap.add_argument("--pairs", type=int, nargs="+", default=[40, 100, 1000])
    ap.add_argument("--rigs", type=int, default=30)
    args = ap.parse_args()
    speed()
    print(f"\n== coverage of 95 % intervals ({args.replicates} replicates; random scenario, σr=0.57°, σt=1 cm) ==")
    print("columns per block: rot x y z, trans x y z (frame a)")
    print(f"{'pairs':>6} {'trials':>6} | {'coverage [%]':^35} | {'RMS(error / boot std)':^35} | "
          f"{'RMS(error / sandwich std)':^35} | time")
    for n in args.pairs:
        coverage(n, args.trials if n <= 100 else max(args.trials // 4, 1), args.replicates)
    rigs(args.rigs, min(args.replicates, 300))
    print("target: coverage ≈ 95 % (100 trials → 85..100); N=1000 replicates on 1000 pairs in a few seconds")


if __name__ == "__main__":
    main()
