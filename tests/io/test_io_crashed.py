"""Crashed and unusual recordings: every intact message is read, with a warning saying what was lost.

MCAP files without a summary section, with a summary but no Statistics record, cut off without
footer or in the middle of a chunk; ROS 1 bags never indexed; ROS 2 bags without (or with a
corrupt) metadata.yaml. Files are written by tests/_logs.py and then damaged byte-wise here.
"""
from __future__ import annotations

import re
import struct
from pathlib import Path

import numpy as np
import pytest
from _logs import POSE, TF, pose_channel, records, write_bag1, write_log, write_mcap

from handeye_cli.errors import HandEyeError
from handeye_cli.io import inspect_log, read_stream
from handeye_cli.simulation import Rig, simulate_rig

MAGIC = b"\x89MCAP0\r\n"


@pytest.fixture(scope="module")
def streams():
    return simulate_rig(Rig(np.eye(4)), duration_s=40.0, rate_a=50.0, rate_b=20.0, seed=7)


def _footer(summary_start: int) -> bytes:
    return bytes([0x02]) + struct.pack("<QQQI", 20, summary_start, 0, 0) + MAGIC


def _summary(path: Path) -> tuple[bytes, int, list[bytes]]:
    """(data section, summary start, summary records) of a complete MCAP."""
    data = path.read_bytes()
    summary_start, offsets_start = struct.unpack_from("<QQ", data, len(data) - 8 - 20)
    records, i = [], summary_start
    while i < (offsets_start or len(data) - 8 - 29):
        (n,) = struct.unpack_from("<Q", data, i + 1)
        records.append(data[i:i + 9 + n])
        i += 9 + n
    return data, summary_start, records


def without_summary(path: Path) -> Path:
    data, start, _ = _summary(path)
    path.write_bytes(data[:start] + _footer(0))
    return path


def without_statistics(path: Path) -> Path:
    data, start, records = _summary(path)
    path.write_bytes(data[:start] + b"".join(r for r in records if r[0] != 0x0B) + _footer(start))
    return path


def chunk_offsets(data: bytes) -> list[int]:
    """Offsets of the top-level Chunk records."""
    out, i = [], len(MAGIC)
    while i + 9 <= len(data):
        (n,) = struct.unpack_from("<Q", data, i + 1)
        if data[i] == 0x06:
            out.append(i)
        if data[i] == 0x0F:
            break
        i += 9 + n
    return out


def assert_prefix_of(s, truth, n_min: int) -> None:
    """``s`` holds at least ``n_min`` samples, each exactly a sample of ``truth``."""
    assert len(s) >= n_min
    index = np.searchsorted(truth.stamps_ns, s.stamps_ns)
    np.testing.assert_array_equal(truth.stamps_ns[index], s.stamps_ns)
    np.testing.assert_allclose(truth.xyz[index], s.xyz, rtol=0, atol=1e-12)


def two_topics(tmp_path: Path, streams, **kw) -> Path:
    a, b = streams
    return write_mcap(tmp_path / "r.mcap", [pose_channel("/a", POSE, records(a, "w", "")),
                                           pose_channel("/b", POSE, records(b, "w", ""))], **kw)


# --- valid MCAPs without summary or statistics ------------------------------------------------
@pytest.mark.parametrize("damage", [without_summary, without_statistics])
def test_valid_mcap_without_summary_or_statistics(tmp_path, streams, damage):
    path = damage(two_topics(tmp_path, streams, chunk_size=20_000))
    s = read_stream(path, topic="/a")
    np.testing.assert_array_equal(s.stamps_ns, streams[0].stamps_ns)
    assert s.warnings == () and s.recovered_truncated == 0
    info = inspect_log(path)
    assert {t["topic"]: t["count"] for t in info["topics"]} == {"/a": len(streams[0]), "/b": len(streams[1])}


# --- crashed MCAP recordings ------------------------------------------------------------------
@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_mcap_cut_mid_chunk(tmp_path, streams, compression):
    """Cut in the middle of the 3rd chunk: the first two chunks and the intact start of the third
    are read (zstd decompresses whole blocks, so less of a cut zstd chunk survives)."""
    path = two_topics(tmp_path, streams, chunk_size=30_000, compression=compression)
    data = path.read_bytes()
    starts = chunk_offsets(data)
    assert len(starts) > 4
    cut = (starts[2] + starts[3]) // 2
    path.write_bytes(data[:cut])
    s = read_stream(path, topic="/a")
    assert_prefix_of(s, streams[0], 10)
    assert len(s) < len(streams[0]) and s.recovered_truncated == len(s)
    (w,) = s.warnings
    assert re.fullmatch(rf"recovered {len(s)} messages from truncated .*r\.mcap; the rest is lost", w)
    info = inspect_log(path)                     # inspect says so too, and what is lost (it said nothing)
    (w,) = info["warnings"]
    assert w.startswith(f"{path} is cut off") and "whatever was recorded after the cut is lost" in w
    assert {t["topic"]: t["count"] for t in info["topics"]}["/a"] == len(s)


