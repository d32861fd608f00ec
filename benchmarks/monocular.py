"""Monocular scale (issue 19): ``--scale auto`` against the true scale, over seeds.

Per kind and seed, in the same run: :func:`handeye_cli.calibrate` with ``scale="auto"`` on stream b
given in odometry units (b's translations divided by ``SCALE``, as a monocular odometry publishes
them), and the same streams with b in metres (the true scale: what the data give when the scale is
known). Kinds: ``rig`` (two absolute sources, 1 mm / 0.1° per pose, smooth 3-D motion),
``arm-continuous`` (a UR5-like arm moving continuously, camera 1 mm / 0.1°), ``vio-mono`` (drifting
VIO against motion capture, b monocular). ``--noise K`` multiplies every source's white noise (the
arm's camera, the rig's two sources, the VIO's and the motion capture's jitter; not the VIO's drift).

Printed per kind: the coverage of the scale's reported σ (share of seeds with |s − SCALE| ≤ 1.96 σ;
goal ≥ 95 %), the RMS of (s − SCALE)/σ (≈ 1 when σ is honest), the same against the recording's mean
scale (the VIO's scale is a random walk from SCALE at the start, ~1.3 % RMS from it after a minute: its
mean over the recording is ``SCALE / stretch``, the walk's mean stretch of b's steps; SCALE for the other
kinds), the median σ, the seeds whose scale was found to drift (the halves disagree: a warning), and the
mean translation error with the estimated scale over that with the true scale (goal ≤ 2).

    python benchmarks/monocular.py [--seeds 20] [--duration 30] [--noise 1] [--kind vio-mono ...]
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
from handeye_cli.simulation.recordings import SourceNoise, absolute, drifting, simulate_recording
from handeye_cli.solvers.scale import drift_warning
from handeye_cli.streams import PoseStream

SCALE = 0.5                       # metres per odometry unit of stream b


def _rig(seed: int, d: float, k: float) -> tuple[PoseStream, PoseStream, np.ndarray, float]:
    X = random_transform(np.random.default_rng([seed, 1]), 0.3)
    a, b = simulate_rig(Rig(X, 0), duration_s=d, rate_a=30, rate_b=30, sigma_r=np.deg2rad(0.1) * k,
                        sigma_t=0.001 * k, seed=seed, speed=0.5)
    return a, b, X, 1.0


def _arm(seed: int, d: float, k: float) -> tuple[PoseStream, PoseStream, np.ndarray, float]:
    c = simulate_arm(max(int(d // 2), 8), dwell_s=0.0, move_s=2.0, camera_sigma_r=np.deg2rad(0.1) * k,
                     camera_sigma_t=0.001 * k, seed=seed)
    return c.robot, c.camera.inverted(), c.truth, 1.0


def _vio(seed: int, d: float, k: float) -> tuple[PoseStream, PoseStream, np.ndarray, float]:
    """The VIO's recording, and the mean over it of the factor its scale walk stretches b's steps by: the
    same recording with only that walk (drawn first from the same generator, so the same walk) against the
    noise-free one, ``Σ|step with the walk| / Σ|step|``."""
    X = random_transform(np.random.default_rng([seed, 1]), 0.3)
    vio = drifting(sigma_r_deg=0.05 * k, sigma_t_m=0.001 * k)
    mocap = absolute(0.05 * k, 0.0005 * k)
    rec = simulate_recording(Rig(X, 0), mocap, vio, duration_s=d, rate_a=100, rate_b=30, seed=seed, speed=0.5)
    walk = simulate_recording(Rig(X, 0), mocap, SourceNoise(scale_walk=vio.scale_walk), duration_s=d, rate_a=100,
                              rate_b=30, seed=seed, speed=0.5).b
    _, clean = simulate_rig(Rig(X, 0), duration_s=d, rate_a=100, rate_b=30, seed=seed, speed=0.5)
    steps = [np.linalg.norm(np.diff(s.xyz, axis=0), axis=1).sum() for s in (walk, clean)]
    return rec.a, rec.b, X, float(steps[0] / steps[1])


KINDS: dict[str, Callable[[int, float, float], tuple[PoseStream, PoseStream, np.ndarray, float]]] = {
    "rig": _rig, "arm-continuous": _arm, "vio-mono": _vio}


def run(kind: str, seed: int, duration: float, noise: float) -> tuple[float, ...]:
    """(scale error / σ, the same against the recording's mean scale, scale relative error, σ / SCALE, 1 where
    the scale was found to drift else 0, translation error with scale auto [m], with the true scale [m])."""
    a, b, X, stretch = KINDS[kind](seed, duration, noise)
    auto = calibrate(a, monocular(b, SCALE), scale="auto", time_offset=0.0)
    known = calibrate(a, replace(b), time_offset=0.0)
    est = auto.diagnostics.scale
    s, std = est.scale, est.scale_std
    return ((s - SCALE) / std, (s - SCALE / stretch) / std, s / SCALE - 1, std / SCALE,
            float(drift_warning(est) is not None),
            extrinsic_error(auto.matrix, X)[1], extrinsic_error(known.matrix, X)[1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--duration", type=float, default=30.0, help="seconds per recording")
    parser.add_argument("--noise", type=float, default=1.0, help="multiplier of every source's white noise")
    parser.add_argument("--kind", choices=list(KINDS), action="append", help="only this kind (repeatable)")
    args = parser.parse_args()
    t0 = time.perf_counter()
    for kind in args.kind or KINDS:
        r = np.array([run(kind, seed, args.duration, args.noise) for seed in range(args.seeds)])
        z, z_mean, rel, sigma, drifts, auto, known = r.T
        cover = float(np.mean(np.abs(z) <= 1.96))
        ratio = float(auto.mean() / known.mean())
        print(f"{kind:<15} coverage {100 * cover:5.1f} %  RMS z {np.sqrt(np.mean(z ** 2)):5.2f}  "
              f"mean z {z.mean():5.2f}  (of the mean scale: {100 * np.mean(np.abs(z_mean) <= 1.96):5.1f} %, "
              f"RMS z {np.sqrt(np.mean(z_mean ** 2)):5.2f})  σ median {100 * np.median(sigma):.3f} %  "
              f"drift {int(drifts.sum())}/{len(z)}  "
              f"|scale error| mean {100 * np.abs(rel).mean():.3f} %   translation auto {1e3 * auto.mean():7.3f} mm "
              f"vs true scale {1e3 * known.mean():7.3f} mm: ×{ratio:4.2f}   "
              f"{'ok' if cover >= 0.95 and ratio <= 2 else 'MISSED'}")
    print(f"{args.seeds} seeds × {args.duration:g} s per kind, noise ×{args.noise:g}; "
          f"total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
