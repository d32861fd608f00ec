"""Frame pairs resolved through /tf + /tf_static, compared with the composed closed-form truth.

Every dynamic edge moves with constant linear and angular velocity about a fixed axis, so linear
interpolation and SLERP between its samples are exact and the truth is known at any time.
Tree::

    world ─(50 Hz)─ base ─(static)─ cam0
      └──(20 Hz, +3 ms)─ arm ─(100 Hz)─ tool ─(static)─ cam1
"""
from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest
from _logs import LOG_KINDS, TF, Channel, write_log, write_mcap
from scipy.spatial.transform import Rotation

from handeye_cli.errors import HandEyeError
from handeye_cli.geometry import se3
from handeye_cli.io import inspect_log, read_stream

START = 1_700_000_000_000_000_000
DURATION_NS = 4 * 10**9
LOG_DELAY_NS = 5_000
# (parent, child) -> (rate Hz, phase ns, rotation axis, ω rad/s, p0 m, v m/s)
DYNAMIC = {
    ("world", "base"): (50, 0, [0, 0, 1], 0.7, [1.0, 2.0, 0.5], [0.3, -0.1, 0.05]),
    ("world", "arm"): (20, 3_000_000, [1, 1, 0], -0.4, [0.0, -1.0, 0.8], [0.0, 0.2, 0.0]),
    ("arm", "tool"): (100, 0, [0, 1, 0], 1.1, [0.4, 0.0, 0.3], [-0.05, 0.02, 0.1]),
}
STATIC = {("base", "cam0"): ([0.1, -0.02, 0.05], [0.1, 0.2, -0.3]),
          ("tool", "cam1"): ([0.0, 0.0, 0.12], [-0.5, 0.1, 0.2])}


