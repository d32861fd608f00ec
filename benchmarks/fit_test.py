"""The fit test over seeds: how often clean recordings pass, and how far wrong ones land beyond the limit.

Per kind of clean simulated recording (the scenarios of :data:`handeye_cli.simulation.recordings.SCENARIOS`:
drifting VIO, VIO vs motion capture, motion capture vs a target camera, a continuous arm, a
200/15 Hz rate mix, a clock offset with tracking jumps; and simulated arms at stations, sparse and
as dwells, eye-in-hand and eye-to-hand), ``calibrate`` with the defaults (``time_offset`` the true
one) is run over the seeds; printed: the pass rate and the ratio's median and maximum (the limit is
:data:`handeye_cli.analysis.fit_test.THRESHOLD`).

Then the wrong cases, each on a few seeds: quaternions stored w-x-y-z read as x-y-z-w, a stream
that needs inversion passed with ``invert_b=False``, the streams of two different rigs, a station
capture whose stamps in seconds are read as milliseconds, b's translations in another unit (×2), and
a 50 ms clock offset ignored on fast motion (``speed`` 1): for that one the residual inflation (the
ratio with the offset over the ratio without) is printed — it is not refused (below).

    python benchmarks/fit_test.py [--seeds 30] [--duration 20]
"""
from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from handeye_cli import calibrate
from handeye_cli.analysis.fit_test import THRESHOLD
from handeye_cli.calibration import Calibration
from handeye_cli.errors import FitRejectedError, HandEyeError
from handeye_cli.simulation.arm import simulate_arm
from handeye_cli.simulation.recordings import SCENARIOS, scenario
from handeye_cli.streams import PoseStream


def _ratio(run: Callable[..., Calibration], *args: Any) -> float:
    """The fit test's ratio of ``run(*args)`` (inf: refused by the fit test; nan: refused by another check)."""
    try:
        return float(run(*args).diagnostics["fit_test"]["ratio"])
    except FitRejectedError:
        return float("inf")
    except HandEyeError:
        return float("nan")


def _arm(seed: int, setup: str, sparse: bool) -> tuple[PoseStream, PoseStream]:
    c = simulate_arm(12, setup=setup, sparse=sparse, seed=seed)
    return (c.robot.inverted() if c.invert_a else c.robot), c.camera.inverted()


def _simulated(name: str, seed: int, duration: float) -> Calibration:
    r = scenario(name, seed, duration)
    return calibrate(r.a, r.b, time_offset=r.rig.time_offset_ns / 1e9)


def _wxyz_read_as_xyzw(s: PoseStream) -> PoseStream:
    return replace(s, quat_xyzw=s.quat_xyzw[:, [3, 0, 1, 2]])


def _ms(s: PoseStream) -> PoseStream:
    return replace(s, stamps_ns=s.stamps_ns // 1000)


def clean(seeds: int, duration: float) -> None:
    print(f"clean recordings, defaults, {seeds} seeds (limit {THRESHOLD:g}×):")
    kinds: dict[str, Callable[[int], Calibration]] = {
        name: (lambda seed, name=name: _simulated(name, seed, duration)) for name in SCENARIOS}
    for setup in ("eye-in-hand", "eye-to-hand"):
        for sparse in (True, False):
            kinds[f"stations {setup} {'sparse' if sparse else 'dwell'}"] = (
                lambda seed, setup=setup, sparse=sparse: calibrate(*_arm(seed, setup, sparse)))
    for name, run in kinds.items():
        t0 = time.perf_counter()
        ratios = np.array([_ratio(run, seed) for seed in range(seeds)])
        passed = np.isfinite(ratios) & (ratios <= THRESHOLD)
        finite = ratios[np.isfinite(ratios)]
        print(f"  {name:<28} pass {100 * passed.mean():5.1f} %   ratio median {np.median(finite):5.2f}  "
              f"max {finite.max():5.2f}   ({(time.perf_counter() - t0) / seeds:.2f} s each)")


def wrong(seeds: int, duration: float) -> None:
    print("\nwrong cases (refused: ratio > limit; 'inf' = refused, 'nan' = refused by another check):")
    cases: dict[str, Callable[[int], Calibration]] = {}
    for name in ("vio-vio", "vio-mocap", "mocap-mocap", "arm", "rates"):
        def rec(seed: int, name: str = name) -> tuple[PoseStream, PoseStream]:
            r = scenario(name, seed, duration)
            return r.a, r.b
        cases[f"{name}: b w-x-y-z read as x-y-z-w"] = lambda s, rec=rec: calibrate(
            rec(s)[0], _wxyz_read_as_xyzw(rec(s)[1]))
        cases[f"{name}: b needs inversion, --no-invert-b"] = lambda s, rec=rec: calibrate(
            rec(s)[0], rec(s)[1].inverted(), invert_b=False)
        cases[f"{name}: b of another rig"] = lambda s, rec=rec: calibrate(
            rec(s)[0], replace(rec(s + 1000)[1], stamps_ns=rec(s + 1000)[1].stamps_ns
                               - rec(s + 1000)[1].stamps_ns[0] + rec(s)[1].stamps_ns[0]))
        cases[f"{name}: b's translations ×2"] = lambda s, rec=rec: calibrate(
            rec(s)[0], replace(rec(s)[1], xyz=2 * rec(s)[1].xyz))
    cases["sparse stations: stamps s read as ms"] = lambda s: calibrate(*(_ms(x) for x in _arm(s, "eye-in-hand", True)))
    cases["sparse stations: --no-invert-b"] = lambda s: calibrate(
        _arm(s, "eye-in-hand", True)[0], _arm(s, "eye-in-hand", True)[1].inverted(), invert_b=False)
    for name, run in cases.items():
        ratios = [_ratio(run, seed) for seed in range(seeds)]
        refused = sum(not (r <= THRESHOLD) for r in ratios)
        print(f"  {name:<42} refused {refused}/{seeds}   ratios {' '.join(f'{r:.3g}' for r in ratios)}")


def offset(seeds: int, duration: float) -> None:
    print("\n50 ms clock offset ignored, fast motion (speed 1): ratio without → with, and the inflation")
    from handeye_cli.simulation import Rig, random_transform
    from handeye_cli.simulation.recordings import absolute, drifting, simulate_recording
    for label, na, nb in (("vio-vio", drifting(), drifting()), ("mocap-mocap", absolute(0.05, 0.0005),
                                                                  absolute(0.2, 0.002))):
        out = []
        for seed in range(seeds):
            rig = Rig(random_transform(np.random.default_rng([seed, 1]), 0.3))
            r = simulate_recording(rig, na, nb, duration_s=duration, rate_a=30, rate_b=30, seed=seed, speed=1.0)
            base = _ratio(calibrate, r.a, r.b)
            late = _ratio(calibrate, r.a, r.b.shifted(50_000_000))
            out.append((base, late))
        a = np.array(out)
        print(f"  {label:<12} ratio {np.median(a[:, 0]):.2f} → {np.median(a[:, 1]):.2f} (median; max with offset "
              f"{np.max(a[:, 1]):.2f}), inflation ×{np.median(a[:, 1] / a[:, 0]):.2f}; refused "
              f"{int(np.sum(~(a[:, 1] <= THRESHOLD)))}/{seeds}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=30)
    parser.add_argument("--duration", type=float, default=20.0, help="seconds per continuous recording")
    args = parser.parse_args()
    t0 = time.perf_counter()
    clean(args.seeds, args.duration)
    wrong(max(args.seeds // 6, 3), args.duration)
    offset(max(args.seeds // 6, 3), args.duration)
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
