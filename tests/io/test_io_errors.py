"""Every bad input gives one HandEyeError line ``what (where): fix`` that names the file."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from _logs import (
    FOX_POSES,
    LOG_KINDS,
    POSE,
    TF,
    Channel,
    json_message,
    pose_channel,
    records,
    write_euroc,
    write_log,
    write_mcap,
    write_tum,
)
from _util import fails
from mcap.reader import make_reader

from handeye_cli.io import inspect_log, read_stream
from handeye_cli.simulation import Rig, simulate_rig

ZERO_Q = (0.0, 0.0, 0.0, 0.0)
NAN_Q = (float("nan"), 0.0, 0.0, 1.0)


@pytest.fixture(scope="module")
def recs() -> list[tuple]:
    a, _ = simulate_rig(Rig(np.eye(4)), duration_s=3.0, rate_a=20.0, seed=3)
    return records(a, "world", "")




def cut(path: Path, keep: int | float) -> Path:
    """Cut the file at ``path`` (or the storage file of a bag directory) in place, to ``keep``
    bytes (int; negative = drop that many from the end) or a fraction (float) of its size."""
    storage = path if path.is_file() else next(p for p in path.iterdir() if p.name != "metadata.yaml")
    data = storage.read_bytes()
    n = int(len(data) * keep) if isinstance(keep, float) else keep % len(data)
    storage.write_bytes(data[:n])
    return path


# --- arguments --------------------------------------------------------------------------------
def test_argument_errors(tmp_path, recs):
    log = write_mcap(tmp_path / "a.mcap", [pose_channel("/p", POSE, recs)])
    tum = write_tum(tmp_path / "a.tum", simulate_rig(Rig(np.eye(4)), duration_s=1.0)[0])
    fails(lambda: read_stream([]), "no input file")
    fails(lambda: read_stream(log, topic="/p", time_source="gps"), "unknown time source 'gps'", "header.*log")
    fails(lambda: read_stream(log), "exactly one of a topic or a .parent, child. frame pair", "a.mcap")
    fails(lambda: read_stream(log, topic="/p", frames=("a", "b")), "exactly one of")
    fails(lambda: read_stream(tum, topic="/p"), "TUM text file holds one stream", "drop --topic")
    fails(lambda: read_stream([tum, tum]), "one file per stream")
    fails(lambda: read_stream([log, log], topic="/p"), "only when all are ROS 1 .bag files")


# --- files ------------------------------------------------------------------------------------
def test_missing_empty_and_unrecognised_files(tmp_path):
    fails(lambda: read_stream(tmp_path / "nope.mcap", topic="/p"), "file not found", "nope.mcap")
    (tmp_path / "empty.bag").write_bytes(b"")
    fails(lambda: read_stream(tmp_path / "empty.bag", topic="/p"), r"empty file \(0 bytes\)", "empty.bag")
    (tmp_path / "dir").mkdir()
    fails(lambda: read_stream(tmp_path / "dir", topic="/p"), "not a ROS 2 bag .no metadata.yaml.")
    (tmp_path / "blob.bin").write_bytes(bytes(range(256)) * 4)
    fails(lambda: read_stream(tmp_path / "blob.bin"), "unrecognised file format", "blob.bin")
    (tmp_path / "comments.tum").write_text("# nothing here\n\n")
    fails(lambda: read_stream(tmp_path / "comments.tum"), "no data lines")


@pytest.mark.parametrize("suffix, kind", [(".mcap", "MCAP"), (".bag", "ROS 1 bag"), (".db3", "ROS 2 SQLite bag")])
def test_wrong_magic(tmp_path, suffix, kind):
    path = tmp_path / f"x{suffix}"
    path.write_text("1.0 0 0 0 0 0 0 1\n")          # a TUM line under a log suffix
    fails(lambda: read_stream(path, topic="/p"), f"not a valid {kind} file: wrong magic", f"x{suffix}")


MCAP_KINDS = ("mcap", "mcap_ros1", "bag2_mcap")


@pytest.mark.parametrize("kind, keep", [(k, keep) for k in LOG_KINDS for keep in (0.5, -8, 20)
                                        if not (k in ("db3", "bag2_sqlite", *MCAP_KINDS) and keep == -8)
                                        and (k, keep) not in (("bag2_mcap", 0.5), ("bag1", -8), ("bag1", 0.5))])
def test_truncated_logs(tmp_path, recs, kind, keep):
    """Cut at half (inside the only chunk), minus the last 8 bytes (the closing magic; SQLite does
    not need those) or down to 20 bytes: nothing intact to recover, so an error. (Recovery of the
    intact part of crashed recordings — rosbag2's uncompressed MCAP or a ROS 1 bag cut at half, a ROS 1 bag
    that lost the end of its index: tests/io/test_io_crashed.py.)"""
    path = cut(write_log(kind, tmp_path, [pose_channel("/p", POSE, recs), pose_channel("/q", POSE, recs)]), keep)
    fails(lambda: read_stream(path, topic="/p"), "cannot read file", str(path))


@pytest.mark.parametrize("kind", MCAP_KINDS)
def test_mcap_without_closing_magic_reads_everything(tmp_path, recs, kind):
    path = cut(write_log(kind, tmp_path, [pose_channel("/p", POSE, recs), pose_channel("/q", POSE, recs)]), -8)
    s = read_stream(path, topic="/p")
    assert len(s) == len(recs) and s.recovered_truncated == 0


def test_truncated_json_mcap(tmp_path, recs):
    path = cut(write_mcap(tmp_path / "j.mcap", [pose_channel("/p", "foxglove.PoseInFrame", recs)]), 0.5)
    fails(lambda: read_stream(path, topic="/p"), "cannot read file", "j.mcap", "mcap recover")


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
@pytest.mark.parametrize("msgtype", [POSE, "foxglove.PoseInFrame"])
def test_corrupt_chunk(tmp_path, compression, msgtype):
    """Bytes flipped inside a chunk whose wanted messages run to its end: its CRC (or the
    decompressor) catches it, whichever path reads it."""
    a, _ = simulate_rig(Rig(np.eye(4)), duration_s=20.0, rate_a=30.0, seed=5)
    path = write_mcap(tmp_path / "c.mcap", [pose_channel("/p", msgtype, records(a))], compression=compression,
                      chunk_size=20_000)
    with open(path, "rb") as f:
        chunk = make_reader(f).get_summary().chunk_indexes[1]
    data = bytearray(path.read_bytes())
    middle = chunk.chunk_start_offset + chunk.chunk_length // 2
    data[middle:middle + 64] = bytes(b ^ 0x5A for b in data[middle:middle + 64])
    path.write_bytes(bytes(data))
    fails(lambda: read_stream(path, topic="/p"), "cannot (read file|decode message)", "c.mcap")


def test_corrupt_message_payload(tmp_path, recs):
    msgs = [(r[0], [r]) for r in recs[:5]] + [(recs[5][0], b"\x00\x01\x00\x00\x07")]
    path = write_mcap(tmp_path / "m.mcap", [Channel("/p", POSE, msgs)])
    fails(lambda: read_stream(path, topic="/p"), "cannot decode message", r"m.mcap:/p, message 5", "corrupt")


# --- topics and message types -----------------------------------------------------------------
@pytest.mark.parametrize("kind", LOG_KINDS)
def test_unknown_topic_lists_pose_topics(tmp_path, recs, kind):
    path = write_log(kind, tmp_path, [pose_channel("/cam0/pose", POSE, recs), pose_channel("/tf", TF, recs)])
    fails(lambda: read_stream(path, topic="/cam1/pose"), "unknown topic '/cam1/pose'",
          r"pose topics in this file: /cam0/pose \(geometry_msgs/msg/PoseStamped\), /tf \(tf2_msgs/msg/TFMessage\)")


def test_unsupported_type_and_no_pose_topics(tmp_path, recs):
    from _logs import ROS2_STORE
    T = ROS2_STORE.types
    point = T["geometry_msgs/msg/PointStamped"](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=1, nanosec=0), frame_id="w"),
        point=T["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=3.0))
    path = write_mcap(tmp_path / "pt.mcap", [Channel("/gps", "geometry_msgs/msg/PointStamped", [(1, point)])])
    fails(lambda: read_stream(path, topic="/gps"), "unsupported message type 'geometry_msgs/msg/PointStamped'",
          "supported types: .*PoseStamped", "pose topics in this file: none")


def test_empty_stream(tmp_path):
    path = write_mcap(tmp_path / "e.mcap", [Channel("/p", POSE, [])])
    fails(lambda: read_stream(path, topic="/p"), "empty stream", r"e.mcap:/p")


def test_poses_in_frame_with_several_poses(tmp_path, recs):
    msg = json_message(FOX_POSES, recs[:1])
    msg["poses"] *= 3
    path = write_mcap(tmp_path / "f.mcap", [Channel("/p", FOX_POSES, [(1, msg)])])
    fails(lambda: read_stream(path, topic="/p"), "'poses' holds 3 poses", r"f.mcap:/p, message 0")


@pytest.mark.parametrize("damage", ["missing", "null", "string"])
def test_json_message_without_a_number_is_a_decode_error(tmp_path, recs, damage):
    """A JSON message lacking a field or holding a non-number is not of its type: one line, not a crash."""
    msg = json_message("foxglove.PoseInFrame", recs[:1])
    if damage == "missing":
        del msg["pose"]["orientation"]
    else:
        msg["pose"]["position"]["x"] = None if damage == "null" else "one"
    path = write_mcap(tmp_path / "j.mcap", [Channel("/p", "foxglove.PoseInFrame", [(1, msg)])])
    fails(lambda: read_stream(path, topic="/p"), "cannot decode message: BadField", r"j.mcap:/p, message 0",
          "not of its declared type")


def test_topic_with_several_frame_pairs(tmp_path, recs):
    two = [(r[0], [(*r[:2], "cam0", *r[3:]), (*r[:2], "cam1", *r[3:])]) for r in recs]
    path = write_mcap(tmp_path / "tf.mcap", [Channel("/tf", TF, two)])
    fails(lambda: read_stream(path, topic="/tf"), r"several frame pairs \(world->cam0, world->cam1\)",
          "--stream-a tf:PARENT,CHILD")


# --- invalid poses: dropped with a warning naming the sample --------------------------------
def dropped(stream, *patterns: str) -> None:
    """``stream`` lost exactly one sample and carries a warning matching every regex in ``patterns``."""
    text = " | ".join(stream.warnings)
    for p in ("dropped 1 invalid pose", *patterns):
        assert re.search(p, text), f"{p!r} not in {text!r}"


@pytest.mark.parametrize("kind", [*LOG_KINDS, "json"])
@pytest.mark.parametrize("bad", [ZERO_Q, NAN_Q], ids=["zero", "nan"])
def test_invalid_quaternion_in_logs(tmp_path, recs, kind, bad):
    broken = [*recs[:7], (*recs[7][:6], *bad), *recs[8:]]
    if kind == "json":
        path = write_mcap(tmp_path / "j.mcap", [pose_channel("/p", "foxglove.PoseInFrame", broken)])
    else:
        path = write_log(kind, tmp_path, [pose_channel("/p", POSE, broken)])
    s = read_stream(path, topic="/p")
    assert len(s) == len(recs) - 1 and recs[7][0] not in s.stamps_ns
    dropped(s, "zero-norm quaternion", r":/p\b", "message 7")


def test_nan_position(tmp_path, recs):
    broken = [*recs[:2], (recs[2][0], "world", "", float("nan"), 0.0, 0.0, 0.0, 0.0, 0.0, 1.0), *recs[3:]]
    dropped(read_stream(write_mcap(tmp_path / "n.mcap", [pose_channel("/p", POSE, broken)]), topic="/p"),
            "NaN/inf", "message 2")


def test_invalid_quaternion_in_text_names_the_line(tmp_path):
    a, _ = simulate_rig(Rig(np.eye(4)), duration_s=1.0, seed=1)
    path = write_tum(tmp_path / "a.tum", a)
    lines = path.read_text().splitlines()
    lines[4] = " ".join(lines[4].split()[:4] + ["0", "0", "0", "0"])
    path.write_text("\n".join(lines) + "\n")
    dropped(read_stream(path), "zero-norm quaternion", r"a.tum", "line 5")
    euroc = write_euroc(tmp_path / "e.csv", a)
    lines = euroc.read_text().splitlines()
    lines[2] = lines[2].split(",")[0] + ",nan" + ",0" * 15
    euroc.write_text("\n".join(lines) + "\n")
    dropped(read_stream(euroc), "NaN/inf", r"e.csv", "line 3")


# --- text syntax ------------------------------------------------------------------------------
def test_malformed_text(tmp_path):
    a, _ = simulate_rig(Rig(np.eye(4)), duration_s=1.0, seed=1)
    tum = write_tum(tmp_path / "a.tum", a)
    tum.write_text(tum.read_text() + "1700000001.5 1 2 3 0 0 1\n")
    fails(lambda: read_stream(tum), r"malformed line \(7 values\)", "expected 8 numbers", r"a.tum, line \d+",
          "fix or delete the line")
    csv = tmp_path / "c.csv"
    csv.write_text("time,x,y,z,qx,qy,qz,qw\n1.0,1,2,3,0,0,0,1\n2.0,1,2,x,0,0,0,1\n")
    fails(lambda: read_stream(csv), "could not convert string to float", "c.csv, line 3")


def test_csv_columns(tmp_path):
    csv = tmp_path / "c.csv"
    csv.write_text("time,x,y,height,qx,qy,qz,qw\n1.0,1,2,3,0,0,0,1\n")
    e = fails(lambda: read_stream(csv), "CSV column for 'z' not found", "header has: time, x, y, height",
              "--csv-columns z=COLUMN")
    assert "columns={" not in str(e)
    assert read_stream(csv, columns={"z": "height"}).xyz.tolist() == [[1.0, 2.0, 3.0]]
    fails(lambda: read_stream(csv, columns={"z": "height", "t_unit": "days"}), "unknown time unit 'days'")
    csv.write_text("timestamp,x,y,z,qx,qy,qz,qw\n1700000000000000000,1,2,3,0,0,0,1\n")
    fails(lambda: read_stream(csv, time_unit="s"), "out of the int64 nanosecond range .wrong time unit", "line 2",
          "--time-unit")
    assert read_stream(csv).stamps_ns.tolist() == [1700000000000000000]     # auto: epoch nanoseconds


def test_inspect_errors(tmp_path):
    fails(lambda: inspect_log(tmp_path / "none.bag"), "file not found")
    (tmp_path / "x.mcap").write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 10)
    fails(lambda: inspect_log(tmp_path / "x.mcap"), "cannot read file", "x.mcap")


def test_two_unknown_topics_name_stream_a_first_whatever_the_hash_seed() -> None:
    """Both topics missing: the error names a's, in every process (it named whichever a set's order gave first,
    which differs with PYTHONHASHSEED)."""
    import os
    import subprocess
    import sys

    from _util import ROOT

    lines = set()
    for seed in ("1", "2", "3", "4"):
        log = str(ROOT / "sample_data" / "ground.mcap")
        out = subprocess.run([sys.executable, "-m", "handeye_cli", "calibrate", log, "--topic-a", "/nope_a",
                              "--topic-b", "/nope_b"], capture_output=True, text=True,
                             env={**os.environ, "PYTHONHASHSEED": seed}, cwd=ROOT)
        assert out.returncode == 2
        lines.add(out.stderr.split("(")[0])
    assert lines == {"error: unknown topic '/nope_a' "}, lines
