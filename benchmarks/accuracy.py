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

Ground robots (:mod:`handeye_cli.simulation.ground`: ``diff-drive`` wheel vs lidar odometry,
``car`` ground truth vs visual odometry; the diff-drive also with a 5 Hz lidar and 20 Hz wheel odometry,
a 20 Hz lidar and 100 Hz wheels, and straighter runs with a turn in place every 90 s; ``localiser``: the 1.5 Hz
localiser with jumps, AMCL-like, against the 10 Hz lidar odometry), per degree of
freedom: the defaults plus ``--prior`` (a nominal that is wrong where the data see: yaw +1°, pitch +1°,
y +2 cm; right in z) against every
fixed strategy through the same observable-subspace solve (:mod:`handeye_cli.analysis.subspace`),
the best in hindsight per degree of freedom, the worst seed's yaw error, and whether the
unobservable degrees of freedom equal the prior exactly. Beside the defaults' yaw per seed, *the data's*: the
least-squares fit of every consecutive pair (no cap) with z and the tilt at the truth, what the translations
determine (issue 22's "≤ 0.05° on every seed" is bounded by it: a seed whose data put yaw 0.049° off cannot be
brought within 0.05° by any pair selection). 24 ground seeds by default: the best of seven strategies in
hindsight is the minimum of seven noisy means, biased low on few seeds (at 8 seeds the car's best was stride:90,
at 24 stride:15, and its ratio 1.23 fell to 1.14 with the defaults unchanged); beside each ratio, the paired test
of the defaults against that best strategy over the seeds (the one tests/rig uses).

    python benchmarks/accuracy.py [--seeds 12] [--duration 60] [--scenarios vio-vio,arm]
        [--ground diff-drive,car,diff-drive-5hz,diff-drive-20hz,diff-drive-straight,localiser] [--ground-seeds 24]
        [--ground-duration 240]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from handeye_cli import calibrate
from handeye_cli.analysis import assess_observability, extrinsic_error
from handeye_cli.analysis.subspace import DOF_NAMES, dof_values, from_values, observable_subspace
from handeye_cli.simulation.ground import simulate_ground
from handeye_cli.simulation.recordings import SCENARIOS, scenario
from handeye_cli.solvers import solve
from handeye_cli.stages.pairs import make_pairs

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from _util import signed_rank_p  # the tests' paired test, one home

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
    ratio = np.asarray(default / best, dtype=float)
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


GROUND_ERRORS = ("yaw [deg]", "in-plane [mm]", "roll/pitch [deg]")


