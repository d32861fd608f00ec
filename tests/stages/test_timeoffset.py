"""Clock-offset estimation: offsets of minutes between 100 Hz and 30 Hz streams with realistic
noise to within 1 ms, streams that do not overlap in raw time, and the refusals and warnings."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from handeye_cli.errors import HandEyeError
from handeye_cli.geometry import se3
from handeye_cli.simulation import Rig, random_transform, simulate_rig
from handeye_cli.solvers import solve
from handeye_cli.stages.pairs import make_pairs
from handeye_cli.stages.sync import associate
from handeye_cli.stages.timeoffset import MIN_CORRELATION, estimate_time_offset
from handeye_cli.streams import PoseStream

X = random_transform(np.random.default_rng(31), 0.3)
NOISE = dict(sigma_r=np.deg2rad(0.1), sigma_t=0.002)      # realistic tracking noise: 0.1°, 2 mm
MS = 1_000_000


def rig(offset_ns: int, seed: int, duration_s: float = 40.0, **kw) -> tuple[PoseStream, PoseStream]:
    """A noisy 100 Hz stream a and 30 Hz stream b whose clock is ``offset_ns`` ahead."""
    return simulate_rig(Rig(X, offset_ns), duration_s=duration_s, rate_a=100, rate_b=30, seed=seed, **{**NOISE, **kw})


@pytest.mark.parametrize("offset_s", [-299.7, -123.456789, -0.0173, 0.0, 0.0333, 57.25, 299.9])
def test_offsets_of_minutes_are_found_within_a_millisecond(offset_s: float) -> None:
    offset = int(round(offset_s * 1e9))
    a, b = rig(offset, seed=int(abs(offset_s) * 10) % 97)
    est = estimate_time_offset(a, b)
    assert abs(est.offset_ns - offset) < 1 * MS
    assert abs(est.coarse_ns - offset) < 10 * MS
    assert 0 < est.std_ns < 1 * MS
    assert est.correlation > 0.95 and est.warnings == ()


@pytest.mark.statistical
def test_refinement_beats_the_coarse_peak_under_heavy_noise() -> None:
    final, coarse = [], []
    for seed in range(6):
        offset = 10_000_000_000 + seed * 777_777_777
        est = estimate_time_offset(*rig(offset, seed=seed, sigma_r=np.deg2rad(0.4), sigma_t=0.004))
        final.append(est.offset_ns - offset)
        coarse.append(est.coarse_ns - offset)
    rms = [float(np.sqrt(np.mean(np.square(e)))) for e in (final, coarse)]
    assert np.max(np.abs(final)) < 1 * MS and rms[0] < 0.6 * rms[1]


def test_streams_that_do_not_overlap_in_raw_time_are_aligned_and_calibrated() -> None:
    offset = 200_000_000_000 + 12_345_678
    a, b = rig(offset, seed=4, duration_s=30)
    assert b.stamps_ns[0] > a.stamps_ns[-1]                  # no raw overlap at all
    with pytest.raises(HandEyeError, match="do not overlap"):
        associate(a, b)
    est = estimate_time_offset(a, b)
    assert abs(est.offset_ns - offset) < 1 * MS
    synced, _ = associate(a, b, time_offset_ns=est.offset_ns)
    pairs, _ = make_pairs(synced)
    E = se3.inverse(X) @ solve(pairs.A, pairs.B).matrix
    assert se3.rotation_angle(E) < np.deg2rad(0.05) and np.linalg.norm(E[:3, 3]) < 2e-3


def test_swapping_the_streams_negates_the_offset() -> None:
    offset = -87_654_321_000
    a, b = rig(offset, seed=5, duration_s=30)
    assert abs(estimate_time_offset(b, a).offset_ns + offset) < 1 * MS


def test_gaps_jumps_and_partial_overlap_are_tolerated() -> None:
    offset = 31_415_926_535
    a, b = rig(offset, seed=6, jumps=5)
    t = (b.stamps_ns - b.stamps_ns[0]) / 1e9
    b = b.select(((t < 12) | (t > 17)) & (t < 30))          # a 5 s hole, and b stops 10 s early
    est = estimate_time_offset(a, b)
    assert abs(est.offset_ns - offset) < 1 * MS


def test_a_search_bound_is_honoured() -> None:
    offset = 100_000_000_000
    a, b = rig(offset, seed=7, duration_s=30)
    assert abs(estimate_time_offset(a, b, max_offset_s=150).offset_ns - offset) < 1 * MS
    # The true offset lies outside ±50 s: the estimate is refused, and the fix names the bound's flag.
    with pytest.raises(HandEyeError, match="widen max_time_offset=SECONDS"):
        estimate_time_offset(a, b, max_offset_s=50)


def test_rotation_free_motion_is_refused() -> None:
    a, b = rig(3_000_000_000, seed=8, motion="linear")
    with pytest.raises(HandEyeError, match=f"do not correlate .* < {MIN_CORRELATION}"):
        estimate_time_offset(a, b)


@pytest.mark.parametrize("n_samples", [0, 1, 5, 55])
def test_too_short_streams_are_refused(n_samples: int) -> None:
    a, b = rig(0, seed=9, duration_s=10)
    with pytest.raises(HandEyeError, match="too short to estimate a time offset"):
        estimate_time_offset(a, b.select(np.arange(n_samples)))


def periodic_streams(offset_ns: int) -> tuple[PoseStream, PoseStream]:
    """A rotation whose speed repeats every 2 s (a robot arm repeating one move), 100 Hz / 30 Hz."""
    def stream(rate: float, shift_ns: int, T_s: np.ndarray) -> PoseStream:
        t = np.arange(int(20 * rate)) / rate
        angle = t + (1 - np.cos(np.pi * t)) / (2 * np.pi)        # speed 1 + 0.5 sin(πt) rad/s
        T = np.tile(np.eye(4), (len(t), 1, 1))
        T[:, :3, :3] = Rotation.from_rotvec(np.outer(angle, [0.3, 0.2, 0.93])).as_matrix()
        return PoseStream.from_matrices(10**18 + shift_ns + np.round(t * 1e9).astype(np.int64), T @ T_s)
    return stream(100, 0, np.eye(4)), stream(30, offset_ns, X)


def test_repetitive_motion_is_flagged_as_ambiguous() -> None:
    a, b = periodic_streams(5_000_000_000)
    est = estimate_time_offset(a, b)
    assert any("ambiguous" in w for w in est.warnings)
    periods = (est.offset_ns - 5_000_000_000) / 2e9
    assert abs(periods - round(periods)) * 2e9 < MS          # right, or off by whole 2 s periods


@pytest.mark.parametrize("duration_s", [12, 400])
def test_a_shared_grid_changes_no_estimate(monkeypatch: pytest.MonkeyPatch, duration_s: float) -> None:
    """A rig's estimates against one reference share its grid (a StreamMemo of grid_of): each stream's grid
    is computed once (a long recording's: its coarse level's, at that level's step), and every estimate is the
    one without the memo, to the nanosecond."""
    from handeye_cli.stages import timeoffset as to

    offsets = (15_000_000, -40_000_000)
    rigs = [simulate_rig(Rig(random_transform(np.random.default_rng(k), 0.3), offset), duration_s=duration_s,
                         rate_a=30, rate_b=rate, sigma_r=np.deg2rad(0.2), sigma_t=0.002, seed=5)
            for k, (offset, rate) in enumerate(zip(offsets, (20, 10), strict=True))]
    ref = rigs[0][0]                                          # seed 5: one trajectory, one reference stream
    alone = [to.estimate_time_offset(ref, b) for _, b in rigs]
    made: list[int] = []
    grid_of = to.grid_of
    monkeypatch.setattr(to, "grid_of", lambda stream, *step: made.append(id(stream)) or grid_of(stream, *step))
    from handeye_cli.streams import StreamMemo

    memo = StreamMemo(to.grid_of)
    shared = [to.estimate_time_offset(ref, b, grid=memo) for _, b in rigs]
    assert [(e.offset_ns, e.std_ns) for e in shared] == [(e.offset_ns, e.std_ns) for e in alone]
    assert made.count(id(ref)) == 1 and len(made) == 3           # the reference's grid once, each other once
    assert all(abs(e.offset_ns - off) < 2_000_000 for e, off in zip(shared, offsets, strict=True))