def test_mcap_without_footer(tmp_path, streams):
    """A recorder killed after writing its last chunk: no DataEnd, summary or footer."""
    path = two_topics(tmp_path, streams, chunk_size=30_000)
    data, start, _ = _summary(path)
    path.write_bytes(data[:start - 13])         # DataEnd (opcode, length, crc) gone as well
    s = read_stream(path, topic="/b")
    np.testing.assert_array_equal(s.stamps_ns, streams[1].stamps_ns)
    assert s.recovered_truncated == len(streams[1]) and "truncated" in s.warnings[0]


def test_truncated_tf_frames(tmp_path, streams):
    a, _ = streams
    path = write_mcap(tmp_path / "tf.mcap", [pose_channel("/tf", TF, records(a, "world", "base"))],
                      chunk_size=20_000, compression="none")
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    s = read_stream(path, frames=("world", "base"))
    assert_prefix_of(s, a, 100)
    assert s.recovered_truncated > 0 and "truncated" in s.warnings[0]


def test_rosbag2_mcap_storage_cut_at_half(tmp_path, streams):
    path = write_log("bag2_mcap", tmp_path, [pose_channel("/a", POSE, records(streams[0], "w", ""))])
    storage = next(path.glob("*.mcap"))
    storage.write_bytes(storage.read_bytes()[: storage.stat().st_size // 2])
    s = read_stream(path, topic="/a")
    assert_prefix_of(s, streams[0], 100)
    assert s.recovered_truncated == len(s)


# --- ROS 1 bags -------------------------------------------------------------------------------
def never_indexed(path: Path) -> Path:
    """What a killed `rosbag record` leaves: index_pos 0 in the bag header, no index section."""
    data = bytearray(path.read_bytes())
    at = data.index(b"index_pos=") + len(b"index_pos=")
    (index_pos,) = struct.unpack_from("<Q", data, at)
    data[at:at + 8] = bytes(8)
    path.write_bytes(bytes(data[:index_pos]))
    return path


@pytest.mark.parametrize("compression", [None, "lz4", "bz2"])
def test_rosbag1_never_indexed(tmp_path, streams, compression):
    path = never_indexed(write_bag1(tmp_path / "r.bag", [pose_channel("/a", POSE, records(streams[0], "w", "")),
                                                          pose_channel("/b", POSE, records(streams[1], "w", ""))],
                                    compression=compression))
    s = read_stream(path, topic="/b")
    np.testing.assert_array_equal(s.stamps_ns, streams[1].stamps_ns)
    assert any("no usable index" in w and "linear scan" in w for w in s.warnings)
    assert {t["topic"] for t in inspect_log(path)["topics"]} == {"/a", "/b"}


def test_rosbag1_cut_inside_its_chunk(tmp_path, streams):
    """Power loss in the middle of the (only, uncompressed) chunk: its complete messages are read."""
    path = write_bag1(tmp_path / "r.bag", [pose_channel("/a", POSE, records(streams[0], "w", ""))])
    path.write_bytes(path.read_bytes()[: int(path.stat().st_size * 0.6)])
    s = read_stream(path, topic="/a")
    assert_prefix_of(s, streams[0], 100)
    assert s.recovered_truncated == len(s) and any("truncated" in w for w in s.warnings)
    (note, cut) = inspect_log(path)["warnings"]
    assert "no usable index" in note and cut.startswith(f"{path} is cut off") and " s of messages are read" in cut


def test_rosbag1_with_a_damaged_index(tmp_path, streams):
    """The index section at the end lost its last bytes: the chunks are intact and read by a scan."""
    path = write_bag1(tmp_path / "r.bag", [pose_channel("/a", POSE, records(streams[0], "w", ""))])
    path.write_bytes(path.read_bytes()[:-8])
    s = read_stream(path, topic="/a")
    np.testing.assert_array_equal(s.stamps_ns, streams[0].stamps_ns)
    assert any("no usable index" in w for w in s.warnings)


# --- ROS 2 bags -------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["bag2_sqlite", "bag2_mcap"])
def test_rosbag2_without_metadata(tmp_path, streams, kind):
    path = write_log(kind, tmp_path, [pose_channel("/a", POSE, records(streams[0], "w", ""))])
    (path / "metadata.yaml").unlink()
    s = read_stream(path, topic="/a")
    np.testing.assert_array_equal(s.stamps_ns, streams[0].stamps_ns)
    assert any("has no metadata.yaml" in w for w in s.warnings)


def test_rosbag2_corrupt_metadata(tmp_path, streams):
    path = write_log("bag2_sqlite", tmp_path, [pose_channel("/a", POSE, records(streams[0], "w", ""))])
    (path / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  version: 9\n  storage: [unclosed\n")
    with pytest.raises(HandEyeError) as info:
        read_stream(path, topic="/a")
    text = str(info.value)
    assert "\n" not in text and text.startswith("corrupt metadata.yaml") and "delete it" in text
