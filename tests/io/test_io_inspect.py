"""``inspect_log``: topics, types, counts, rates, pose topics and the TF tree; and the progress bar."""
from __future__ import annotations

import io
import json
import sys

import numpy as np
import pytest
from _logs import (
    LOG_KINDS,
    ODOM,
    POSE,
    ROS2_STORE,
    TF,
    Channel,
    pose_channel,
    records,
    write_csv,
    write_euroc,
    write_log,
    write_mcap,
    write_tum,
)
from _util import run

from handeye_cli.io import inspect_log, read_stream
from handeye_cli.simulation import Rig, simulate_rig


@pytest.fixture(scope="module")
def streams():
    return simulate_rig(Rig(np.eye(4)), duration_s=10.0, rate_a=30.0, rate_b=10.0, seed=2)


def log_channels(a, b) -> list[Channel]:
    """Two pose topics, /tf with two edges per message, /tf_static, and a non-pose topic."""
    t0 = int(a.stamps_ns[0])
    note = ROS2_STORE.types["std_msgs/msg/String"](data="not a pose")
    tf = [(r[0], [r, (r[0], "world", "base", *r[3:])]) for r in records(b, "base", "cam1")]
    return [pose_channel("/cam0/pose", POSE, records(a, "world", "")),
            pose_channel("/odom", ODOM, records(b, "odom", "base")),
            Channel("/tf", TF, tf),
            Channel("/tf_static", TF, [(t0, [(t0, "cam1", "lens", 0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0)])], static=True),
            Channel("/notes", "std_msgs/msg/String", [(int(t), note) for t in a.stamps_ns[::30]])]


@pytest.mark.parametrize("kind", LOG_KINDS)
def test_inspect_log(tmp_path, streams, kind):
    a, b = streams
    path = write_log(kind, tmp_path, log_channels(a, b))
    info = inspect_log(path)
    json.dumps(info)                                         # JSON-able as is
    fmt = {"mcap": "mcap", "mcap_ros1": "mcap", "bag1": "rosbag1"}.get(kind, "rosbag2")
    assert (info["format"], info["path"]) == (fmt, str(path))
    first, last = int(min(a.stamps_ns[0], b.stamps_ns[0])), int(max(a.stamps_ns[-1], b.stamps_ns[-1]))
    assert (info["start_ns"], info["end_ns"], info["duration_ns"]) == (first, last, last - first)
    topics = {t["topic"]: t for t in info["topics"]}
    assert [t["topic"] for t in info["topics"]] == sorted(topics)
    enc = "ros1" if kind in ("mcap_ros1", "bag1") else "cdr"
    own = int(a.stamps_ns[-1] - a.stamps_ns[0])              # rated over its own span, not the log's
    assert topics["/cam0/pose"] == {"topic": "/cam0/pose", "type": POSE, "encoding": enc, "count": len(a),
                                    "first_ns": int(a.stamps_ns[0]), "last_ns": int(a.stamps_ns[-1]),
                                    "rate_hz": round((len(a) - 1) / own * 1e9, 3), "rate_over": "topic", "pose": True}
    assert topics["/odom"]["count"] == len(b) and topics["/odom"]["pose"]
    assert topics["/odom"]["rate_hz"] == round((len(b) - 1) / int(b.stamps_ns[-1] - b.stamps_ns[0]) * 1e9, 3)
    assert topics["/tf"]["type"] == TF and not topics["/tf"]["pose"]           # two frame pairs
    assert topics["/tf_static"]["type"] == TF and topics["/tf_static"]["pose"]  # one pair
    assert (topics["/tf_static"]["rate_hz"], topics["/tf_static"]["rate_over"]) == (None, "latched")
    assert info["warnings"] == [] and info["tf_messages"] == len(b) + 1
    assert topics["/notes"]["type"] == "std_msgs/msg/String" and not topics["/notes"]["pose"]
    assert info["tf_frames"] == [{"parent": "base", "child": "cam1", "static": False, "count": len(b)},
                                 {"parent": "cam1", "child": "lens", "static": True, "count": 1},
                                 {"parent": "world", "child": "base", "static": False, "count": len(b)}]


def test_inspect_json_channels(tmp_path, streams):
    a, _ = streams
    path = write_mcap(tmp_path / "fox.mcap", [pose_channel("/p", "foxglove.PoseInFrame", records(a)),
                                              pose_channel("/tf", "foxglove.FrameTransform", records(a, "w", "c"))])
    topics = {t["topic"]: t for t in inspect_log(path)["topics"]}
    assert topics["/p"]["type"] == "foxglove.PoseInFrame" and topics["/p"]["encoding"] == "json"
    assert topics["/p"]["pose"] and topics["/p"]["count"] == len(a)
    assert inspect_log(path)["tf_frames"] == [{"parent": "w", "child": "c", "static": False, "count": len(a)}]


