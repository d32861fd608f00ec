"""The adversarial corpus: hostile inputs, each generated here (small: < 20 MB, most < 1 MB), read
by ``python -m handeye_cli calibrate`` in a subprocess under a 1.5 GB address-space limit (a
decompression or allocation bomb fails loudly instead of passing) and a wall-clock timeout. Each
must end in exit 2, exactly one stderr line ``error: …``, nothing on stdout, no output file, and
a bounded peak RSS. The bounds are listed in docs/design.md, "What each reader bounds".
"""
from __future__ import annotations

import contextlib
import os
import resource
import sqlite3
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import lz4.frame
import numpy as np
import pytest
import zstandard
from _logs import POSE, ROS2_STORE, _serialize, pose_channel, write_bag1, write_bag2, write_mcap
from _util import ROOT, run
from mcap.data_stream import RecordBuilder
from mcap.records import Channel, Chunk, ChunkIndex, DataEnd, Footer, Header, Message, MessageIndex, Schema, Statistics

from handeye_cli.io import common, inputs, read_stream
from handeye_cli.io.rosbag1_scan import check_lengths

# issue 36: run under -W error, every warning a failure (an unclosed file or pipe: its ResourceWarning,
# reported at garbage collection as PytestUnraisableExceptionWarning); not a filter to hide one
pytestmark = pytest.mark.filterwarnings("error")

ADDRESS_LIMIT = 1536 << 20      # [B] a bomb asking for gigabytes dies with MemoryError under this
PEAK_LIMIT_MB = 500             # peak RSS [MB] of a refused input
TIMEOUT_S = 30
_MAGIC = b"\x89MCAP0\r\n"


@dataclass(frozen=True)
class Run:
    code: int
    out: str
    err: str
    peak_mb: float
    seconds: float


def _limit() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_LIMIT, ADDRESS_LIMIT))


def cli(tmp: Path, *args: object) -> Run:
    """``python -m handeye_cli ARGS`` under the address-space limit: its exit code, output, own peak
    RSS (``wait4`` of that child) and wall time; killed after TIMEOUT_S."""
    out_path, err_path = tmp / "stdout.txt", tmp / "stderr.txt"
    with open(out_path, "wb") as out, open(err_path, "wb") as err:
        start = time.monotonic()
        p = subprocess.Popen([sys.executable, "-m", "handeye_cli", *map(str, args)], stdout=out, stderr=err,
                             stdin=subprocess.DEVNULL, preexec_fn=_limit, cwd=tmp)
        timer = threading.Timer(TIMEOUT_S, p.kill)
        timer.start()
        _, status, usage = os.wait4(p.pid, 0)
        timer.cancel()
        p.returncode = os.waitstatus_to_exitcode(status)
    return Run(p.returncode, out_path.read_text(), err_path.read_text(), usage.ru_maxrss / 1024,
               time.monotonic() - start)


def refused(tmp: Path, *args: object) -> str:
    """Calibrate ``ARGS -o out.yaml``: assert the one-line refusal; return that line."""
    target = tmp / "out.yaml"
    r = cli(tmp, "calibrate", *args, "-o", target)
    assert r.seconds < TIMEOUT_S, f"killed after {r.seconds:.1f} s"
    assert r.code == 2, r.err[-3000:]
    lines = r.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), r.err[-3000:]
    assert r.out == ""
    assert not target.exists()
    assert r.peak_mb < PEAK_LIMIT_MB, f"peak RSS {r.peak_mb:.0f} MB"
    return lines[0]


# --- hand-built MCAPs -------------------------------------------------------------------------
def _pose(t: int, frame: str = "world", x: float = 0.0) -> bytes:
    return bytes(_serialize(ROS2_STORE, POSE, [(t, frame, "", x, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)]))


def _records(messages: list[tuple[int, int, bytes]]) -> bytes:
    """Message records (channel, log time, data) as a chunk's records."""
    b = RecordBuilder()
    for seq, (cid, t, data) in enumerate(messages):
        Message(channel_id=cid, log_time=t, data=data, publish_time=t, sequence=seq).write(b)
    return b.end()


