"""The pose-jump gates: ``auto`` keeps ordinary motion and drops tracking jumps at any rate, ``paper`` is the
paper's per-step gate on the raw streams; both accept a re-localisation as a new segment that no pair
spans, and the samples are associated once."""
from __future__ import annotations

import re

import numpy as np
import pytest

from handeye_cli.errors import ConfigError, DataError, as_flags
from handeye_cli.geometry import se3
from handeye_cli.simulation import Rig, random_transform
from handeye_cli.simulation.rates import Jumps, simulate_rates
from handeye_cli.stages import gates
from handeye_cli.stages.gates import paper_gate, pose_jump_gate, sync_and_gate
from handeye_cli.stages.pairs import make_pairs
from handeye_cli.stages.sync import associate
from handeye_cli.streams import PoseStream

X = random_transform(np.random.default_rng(11), 0.3)


def shifted_from(stream: PoseStream, k: int, dx: float) -> PoseStream:
    """``stream`` with samples from ``k`` on displaced by ``dx`` [m] along x (a re-localisation)."""
    xyz = stream.xyz.copy()
    xyz[k:, 0] += dx
    return PoseStream(stream.stamps_ns, xyz, stream.quat_xyzw)


@pytest.mark.parametrize("slow_hz", [30, 5, 1, 0.5])
@pytest.mark.parametrize("slow", ["a", "b"])
def test_auto_drops_the_slow_streams_jumps_and_only_them(slow: str, slow_hz: float) -> None:
    rates = (slow_hz, 100) if slow == "a" else (100, slow_hz)
    rec = simulate_rates(Rig(X), *rates, duration_s=120, seed=2, **{f"jumps_{slow}": Jumps(4)})
    synced, _ = associate(rec.a, rec.b)
    assert synced.reference == slow
    kept, counts = pose_jump_gate(synced)
    jumped = getattr(rec, f"jumped_{slow}")
    slow_stamps = getattr(rec, slow).stamps_ns
    np.testing.assert_array_equal(np.sort(np.setdiff1d(synced.stamps_ns, kept.stamps_ns)),
                                  slow_stamps[jumped])
    assert counts == {"dropped_pose_jump": 4, "accepted_jumps": 0} and not kept.segment.any()


@pytest.mark.parametrize("slow_hz", [5, 1, 0.5])
def test_ordinary_motion_of_a_slow_stream_passes_auto_but_not_the_paper_gate(slow_hz: float) -> None:
    rec = simulate_rates(Rig(X), 100, slow_hz, duration_s=120, seed=3)
    kept, counts = pose_jump_gate(associate(rec.a, rec.b)[0])
    assert counts["dropped_pose_jump"] == 0
    keep, _, _ = paper_gate(rec.b)
    assert (~keep).mean() > (0.3 if slow_hz < 5 else 0.01)     # the paper's 10 cm / 11.5° are for ~5 Hz


def test_a_jump_in_the_fast_stream_is_caught_where_it_is_interpolated() -> None:
    rec = simulate_rates(Rig(X), 100, 2, duration_s=60, seed=4, sigma_r=0.0, sigma_t=0.0)
    a, b = rec.a, rec.b
    k = int(np.searchsorted(a.stamps_ns, b.stamps_ns[40]))      # the 100 Hz sample right after a 2 Hz stamp
    xyz = a.xyz.copy()
    xyz[k] += [0.3, 0.0, 0.0]
    synced, _ = associate(PoseStream(a.stamps_ns, xyz, a.quat_xyzw), b)
    kept, counts = pose_jump_gate(synced)
    assert counts["dropped_pose_jump"] == 1 and b.stamps_ns[40] not in kept.stamps_ns


@pytest.mark.parametrize("gate", ["auto", "paper"])
def test_relocalisation_starts_a_new_segment_and_no_pair_spans_it(gate: str) -> None:
    rec = simulate_rates(Rig(X), 100, 30, duration_s=30, seed=5, speed=0.5)
    k = len(rec.b) // 2
    b = shifted_from(rec.b, k, 0.25)
    kept, counts = sync_and_gate(rec.a, b, gate=gate)
    assert counts["accepted_jumps"] == 1
    np.testing.assert_array_equal(kept.segment, (kept.stamps_ns >= b.stamps_ns[k]).astype(int))
    for strategy in ("keyframes", "consecutive", "all"):
        pairs, _ = make_pairs(kept, strategy, max_pairs=500)
        assert len(pairs) > 0
        np.testing.assert_array_equal(kept.segment[pairs.i], kept.segment[pairs.j])