@pytest.mark.parametrize("writer, fmt", [(write_tum, "tum"), (write_euroc, "euroc"),
                                         (lambda p, s: write_csv(p, s, ["t_ns", "x", "y", "z", "qx", "qy", "qz", "qw"]),
                                          "csv")])
def test_inspect_text(tmp_path, streams, writer, fmt):
    a, _ = streams
    info = inspect_log(writer(tmp_path / "traj.txt", a))
    span = int(a.stamps_ns[-1] - a.stamps_ns[0])
    assert info == {"format": fmt, "path": str(tmp_path / "traj.txt"), "rows": len(a),
                    "start_ns": int(a.stamps_ns[0]), "end_ns": int(a.stamps_ns[-1]), "duration_ns": span,
                    "rate_hz": round((len(a) - 1) / span * 1e9, 3)}


# --- progress bar -----------------------------------------------------------------------------
class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.fixture()
def big_log(tmp_path):
    a, _ = simulate_rig(Rig(np.eye(4)), duration_s=60.0, rate_a=200.0, seed=4)
    return write_mcap(tmp_path / "big.mcap", [pose_channel("/p", POSE, records(a))])


@pytest.mark.parametrize("tty, quiet, shown", [(True, False, True), (True, True, False), (False, False, False)])
def test_progress_bar_only_on_a_terminal_and_not_quiet(big_log, monkeypatch, tty, quiet, shown):
    err = _Tty() if tty else io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    assert len(read_stream(big_log, topic="/p", quiet=quiet)) == 12_000
    assert ("reading /p" in err.getvalue() and "100%" in err.getvalue()) == shown
    assert shown or err.getvalue() == ""


def test_inspect_text_rates_tf_tree_and_a_cut_file_as_the_user_reads_them(capsys, tmp_path):
    """What a new user hit (issue 21): rates over the whole log's span (99.651 Hz for 100 Hz, 0.007 Hz for a
    latched /tf_static), TF edge counts stopping at 2000, a flat edge list where a tree was promised, and
    nothing said of a file cut off."""
    a, b = simulate_rig(Rig(np.eye(4)), duration_s=30.0, rate_a=100.0, rate_b=10.0, seed=3)
    late = [(int(t) + 10**9, [(int(t) + 10**9, "odom", "base", *r[3:])]) for t, r in
            zip(b.stamps_ns, records(b, "odom", "base"), strict=True)]        # 10 Hz, ends 1 s after a
    t0 = int(a.stamps_ns[0])
    path = write_mcap(tmp_path / "log.mcap", [
        pose_channel("/cam0/pose", POSE, records(a, "world", "")),
        Channel("/tf", TF, [(r[0], [r]) for r in records(a, "world", "odom")] + late),
        Channel("/tf_static", TF, [(t0, [(t0, "base", "cam1", 0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0)])], static=True)],
        chunk_size=30_000)
    code, out, err = run(capsys, "inspect", path)
    assert code == 0 and err == ""
    rows = {line.split()[1]: line for line in out.splitlines() if line.startswith("  * ") or line.startswith("    /")}
    own = (len(a) - 1) / (a.stamps_ns[-1] - a.stamps_ns[0]) * 1e9
    assert rows["/cam0/pose"].endswith(f"{len(a)} msgs  {round(own, 3)} Hz") and abs(own - 100.0) < 0.05
    assert rows["/tf_static"].endswith("1 msgs  latched (static)")
    n_tf = len(a) + len(b) + 1
    assert n_tf > 2000 and f"TF tree, from all {n_tf} TF messages" in out
    tree = out.split("tf:PARENT,CHILD, the parent first):\n", 1)[1].splitlines()
    assert tree == ["    world", f"      odom  {len(a)} msgs", f"        base  {len(b)} msgs", "          cam1  static"]
    data = path.read_bytes()
    path.write_bytes(data[:len(data) * 2 // 3])                       # the recorder was killed
    code, out, err = run(capsys, "inspect", path)
    warning = out.splitlines()[1]
    assert code == 0 and warning.startswith(f"  warning: {path} is cut off") and "is lost" in warning


def test_a_topic_whose_span_the_log_does_not_tell_is_rated_over_the_logs(tmp_path, streams, monkeypatch):
    """A storage the readers cannot ask for a topic's span (several MCAP files of a ROS 2 bag, a compressed
    .db3): its rate is over the log's span, and says so."""
    from handeye_cli.cli.inspect import _rate
    from handeye_cli.io import mcap_reader

    a, b = streams
    path = write_mcap(tmp_path / "log.mcap", log_channels(a, b))
    monkeypatch.setattr(mcap_reader.McapSource, "topic_spans", lambda self: {})
    info = inspect_log(path)
    cam = next(t for t in info["topics"] if t["topic"] == "/cam0/pose")
    assert (cam["first_ns"], cam["last_ns"], cam["rate_over"]) == (None, None, "log")
    assert cam["rate_hz"] == round(len(a) / info["duration_ns"] * 1e9, 3)
    assert _rate(cam) == f"{cam['rate_hz']} Hz (over the log's span)"
