"""Write sample_data/rig4.mcap: a four-sensor rig in one log, and its truth (rig4_truth.yaml).

Run from anywhere: ``python sample_data/make_rig4.py [OUT_DIR]`` (deterministic). Four pose
sources on one rigid body, each tracked in its own world frame with its own rate, noise, clock
offset and drift (see :mod:`handeye_cli.rig.simulate`), over 45 s of 3-D motion:

==========  ===============================  =======  ===============  ==========  =============
name        source in the log                rate     noise            clock       drift
==========  ===============================  =======  ===============  ==========  =============
cam0 (ref)  /cam0/pose  PoseStamped          20 Hz    0.2° / 2 mm      0           none
cam1        /cam1/pose  PoseStamped          15 Hz    0.3° / 3 mm      +15 ms      none
lidar       /lidar/odom Odometry             10 Hz    0.1° / 2 mm      -40 ms      0.5°/min, 1 cm/min
imu         /tf  odom → imu_link             25 Hz    0.4° / 4 mm      +25 ms      1°/min, 2 cm/min
==========  ===============================  =======  ===============  ==========  =============

``handeye rig sample_data/rig4.mcap --stream cam0=/cam0/pose --stream cam1=/cam1/pose
--stream lidar=/lidar/odom --stream imu=tf:odom,imu_link`` recovers every ``T_cam0_k``.
Conventions: ``T_ref_k`` is the pose of sensor k in cam0's frame (maps points from k to cam0),
metres, quaternions Hamilton x-y-z-w; header stamps are in each sensor's clock, log time 3 ms later.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from _logs import ODOM, POSE, TF, pose_channel, records, write_mcap  # noqa: E402

from handeye_cli.geometry import se3  # noqa: E402
from handeye_cli.rig.simulate import SimSensor, simulate_streams  # noqa: E402

SEED = 4
DURATION_S = 45.0
LOG_DELAY_NS = 3_000_000


def pose(xyz: list[float], rotvec_deg: list[float]) -> np.ndarray:
    """A 4x4 transform from a translation [m] and a rotation vector [deg]."""
    return se3.from_xyz_quat(np.array(xyz, dtype=float), Rotation.from_rotvec(rotvec_deg, degrees=True).as_quat())


def sensors() -> list[SimSensor]:
    d = np.deg2rad
    return [
        SimSensor("cam0", np.eye(4), 20.0, d(0.2), 0.002),
        SimSensor("cam1", pose([0.12, 0.0, 0.0], [0.0, 0.0, 5.0]), 15.0, d(0.3), 0.003, 15_000_000),
        SimSensor("lidar", pose([0.05, -0.10, 0.25], [-90.0, 0.0, 90.0]), 10.0, d(0.1), 0.002, -40_000_000,
                  drift=(0.0, 0.0, d(0.5) / 60, 0.01 / 60, 0.0, 0.0)),
        SimSensor("imu", pose([-0.03, 0.06, -0.08], [180.0, 0.0, 0.0]), 25.0, d(0.4), 0.004, 25_000_000,
                  drift=(0.0, 0.0, d(1.0) / 60, 0.02 / 60, 0.01 / 60, 0.0)),
    ]


COMMAND = ("handeye rig sample_data/rig4.mcap --stream cam0=/cam0/pose --stream cam1=/cam1/pose "
           "--stream lidar=/lidar/odom --stream imu=tf:odom,imu_link")


def main(out: Path = HERE) -> None:
    """(Re)write rig4.mcap and rig4_truth.yaml into ``out`` (default: this folder)."""
    rig = sensors()
    s = simulate_streams(rig, duration_s=DURATION_S, seed=SEED)
    channels = [pose_channel("/cam0/pose", POSE, records(s["cam0"], "world_cam0", "cam0"), LOG_DELAY_NS),
                pose_channel("/cam1/pose", POSE, records(s["cam1"], "world_cam1", "cam1"), LOG_DELAY_NS),
                pose_channel("/lidar/odom", ODOM, records(s["lidar"], "map", "lidar"), LOG_DELAY_NS),
                pose_channel("/tf", TF, records(s["imu"], "odom", "imu_link"), LOG_DELAY_NS)]
    write_mcap(out / "rig4.mcap", channels)
    truth = {"convention": "T_ref_k = pose of sensor k in the reference cam0 (maps points from k to cam0); metres; "
                           "quaternion Hamilton x-y-z-w; time offsets: the sensor's clock ahead of cam0's",
             "command": COMMAND, "reference": "cam0", "duration_s": DURATION_S, "seed": SEED,
             "sensors": [{"name": k.name, "rate_hz": k.rate_hz, "sigma_r_deg": float(np.rad2deg(k.sigma_r)),
                          "sigma_t_m": k.sigma_t, "time_offset_s": k.time_offset_ns / 1e9,
                          "translation": se3.to_xyz_quat(k.T_ref_k)[0].tolist(),
                          "quaternion_xyzw": se3.to_xyz_quat(k.T_ref_k)[1].tolist()} for k in rig]}
    with open(out / "rig4_truth.yaml", "w") as f:
        f.write("# Ground truth of rig4.mcap. Written by make_rig4.py; do not edit.\n")
        yaml.safe_dump(truth, f, sort_keys=False, width=110, default_flow_style=None)
    print(f"{out / 'rig4.mcap'}: {sum(map(len, s.values()))} poses, {(out / 'rig4.mcap').stat().st_size / 1e3:.0f} kB")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE)