def stamps(edge: tuple[str, str]) -> np.ndarray:
    rate, phase = DYNAMIC[edge][:2]
    return np.arange(START + phase, START + DURATION_NS, 10**9 // rate, dtype=np.int64)


def edge_truth(edge: tuple[str, str], t_ns: np.ndarray) -> np.ndarray:
    """(N, 4, 4) T_parent_child at any stamps (closed form)."""
    if edge in STATIC:
        xyz, rotvec = STATIC[edge]
        return np.broadcast_to(se3.from_xyz_quat(np.array(xyz), Rotation.from_rotvec(rotvec).as_quat()),
                               (len(t_ns), 4, 4))
    _, _, axis, omega, p0, v = DYNAMIC[edge]
    s = (t_ns - START).astype(float) / 1e9
    T = np.tile(np.eye(4), (len(t_ns), 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(np.outer(s * omega, np.array(axis) / np.linalg.norm(axis))).as_matrix()
    T[:, :3, 3] = np.array(p0) + np.outer(s, v)
    return T


def rec(edge: tuple[str, str], t: int, T: np.ndarray, slash: str = "") -> tuple:
    xyz, q = se3.to_xyz_quat(T)
    return (int(t), slash + edge[0], slash + edge[1], *xyz.tolist(), *q.tolist())


def tf_channels(slash: str = "", dynamic_type: str = TF, static_type: str = TF) -> list[Channel]:
    """/tf: one message per stamp holding every edge sampled then (often two); /tf_static: one
    message with both static edges."""
    by_stamp: dict[int, list[tuple]] = defaultdict(list)
    for edge in DYNAMIC:
        t = stamps(edge)
        for ti, T in zip(t, edge_truth(edge, t), strict=True):
            by_stamp[int(ti)].append(rec(edge, ti, T, slash))
    static = [rec(e, START, edge_truth(e, np.array([START]))[0], slash) for e in STATIC]
    return [Channel("/tf", dynamic_type, [(t + LOG_DELAY_NS, r) for t, r in sorted(by_stamp.items())]),
            Channel("/tf_static", static_type, [(START, static)], static=True)]


def chain_truth(t: np.ndarray, *edges: tuple[str, str], inverse_first: int = 0) -> np.ndarray:
    """Product of the edges at ``t``; the first ``inverse_first`` edges form an inverted prefix."""
    head = np.broadcast_to(np.eye(4), (len(t), 4, 4))
    for e in edges[:inverse_first]:
        head = head @ edge_truth(e, t)
    T = se3.inverse(head) if inverse_first else head
    for e in edges[inverse_first:]:
        T = T @ edge_truth(e, t)
    return T


LOGS = [*LOG_KINDS, "json"]


@pytest.fixture(scope="module", params=LOGS)
def tf_log(request, tmp_path_factory):
    d = tmp_path_factory.mktemp(request.param)
    if request.param == "json":
        return write_mcap(d / "fox.mcap", tf_channels(dynamic_type="foxglove.FrameTransforms",
                                                      static_type="foxglove.FrameTransforms"))
    return write_log(request.param, d, tf_channels(slash="/" if request.param == "bag1" else ""))


def assert_poses(s, T: np.ndarray, tol: float = 1e-10) -> None:
    np.testing.assert_allclose(s.matrices(), T, rtol=0, atol=tol)


def test_dynamic_plus_static(tf_log):
    s = read_stream(tf_log, frames=("world", "cam0"))
    t = stamps(("world", "base"))
    np.testing.assert_array_equal(s.stamps_ns, t)
    assert_poses(s, chain_truth(t, ("world", "base"), ("base", "cam0")))
    assert (s.frame_id, s.child_frame_id) == ("world", "cam0")


def test_chain_through_common_ancestor_interpolates(tf_log):
    """cam0 → base → world ← arm ← tool ← cam1: sampled at the 100 Hz edge, within the span
    of the 20 Hz and 50 Hz edges, which are interpolated."""
    s = read_stream(tf_log, frames=("cam0", "cam1"))
    ref = stamps(("arm", "tool"))
    lo, hi = stamps(("world", "arm"))[[0, -1]]
    np.testing.assert_array_equal(s.stamps_ns, ref[(ref >= lo) & (ref <= hi)])
    T = chain_truth(s.stamps_ns, ("world", "base"), ("base", "cam0"),
                    ("world", "arm"), ("arm", "tool"), ("tool", "cam1"), inverse_first=2)
    assert_poses(s, T)


def test_reverse_lookup_is_the_inverse(tf_log):
    fwd = read_stream(tf_log, frames=("world", "cam0"))
    back = read_stream(tf_log, frames=("/cam0", "/world"))
    assert_poses(back, se3.inverse(fwd.matrices()))


def test_tf_log_time(tf_log):
    s = read_stream(tf_log, frames=("world", "cam0"), time_source="log")
    t = stamps(("world", "base"))
    np.testing.assert_array_equal(s.stamps_ns, t + LOG_DELAY_NS)
    assert_poses(s, chain_truth(t, ("world", "base"), ("base", "cam0")))
    assert s.time_source == "log"


def test_inspect_lists_tf_tree(tf_log):
    edges = {(e["parent"], e["child"]): (e["static"], e["count"]) for e in inspect_log(tf_log)["tf_frames"]}
    assert edges == {**{k: (False, len(stamps(k))) for k in DYNAMIC}, **{k: (True, 1) for k in STATIC}}


def test_tf_message_topic_of_one_edge_reads_as_topic(tmp_path):
    edge = ("arm", "tool")
    t = stamps(edge)
    msgs = [(int(ti), [rec(edge, ti, T)]) for ti, T in zip(t, edge_truth(edge, t), strict=True)]
    s = read_stream(write_mcap(tmp_path / "one.mcap", [Channel("/tf", TF, msgs)]), topic="/tf")
    assert_poses(s, edge_truth(edge, t))
    assert (s.frame_id, s.child_frame_id) == edge


def test_duplicated_tf_samples_dropped(tmp_path):
    ch = tf_channels()
    msgs = list(ch[0].messages)
    ch[0].messages = msgs + msgs[:5]            # a recorder hiccup re-sent five messages
    s = read_stream(write_mcap(tmp_path / "dup.mcap", ch), frames=("world", "cam0"))
    np.testing.assert_array_equal(s.stamps_ns, stamps(("world", "base")))
    assert s.duplicates_dropped == sum(r[1:3] == ("world", "base") for _, m in msgs[:5] for r in m) == 2


# --- errors -----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def mcap_tf(tmp_path_factory):
    return write_mcap(tmp_path_factory.mktemp("tf") / "tf.mcap", tf_channels())


def test_unknown_frame_lists_known_frames(mcap_tf):
    with pytest.raises(HandEyeError, match=r"unknown TF frame 'cam9'.*known frames: arm, base, cam0, cam1"):
        read_stream(mcap_tf, frames=("world", "cam9"))


def test_static_only_chain(mcap_tf):
    with pytest.raises(HandEyeError, match="static transforms only"):
        read_stream(mcap_tf, frames=("base", "cam0"))


def test_two_parents_and_disconnected_frames(tmp_path):
    ch = tf_channels()
    ch[1].messages = [*ch[1].messages, (START + 1, [rec(("other", "cam0"), START, np.eye(4))])]
    with pytest.raises(HandEyeError, match="two parents"):
        read_stream(write_mcap(tmp_path / "x.mcap", ch), frames=("world", "cam0"))
    ch[1].messages = [(START, [rec(("island", "rock"), START, np.eye(4))])]
    with pytest.raises(HandEyeError, match="not connected.*roots 'world' and 'island'"):
        read_stream(write_mcap(tmp_path / "y.mcap", ch), frames=("world", "rock"))


def test_dynamic_edges_without_overlap(tmp_path):
    t = stamps(("world", "base"))
    early = [(int(ti), [rec(("world", "base"), ti, np.eye(4))]) for ti in t[:10]]
    late = [(int(ti), [rec(("base", "cam0"), ti, np.eye(4))]) for ti in t[-10:]]
    path = write_mcap(tmp_path / "gap.mcap", [Channel("/tf", TF, early + late)])
    with pytest.raises(HandEyeError, match="do not overlap in time"):
        read_stream(path, frames=("world", "cam0"))


def test_zero_static_quaternion(tmp_path):
    ch = tf_channels()
    ch[1].messages = [(START, [(START, "base", "cam0", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)])]
    with pytest.raises(HandEyeError, match=r"zero-norm quaternion.*TF base->cam0, transform 0"):
        read_stream(write_mcap(tmp_path / "z.mcap", ch), frames=("world", "cam0"))


def test_no_tf_topics(tmp_path):
    from _logs import POSE, pose_channel
    path = write_mcap(tmp_path / "p.mcap", [pose_channel("/p", POSE, [(START, "w", "", 0, 0, 0, 0, 0, 0, 1)])])
    with pytest.raises(HandEyeError, match=r"no TF topics.*pose topics: /p \(geometry_msgs/msg/PoseStamped\)"):
        read_stream(path, frames=("w", "c"))
