"""Pathological stamp layouts (issue 34): each ends within seconds in a result or a one-line refusal (exit 2),
never a traceback, never a Python warning.

Every case is a pair of TUM files of one simulated rig (``simulate_rig``: a at 100 Hz, b at 40 Hz, 18 s, so
1,800 and 720 lines; ``T_a_b`` random, no clock offset) whose stamps are rewritten: TUM stamps are seconds
(``tests/_logs.write_tum`` writes them exactly), so a file stamped in milliseconds or microseconds since the
start is read as a recording 10³ or 10⁶ times longer and slower. The CLI runs in a subprocess with
``PYTHONWARNINGS=error`` (``python -W error``: any numpy or Runtime warning is an exception, so a traceback and
exit 4) under the adversarial corpus's address-space limit and kill timer (``test_adversarial_readers.cli``).
The corpus's own cases that run the CLI (each a calibration or a one-line refusal) are imported and so run here
a second time, under the same ``PYTHONWARNINGS=error`` (the autouse fixture below).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from _logs import write_tum
from _util import pose_error
from test_adversarial_readers import (  # noqa: F401  (re-collected here: the corpus's CLI runs, under -W error)
    cli,
    test_bag_chunk_data_claiming_4_gb,
    test_bag_chunk_header_claiming_4_gb,
    test_character_device,
    test_chunk_declaring_50_gb_without_summary,
    test_db3_row_that_is_not_bytes,
    test_identical_stamps,
    test_lz4_chunk_inflating_to_2_gib,
    test_one_256_kb_frame_id_among_1800,
    test_zero_positions_rotation_only,
    test_zstd_chunk_inflating_to_2_gib,
)

from handeye_cli.simulation import Rig, random_transform, simulate_rig
from handeye_cli.streams import PoseStream
from handeye_cli.verify.policy import LARGE_OFFSET_PERIODS

S = 1_000_000_000               # [ns] a second
FEW_SECONDS = 20.0              # [s] wall time each case must end within (start-up included)


def _rig() -> tuple[np.ndarray, PoseStream, PoseStream]:
    """(T_a_b, a, b): 100 Hz and 40 Hz, 18 s, 0.05° / 1 mm noise, stamps epoch nanoseconds (2023)."""
    X = random_transform(np.random.default_rng(34), 0.3)
    a, b = simulate_rig(Rig(X, 0), duration_s=18, rate_a=100, rate_b=40, sigma_r=np.deg2rad(0.05),
                        sigma_t=0.001, seed=34)
    return X, a, b


def _restamped(s: PoseStream, stamps_ns: np.ndarray) -> PoseStream:
    return PoseStream(np.asarray(stamps_ns, dtype=np.int64), s.xyz, s.quat_xyzw)


def _since_start(a: PoseStream, b: PoseStream, scale: int) -> tuple[PoseStream, PoseStream]:
    """Stamps since a's first sample in units of 1/``scale`` s, written where TUM's seconds go."""
    t0 = int(a.stamps_ns[0])
    return _restamped(a, (a.stamps_ns - t0) * scale), _restamped(b, (b.stamps_ns - t0) * scale)


def _calibrate(tmp: Path, a: PoseStream, b: PoseStream, *args: object, lines: list[str] | None = None):
    """Write a and b as TUM (``lines``: extra text lines appended to b), run ``calibrate`` under ``-W error``."""
    fa, fb = write_tum(tmp / "a.tum", a), write_tum(tmp / "b.tum", b)
    if lines:
        with open(fb, "a") as f:
            f.write("\n".join(lines) + "\n")
    return cli(tmp, "calibrate", fa, fb, "-o", tmp / "out.yaml", *args)


def _ended_cleanly(r, tmp: Path) -> dict | None:
    """Assert a result (exit 0, a document) or a one-line refusal (exit 2, nothing written), no traceback and no
    Python warning, within ``FEW_SECONDS``; return the document, or None for a refusal."""
    assert r.seconds < FEW_SECONDS, f"{r.seconds:.1f} s"
    assert "Traceback" not in r.err and "Warning:" not in r.err, r.err[-3000:]
    assert r.code in (0, 2), r.err[-3000:]
    if r.code == 2:
        lines = r.err.splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), r.err[-3000:]
        assert not (tmp / "out.yaml").exists()
        return None
    return yaml.safe_load((tmp / "out.yaml").read_text())


@pytest.fixture(autouse=True)
def _warnings_are_errors(monkeypatch):
    monkeypatch.setenv("PYTHONWARNINGS", "error")


@pytest.mark.parametrize("layout", ["epoch ns", "s", "ms", "us"])
def test_stamps_in_any_unit_since_start_or_epoch(tmp_path, layout):
    """Epoch nanoseconds and seconds since start calibrate; milliseconds and microseconds since start, read as TUM
    seconds (a rig 10³ or 10⁶ times slower: 10 s or 10⁴ s per step), end as fast in a result or a refusal."""
    X, a, b = _rig()
    if layout != "epoch ns":
        a, b = _since_start(a, b, {"s": 1, "ms": 1000, "us": 1_000_000}[layout])
    r = _calibrate(tmp_path, a, b, "--no-wxyz-a", "--no-wxyz-b")
    doc = _ended_cleanly(r, tmp_path)
    if layout in ("epoch ns", "s"):
        assert doc is not None, r.err
        rot_deg, trans_m = pose_error(np.array(doc["matrix"]), X)
        assert rot_deg < 0.2 and trans_m < 0.01, (rot_deg, trans_m)


def test_streams_5000_s_apart_are_refused_by_default_and_calibrate_within_an_explicit_range(tmp_path):
    """b's clock 5,000 s ahead, far beyond the 18-s recording: the default search range (the shorter stream's
    span) holds no offset at which the streams overlap, so the refusal names --max-time-offset; with
    ``--max-time-offset 6000`` the offset is found, applied and warned about with its σ."""
    X, a, b = _rig()
    b = _restamped(b, b.stamps_ns + 5000 * S)
    r = _calibrate(tmp_path, a, b, "--no-wxyz-a", "--no-wxyz-b")
    assert _ended_cleanly(r, tmp_path) is None
    assert "--max-time-offset" in r.err and "do not overlap" in r.err, r.err
    r = _calibrate(tmp_path, a, b, "--no-wxyz-a", "--no-wxyz-b", "--max-time-offset", "6000")
    doc = _ended_cleanly(r, tmp_path)
    assert doc is not None, r.err
    report = doc["time_offset"]
    assert report["applied"] is True and abs(report["seconds"] - 5000) < 1e-3, report
    warned = [w for w in doc["warnings"] if "clock offset of" in w and "was applied" in w]
    assert len(warned) == 1 and "did not overlap" in warned[0] and "--time-offset 0" in warned[0], doc["warnings"]
    assert f"{report['std_seconds']:.2g}" in warned[0], warned
    assert pose_error(np.array(doc["matrix"]), X)[0] < 0.2
    r = _calibrate(tmp_path, a, b, "--no-wxyz-a", "--no-wxyz-b", "--max-time-offset", "6000", "--strict")
    assert r.code == 3, r.err                       # the warning fails --strict


def test_1e5_duplicate_stamps_with_conflicting_poses(tmp_path):
    """10⁵ more lines in b repeating its stamps with other poses (some before the original, so that those are the
    ones kept): a result or a refusal, the readers' own warning, no Python warning."""
    X, a, b = _rig()
    rng = np.random.default_rng(5)
    k = rng.integers(0, len(b), 100_000)
    xyz = b.xyz[k] + rng.normal(scale=0.05, size=(len(k), 3))
    quat = b.quat_xyzw[k] + rng.normal(scale=0.05, size=(len(k), 4))
    lines = [f"{t // S}.{t % S:09d} " + " ".join(repr(float(v)) for v in (*p, *q))
             for t, p, q in zip(b.stamps_ns[k].tolist(), xyz, quat, strict=True)]
    r = _calibrate(tmp_path, a, b, "--no-wxyz-a", "--no-wxyz-b", lines=lines)
    doc = _ended_cleanly(r, tmp_path)
    assert "repeat a stamp with a different pose" in r.err, r.err
    if doc is not None:
        assert doc["samples"]["duplicates_dropped_b"] == 100_000


