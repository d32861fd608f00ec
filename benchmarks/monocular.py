"""Monocular scale (issue 19): ``--scale auto`` against the true scale, over seeds.

Per kind and seed, in the same run: :func:`handeye_cli.calibrate` with ``scale="auto"`` on stream b
given in odometry units (b's translations divided by ``SCALE``, as a monocular odometry publishes
them), and the same streams with b in metres (the true scale: what the data give when the scale is
known). Kinds: ``rig`` (two absolute sources, 1 mm / 0.1° per pose, smooth 3-D motion),
``arm-continuous`` (a UR5-like arm moving continuously, camera 1 mm / 0.1°), ``vio-mono`` (drifting
VIO against motion capture, b monocular). ``--noise K`` multiplies every source's white noise (the
arm's camera, the rig's two sources, the VIO's and the motion capture's jitter; not the VIO's drift).

Printed per kind: the coverage of the scale's reported σ (share of seeds with |s − SCALE| ≤ 1.96 σ;
goal ≥ 95 %), the RMS of (s − SCALE)/σ (≈ 1 when σ is honest), and the mean translation error
with the estimated scale over that with the true scale (goal ≤ 2).

    python benchmarks/monocular.py [--seeds 20] [--duration 30] [--noise 1]
"""
from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from handeye_cli import calibrate
from handeye_cli.analysis import extrinsic_error
from handeye_cli.simulation import Rig, random_transform, simulate_rig
from handeye_cli.simulation.arm import monocular, simulate_arm
from handeye_cli.simulation.recordings import absolute, drifting, simulate_recording
from handeye_cli.streams import PoseStream

SCALE = 0.5                       # metres per odometry unit of stream b


def _rig(seed: int, d: float, k: float) -> tuple[PoseStream, PoseStream, np.ndarray]:
    X = random_transform(np.random.default_rng([seed, 1]), 0.3)
    a, b = simulate_rig(Rig(X, 0), duration_s=d, rate_a=30, rate_b=30, sigma_r=np.deg2rad(0.1) * k,
                        sigma_t=0.001 * k, seed=seed, speed=0.5)
    return a, b, X


def _arm(seed: int, d: float, k: float) -> tuple[PoseStream, PoseStream, np.ndarray]:
    c = simulate_arm(max(int(d // 2), 8), dwell_s=0.0, move_s=2.0, camera_sigma_r=np.deg2rad(0.1) * k,
                     camera_sigma_t=0.001 * k, seed=seed)
    return c.robot, c.camera.inverted(), c.truth


def _vio(seed: int, d: float, k: float) -> tuple[PoseStream, PoseStream, np.ndarray]:
    X = random_transform(np.random.default_rng([seed, 1]), 0.3)
    vio = drifting(sigma_r_deg=0.05 * k, sigma_t_m=0.001 * k)
    rec = simulate_recording(Rig(X, 0), absolute(0.05 * k, 0.0005 * k), vio, duration_s=d, rate_a=100, rate_b=30,
                             seed=seed, speed=0.5)
    return rec.a, rec.b, X


KINDS: dict[str, Callable[[int, float, float], tuple[PoseStream, PoseStream, np.ndarray]]] = {
    "rig": _rig, "arm-continuous": _arm, "vio-mono": _vio}


def run(kind: str, seed: int, duration: float, noise: float) -> tuple[float, float, float, float]:
    """(scale error / σ, scale relative error, translation error with scale auto [m], with the true scale [m])."""
    a, b, X = KINDS[kind](seed, duration, noise)
    auto = calibrate(a, monocular(b, SCALE), scale="auto", time_offset=0.0)
    known = calibrate(a, replace(b), time_offset=0.0)
    s, std = auto.diagnostics["scale"]["value"], auto.diagnostics["scale"]["std"]
    return ((s - SCALE) / std, s / SCALE - 1, extrinsic_error(auto.matrix, X)[1], extrinsic_error(known.matrix, X)[1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--duration", type=float, default=30.0, help="seconds per recording")
    parser.add_argument("--noise", type=float, default=1.0, help="multiplier of every source's white noise")
    args = parser.parse_args()
    t0 = time.perf_counter()
    for kind in KINDS:
        r = np.array([run(kind, seed, args.duration, args.noise) for seed in range(args.seeds)])
        z, rel, auto, known = r.T
        cover = float(np.mean(np.abs(z) <= 1.96))
        ratio = float(auto.mean() / known.mean())
        print(f"{kind:<15} coverage {100 * cover:5.1f} %  RMS z {np.sqrt(np.mean(z ** 2)):5.2f}  "
              f"mean z {z.mean():5.2f}  "
              f"|scale error| mean {100 * np.abs(rel).mean():.3f} %   translation auto {1e3 * auto.mean():7.3f} mm "
              f"vs true scale {1e3 * known.mean():7.3f} mm: ×{ratio:4.2f}   "
              f"{'ok' if cover >= 0.95 and ratio <= 2 else 'MISSED'}")
    print(f"{args.seeds} seeds × {args.duration:g} s per kind, noise ×{args.noise:g}; "
          f"total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
