"""Statistical efficiency: dqopt, Park, Park + LM and the maximum-likelihood refinement on look-at stations.

An eye-in-hand camera looks at a target from 0.1–0.3 m (``simulation.arm.look_at_stations``); both
streams' poses get ``simulation.perturb`` noise (σ_r the angle about a random axis, σ_t per axis), and
the motions are the pairs of stations (all with all, consecutive, or disjoint: the only independent
ones). Per noise regime it prints the median rotation [mrad] and translation [mm] error over the seeds of:

* ``dqopt a=1``: cost (8) with α = 1 /m; ``dqopt auto``: with the noise model's ML α
  (``analysis.alpha.noise_model_alpha``, the default ``auto`` rule without its time-block cap);
* ``park``; ``park+LM``: Park's start, then SciPy's Levenberg–Marquardt on equal-weight residuals
  (rotation vector [rad], translation [m]), as the anchor tools do (kinhec);
* ``refine``: :func:`handeye_cli.solvers.refine.refine` from dqopt's (α = 1) optimum, with the true
  noise levels, and its time per call against dqopt's in the same run.

    python benchmarks/efficiency.py [--seeds 30] [--stations 20] [--pairs all|consecutive|disjoint]
"""
from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from handeye_cli.analysis.alpha import noise_model_alpha
from handeye_cli.geometry import se3
from handeye_cli.simulation import perturb
from handeye_cli.simulation.arm import look_at_stations
from handeye_cli.solvers import solve
from handeye_cli.solvers.refine import motion_covariances, refine

# σ_r [rad] (angle), σ_t [m] of (robot flange, camera): robot poses are good, the camera's vary
REGIMES: dict[str, tuple[float, float, float, float]] = {
    "rotation-dominated": (1e-4, 1e-4, 5e-3, 2e-4),
    "balanced": (1e-4, 1e-4, 1e-3, 2e-4),
    "translation-dominated": (1e-4, 1e-4, 2e-4, 2e-3),
}
METHODS = ("dqopt a=1", "dqopt auto", "park", "park+LM", "refine")


def park_lm(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Park, then LM on the equal-weight residuals ``Log(R_A R R_Bᵀ Rᵀ)`` [rad], ``R_A t + t_A − R t_B − t`` [m]."""
    X0 = solve(A, B, method="park").matrix

    def residuals(p: np.ndarray) -> np.ndarray:
        R = Rotation.from_rotvec(p[:3]).as_matrix()
        rot = Rotation.from_matrix(A[:, :3, :3] @ R @ B[:, :3, :3].transpose(0, 2, 1) @ R.T).as_rotvec()
        tra = A[:, :3, :3] @ p[3:] + A[:, :3, 3] - B[:, :3, 3] @ R.T - p[3:]
        return np.concatenate((rot, tra), axis=1).ravel()

    p = least_squares(residuals, np.r_[Rotation.from_matrix(X0[:3, :3]).as_rotvec(), X0[:3, 3]], method="lm").x
    X = np.eye(4)
    X[:3, :3], X[:3, 3] = Rotation.from_rotvec(p[:3]).as_matrix(), p[3:]
    return X


def _pairs(stations: int, pairs: str) -> tuple[np.ndarray, np.ndarray]:
    """Station indices (i, j) of the motions: all with all, consecutive, or disjoint (0-1, 2-3, …: independent)."""
    if pairs == "all":
        i, j = np.triu_indices(stations, 1)
        return i, j
    if pairs == "disjoint":
        return np.arange(0, stations - 1, 2), np.arange(1, stations, 2)
    return np.arange(stations - 1), np.arange(1, stations)


def trial(seed: int, regime: tuple[float, float, float, float], stations: int = 20, pairs: str = "all"
          ) -> tuple[dict[str, tuple[float, float]], dict[str, float]]:
    """One capture: each method's (rotation error [rad], translation error [m]); the times [s] of dqopt and refine."""
    rng = np.random.default_rng(seed)
    Ta, Tb, X = look_at_stations(stations, rng)
    ra, ta, rb, tb = regime
    Ta, Tb = perturb(Ta, rng, ra, ta), perturb(Tb, rng, rb, tb)
    i, j = _pairs(stations, pairs)
    A, B = se3.relative(Ta[i], Ta[j]), se3.relative(Tb[i], Tb[j])
    cov_a = motion_covariances(Ta[i], Ta[j], ra / np.sqrt(3), ta)     # perturb's angle σ is σ/√3 per axis
    cov_b = motion_covariances(Tb[i], Tb[j], rb / np.sqrt(3), tb)
    times: dict[str, float] = {}
    t0 = time.perf_counter()
    start = solve(A, B).matrix
    times["dqopt"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    refined = refine(A, B, start, cov_a, cov_b).matrix
    times["refine"] = time.perf_counter() - t0
    estimates: dict[str, Callable[[], np.ndarray]] = {
        "dqopt a=1": lambda: start,
        "dqopt auto": lambda: solve(A, B, alpha=noise_model_alpha(A, B).alpha).matrix,
        "park": lambda: solve(A, B, method="park").matrix,
        "park+LM": lambda: park_lm(A, B),
        "refine": lambda: refined,
    }
    errors = {}
    for name, estimate in estimates.items():
        E = se3.inverse(X) @ estimate()
        errors[name] = (float(se3.rotation_angle(E)), float(np.linalg.norm(E[:3, 3])))
    return errors, times


def table(seeds: int, regime: tuple[float, float, float, float], stations: int = 20, pairs: str = "all"
          ) -> tuple[dict[str, tuple[float, float]], dict[str, float]]:
    """Median (rotation [rad], translation [m]) error per method over ``seeds`` captures, and median times [s]."""
    runs = [trial(seed, regime, stations, pairs) for seed in range(seeds)]
    medians = {m: (float(np.median([r[0][m][0] for r in runs])), float(np.median([r[0][m][1] for r in runs])))
               for m in METHODS}
    return medians, {k: float(np.median([r[1][k] for r in runs])) for k in ("dqopt", "refine")}


def show(name: str, medians: dict[str, tuple[float, float]], times: dict[str, float]) -> None:
    print(f"== {name} ==")
    print(f"{'method':<12} {'rot [mrad]':>11} {'trans [mm]':>11}")
    for m, (rot, tra) in medians.items():
        print(f"{m:<12} {rot * 1e3:>11.4f} {tra * 1e3:>11.4f}")
    print(f"time per call (median): dqopt {times['dqopt'] * 1e3:.2f} ms, refine {times['refine'] * 1e3:.2f} ms "
          f"({times['refine'] / times['dqopt']:.1f}x)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=30)
    parser.add_argument("--stations", type=int, default=20)
    parser.add_argument("--pairs", choices=("all", "consecutive", "disjoint"), default="all")
    args = parser.parse_args()
    print(f"{args.seeds} seeds, {args.stations} stations, {args.pairs} pairs; σ_r [rad] angle, σ_t [m] per axis")
    for name, regime in REGIMES.items():
        print(f"-- robot σ_r {regime[0]:g}, σ_t {regime[1]:g}; camera σ_r {regime[2]:g}, σ_t {regime[3]:g}")
        show(name, *table(args.seeds, regime, args.stations, args.pairs))


if __name__ == "__main__":
    main()