def test_one_stamp_in_2261(tmp_path):
    """One sample of b stamped 9.2·10¹⁸ ns (year 2261) after 18 s of 2023: a result or a refusal, never a search
    over the 240 years between."""
    X, a, b = _rig()
    lines = [f"{9_200_000_000}.000000000 " + " ".join(repr(float(v)) for v in (*b.xyz[-1], *b.quat_xyzw[-1]))]
    r = _calibrate(tmp_path, a, b, "--no-wxyz-a", "--no-wxyz-b", lines=lines)
    doc = _ended_cleanly(r, tmp_path)
    if doc is not None:
        assert pose_error(np.array(doc["matrix"]), X)[0] < 0.2


def test_an_offset_of_many_sample_periods_is_warned_about(tmp_path):
    """b's clock 2 s ahead, within the default range: applied (the streams overlap without it too) and, being more
    than LARGE_OFFSET_PERIODS of b's 25-ms period, named in a warning; 10 ms (< 5 periods) is not."""
    X, a, b = _rig()
    for offset_ns, warned in ((2 * S, True), (10_000_000, False)):
        shifted = _restamped(b, b.stamps_ns + offset_ns)
        doc = _ended_cleanly(_calibrate(tmp_path, a, shifted, "--no-wxyz-a", "--no-wxyz-b"), tmp_path)
        assert doc is not None and doc["time_offset"]["applied"] is True, doc and doc["time_offset"]
        assert (offset_ns > LARGE_OFFSET_PERIODS * 25_000_000) == warned
        found = [w for w in doc["warnings"] if "was applied" in w]
        assert bool(found) == warned, doc["warnings"]