def _ground_errors(X: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """|yaw error| [deg], in-plane translation error [mm], max |roll|, |pitch| error [deg]."""
    d = dof_values(X) - dof_values(truth)
    return np.array([abs(d[5]), 1e3 * np.hypot(d[0], d[1]), np.abs(d[3:5]).max()])


def _stp(T: np.ndarray) -> str:
    """A static_transform_publisher line of ``T`` (x y z yaw pitch roll, ROS 1 order) from base_link to sensor."""
    v = dof_values(T)
    return ("rosrun tf static_transform_publisher " + " ".join(repr(float(x)) for x in v[:3]) + " "
            + " ".join(repr(float(np.deg2rad(a))) for a in v[5:2:-1]) + " base_link sensor 100")


GROUND_VARIANTS: dict[str, tuple[str, dict[str, Any], str]] = {
    # name: (kind, simulate_ground options, stream a: the base's odometry or the localiser; b is the sensor)
    "diff-drive": ("diff-drive", {}, "base"),
    "car": ("car", {}, "base"),
    "diff-drive-5hz": ("diff-drive", {"base_rate": 20.0, "sensor_rate": 5.0}, "base"),
    "diff-drive-20hz": ("diff-drive", {"base_rate": 100.0, "sensor_rate": 20.0}, "base"),
    "diff-drive-straight": ("diff-drive", {"turning": 0.3, "spin_period_s": 90.0}, "base"),
    "localiser": ("diff-drive", {}, "localiser"),
}


def run_ground(variant: str, seed: int, duration: float) -> tuple[np.ndarray, np.ndarray, float, bool, float]:
    """(default errors (3,), fixed errors (strategies, 3), default signed yaw error [deg], unobservable = prior,
    the data's signed yaw error [deg]) on a :data:`GROUND_VARIANTS` log."""
    kind, options, a = GROUND_VARIANTS[variant]
    g = simulate_ground(kind, seed=seed, duration_s=duration, **options)
    v = dof_values(g.truth)
    v[[5, 4, 1]] += (1.0, 1.0, 0.02)                       # wrong where the data see, right in z
    wrong = from_values(v)
    cal = calibrate(getattr(g, a), g.sensor, prior=_stp(wrong), name_a="base_link", name_b="sensor")
    dofs = cal.diagnostics["degrees_of_freedom"]
    got = dof_values(cal.matrix)
    exact = all(got[k] == v[k] or abs(got[k] - v[k]) < 1e-9 for k, n in enumerate(DOF_NAMES)
                if dofs[n]["status"] == "from_prior")
    fixed = np.full((len(STRATEGIES), 3), np.nan)
    for s, strategy in enumerate(STRATEGIES):
        pairs, _ = make_pairs(cal.synced, strategy)
        if len(pairs) < 3:
            continue
        X = solve(pairs.A, pairs.B, alpha=1.0).matrix
        obs = assess_observability(pairs.A, pairs.B, X)
        fixed[s] = _ground_errors(observable_subspace(pairs.A, pairs.B, X, obs, nominal=wrong).matrix, g.truth)
    d = dof_values(cal.matrix) - dof_values(g.truth)
    return _ground_errors(cal.matrix, g.truth), fixed, float(d[5]), exact, _data_yaw(cal.synced, g.truth)


def _data_yaw(synced: Any, truth: np.ndarray) -> float:
    """Signed yaw error [deg] of the least-squares fit of every consecutive pair with z and the tilt at the truth."""
    pairs, _ = make_pairs(synced, "consecutive", max_pairs=len(synced))
    X = solve(pairs.A, pairs.B).matrix
    fit = observable_subspace(pairs.A, pairs.B, X, assess_observability(pairs.A, pairs.B, X), nominal=truth,
                              max_tilt_std_deg=0.0)
    return float(dof_values(fit.matrix)[5] - dof_values(truth)[5])


def report_ground(kind: str, runs: list[tuple[np.ndarray, np.ndarray, float, bool, float]]) -> np.ndarray:
    """Print one ground kind's table; return the ratios default/best per error of :data:`GROUND_ERRORS`."""
    default = np.mean([r[0] for r in runs], axis=0)
    fixed = np.mean([r[1] for r in runs], axis=0)
    best = np.nanmin(fixed, axis=0)
    print(f"\n{kind} (defaults + --prior wrong by yaw +1°, pitch +1°, y +2 cm; mean over {len(runs)} seeds):")
    print("  " + " " * 13 + "".join(f"{e:>18}" for e in GROUND_ERRORS))
    print(f"  {'defaults':<13}" + "".join(f"{x:18.4f}" for x in default))
    for s, strategy in enumerate(STRATEGIES):
        print(f"  {strategy:<13}" + "".join(f"{x:18.4f}" for x in fixed[s]))
    ratio = np.asarray(default / best, dtype=float)
    yaw = np.array([r[2] for r in runs])
    print("  ratio defaults / best: " + "  ".join(f"{e} {r:.2f}" for e, r in zip(GROUND_ERRORS, ratio, strict=True)))
    errors, each = np.array([r[0] for r in runs]), np.array([r[1] for r in runs])      # (seeds, 3), (seeds, S, 3)
    paired = []
    for k, name in enumerate(GROUND_ERRORS):
        b = int(np.nanargmin(fixed[:, k]))
        d = errors[:, k] - each[:, b, k]
        paired.append(f"{name} vs {STRATEGIES[b]}: better on {int(np.sum(d < 0))}/{len(d)}, p {signed_rank_p(d):.3f}")
    print("  paired over the seeds (one-sided Wilcoxon signed-rank, small p: the defaults worse): " + "; ".join(paired))
    print(f"  defaults' yaw error per seed [deg]: {np.array2string(yaw, precision=4)}; worst |{np.abs(yaw).max():.4f}|"
          f"; from_prior DOFs equal the prior exactly on every seed: {all(r[3] for r in runs)}")
    data = np.array([r[4] for r in runs])
    listed = " ".join(f"{x:+.4f}" for x in data)
    print(f"  the data's yaw error per seed [deg]: [{listed}]; RMS "
          f"{np.sqrt(np.mean(data ** 2)):.4f}, defaults' {np.sqrt(np.mean(yaw ** 2)):.4f}; "
          f"worst |defaults − data| {np.abs(yaw - data).max():.4f}")
    return ratio


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=12)
    parser.add_argument("--duration", type=float, default=60.0, help="seconds per recording")
    parser.add_argument("--scenarios", default=",".join(SCENARIOS))
    parser.add_argument("--ground", default=",".join(GROUND_VARIANTS),
                        help="ground variants ('' for none): " + ", ".join(GROUND_VARIANTS))
    parser.add_argument("--ground-seeds", type=int, default=24)
    parser.add_argument("--ground-duration", type=float, default=240.0)
    args = parser.parse_args()
    t0 = time.perf_counter()
    worst = []
    for name in filter(None, args.scenarios.split(",")):
        runs = [run_seed(name, seed, args.duration) for seed in range(args.seeds)]
        default = np.mean([r[0] for r in runs], axis=0)
        fixed = np.mean([r[1] for r in runs], axis=0)
        worst.append((name, *report(name, default, fixed, [r[2] for r in runs], [r[3] for r in runs],
                                    float(np.mean([r[4] for r in runs])), np.mean([r[5] for r in runs], axis=0))))
    for variant in filter(None, args.ground.split(",")):
        ground = [run_ground(variant, seed, args.ground_duration) for seed in range(args.ground_seeds)]
        ratio = report_ground(variant, ground)
        worst.append((f"{variant} yaw/xy", float(ratio[0]), float(ratio[1]), float("nan")))
    print("\nsummary (defaults / best fixed strategy and α in hindsight, and rotation / park on the same pairs; "
          "goal ≤ 1.2):")
    for name, rot, trans, park in worst:
        print(f"  {name:<27} rot {rot:5.2f}  trans {trans:5.2f}  rot/park {park:5.2f}  "
              f"{'ok' if max(rot, trans, 0.0 if park != park else park) <= 1.2 else 'MISSED'}")
    print(f"{args.seeds} seeds × {args.duration:g} s per scenario, {args.ground_seeds} seeds × "
          f"{args.ground_duration:g} s per ground kind; total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