def hostile_mcap(path: Path, chunks: list[tuple[str, bytes, int, bytes]], *, summary: bool = True,
                 profile: str = "ros2") -> Path:
    """An MCAP with channels 1 (/a) and 2 (/b), PoseStamped, whose chunks are given as
    (compression, compressed data, declared uncompressed size, the records really inside it — for
    the message indexes); ``summary``: with Statistics and ChunkIndex records."""
    text, _ = ROS2_STORE.generate_msgdef(POSE, ros_version=2)
    schema = Schema(id=1, name=POSE, encoding="ros2msg", data=text.encode())
    channels = [Channel(id=i, topic=t, message_encoding="cdr", schema_id=1, metadata={})
                for i, t in ((1, "/a"), (2, "/b"))]
    b = RecordBuilder()
    b.write(_MAGIC)
    Header(profile=profile, library="tests/io/test_adversarial_readers.py").write(b)
    schema.write(b)
    for ch in channels:
        ch.write(b)
    indexes, counts = [], {1: 0, 2: 0}
    for compression, data, declared, inside in chunks:
        start = b.count
        Chunk(compression=compression, data=data, message_start_time=0, message_end_time=10**9,
              uncompressed_size=declared, uncompressed_crc=0).write(b)
        end = b.count
        offsets = {}
        for cid, rows in _index_of(inside).items():
            offsets[cid] = b.count
            counts[cid] += len(rows)
            MessageIndex(channel_id=cid, records=rows).write(b)
        indexes.append(ChunkIndex(message_start_time=0, message_end_time=10**9, chunk_start_offset=start,
                                  chunk_length=end - start, message_index_offsets=offsets,
                                  message_index_length=b.count - end, compression=compression,
                                  compressed_size=len(data), uncompressed_size=declared))
    DataEnd(data_section_crc=0).write(b)
    summary_start = 0
    if summary:
        summary_start = b.count
        schema.write(b)
        for ch in channels:
            ch.write(b)
        Statistics(message_count=sum(counts.values()), schema_count=1, channel_count=2, attachment_count=0,
                   metadata_count=0, chunk_count=len(chunks), message_start_time=0, message_end_time=10**9,
                   channel_message_counts=counts).write(b)
        for ix in indexes:
            ix.write(b)
    Footer(summary_start=summary_start, summary_offset_start=0, summary_crc=0).write(b)
    b.write(_MAGIC)
    path.write_bytes(b.end())
    return path


def _index_of(records: bytes) -> dict[int, list[tuple[int, int]]]:
    """Each channel's (log time, offset) of the Message records at the start of ``records``."""
    out: dict[int, list[tuple[int, int]]] = {}
    i = 0
    while i + 9 <= len(records) and records[i] == 0x05:
        n = int.from_bytes(records[i + 1:i + 9], "little")
        cid = int.from_bytes(records[i + 9:i + 11], "little")
        out.setdefault(cid, []).append((int.from_bytes(records[i + 15:i + 23], "little"), i))
        i += 9 + n
    return out


def _messages(n: int = 40) -> bytes:
    return _records([(1 + k % 2, k * 10**7, _pose(k * 10**7, x=0.01 * k)) for k in range(n)])


BOMB_BYTES = 2 << 30      # [B] what the bombs inflate to: past ADDRESS_LIMIT, so an unbounded read fails


