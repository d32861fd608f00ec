"""Issue 13 through the command line: streams at any rate calibrate with the default flags.

Every rate mix of the issue's table (100 Hz against 5, 2, 1 and 0.5 Hz, in both orders), a mix
with a clock offset and ``--time-offset auto``, and one with tracking jumps in the slow stream:
the default flags land within 0.1° / 3 mm of the truth and within 1.5× the error of the best
hand-tuned flags (the explicit ``--sync`` choices with a ``--max-dt`` that fits the slow stream,
and the gates set by hand), computed on the same data in the same test.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from _util import run, write_tum

from handeye_cli.calibration import calibrate
from handeye_cli.errors import HandEyeError
from handeye_cli.geometry import se3
from handeye_cli.simulation import Rig
from handeye_cli.simulation.rates import Jumps, RateRecording, simulate_rates

X = se3.from_xyz_quat(np.array([0.21, -0.18, 0.05]), np.array([0.2, 0.4, -0.1, 0.85]))
DURATION_S = 120.0
TABLE = [(100, 5), (100, 2), (100, 1), (100, 0.5), (5, 100), (2, 100), (1, 100), (0.5, 100)]


def score(T: np.ndarray) -> tuple[float, float, float]:
    """(rotation error [deg], translation error [mm], their sum in units of the 0.1° / 3 mm tolerance)."""
    rot = float(np.rad2deg(se3.rotation_angle(T[:3, :3].T @ X[:3, :3])))
    trans = 1e3 * float(np.linalg.norm(T[:3, 3] - X[:3, 3]))
    return rot, trans, rot / 0.1 + trans / 3.0


def cli_default(capsys, tmp_path: Path, rec: RateRecording, *flags: str) -> dict:
    fa, fb = write_tum(tmp_path / "a.tum", rec.a), write_tum(tmp_path / "b.tum", rec.b)
    code, out, err = run(capsys, "calibrate", fa, fb, "-q", *flags)
    assert code == 0, err
    return yaml.safe_load(out)


def best_hand_tuned(rec: RateRecording, slow_hz: float, variants: list[dict]) -> float:
    """The smallest error score over the hand-tuned flag sets that calibrate at all."""
    scores = []
    for sync in ("interpolate", "nearest"):
        for extra in variants:
            try:
                # the hand-tuned baselines interpolate (or take the nearest of) the slow stream across its
                # steps and misfit (7–16° median at 100/1 Hz): kept past the fit test, for their accuracy
                cal = calibrate(rec.a, rec.b, sync=sync, max_dt=1.2 / slow_hz, accept_poor_fit=True, **extra)
            except HandEyeError:
                continue
            scores.append(score(cal.matrix)[2])
    assert scores, "no hand-tuned flag set calibrates"
    return min(scores)


@pytest.mark.parametrize(("rate_a", "rate_b"), TABLE)
def test_every_rate_mix_calibrates_with_the_defaults(capsys, tmp_path, rate_a: float, rate_b: float) -> None:
    rec = simulate_rates(Rig(X), rate_a, rate_b, duration_s=DURATION_S, seed=1)
    doc = cli_default(capsys, tmp_path, rec)
    rot, trans, default = score(np.array(doc["matrix"]))
    assert rot < 0.1 and trans < 3.0
    slow = "a" if rate_a < rate_b else "b"
    assert doc["sync"] == {"reference": slow, "rate_a_hz": pytest.approx(rate_a, rel=0.05),
                           "rate_b_hz": pytest.approx(rate_b, rel=0.05)}
    assert doc["samples"]["synced_kept"] >= 0.95 * DURATION_S * min(rate_a, rate_b)
    best = best_hand_tuned(rec, min(rate_a, rate_b), [{"gate": "off"}])
    assert default <= 1.5 * best


def test_a_clock_offset_is_estimated_at_a_slow_rate(capsys, tmp_path) -> None:
    offset_s = 0.237
    rec = simulate_rates(Rig(X, int(offset_s * 1e9)), 100, 1, duration_s=DURATION_S, seed=2)
    doc = cli_default(capsys, tmp_path, rec, "--time-offset", "auto")
    assert doc["time_offset"]["seconds"] == pytest.approx(offset_s, abs=1e-3)
    rot, trans, default = score(np.array(doc["matrix"]))
    assert rot < 0.1 and trans < 3.0
    known = score(calibrate(rec.a, rec.b, time_offset=offset_s).matrix)[2]      # the true offset, given by hand
    assert default <= 1.5 * min(known, best_hand_tuned(rec, 1.0, [{"gate": "off", "time_offset": offset_s}]))


@pytest.mark.parametrize(("rate_a", "rate_b"), [(100, 1), (2, 100)])
def test_tracking_jumps_in_the_slow_stream_are_dropped(capsys, tmp_path, rate_a: float, rate_b: float) -> None:
    slow = "a" if rate_a < rate_b else "b"
    rec = simulate_rates(Rig(X), rate_a, rate_b, duration_s=DURATION_S, seed=3, **{f"jumps_{slow}": Jumps(5)})
    doc = cli_default(capsys, tmp_path, rec)
    assert doc["samples"]["dropped_pose_jump"] == 5
    rot, trans, default = score(np.array(doc["matrix"]))
    assert rot < 0.1 and trans < 3.0
    by_hand = [{"gate": "off"}, {"gate": "off", "robust": True},
               {"gate": "paper", "max_jump": 1.5, "max_jump_deg": 90.0}]   # the paper gate opened to the slow steps
    assert default <= 1.5 * best_hand_tuned(rec, min(rate_a, rate_b), by_hand)


def test_the_paper_gate_stays_available_and_says_what_to_relax(capsys, tmp_path) -> None:
    rec = simulate_rates(Rig(X), 100, 1, duration_s=60, seed=4)
    fa, fb = write_tum(tmp_path / "a.tum", rec.a), write_tum(tmp_path / "b.tum", rec.b)
    code, _, err = run(capsys, "calibrate", fa, fb, "--gate", "paper")
    assert code == 2 and err.count("\n") == 1
    assert "a 100 Hz, b 1 Hz" in err and "--gate auto" in err and "wider --max-jump/--max-jump-deg" in err
    code, out, err = run(capsys, "calibrate", fa, fb, "--gate", "paper", "--max-jump", "off", "--max-jump-deg", "off",
                         "-q")
    assert code == 0, err


def test_jumps_in_the_fast_stream_do_not_make_it_a_station_capture(capsys, tmp_path) -> None:
    rec = simulate_rates(Rig(X), 100, 1, duration_s=DURATION_S, seed=5, jumps_a=Jumps(5), jumps_b=Jumps(3))
    doc = cli_default(capsys, tmp_path, rec)
    assert "stations" not in doc and doc["sync"]["reference"] == "b"
    rot, trans, _ = score(np.array(doc["matrix"]))
    assert rot < 0.1 and trans < 3.0
