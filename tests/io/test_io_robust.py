"""Damaged or odd input on the read path: one-line errors, or a repaired stream with a named warning.

All-zero stamps, a clock jumping back, conflicting duplicate stamps, absurd or non-finite poses
(no numpy warning may leak), w-x-y-z quaternions, stamps in other time units, the wrong kind of
file passed as a stream, stdin and pipes, frame names.
"""
from __future__ import annotations

import io
import os
import re
import sys
import threading
import warnings
from pathlib import Path

import numpy as np
import pytest
from _logs import POSE, Channel, pose_channel, records, write_mcap, write_tum
from _util import fails

from handeye_cli.cli import main
from handeye_cli.io import detect_format, read_stream, valid_frame_id
from handeye_cli.simulation import Rig, simulate_rig

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def rig():
    return simulate_rig(Rig(np.eye(4)), duration_s=20.0, rate_a=30.0, rate_b=20.0, seed=21)




def tum_lines(path: Path) -> list[str]:
    return path.read_text().splitlines()[1:]


# --- stamps -----------------------------------------------------------------------------------
def test_all_zero_header_stamps(tmp_path, rig):
    recs = [(0, *r[1:]) for r in records(rig[0], "w", "")]
    path = write_mcap(tmp_path / "z.mcap", [Channel("/p", POSE, [(t, [r]) for t, r in
                                                                 zip(rig[0].stamps_ns.tolist(), recs, strict=True)])])
    fails(lambda: read_stream(path, topic="/p"), r"stamps are all zero", "z.mcap:/p", "--time-source log")
    np.testing.assert_array_equal(read_stream(path, topic="/p", time_source="log").stamps_ns, rig[0].stamps_ns)


@pytest.mark.parametrize("kind", ["mcap", "tum"])
def test_clock_jumping_back(tmp_path, rig, kind):
    """Stamps jump back 5 s after 60% of the messages: only the longest run is kept, with a named warning."""
    a = rig[0]
    k = int(0.6 * len(a))
    jumped = a.stamps_ns.copy()
    jumped[k:] -= (jumped[k] - jumped[k - 1]) + 5_000_000_000
    recs = [(int(t), *r[1:]) for t, r in zip(jumped, records(a, "w", ""), strict=True)]
    if kind == "mcap":
        path = write_mcap(tmp_path / "j.mcap", [Channel("/p", POSE, [(int(t), [r]) for t, r in
                                                                     zip(a.stamps_ns, recs, strict=True)])])
        s = read_stream(path, topic="/p")
    else:
        b = simulate_rig(Rig(np.eye(4)), duration_s=1.0)[0]
        path = write_tum(tmp_path / "j.tum", type(b)(jumped, a.xyz, a.quat_xyzw))
        s = read_stream(path)
    np.testing.assert_array_equal(s.stamps_ns, a.stamps_ns[:k])      # the longer run, never sorted together
    (w,) = s.warnings
    assert re.search(r"clock of .*j\.(mcap:/p|tum) jumps back 5\.0\d\d s at t=\d+\.\d{3} s", w), w
    assert f"{k} of {len(a)} samples" in w


def test_reordered_messages_are_not_a_clock_jump(tmp_path, rig):
    recs = records(rig[0], "w", "")
    shuffled = [recs[i] for i in np.random.default_rng(0).permutation(len(recs))]
    path = write_mcap(tmp_path / "s.mcap", [Channel("/p", POSE, [(recs[0][0] + i, [r])
                                                                 for i, r in enumerate(shuffled)])])
    s = read_stream(path, topic="/p")
    np.testing.assert_array_equal(s.stamps_ns, rig[0].stamps_ns)
    assert s.warnings == ()


def test_duplicate_stamps(tmp_path, rig):
    recs = records(rig[0], "w", "")
    moved = [(r[0], "w", "", r[3] + 1.0, *r[4:]) for r in recs[10:13]]
    path = write_mcap(tmp_path / "d.mcap", [pose_channel("/p", POSE, recs[:20] + moved + recs[5:7] + recs[20:])])
    s = read_stream(path, topic="/p")
    assert s.duplicates_dropped == 5 and len(s) == len(recs)
    (w,) = s.warnings
    assert w.startswith("3 sample(s) of ") and "repeat a stamp with a different pose" in w
    np.testing.assert_array_equal(s.xyz, rig[0].xyz)        # the first of each stamp is kept


