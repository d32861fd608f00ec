"""Write sample_data/: one simulated rig recorded in every format handeye reads, plus its truth.

Run from anywhere: ``python sample_data/make_samples.py [OUT_DIR]`` (deterministic: the same
bytes every run). The rig: sensor a (``cam0``) and sensor b
(``cam1``) rigidly mounted 28 cm apart at 50° relative rotation, tracked by two different
systems — a at 30 Hz in frame ``world``, b at 12 Hz in frame ``odom`` — with 0.2° / 2 mm pose
noise, three tracking jumps per stream, over 75 s of 3-D motion.

Conventions: the extrinsic is ``T_a_b`` (the pose of b in a, ``p_a = T_a_b · p_b``), metres,
quaternions Hamilton x-y-z-w. Stream a is always the first topic / frame pair / file.

TF tree in ``rig.mcap``, ``rig_ros1.bag`` and ``rig_json.mcap``::

    world ─(/tf, 30 Hz)─ base_link ─(/tf_static)─ cam0
      └──(/tf_static)─ odom ─(/tf, 12 Hz)─ cam1
"""
from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from _logs import (  # noqa: E402
    FOX_POSE,
    FOX_POSES,
    FOX_TF,
    FOX_TFS,
    ODOM,
    POSE,
    POSE_COV,
    TF,
    TRANSFORM,
    Channel,
    pose_channel,
    records,
    write_bag1,
    write_bag2,
    write_euroc,
    write_mcap,
    write_tum,
)

from handeye_cli.geometry import se3  # noqa: E402
from handeye_cli.simulation import Rig, simulate_rig  # noqa: E402
from handeye_cli.streams import PoseStream  # noqa: E402

SEED = 20240607
SIM = {"duration_s": 75.0, "rate_a": 30.0, "rate_b": 12.0, "sigma_r_deg": 0.2, "sigma_t_m": 0.002,
       "jumps_per_stream": 3, "speed": 0.5}
LOG_DELAY_NS = 3_000_000          # recorder log time = header.stamp + 3 ms


def pose(xyz: list[float], rotvec_deg: list[float]) -> np.ndarray:
    """A 4x4 transform from a translation [m] and a rotation vector [deg]."""
    return se3.from_xyz_quat(np.array(xyz, dtype=float), Rotation.from_rotvec(rotvec_deg, degrees=True).as_quat())


# T_a_b: 50° about a tilted axis, 28 cm lever arm.
AXIS = np.array([0.3, 0.9, 0.3]) / np.linalg.norm([0.3, 0.9, 0.3])
X = pose((0.28 * np.array([0.6, -0.64, 0.48])).tolist(), (50.0 * AXIS).tolist())
T_ODOM_WORLD = pose([3.0, -1.5, 0.4], [0.0, 0.0, 35.0])      # b's tracker frame seen from a's: T_wb_wa
T_BASE_CAM0 = pose([0.12, 0.0, 0.05], [-60.0, 10.0, -60.0])  # cam0's mount on the tracked body


def simulate() -> tuple[PoseStream, PoseStream]:
    """Stream a = ``T_world_cam0(t)``, stream b = ``T_odom_cam1(t)``."""
    return simulate_rig(Rig(X), duration_s=SIM["duration_s"], rate_a=SIM["rate_a"], rate_b=SIM["rate_b"],
                        sigma_r=np.deg2rad(SIM["sigma_r_deg"]), sigma_t=SIM["sigma_t_m"],
                        jumps=SIM["jumps_per_stream"], seed=SEED, T_wb_wa=T_ODOM_WORLD, speed=SIM["speed"])


def edge_record(stamp_ns: int, parent: str, child: str, T: np.ndarray) -> tuple:
    xyz, quat = se3.to_xyz_quat(T)
    return (stamp_ns, parent, child, *xyz.tolist(), *quat.tolist())


def tf_records(a: PoseStream, b: PoseStream) -> tuple[list[tuple[int, list]], list[tuple]]:
    """(/tf messages: one per sample of each stream, /tf_static transforms) of the tree above."""
    body = PoseStream.from_matrices(a.stamps_ns, a.matrices() @ se3.inverse(T_BASE_CAM0))
    dynamic = [(r[0], [r]) for r in records(body, "world", "base_link") + records(b, "odom", "cam1")]
    t0 = int(min(a.stamps_ns[0], b.stamps_ns[0]))
    static = [edge_record(t0, "base_link", "cam0", T_BASE_CAM0),
              edge_record(t0, "world", "odom", se3.inverse(T_ODOM_WORLD))]
    return sorted(dynamic, key=lambda m: m[0]), static


def tf_channels(a: PoseStream, b: PoseStream, dynamic_type: str, static_type: str) -> list[Channel]:
    """/tf and /tf_static channels; a single-transform static type gets one message per edge."""
    dynamic, static = tf_records(a, b)
    t0 = static[0][0]
    statics = [(t0, static)] if static_type in (TF, FOX_TFS) else [(t0, [r]) for r in static]
    return [Channel("/tf", dynamic_type, [(t + LOG_DELAY_NS, recs) for t, recs in dynamic]),
            Channel("/tf_static", static_type, statics, static=True)]