@cache
def _zstd_bomb() -> bytes:
    """One zstd frame: 40 messages, then 2 GiB of zeros (66 kB; the frame header states its size)."""
    head = _messages()
    c = zstandard.ZstdCompressor(level=1).compressobj(size=len(head) + BOMB_BYTES)
    zeros = bytes(64 << 20)
    return b"".join([c.compress(head), *(c.compress(zeros) for _ in range(BOMB_BYTES // len(zeros))), c.flush()])


@cache
def _lz4_bomb() -> bytes:
    """One lz4 frame: 40 messages, then 2 GiB of zeros (8.8 MB)."""
    c = lz4.frame.LZ4FrameCompressor()
    zeros = bytes(64 << 20)
    return b"".join([c.begin(), c.compress(_messages()), *(c.compress(zeros) for _ in range(BOMB_BYTES // len(zeros))),
                     c.flush()])


def _unsized_zstd(records: bytes) -> bytes:
    return zstandard.ZstdCompressor(write_content_size=False).compress(records)


TOPICS = ("--topic-a", "/a", "--topic-b", "/b")


# --- MCAP chunks ------------------------------------------------------------------------------
def test_chunk_declaring_50_gb_without_summary(tmp_path):
    records = _messages()
    log = hostile_mcap(tmp_path / "big.mcap", [("zstd", _unsized_zstd(records), 50 * 10**9, records)],
                       summary=False)
    line = refused(tmp_path, log, *TOPICS)
    assert "50000000000 bytes uncompressed" in line and "256 MiB" in line and str(log) in line


@pytest.mark.parametrize("profile", ["ros2", ""])
def test_zstd_chunk_inflating_to_2_gib(tmp_path, profile):
    records = _messages()
    log = hostile_mcap(tmp_path / "zbomb.mcap", [("zstd", _zstd_bomb(), len(records), records)], profile=profile)
    assert log.stat().st_size < 1 << 20
    line = refused(tmp_path, log, *TOPICS)
    assert "inflates past" in line or "holds" in line, line


def test_lz4_chunk_inflating_to_2_gib(tmp_path):
    records = _messages()
    log = hostile_mcap(tmp_path / "lbomb.mcap", [("lz4", _lz4_bomb(), len(records), records)], profile="")
    assert log.stat().st_size < 20 << 20
    line = refused(tmp_path, log, *TOPICS)
    assert "inflates past" in line, line


@pytest.mark.parametrize("summary", [True, False])
@pytest.mark.parametrize("fast", [True, False])
def test_a_bomb_chunk_is_skipped_and_the_rest_read(tmp_path, summary, fast, monkeypatch):
    good = _records([(1, k * 10**7, _pose(k * 10**7, x=0.01 * k)) for k in range(30)])
    bad = _records([(1, 10**9 + k * 10**7, _pose(10**9 + k * 10**7)) for k in range(30)])
    log = hostile_mcap(tmp_path / "mixed.mcap", [("zstd", zstandard.compress(good), len(good), good),
                                                 ("zstd", _unsized_zstd(bad), 10**12, bad)], summary=summary)
    if not fast:
        monkeypatch.setattr("handeye_cli.io.mcap_reader.McapSource.read_fast", lambda *a: {})
    s = read_stream(log, topic="/a")
    assert len(s) == 30 and s.stamps_ns[-1] == 29 * 10**7
    assert any("skipped the chunk at byte" in w and "its messages are lost" in w for w in s.warnings), s.warnings


def test_inflate_bounds():
    data = zstandard.compress(bytes(1000))
    assert common.inflate("zstd", data, 1000) == bytes(1000)
    with pytest.raises(common.ChunkError, match="inflates past"):
        common.inflate("zstd", data, 999)
    with pytest.raises(common.ChunkError, match="over the 256 MiB limit"):
        common.inflate("lz4", lz4.frame.compress(b"x"), common.CHUNK_LIMIT + 1)
    cut = common.inflate("zstd", data[:len(data) // 2], 1000, partial=True)    # a crash cut the frame
    assert len(cut) <= 1000 and not any(cut)


# --- frame ids --------------------------------------------------------------------------------
def test_one_256_kb_frame_id_among_1800(tmp_path):
    recs = [(k * 10**7, "world", "", 0.001 * k, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0) for k in range(1800)]
    recs[900] = (recs[900][0], "f" * (256 << 10), *recs[900][2:])
    log = write_mcap(tmp_path / "longid.mcap", [pose_channel("/a", POSE, recs), pose_channel("/b", POSE, recs)])
    line = refused(tmp_path, log, *TOPICS)
    assert "several frame pairs" in line and len(line) < 1000, line[:300]


# --- ROS 1 bags -------------------------------------------------------------------------------
def _bag(tmp: Path) -> tuple[Path, bytearray, int]:
    recs = [(k * 10**7, "world", "cam", 0.01 * k, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0) for k in range(50)]
    bag = write_bag1(tmp / "log.bag", [pose_channel("/a", "geometry_msgs/msg/TransformStamped", recs)])
    data = bytearray(bag.read_bytes())
    first = 13 + 4 + int.from_bytes(data[13:17], "little")      # past the magic and the bag header's header
    first += 4 + int.from_bytes(data[first:first + 4], "little")    # past its data: the first chunk
    return bag, data, first


def test_bag_chunk_header_claiming_4_gb(tmp_path):
    bag, data, chunk = _bag(tmp_path)
    data[chunk:chunk + 4] = (0xFFFFFFF0).to_bytes(4, "little")
    bag.write_bytes(data)
    line = refused(tmp_path, bag, *TOPICS)
    assert "no complete message" in line and str(bag) in line


def test_bag_chunk_data_claiming_4_gb(tmp_path):
    bag, data, chunk = _bag(tmp_path)
    at = chunk + 4 + int.from_bytes(data[chunk:chunk + 4], "little")
    data[at:at + 4] = (0xFFFFFFF0).to_bytes(4, "little")
    bag.write_bytes(data)
    assert "4294967280 bytes, past the end of the file" in check_lengths(bag)
    s = read_stream(bag, topic="/a")       # the chunk's records are there: read by the linear scan
    assert len(s) == 50 and any("linear scan" in w for w in s.warnings)
    line = refused(tmp_path, bag, *TOPICS)
    assert "unknown topic '/b'" in line


# --- ROS 2 sqlite bags ------------------------------------------------------------------------
@pytest.mark.parametrize("value", [None, "text", 12345])
def test_db3_row_that_is_not_bytes(tmp_path, value):
    recs = [(k * 10**7, "world", "cam", 0.01 * k, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0) for k in range(20)]
    bag = write_bag2(tmp_path / "bag", [pose_channel("/a", POSE, recs), pose_channel("/b", POSE, recs)])
    db = next(bag.glob("*.db3"))
    with sqlite3.connect(db) as con:    # the copy drops the NOT NULL constraint rosbags' writer declares
        con.executescript("CREATE TABLE m AS SELECT * FROM messages; DROP TABLE messages; "
                          "ALTER TABLE m RENAME TO messages;")
        con.execute("UPDATE messages SET data = ? WHERE id = 7", (value,))
    con.close()
    line = refused(tmp_path, bag, *TOPICS)
    assert "not bytes" in line and (":/a, message" in line or ":/b, message" in line), line


# --- endless and blocking inputs --------------------------------------------------------------
def test_character_device(tmp_path):
    line = refused(tmp_path, "/dev/zero", tmp_path / "b.tum")
    assert "/dev/zero" in line and "character device" in line


def test_fifo_no_one_writes(tmp_path, capsys, monkeypatch):
    fifo = tmp_path / "pipe.tum"
    os.mkfifo(fifo)
    monkeypatch.setattr(inputs, "FIFO_WAIT_S", 0.2)
    start = time.monotonic()
    code, out, err = run(capsys, "calibrate", fifo, fifo, "-o", tmp_path / "out.yaml")
    assert time.monotonic() - start < 5
    assert code == 2 and out == "" and err.count("\n") == 1 and err.startswith("error: ")
    assert "no one wrote" in err and str(fifo) in err
    assert not (tmp_path / "out.yaml").exists()


def test_endless_fifo(tmp_path, capsys, monkeypatch):
    fifo = tmp_path / "endless.tum"
    os.mkfifo(fifo)
    monkeypatch.setattr(inputs, "STREAM_LIMIT", 1 << 20)
    stop = threading.Event()

    def write() -> None:
        line = b"1.0 0 0 0 0 0 0 1\n" * 1000
        try:                                  # the reader's close breaks the pipe: in a write, or in the close's flush
            with open(fifo, "wb") as f:
                while not stop.is_set():
                    f.write(line)
        except BrokenPipeError:
            pass

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    try:
        code, out, err = run(capsys, "calibrate", fifo, tmp_path / "b.tum", "-o", tmp_path / "out.yaml")
    finally:
        stop.set()
        writer.join(5)                        # ends here, in its own test (an exception of its would land elsewhere)
    assert code == 2 and out == "" and err.count("\n") == 1 and err.startswith("error: ")
    assert "more than 1 MiB" in err and str(fifo) in err


# --- degenerate data --------------------------------------------------------------------------
def test_identical_stamps(tmp_path):
    same = tmp_path / "same.tum"
    same.write_bytes(b"1.0 0 0 0 0 0 0 1\n" * 200_000)
    line = refused(tmp_path, same, same)
    assert "same stamp" in line or "identical" in line, line


def test_zero_positions_rotation_only(tmp_path):
    """All positions exactly 0 (pure rotation): the rotation is calibrated, no traceback."""
    t = np.arange(400) * 0.05
    from scipy.spatial.transform import Rotation
    ra = Rotation.from_rotvec(np.c_[0.8 * np.sin(t), 0.6 * np.cos(1.3 * t), 0.4 * np.sin(0.5 * t + 1)])
    X = Rotation.from_rotvec([0.3, -0.2, 1.0])
    paths = []
    for name, r in (("a.tum", ra), ("b.tum", ra * X)):
        np.savetxt(tmp_path / name, np.c_[t, np.zeros((len(t), 3)), r.as_quat()], fmt="%.9f")
        paths.append(tmp_path / name)
    for method in ("dqopt", "daniilidis"):
        r = cli(tmp_path, "calibrate", *paths, "--method", method, "-o", tmp_path / f"{method}.yaml")
        assert "Traceback" not in r.err and r.code in (0, 2), r.err[-2000:]
        if r.code == 2:
            assert len(r.err.strip().splitlines()[-1:]) == 1 and r.err.strip().splitlines()[-1].startswith("error:")



# --- an interrupted read leaves nothing open ---------------------------------------------------

def _open_on(path: Path) -> int:
    """How many of this process's descriptors are open on ``path`` (a file object's and a map's own)."""
    out = 0
    for fd in os.listdir("/proc/self/fd"):
        with contextlib.suppress(OSError):               # the listing's own descriptor, closed by now
            out += os.readlink(f"/proc/self/fd/{fd}") == str(path)
    return out


@pytest.mark.parametrize("interrupt", [KeyboardInterrupt, SystemExit])
def test_an_interrupted_fast_read_leaves_no_file_open(tmp_path, monkeypatch, interrupt):
    """Ctrl-C (a batch's SIGTERM, its time limit) in the middle of the fast path's read: no file
    object was open through the read, so none is left unclosed (a ResourceWarning at garbage
    collection, an error under ``-W error``), and no descriptor outlives the read."""
    import gc
    import warnings

    import handeye_cli.io.mcap_fast as mcap_fast
    from handeye_cli.io.mcap_reader import McapSource

    path = ROOT / "sample_data" / "rig.mcap"
    during: list[int] = []
    real = mcap_fast._Chunks.read

    def read(self, index, wanted):
        real(self, index, wanted)                        # the chunk read, its view of the map held
        during.append(_open_on(path))                    # the map's descriptor only: the file is closed
        raise interrupt()

    monkeypatch.setattr(mcap_fast._Chunks, "read", read)
    gc.collect()
    before = _open_on(path)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ResourceWarning)
        with pytest.raises(interrupt), McapSource(path) as src:
            src.read_fast(["/cam0/pose", "/cam1/pose"], "header")
        gc.collect()
    assert during == [before + 1] and _open_on(path) == before
