"""Generate sample_data/ground.mcap, the log of the "Ground robots" tutorial (docs/tutorials/ground-robot.md).

A differential-drive base (:func:`handeye_cli.simulation.ground.simulate_ground`, seed 3, 120 s):

* ``/tf``: ``odom → base_link`` from the wheel odometry, 50 Hz;
* ``/lidar/odometry`` (nav_msgs/Odometry): ``odom_lidar → lidar`` from scan matching, 10 Hz;
* ``/amcl_pose`` (geometry_msgs/PoseWithCovarianceStamped): ``map → base_link``, 1.5 Hz, with jumps.

The true ``T_base_link_lidar`` goes to ``ground_truth.yaml``. Run: ``python sample_data/make_ground.py``.
"""
from __future__ import annotations

import sys
from pathlib import Path

import yaml

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from _logs import ODOM, POSE_COV, TF, pose_channel, records, write_mcap  # noqa: E402

from handeye_cli.geometry import se3  # noqa: E402
from handeye_cli.simulation.ground import simulate_ground  # noqa: E402

SEED, DURATION_S = 3, 120.0


def main(out: Path = HERE) -> None:
    g = simulate_ground("diff-drive", seed=SEED, duration_s=DURATION_S)
    assert g.localiser is not None
    write_mcap(out / "ground.mcap", [
        pose_channel("/tf", TF, records(g.base)),
        pose_channel("/lidar/odometry", ODOM, records(g.sensor)),
        pose_channel("/amcl_pose", POSE_COV, records(g.localiser)),
    ])
    xyz, quat = se3.to_xyz_quat(g.truth)
    (out / "ground_truth.yaml").write_text(yaml.safe_dump(
        {"T_base_link_lidar": {"translation": xyz.tolist(), "quaternion_xyzw": quat.tolist()},
         "simulation": {"kind": "diff-drive", "seed": SEED, "duration_s": DURATION_S}}, sort_keys=False))


if __name__ == "__main__":
    main()