def streams_channels(a: PoseStream, b: PoseStream, spec: dict) -> list[Channel]:
    """The two pose topics of one file as ``spec`` (its entry in FILES) describes them."""
    out = []
    for s, side, frames in ((a, "a", ("world", "cam0")), (b, "b", ("odom", "cam1"))):
        topic, msgtype = spec[side]["topic"], spec[side]["type"]
        out.append(pose_channel(topic, msgtype, records(s, *frames), LOG_DELAY_NS))
    return out


def side(topic: str, msgtype: str, frames: tuple[str, str] | None) -> dict:
    entry = {"topic": topic, "type": msgtype}
    if frames:
        entry["frames"] = list(frames)
    return entry


FILES = {
    "rig.mcap": {"format": "MCAP (ROS 2 CDR)",
                 "a": side("/cam0/pose", POSE, ("world", "cam0")), "b": side("/cam1/pose", POSE, ("odom", "cam1"))},
    "rig_ros1.bag": {"format": "ROS 1 bag (LZ4 chunks)",
                     "a": side("/cam0/odom", ODOM, ("world", "cam0")),
                     "b": side("/cam1/pose", POSE_COV, ("odom", "cam1"))},
    "rig_ros2": {"format": "ROS 2 bag directory (sqlite3)",
                 "a": side("/cam0/transform", TRANSFORM, None), "b": side("/cam1/odom", ODOM, None)},
    "rig_json.mcap": {"format": "MCAP (Foxglove JSON channels)",
                      "a": side("/cam0/pose", FOX_POSE, ("world", "cam0")),
                      "b": side("/cam1/pose", FOX_POSES, ("odom", "cam1"))},
}
TEXT_FILES = {
    "TUM": ("rig_a.tum", "rig_b.tum"),
    "EuRoC CSV (17 columns)": ("rig_a_euroc.csv", "rig_b_euroc.csv"),
}


def write_logs(a: PoseStream, b: PoseStream, out: Path) -> None:
    write_mcap(out / "rig.mcap", streams_channels(a, b, FILES["rig.mcap"]) + tf_channels(a, b, TF, TF))
    write_bag1(out / "rig_ros1.bag", streams_channels(a, b, FILES["rig_ros1.bag"]) + tf_channels(a, b, TF, TF),
               compression="lz4")
    write_bag2(out / "rig_ros2", streams_channels(a, b, FILES["rig_ros2"]))
    write_mcap(out / "rig_json.mcap", streams_channels(a, b, FILES["rig_json.mcap"])
               + tf_channels(a, b, FOX_TFS, FOX_TF))
    (path_a, path_b), (euroc_a, euroc_b) = TEXT_FILES.values()
    write_tum(out / path_a, a)
    write_tum(out / path_b, b)
    write_euroc(out / euroc_a, a)
    write_euroc(out / euroc_b, b)


def commands() -> dict[str, list[str]]:
    """One ``handeye calibrate`` command per file (topics; frames where the file has TF)."""
    out = {}
    for name, spec in FILES.items():
        cmds = [f"handeye calibrate sample_data/{name} --topic-a {spec['a']['topic']} --topic-b {spec['b']['topic']}"]
        if "frames" in spec["a"]:
            cmds.append(f"handeye calibrate sample_data/{name} --frames-a {' '.join(spec['a']['frames'])} "
                        f"--frames-b {' '.join(spec['b']['frames'])}")
        out[name] = cmds
    for path_a, path_b in TEXT_FILES.values():
        out[path_a] = [f"handeye calibrate sample_data/{path_a} sample_data/{path_b}"]
    return out


def truth() -> dict:
    xyz, quat = se3.to_xyz_quat(X)
    files = {name: {**spec, "command": commands()[name]} for name, spec in FILES.items()}
    for fmt, (path_a, path_b) in TEXT_FILES.items():
        files[path_a] = {"format": fmt, "a": {"file": path_a}, "b": {"file": path_b},
                         "command": commands()[path_a]}
    return {
        "convention": "T_a_b = pose of b (cam1) in a (cam0); p_a = T_a_b * p_b; metres; "
                      "quaternion Hamilton x-y-z-w; stream a = first topic/frames/file",
        "matrix": np.round(X, 15).tolist(),
        "translation": xyz.tolist(),
        "quaternion_xyzw": quat.tolist(),
        "rotation_deg": float(np.rad2deg(se3.rotation_angle(X))),
        "distance_m": float(np.linalg.norm(xyz)),
        "frames": {"a": "cam0", "b": "cam1"},
        "time_offset_ns": 0,
        "log_time_minus_header_stamp_ns": LOG_DELAY_NS,
        "simulation": {**SIM, "seed": SEED, "T_odom_world": np.round(T_ODOM_WORLD, 15).tolist(),
                       "T_base_link_cam0": np.round(T_BASE_CAM0, 15).tolist()},
        "files": files,
    }


def main(out: Path = HERE) -> None:
    """(Re)write every sample file and truth.yaml into ``out`` (default: this folder)."""
    a, b = simulate()
    for name in [*FILES, *(p for pair in TEXT_FILES.values() for p in pair)]:
        target = out / name
        if target.is_dir():
            shutil.rmtree(target)
        elif target.exists():
            target.unlink()
    write_logs(a, b, out)
    with open(out / "truth.yaml", "w") as f:
        f.write("# Ground truth of every file in this folder. Written by make_samples.py; do not edit.\n")
        yaml.safe_dump(truth(), f, sort_keys=False, width=110, default_flow_style=None)
    total = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    print(f"{out}: {len(a)} + {len(b)} poses, {total / 1e6:.2f} MB in total")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE)