# --- invalid poses ----------------------------------------------------------------------------
def test_absurd_and_non_finite_poses_are_dropped_without_numpy_warnings(tmp_path, rig):
    path = write_tum(tmp_path / "a.tum", rig[0])
    lines = path.read_text().splitlines()
    for n, value in ((5, "1e300"), (9, "inf"), (12, "-2e8")):
        f = lines[n - 1].split()
        lines[n - 1] = " ".join([f[0], value, *f[2:]])
    path.write_text("\n".join(lines) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = read_stream(path)
    assert len(s) == len(rig[0]) - 3
    (w,) = s.warnings
    assert "dropped 3 invalid pose(s)" in w and "|position| > 1e8 m" in w and "line 5" in w


# --- text conventions -------------------------------------------------------------------------
def write_wxyz(path: Path, stream) -> Path:
    rows = [f"{t / 1e9:.9f} " + " ".join(repr(float(v)) for v in (*p, q[3], *q[:3]))
            for t, p, q in zip(stream.stamps_ns, stream.xyz, stream.quat_xyzw, strict=True)]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_wxyz_quaternions(tmp_path):
    a = simulate_rig(Rig(np.eye(4)), duration_s=10.0, rate_a=30.0, seed=2)[0]
    a = type(a)(a.stamps_ns, a.xyz, a.quat_xyzw * np.sign(a.quat_xyzw[:, 3:]))      # w >= 0, as writers emit
    path = write_wxyz(tmp_path / "wxyz.tum", a)
    s = read_stream(path)                          # the format's order, left open for the fit to overturn
    assert s.warnings == () and s.quaternion_order == "xyzw"     # (tests/analysis/test_readings.py: the fit's choice)
    right = read_stream(path, quaternion_order="wxyz")
    assert right.warnings == () and right.quaternion_order is None
    np.testing.assert_allclose(np.abs(np.sum(right.quat_xyzw * a.quat_xyzw, axis=1)), 1.0, atol=1e-9)
    assert read_stream(write_tum(tmp_path / "xyzw.tum", a)).warnings == ()
    fails(lambda: read_stream(path, quaternion_order="zyxw"), "unknown quaternion order")


@pytest.mark.parametrize("fmt", ["tum", "csv"])
@pytest.mark.parametrize("unit, scale, since_start, warned", [
    ("ns", 1, False, False), ("us", 1_000, False, False), ("ms", 1_000_000, False, False),
    ("ms", 1_000_000, True, True), ("us", 1_000, True, True), ("s", 10**9, True, False)])
def test_time_units(tmp_path, rig, fmt, unit, scale, since_start, warned):
    """Epoch-sized stamps name their unit by magnitude in every format. Small stamps (since start) are
    seconds in a TUM file, as the format defines them (an arm's stations step seconds apart: read as ms
    they would be 1000× too close); only a CSV without a unit has its unit guessed from the step, warned."""
    a = rig[0]
    t = (a.stamps_ns - (a.stamps_ns[0] if since_start else 0)) // scale
    rows = [f"{ti} " + " ".join(repr(float(v)) for v in (*p, *q))
            for ti, p, q in zip(t, a.xyz, a.quat_xyzw, strict=True)]
    if unit == "s":
        rows = [f"{ti / 1e9:.9f} " + r.split(" ", 1)[1]
                for ti, r in zip(a.stamps_ns - a.stamps_ns[0], rows, strict=True)]
    path = tmp_path / f"u.{fmt}"
    if fmt == "csv":
        rows = ["t,x,y,z,qx,qy,qz,qw", *(r.replace(" ", ",") for r in rows)]
    path.write_text("\n".join(rows) + "\n")
    s = read_stream(path)
    expected = t * scale if unit != "s" else a.stamps_ns - a.stamps_ns[0]
    if fmt == "tum" and since_start and unit != "s":
        expected, warned = t * 10**9, False              # TUM: seconds, as defined
    np.testing.assert_array_equal(s.stamps_ns, expected)
    assert any("⟦time_unit" in w for w in s.warnings) == warned
    assert read_stream(path, time_unit=unit).warnings == ()


# --- the wrong kind of file -------------------------------------------------------------------
@pytest.mark.parametrize("path, patterns", [
    (ROOT / "README.md", ["Markdown/text document, not a pose stream", "README.md"]),
    (ROOT / "configs" / "default.yaml", ["a YAML file, not a pose stream", "--config"]),
    (ROOT / "sample_data" / "pairs.csv", ["a motion-pairs file", "handeye solve .*pairs.csv"]),
])
def test_wrong_kind_of_file(capsys, path, patterns):
    e = fails(lambda: read_stream(path), *patterns)
    assert "{" not in str(e)
    with pytest.raises(SystemExit) as info:
        main(["calibrate", str(path), str(ROOT / "sample_data" / "rig_b.tum")])
    err = capsys.readouterr().err.strip()
    assert info.value.code == 2 and "\n" not in err and "Traceback" not in err and patterns[0].split(",")[0] in err


# --- stdin, pipes, names ----------------------------------------------------------------------
def test_stdin(monkeypatch, rig, tmp_path):
    data = write_tum(tmp_path / "a.tum", rig[0]).read_bytes()
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data)))
    assert detect_format("-") == "tum"          # detection and reading share the bytes read once
    s = read_stream("-")
    np.testing.assert_array_equal(s.stamps_ns, rig[0].stamps_ns)
    assert (s.frame_id, s.child_frame_id, s.source) == ("", "stdin", "-")       # the world is unnamed


def test_pipe_is_read_once(tmp_path, rig):
    """Like ``<(cat a.tum)``: a FIFO can be read once, yet detection and reading both work."""
    data = write_tum(tmp_path / "a.tum", rig[0]).read_bytes()
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    writer = threading.Thread(target=lambda: fifo.write_bytes(data))
    writer.start()
    assert detect_format(fifo) == "tum"
    s = read_stream(fifo)
    writer.join(timeout=10)
    np.testing.assert_array_equal(s.stamps_ns, rig[0].stamps_ns)


def test_valid_frame_id():
    assert valid_frame_id("/cam0/pose") == "cam0_pose"
    assert valid_frame_id("rig a.tum") == "rig_a.tum"
    assert valid_frame_id("base_link") == "base_link"
    assert valid_frame_id("/") == "sensor"
