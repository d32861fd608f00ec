"""Station captures of a simulated arm: handeye's defaults against Daniilidis on all pairs, and the scale.

1. 101 sparse stations, 0.1° / 1 mm on every absolute pose (robot and camera), no kinematic error:
   RMS error over seeds of Daniilidis and dqopt on all 5,050 pairs, the AX = YB linear translation
   (same rotation), pairs relative to one base station, and ``calibrate`` with default flags.
2. 12 stations, sparse and as 2 s dwells in a continuous log (robot 100 Hz, camera 30 Hz, camera
   noise 0.1° / 1 mm, kinematic errors), eye-in-hand and eye-to-hand: defaults against Daniilidis on
   all pairs of one sample per station (what OpenCV's calibrateHandEye is given).
3. ``--scale auto`` on a monocular camera stream (scale 0.37 m per unit), stations as dwells; the
   reported std covers the noise, not the arm's kinematic errors (without them the RMS error equals it).

    python benchmarks/stations.py [--seeds 10]
"""
from __future__ import annotations

import argparse

import numpy as np
from scipy.spatial.transform import Rotation

from handeye_cli.analysis.residuals import extrinsic_error
from handeye_cli.calibration import calibrate
from handeye_cli.geometry import se3
from handeye_cli.simulation.arm import ArmCapture, monocular, simulate_arm
from handeye_cli.solvers import solve


def _rms(errors: list[tuple[float, float]]) -> str:
    e = np.asarray(errors)
    return f"{np.sqrt(np.mean(e[:, 0] ** 2)):.4f}° / {1000 * np.sqrt(np.mean(e[:, 1] ** 2)):.3f} mm"


def _axyb(Ta: np.ndarray, Tb: np.ndarray, R_X: np.ndarray) -> np.ndarray:
    """t_X from T_a X = Y T_b by linear least squares over (t_X, t_Y), with R_X given and R_Y averaged."""
    R_Y = Rotation.from_matrix(Ta[:, :3, :3] @ R_X @ np.swapaxes(Tb[:, :3, :3], 1, 2)).mean().as_matrix()
    M = np.zeros((len(Ta), 3, 6))
    M[:, :, :3], M[:, :, 3:] = Ta[:, :3, :3], -np.eye(3)
    sol = np.linalg.lstsq(M.reshape(-1, 6), (Tb[:, :3, 3] @ R_Y.T - Ta[:, :3, 3]).ravel(), rcond=None)[0]
    X = np.eye(4)
    X[:3, :3], X[:3, 3] = R_X, sol[:3]
    return X


def many_stations(seeds: int) -> None:
    print("101 stations, 0.1° / 1 mm on every absolute pose, RMS over", seeds, "seeds:")
    errors: dict[str, list[tuple[float, float]]] = {}
    for seed in range(seeds):
        c = simulate_arm(101, sparse=True, seed=seed, robot_sigma_r=np.deg2rad(0.1), robot_sigma_t=0.001,
                         dh_error=0.0, joint_noise=0.0)
        a, b = c.robot, c.camera.inverted()
        Ta, Tb = a.matrices(), b.matrices()
        i, j = np.triu_indices(len(Ta), 1)
        A, B = se3.relative(Ta[i], Ta[j]), se3.relative(Tb[i], Tb[j])
        dq = solve(A, B).matrix
        star = solve(se3.relative(Ta[:1], Ta[1:]), se3.relative(Tb[:1], Tb[1:])).matrix
        found = {"daniilidis, all 5050 pairs": solve(A, B, method="daniilidis").matrix,
                 "dqopt, all 5050 pairs": dq,
                 "AX=YB linear translation": _axyb(Ta, Tb, dq[:3, :3]),
                 "dqopt, 100 pairs to station 0": star,
                 "calibrate, default flags": calibrate(a, c.camera, invert_b=True).matrix,
                 "calibrate --max-pairs 10000": calibrate(a, c.camera, invert_b=True, max_pairs=10000).matrix}
        for name, X in found.items():
            errors.setdefault(name, []).append(extrinsic_error(X, c.truth))
    for name, e in errors.items():
        print(f"  {name:32s} {_rms(e)}")


def _one_sample_per_station(c: ArmCapture) -> np.ndarray:
    def at(T: np.ndarray, stamps: np.ndarray) -> np.ndarray:
        return T[np.searchsorted(stamps, c.station_times_ns).clip(0, len(T) - 1)]

    a = c.robot.inverted() if c.invert_a else c.robot
    Ta, Tb = at(a.matrices(), a.stamps_ns), at(c.camera.inverted().matrices(), c.camera.stamps_ns)
    i, j = np.triu_indices(len(Ta), 1)
    return solve(se3.relative(Ta[i], Ta[j]), se3.relative(Tb[i], Tb[j]), method="daniilidis").matrix


def twelve_stations(seeds: int) -> None:
    print("12 stations, RMS over", seeds, "seeds: defaults vs Daniilidis on all pairs of one sample per station")
    for setup in ("eye-in-hand", "eye-to-hand"):
        for sparse in (True, False):
            ours, ref = [], []
            for seed in range(seeds):
                c = simulate_arm(12, setup=setup, sparse=sparse, seed=seed)
                cal = calibrate(c.robot, c.camera, invert_a=c.invert_a, invert_b=True)
                ours.append(extrinsic_error(cal.matrix, c.truth))
                ref.append(extrinsic_error(_one_sample_per_station(c), c.truth))
            kind = "sparse" if sparse else "dwells"
            print(f"  {setup:11s} {kind:6s}  defaults {_rms(ours)}   daniilidis {_rms(ref)}")


def scale(seeds: int) -> None:
    rel = []
    for seed in range(seeds):
        c = simulate_arm(15, seed=seed)
        cal = calibrate(c.robot, monocular(c.camera.inverted(), 0.37), invert_b=False, scale="auto")
        rel.append((cal.diagnostics["scale"]["value"] / 0.37 - 1, cal.diagnostics["scale"]["std"] / 0.37))
    r = np.asarray(rel)
    print(f"--scale auto, 15 dwelling stations: |error| max {100 * np.abs(r[:, 0]).max():.3f} %, "
          f"RMS {100 * np.sqrt(np.mean(r[:, 0] ** 2)):.3f} %, mean reported std {100 * r[:, 1].mean():.3f} %")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    n = parser.parse_args().seeds
    many_stations(n)
    twelve_stations(n)
    scale(n)


if __name__ == "__main__":
    main()
