"""The fast paths give exactly what the generic readers give: MCAP (numpy CDR decode at computed
offsets vs rosbags/mcap per message) and text (vectorised block parser vs the line loop)."""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from _logs import (
    ODOM,
    POSE,
    ROS_POSE_TYPES,
    TF,
    TRANSFORM,
    Channel,
    image_channel,
    pose_channel,
    records,
    write_mcap,
    write_tum,
)

from handeye_cli.errors import HandEyeError
from handeye_cli.io.logs import read_requests
from handeye_cli.io.mcap_reader import McapSource
from handeye_cli.io.table import fast_table, slow_table
from handeye_cli.simulation import Rig, simulate_rig

SAMPLES = Path(__file__).resolve().parents[2] / "sample_data"


def both_paths(path: Path, requests, time_source: str = "header"):
    """(fast, generic) streams of ``requests``; asserts the fast path really decoded the topics."""
    with McapSource(path) as src:
        topics = sorted({t for t, _ in requests if t} | ({t.topic for t in src.topics() if "TF" in t.msgtype}
                                                         if any(f for _, f in requests) else set()))
        assert set(src.read_fast(topics, time_source)) == set(topics), "fast path declined"
        fast = read_requests(src, requests, time_source=time_source)
    with McapSource(path, fast=False) as src:
        slow = read_requests(src, requests, time_source=time_source)
    return fast, slow


def assert_identical(a, b) -> None:
    np.testing.assert_array_equal(a.stamps_ns, b.stamps_ns)
    np.testing.assert_array_equal(a.xyz, b.xyz)
    np.testing.assert_array_equal(a.quat_xyzw, b.quat_xyzw)
    assert (a.frame_id, a.child_frame_id, a.duplicates_dropped, a.warnings) == \
        (b.frame_id, b.child_frame_id, b.duplicates_dropped, b.warnings)


@pytest.fixture(scope="module")
def rig():
    return simulate_rig(Rig(np.eye(4)), duration_s=6.0, rate_a=50.0, rate_b=20.0, seed=11)


def test_sample_rig_mcap():
    """Pose topics and TF pairs of the sample rig; both paths give identical arrays."""
    requests = [("/cam0/pose", None), ("/cam1/pose", None), (None, ("world", "cam0")), (None, ("world", "cam1"))]
    for a, b in zip(*both_paths(SAMPLES / "rig.mcap", requests), strict=True):
        assert len(a) > 100
        assert_identical(a, b)


def test_sample_json_mcap_is_left_to_the_generic_reader():
    """Foxglove JSON channels are not CDR: the fast path declines them, the result is the generic one."""
    with McapSource(SAMPLES / "rig_json.mcap") as src:
        assert src.read_fast(["/cam0/pose", "/tf"], "header") == {}
        (s,) = read_requests(src, [("/cam0/pose", None)])
    assert len(s) == 2250


@pytest.mark.parametrize("msgtype", ROS_POSE_TYPES)
@pytest.mark.parametrize("time_source", ["header", "log"])
def test_every_pose_type(tmp_path, rig, msgtype, time_source):
    """Each type beside another topic, small chunks (many chunks, interleaved topics)."""
    child = "cam" if msgtype in (TRANSFORM, ODOM, TF) else ""
    recs = records(rig[0], "odom", child)
    path = write_mcap(tmp_path / "t.mcap", [pose_channel("/p", msgtype, recs, log_offset_ns=7),
                                            pose_channel("/other", POSE, records(rig[1], "w", ""))],
                      chunk_size=4000)
    (a,), (b,) = both_paths(path, [("/p", None)], time_source)
    assert len(a) == len(recs)
    assert_identical(a, b)


