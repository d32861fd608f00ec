"""Every container, message type and text format gives back the stream that was written."""
from __future__ import annotations

import numpy as np
import pytest
from _logs import (
    JSON_POSE_TYPES,
    LOG_KINDS,
    ODOM,
    POSE,
    POSE_COV,
    ROS_POSE_TYPES,
    TF,
    TRANSFORM,
    Channel,
    pose_channel,
    records,
    write_bag1,
    write_csv,
    write_euroc,
    write_log,
    write_mcap,
    write_tum,
)

from handeye_cli.io import detect_format, read_stream
from handeye_cli.simulation import Rig, simulate_rig
from handeye_cli.streams import PoseStream

TOL = 1e-12
CHILD_IN_MESSAGE = {TRANSFORM, ODOM, TF, "foxglove.FrameTransform", "foxglove.FrameTransforms"}


@pytest.fixture(scope="module")
def truth() -> PoseStream:
    """A noisy 3-D stream with tracking jumps: the kind of data the readers carry."""
    a, _ = simulate_rig(Rig(np.eye(4)), duration_s=8.0, rate_a=30.0, sigma_r=np.deg2rad(0.2),
                        sigma_t=0.002, jumps=2, seed=7)
    return a


def assert_same(s: PoseStream, truth: PoseStream, offset_ns: int = 0) -> None:
    np.testing.assert_array_equal(s.stamps_ns, truth.stamps_ns + offset_ns)
    np.testing.assert_allclose(s.xyz, truth.xyz, rtol=0, atol=TOL)
    np.testing.assert_allclose(s.quat_xyzw, truth.quat_xyzw, rtol=0, atol=TOL)
    assert s.stamps_ns.dtype == np.int64 and s.duplicates_dropped == 0


@pytest.mark.parametrize("kind", LOG_KINDS)
@pytest.mark.parametrize("msgtype", ROS_POSE_TYPES)
def test_ros_types_round_trip(tmp_path, truth, kind, msgtype):
    path = write_log(kind, tmp_path, [pose_channel("/rig/pose", msgtype, records(truth, "odom", "cam0"))])
    s = read_stream(path, topic="/rig/pose")
    assert_same(s, truth)
    assert s.frame_id == "odom" and s.time_source == "header"
    assert s.child_frame_id == ("cam0" if msgtype in CHILD_IN_MESSAGE else "rig_pose")   # a valid tf2 frame id
    assert str(path) in s.source and "/rig/pose" in s.source


@pytest.mark.parametrize("msgtype", JSON_POSE_TYPES)
def test_foxglove_json_round_trip(tmp_path, truth, msgtype):
    """JSON channels beside a CDR channel (a file rosbags cannot open)."""
    path = write_mcap(tmp_path / "fox.mcap", [pose_channel("/fox", msgtype, records(truth, "map", "body")),
                                              pose_channel("/cdr", POSE, records(truth, "map", ""))])
    s = read_stream(path, topic="/fox")
    assert_same(s, truth)
    assert (s.frame_id, s.child_frame_id) == ("map", "body" if msgtype in CHILD_IN_MESSAGE else "fox")
    assert_same(read_stream(path, topic="/cdr"), truth)


@pytest.mark.parametrize("with_json", [False, True], ids=["ros2-only", "mixed"])
def test_ros2idl_schema(tmp_path, truth, with_json):
    """IDL schemas are decoded by AnyReader (pure ROS 2 file) or by handeye's mcap path (mixed)."""
    extra = [pose_channel("/fox", "foxglove.PoseInFrame", records(truth))] if with_json else []
    path = write_mcap(tmp_path / "idl.mcap", [pose_channel("/p", POSE, records(truth, "map", "")), *extra], idl=True)
    assert_same(read_stream(path, topic="/p"), truth)


@pytest.mark.parametrize("kind", LOG_KINDS)
def test_log_time_on_request(tmp_path, truth, kind):
    offset = 1_234_567     # recorder receives each message 1.23 ms after its header stamp
    path = write_log(kind, tmp_path, [pose_channel("/p", ODOM, records(truth, "w", "c"), offset)])
    assert_same(read_stream(path, topic="/p"), truth)
    s = read_stream(path, topic="/p", time_source="log")
    assert_same(s, truth, offset)
    assert s.time_source == "log"


def test_json_log_time(tmp_path, truth):
    path = write_mcap(tmp_path / "j.mcap", [pose_channel("/p", "foxglove.PoseInFrame", records(truth), 99)])
    assert_same(read_stream(path, topic="/p", time_source="log"), truth, 99)


@pytest.mark.parametrize("kind", ["mcap", "mcap_ros1", "bag1", "db3"])
def test_sorted_by_stamp_and_duplicates_dropped(tmp_path, truth, kind):
    """Messages logged out of stamp order come back sorted; repeated stamps are dropped (first
    kept) and counted."""
    recs = records(truth, "w", "")
    shuffled = [recs[i] for i in np.random.default_rng(0).permutation(len(recs))]
    dups = [recs[3], recs[10], recs[10]]
    msgs = [(recs[0][0] + 1000 * i, [r]) for i, r in enumerate(shuffled + dups)]
    path = write_log(kind, tmp_path, [Channel("/p", POSE, msgs)])
    s = read_stream(path, topic="/p")
    np.testing.assert_array_equal(s.stamps_ns, truth.stamps_ns)
    np.testing.assert_allclose(s.xyz, truth.xyz, rtol=0, atol=TOL)
    assert s.duplicates_dropped == 3