def test_paper_gate_drops_the_injected_jumps_of_each_raw_stream_and_counts_them() -> None:
    rec = simulate_rates(Rig(X), 30, 20, duration_s=60, seed=6, speed=0.5, jumps_a=Jumps(3), jumps_b=Jumps(5))
    np.testing.assert_array_equal(paper_gate(rec.a)[0], ~rec.jumped_a)
    np.testing.assert_array_equal(paper_gate(rec.b)[0], ~rec.jumped_b)
    kept, counts = sync_and_gate(rec.a, rec.b, gate="paper")
    expected, _ = associate(rec.a.select(~rec.jumped_a), rec.b.select(~rec.jumped_b))
    np.testing.assert_array_equal(kept.stamps_ns, expected.stamps_ns)
    assert (counts["jumps_a"], counts["jumps_b"], counts["dropped_pose_jump"]) == (3, 5, 8)
    assert (counts["read_a"], counts["read_b"]) == (len(rec.a), len(rec.b))


def test_paper_limits_can_be_switched_off_one_by_one() -> None:
    rec = simulate_rates(Rig(X), 30, 20, duration_s=20, seed=7, speed=0.5)
    T = rec.a.matrices()
    T[300] = T[300] @ se3.from_xyz_quat(np.zeros(3), [0.0, 0.0, np.sin(0.25), np.cos(0.25)])   # 28.6°, no shift
    a = PoseStream.from_matrices(rec.a.stamps_ns, T)
    assert (~paper_gate(a)[0]).sum() == 1
    assert (~paper_gate(a, max_translation_m=None)[0]).sum() == 1
    assert (~paper_gate(a, max_rotation_rad=None)[0]).sum() == 0


def test_samples_are_associated_once(monkeypatch: pytest.MonkeyPatch) -> None:
    rec = simulate_rates(Rig(X), 100, 5, duration_s=30, seed=8, jumps_a=Jumps(2), jumps_b=Jumps(2))
    calls = []

    def counting(*args, **kw):
        calls.append(kw.get("method"))
        return associate(*args, **kw)

    monkeypatch.setattr(gates, "associate", counting)
    for gate in ("auto", "paper", "off"):
        calls.clear()
        sync_and_gate(rec.a, rec.b, gate=gate)
        assert calls == ["auto"]


def test_too_few_samples_name_the_flags_and_the_rates() -> None:
    rec = simulate_rates(Rig(X), 100, 1, duration_s=60, seed=9)
    with pytest.raises(DataError) as info:
        sync_and_gate(rec.a, rec.b, gate="paper", min_samples=10)    # a 1 Hz stream steps beyond 10 cm / 11.5°
    text = info.value.line(as_flags)                                  # as the CLI says it
    for flag in ("--gate auto", "--gate off", "--gate paper with wider --max-jump/--max-jump-deg",
                 "--time-offset SECONDS"):
        assert flag in text
    assert re.search(r"a 100 Hz, b (0\.99|1\.0|1) Hz", text) and "gates." not in text
    with pytest.raises(DataError, match="sync='auto'.*max_dt"):
        sync_and_gate(rec.a, rec.b.select(np.arange(len(rec.b)) % 4 == 0), sync="interpolate", max_dt_ns=10**9,
                      min_samples=10)


def test_bad_gate_settings_are_config_errors() -> None:
    rec = simulate_rates(Rig(X), 30, 20, duration_s=10, seed=10)
    with pytest.raises(ConfigError, match=r"\(gate\)"):
        sync_and_gate(rec.a, rec.b, gate="strict")
    with pytest.raises(ConfigError, match="accept_after"):
        paper_gate(rec.a, accept_after=0)


def test_auto_pairs_rejoin_segments_where_the_world_did_not_move() -> None:
    """Segments split where nothing moved the world (a camera that lost its target for a moment) are one again
    for the auto pairs, and a real re-localisation stays a boundary no pair spans (the ETH PrimeSense recording:
    21 gate segments, 98 mm; rejoined 9.8 mm between its two recordings)."""
    from dataclasses import replace

    from handeye_cli.analysis.selection import select_pairs

    rec = simulate_rates(Rig(X), 100, 30, duration_s=60, seed=5, speed=0.5)
    k = len(rec.b) // 2
    synced, _ = associate(rec.a, shifted_from(rec.b, k, 0.25))
    t = synced.stamps_ns
    moved = t >= rec.b.stamps_ns[k]
    labels = (t >= t[len(t) // 4]).astype(np.int64) + moved + (t >= t[3 * len(t) // 4])   # 4 segments, 1 real
    selection = select_pairs(replace(synced, segment=labels))
    assert selection.rejoined == 2 and selection.as_dict()["segments_rejoined"] == 2
    i, j = selection.pairs.i, selection.pairs.j
    assert not np.any(moved[i] != moved[j])                                    # none across the re-localisation
    assert np.any(labels[i] != labels[j])                                      # some across the other two