def test_chunk_decompressed_only_as_far_as_needed(tmp_path, rig, monkeypatch):
    """/early ends early in the (only) chunk: the zstd stream stops after its last message, and
    the reader never holds more of the chunk than that."""
    import handeye_cli.io.mcap_fast as mcap_fast
    a, b = rig
    early = records(a, "w", "")[: len(a) // 6]
    path = write_mcap(tmp_path / "e.mcap", [pose_channel("/early", POSE, early),
                                            pose_channel("/all", POSE, records(b, "w", ""))])
    held = []
    real = mcap_fast._Chunks.read

    def read(self, index, wanted):
        out = real(self, index, wanted)
        held.append((len(out[1]), len(self._raw), index.uncompressed_size))
        return out

    monkeypatch.setattr(mcap_fast._Chunks, "read", read)
    (fast,), (slow,) = both_paths(path, [("/early", None)])
    assert_identical(fast, slow)
    assert len(fast) == len(early) and held and all(max(n, buf) < total * 0.6 for n, buf, total in held)


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
@pytest.mark.parametrize("image_bytes, distinct", [(20_000, False), (60_000, True)])
def test_image_heavy_log(tmp_path, rig, compression, image_bytes, distinct):
    """Poses, /tf and images interleaved, chunks of 50 kB that each end in an image: 20 kB images
    (the last pose about 2/3 into its chunk: zstd decompresses the whole frame in one pass) or 60 kB
    ones (a chunk is a few poses and one image: zstd streams only through the last pose). Both
    paths agree on every pose topic and TF pair, with header stamps and with log times."""
    a, b = rig
    path = write_mcap(tmp_path / "i.mcap", [
        pose_channel("/a/pose", POSE, records(a, "world", "")), pose_channel("/b/pose", POSE, records(b, "odom", "")),
        pose_channel("/tf", TF, records(a, "world", "base_link")),
        image_channel("/camera/image", int(a.stamps_ns[0]), int(a.stamps_ns[-1]), 20.0, image_bytes,
                      distinct=distinct)], compression=compression, chunk_size=50_000)
    requests = [("/a/pose", None), ("/b/pose", None), (None, ("world", "base_link"))]
    for time_source in ("header", "log"):
        for fast, slow in zip(*both_paths(path, requests, time_source), strict=True):
            assert len(fast) >= len(b)
            assert_identical(fast, slow)


@pytest.mark.parametrize("msgtype", [POSE, ODOM, TF])
def test_decoded_in_batches(tmp_path, rig, msgtype, monkeypatch):
    """Batches smaller than a chunk (and ending inside one), frame ids of varying length: the
    same arrays as one batch (which test_frame_ids_of_varying_length compares with the generic reader)."""
    import handeye_cli.io.mcap_fast as mcap_fast
    recs = [(r[0], "m" * (1 + i % 2), "c" * (1 + i % 3), *r[3:]) for i, r in enumerate(records(rig[0]))]
    path = write_mcap(tmp_path / "b.mcap", [pose_channel("/p", msgtype, recs[:40]),
                                            pose_channel("/q", msgtype, recs[40:])], chunk_size=3000)
    with McapSource(path) as src:
        whole = src.read_fast(["/p", "/q"], "header")
        monkeypatch.setattr(mcap_fast, "_BATCH", 7)
        batched = src.read_fast(["/p", "/q"], "header")
    assert set(whole) == set(batched) == {"/p", "/q"}
    for topic, poses in whole.items():
        np.testing.assert_array_equal(poses.stamps, batched[topic].stamps)
        np.testing.assert_array_equal(poses.values, batched[topic].values)
        np.testing.assert_array_equal(poses.pair, batched[topic].pair)
        assert poses.pair_names == batched[topic].pair_names and len(poses.pair_names) == (2 if msgtype == POSE else 6)


@pytest.mark.parametrize("msgtype", [POSE, ODOM])
def test_frame_ids_of_varying_length(tmp_path, rig, msgtype):
    """Strings of different lengths per message move every later offset: the fast path sees the
    same frame pairs (and so the same error) as the generic one."""
    recs = [(r[0], "m" * (1 + i % 5), "c" * (1 + i % 3), *r[3:]) for i, r in enumerate(records(rig[0]))]
    path = write_mcap(tmp_path / "v.mcap", [pose_channel("/p", msgtype, recs)], chunk_size=3000)
    errors = []
    for fast in (True, False):
        with McapSource(path, fast=fast) as src, pytest.raises(HandEyeError, match="several frame pairs") as info:
            read_requests(src, [("/p", None)])
        errors.append(str(info.value))
    assert errors[0] == errors[1]


def test_tf_messages_with_several_transforms(tmp_path, rig):
    a_recs, b_recs = records(rig[0], "world", "base"), records(rig[1], "base", "camera_optical_frame")
    n = min(len(a_recs), len(b_recs))
    msgs = [(a_recs[i][0], [a_recs[i], (a_recs[i][0], *b_recs[i][1:])] if i % 2 else [a_recs[i]]) for i in range(n)]
    path = write_mcap(tmp_path / "tf.mcap", [Channel("/tf", TF, msgs)], chunk_size=3000)
    fast, slow = both_paths(path, [(None, ("world", "camera_optical_frame")), (None, ("world", "base"))])
    for a, b in zip(fast, slow, strict=True):
        assert len(a) > 10
        assert_identical(a, b)


def test_big_endian_payload_falls_back(tmp_path, rig):
    """A payload the fast path does not handle (here: a corrupt encapsulation header) leaves the
    topic to the generic decoder, which reports it."""
    recs = records(rig[0], "w", "")
    msgs = [(r[0], [r]) for r in recs[:5]] + [(recs[5][0], b"\x00\x00\x00\x00" + b"\x00" * 60)]
    path = write_mcap(tmp_path / "be.mcap", [Channel("/p", POSE, msgs)])
    with McapSource(path) as src:
        assert src.read_fast(["/p"], "header") == {}


# --- text -------------------------------------------------------------------------------------
ODD = (b"# comment\n\n1.5 1 2 3 0 0 0 1\r\n  \t\n-2.25,1e-3,2,3,0,0,0,1\n3\t1\t2\t3\t0\t0\t0\t1   \n"
       b"# another\n1700000000.123456789 0.1 -0.2 nan 0 0 0 1\n17 1 2 3 0 0 0 1")


@pytest.mark.parametrize("data", [ODD, ODD.replace(b"\n", b"\r\n"), b"1 2 3 4 5 6 7 8\n" * 3])
def test_text_fast_equals_slow(data):
    fast = fast_table(io.BytesIO(data))
    slow = slow_table(io.BytesIO(data), "x", need=8, expected="")
    assert fast is not None
    np.testing.assert_array_equal(fast.lines, slow.lines)
    np.testing.assert_array_equal(fast.values[:, 1:], slow.values[:, 1:])
    for digits in (9, 6, 3, 0):
        np.testing.assert_array_equal(fast.stamps_ns(digits, "x"), slow.stamps_ns(digits, "x"))


def test_text_fast_declines_what_it_cannot_do_exactly():
    for data in (b"1.7e9 1 2 3 0 0 0 1\n", b"1.0000000001 1 2 3 0 0 0 1\n", b"1 2 3\n4 5 6 7\n", b"1 x 3\n"):
        assert fast_table(io.BytesIO(data)) is None


def test_tum_round_trip_on_many_blocks(tmp_path, monkeypatch, rig):
    """Blocks cut between lines: the parse over several 4 kB blocks equals the truth."""
    import handeye_cli.io.table as table
    from handeye_cli.io import read_stream
    monkeypatch.setattr(table, "_BLOCK", 4096)
    path = write_tum(tmp_path / "a.tum", rig[0])
    s = read_stream(path)
    np.testing.assert_array_equal(s.stamps_ns, rig[0].stamps_ns)
    np.testing.assert_allclose(s.xyz, rig[0].xyz, rtol=0, atol=0)


# --- inspect ----------------------------------------------------------------------------------
def test_inspect_counts_every_tf_message(tmp_path, monkeypatch):
    """Counts come from the summary; the TF edges from every TF message (they stopped at 2000, and
    a frame first sent late was missing), by the fast path and the generic reader alike."""
    from handeye_cli.io import inspect_log, mcap_reader
    a = simulate_rig(Rig(np.eye(4)), duration_s=60.0, rate_a=50.0, seed=4)[0]
    late = (int(a.stamps_ns[-1]), [(int(a.stamps_ns[-1]), "world", "late_frame", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)])
    path = write_mcap(tmp_path / "tf.mcap", [Channel("/tf", TF, [(r[0], [r]) for r in records(a, "world", "base")]
                                                     + [late])])
    n = len(a) + 1
    assert n > 2000
    fast = inspect_log(path)
    monkeypatch.setattr(mcap_reader.McapSource, "read_fast", lambda self, topics, time_source: {})
    slow = inspect_log(path)
    for info in (fast, slow):
        assert info["topics"][0]["count"] == info["tf_messages"] == n
        assert info["tf_frames"] == [{"parent": "world", "child": "base", "static": False, "count": len(a)},
                                     {"parent": "world", "child": "late_frame", "static": False, "count": 1}]