def test_duplicate_keeps_first_sample(tmp_path, truth):
    recs = records(truth, "w", "")
    moved = (recs[5][0], "w", "", 9.0, 9.0, 9.0, 0.0, 0.0, 0.0, 1.0)
    path = write_mcap(tmp_path / "d.mcap", [pose_channel("/p", POSE, recs[:6] + [moved] + recs[6:])])
    s = read_stream(path, topic="/p")
    assert s.duplicates_dropped == 1
    np.testing.assert_allclose(s.xyz[5], truth.xyz[5], rtol=0, atol=0)


def test_split_ros1_bags_read_as_one(tmp_path, truth):
    recs = records(truth, "w", "")
    half = len(recs) // 2
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    p1 = write_bag1(tmp_path / "a" / "part.bag", [pose_channel("/p", POSE, recs[:half])])
    p2 = write_bag1(tmp_path / "b" / "part.bag", [pose_channel("/p", POSE, recs[half:])])
    assert_same(read_stream([p2, p1], topic="/p"), truth)


def test_unnormalised_quaternions_are_normalised(tmp_path, truth):
    recs = [(*r[:6], *(2.5 * np.array(r[6:]))) for r in records(truth, "w", "")]
    s = read_stream(write_mcap(tmp_path / "q.mcap", [pose_channel("/p", POSE, recs)]), topic="/p")
    np.testing.assert_allclose(s.quat_xyzw, truth.quat_xyzw, rtol=0, atol=TOL)


def test_ros1_leading_slash_kept_on_topics(tmp_path, truth):
    path = write_log("bag1", tmp_path, [pose_channel("/p", TRANSFORM, records(truth, "/world", "/cam"))])
    s = read_stream(path, topic="/p")
    assert (s.frame_id, s.child_frame_id) == ("/world", "/cam")


def test_pose_with_covariance_in_bag_dir_mcap(tmp_path, truth):
    """A ROS 2 bag directory with MCAP storage holding two pose types side by side."""
    path = write_log("bag2_mcap", tmp_path, [pose_channel("/a", POSE_COV, records(truth, "map", "")),
                                             pose_channel("/b", ODOM, records(truth, "odom", "base"))])
    assert_same(read_stream(path, topic="/a"), truth)
    assert_same(read_stream(path, topic="/b"), truth)


# --- content, not suffix ----------------------------------------------------------------------
@pytest.mark.parametrize("kind, fmt", [("mcap", "mcap"), ("mcap_ros1", "mcap"), ("bag1", "rosbag1"),
                                       ("db3", "rosbag2"), ("bag2_sqlite", "rosbag2")])
def test_detected_by_content_under_any_name(tmp_path, truth, kind, fmt):
    path = write_log(kind, tmp_path, [pose_channel("/p", POSE, records(truth, "w", ""))])
    assert detect_format(path) == fmt
    if path.is_file():
        renamed = path.rename(tmp_path / "recording.dat")
        assert detect_format(renamed) == fmt
        assert_same(read_stream(renamed, topic="/p"), truth)


# --- text -------------------------------------------------------------------------------------
@pytest.mark.parametrize("sep", [" ", ",", "\t"])
def test_tum_round_trip(tmp_path, truth, sep):
    path = write_tum(tmp_path / "a.txt", truth, sep=sep)
    assert detect_format(path) == "tum"
    s = read_stream(path)
    assert_same(s, truth)
    assert (s.frame_id, s.child_frame_id) == ("", "a")                     # the world is unnamed
    assert (s.inverted().frame_id, s.inverted().child_frame_id) == ("", "a")   # the sensor keeps its name


def test_tum_messy_whitespace_and_comments(tmp_path, truth):
    path = write_tum(tmp_path / "m.tum", truth)
    lines = path.read_text().splitlines()
    messy = ["# exported by some tool", ""] + [f"  {ln.replace(' ', chr(9), 2)}   " for ln in lines[1:]]
    path.write_text("\n".join(messy) + "\n\n")
    assert_same(read_stream(path), truth)


@pytest.mark.parametrize("header, columns", [(True, 17), (False, 17), (False, 8), (True, 8)])
def test_euroc_round_trip(tmp_path, truth, header, columns):
    path = write_euroc(tmp_path / "data.csv", truth, header=header, columns=columns)
    assert detect_format(path) == "euroc"
    assert_same(read_stream(path), truth)


@pytest.mark.parametrize("names, t_scale, columns", [
    (["timestamp_ns", "x", "y", "z", "qx", "qy", "qz", "qw"], 1, None),
    (["stamp [us]", "pos_x", "pos_y", "pos_z", "rot_x", "rot_y", "rot_z", "rot_w"], 1000, None),
    (["T", "A", "B", "C", "D", "E", "F", "G"], 1,
     {"t": "T", "x": "A", "y": "B", "z": "C", "qx": "D", "qy": "E", "qz": "F", "qw": "G", "t_unit": "ns"}),
])
def test_generic_csv_round_trip(tmp_path, truth, names, t_scale, columns):
    path = write_csv(tmp_path / "poses.csv", truth, names, t_scale=t_scale)
    assert detect_format(path) == "csv"
    s = read_stream(path, columns=columns)
    np.testing.assert_array_equal(s.stamps_ns, truth.stamps_ns // t_scale * t_scale)
    np.testing.assert_allclose(s.xyz, truth.xyz, rtol=0, atol=TOL)


def test_csv_seconds_exact_to_the_nanosecond(tmp_path, truth):
    path = tmp_path / "s.csv"
    rows = [f"{t // 10**9}.{t % 10**9:09d},{x!r},{y!r},{z!r},0,0,0,1"
            for t, (x, y, z) in zip(truth.stamps_ns.tolist(), truth.xyz.tolist(), strict=True)]
    path.write_text("time,tx,ty,tz,qx,qy,qz,qw\n" + "\n".join(rows) + "\n")
    np.testing.assert_array_equal(read_stream(path).stamps_ns, truth.stamps_ns)
