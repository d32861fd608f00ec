"""Association of stream b to a's stamps: interpolation and nearest exactness on analytic
trajectories, the timestamp gate's counts, the time-offset sign and the error cases."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from handeye_cli.errors import ConfigError, DataError, HandEyeError, as_flags
from handeye_cli.geometry import se3
from handeye_cli.simulation import Rig, random_transform, simulate_rig
from handeye_cli.stages.sync import Synced, associate, default_max_dt_ns
from handeye_cli.streams import PoseStream

T0 = 1_700_000_000_000_000_000        # epoch-scale stamps [ns]: float seconds would lose precision
VEL = np.array([0.3, -0.2, 0.1])      # [m/s]
OMEGA = np.array([0.2, 0.5, -0.4])    # [rad/s], about a fixed axis: SLERP is exact on it


def analytic_poses(stamps_ns: np.ndarray) -> np.ndarray:
    """``T_w_s(t)``: constant velocity and constant angular velocity from a fixed start pose."""
    t = (np.asarray(stamps_ns) - T0) / 1e9
    T = np.tile(np.eye(4), (len(t), 1, 1))
    T[:, :3, :3] = (Rotation.from_rotvec([0.3, 0.1, -0.2]) * Rotation.from_rotvec(OMEGA * t[:, None])).as_matrix()
    T[:, :3, 3] = [1.0, 2.0, 0.5] + VEL * t[:, None]
    return T


def irregular_stamps(rate_hz: float, duration_s: float, seed: int) -> np.ndarray:
    """Jittered stamps [ns] at about ``rate_hz`` starting at ``T0``."""
    rng = np.random.default_rng(seed)
    n = int(rate_hz * duration_s)
    return T0 + np.round((np.arange(n) + rng.uniform(-0.3, 0.3, n)) / rate_hz * 1e9).astype(np.int64)


def analytic_stream(stamps_ns: np.ndarray) -> PoseStream:
    return PoseStream.from_matrices(stamps_ns, analytic_poses(stamps_ns))


def pose_error(T: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Largest (rotation [rad], translation [m]) difference over a stack of poses."""
    return (float(np.max(se3.rotation_angle(se3.relative(truth, T)))),
            float(np.max(np.linalg.norm(T[:, :3, 3] - truth[:, :3, 3], axis=1))))


def test_interpolation_is_exact_on_constant_velocity_and_rate() -> None:
    a = analytic_stream(irregular_stamps(100, 10, seed=1))
    b = analytic_stream(irregular_stamps(30, 10, seed=2))
    synced, counts = associate(a, b, method="interpolate")
    rot, trans = pose_error(synced.T_b, analytic_poses(synced.stamps_ns))
    assert rot < 1e-9 and trans < 1e-9
    assert counts["synced"] == len(synced) >= len(a) - 2 and synced.reference == "a"
    np.testing.assert_array_equal(synced.T_a, a.matrices()[np.isin(a.stamps_ns, synced.stamps_ns)])


def test_nearest_takes_the_closest_sample_and_reports_its_distance() -> None:
    a = analytic_stream(irregular_stamps(100, 10, seed=1))
    b = analytic_stream(irregular_stamps(30, 10, seed=2))
    synced, _ = associate(a, b, method="nearest")
    closest = b.stamps_ns[np.argmin(np.abs(synced.stamps_ns[:, None] - b.stamps_ns[None, :]), axis=1)]
    np.testing.assert_array_equal(synced.dt_ns, np.abs(closest - synced.stamps_ns))
    rot, trans = pose_error(synced.T_b, analytic_poses(closest))
    assert rot < 1e-12 and trans < 1e-12
    off_rot, off_trans = pose_error(synced.T_b, analytic_poses(synced.stamps_ns))
    assert off_trans > 1e-3          # nearest is not interpolation: it is off by velocity × distance


def test_both_methods_are_exact_where_the_stamps_coincide() -> None:
    stamps = irregular_stamps(50, 4, seed=3)
    b = analytic_stream(stamps)
    a = analytic_stream(stamps[::3])
    for method in ("interpolate", "nearest"):
        synced, counts = associate(a, b, method=method)
        assert counts["synced"] == len(a)
        assert not synced.dt_ns.any()
        rot, trans = pose_error(synced.T_b, analytic_poses(a.stamps_ns))
        assert rot < 1e-12 and trans < 1e-12


def test_sampling_a_stream_marks_queries_outside_the_span() -> None:
    b = analytic_stream(T0 + np.arange(0, 10) * 100_000_000)
    query = T0 + np.array([-1, 0, 50_000_000, 900_000_000, 900_000_001])
    at = b.sample(query)
    np.testing.assert_array_equal(at.inside, [False, True, True, True, False])
    np.testing.assert_array_equal(at.gap_ns, [0, 50_000_000, 0])
    np.testing.assert_array_equal(at.used, [0, 0, 9])
    assert len(at.xyz) == len(at.quat_xyzw) == 3
    near = b.sample(T0 + np.array([40_000_000, 60_000_000]), "nearest")
    np.testing.assert_array_equal(near.used, [0, 1])
    np.testing.assert_array_equal(near.gap_ns, [40_000_000, 40_000_000])


@pytest.mark.parametrize("method", ["interpolate", "nearest"])
def test_timestamp_gate_drops_exactly_the_samples_in_a_gap(method: str) -> None:
    a_stamps = T0 + np.arange(2000) * 10_000_000                  # 100 Hz, 20 s
    b_stamps = T0 + 5_000_000 + np.arange(600) * 33_333_333       # 30 Hz, offset from a's grid
    gap = (b_stamps > T0 + 8_000_000_000) & (b_stamps < T0 + 10_500_000_000)
    b = analytic_stream(b_stamps[~gap])
    max_dt = 100_000_000
    synced, counts = associate(analytic_stream(a_stamps), b, method=method, max_dt_ns=max_dt)

    last, first = b.stamps_ns[b.stamps_ns < T0 + 9_000_000_000][-1], b.stamps_ns[b.stamps_ns > T0 + 9_000_000_000][0]
    span = (a_stamps >= b.stamps_ns[0]) & (a_stamps <= b.stamps_ns[-1])
    if method == "interpolate":     # both bracketing samples within max_dt: nothing inside the gap
        dropped = (a_stamps > last) & (a_stamps < first)
    else:                           # the nearer sample within max_dt: the gap's middle only
        dropped = (a_stamps > last + max_dt) & (a_stamps < first - max_dt)
    assert counts["dropped_outside_span"] == int((~span).sum())
    assert counts["dropped_timestamp_gate"] == int(dropped.sum()) > 0
    np.testing.assert_array_equal(synced.stamps_ns, a_stamps[span & ~dropped])
    assert counts["read_a"] == counts["synced"] + counts["dropped_outside_span"] + counts["dropped_timestamp_gate"]
    assert synced.dt_ns.max() <= max_dt


def test_time_offset_shifts_stream_b_by_b_clock_ahead_of_a() -> None:
    X = random_transform(np.random.default_rng(4), 0.3)
    offset = 2_345_678_901                                   # b's clock 2.35 s ahead of a's
    a, b = simulate_rig(Rig(X, offset), duration_s=10, rate_a=20, rate_b=400, seed=4, T_wb_wa=np.eye(4))
    assert b.stamps_ns[0] - a.stamps_ns[0] > 2_000_000_000
    synced, _ = associate(a, b, time_offset_ns=offset, method="interpolate")
    rot, trans = pose_error(synced.T_b, synced.T_a @ X)     # with T_wb_wa = I: T_wb_b = T_wa_a X
    assert rot < 1e-5 and trans < 1e-5
    wrong, _ = associate(a, b, time_offset_ns=-offset, method="interpolate")
    assert len(wrong) < len(synced)
    assert pose_error(wrong.T_b, wrong.T_a @ X)[1] > 0.1


def test_streams_that_do_not_overlap_are_an_error_until_offset() -> None:
    a = analytic_stream(T0 + np.arange(100) * 10_000_000)
    b = analytic_stream(T0 + 60_000_000_000 + np.arange(100) * 10_000_000)
    with pytest.raises(HandEyeError, match="do not overlap"):
        associate(a, b)
    synced, counts = associate(a, b, time_offset_ns=60_000_000_000)
    assert counts["synced"] == 100


def test_empty_streams_and_bad_settings_are_errors() -> None:
    a = analytic_stream(T0 + np.arange(100) * 10_000_000)
    empty = PoseStream(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 4)), source="log.mcap:/b")
    with pytest.raises(HandEyeError, match=r"pose stream b is empty \(log.mcap:/b\)"):
        associate(a, empty)
    with pytest.raises(HandEyeError, match="pose stream a is empty"):
        associate(empty, a)
    with pytest.raises(ConfigError, match="unknown association method"):
        associate(a, a, method="cubic")
    b = analytic_stream(T0 + 5_000_000 + np.arange(100) * 10_000_000)
    with pytest.raises(HandEyeError, match="no sample passed the timestamp gate"):
        associate(a, b, method="nearest", max_dt_ns=1_000_000)


@pytest.mark.parametrize(("rate_a", "rate_b", "reference"), [(100, 1, "b"), (1, 100, "a"), (30, 20, "b")])
def test_auto_lets_the_slower_stream_set_the_sample_times(rate_a: float, rate_b: float, reference: str) -> None:
    a = analytic_stream(irregular_stamps(rate_a, 20, seed=5))
    b = analytic_stream(irregular_stamps(rate_b, 20, seed=6))
    synced, counts = associate(a, b)
    slow = b if reference == "b" else a
    assert synced.reference == reference
    assert np.isin(synced.stamps_ns, slow.stamps_ns).all() and len(synced) >= len(slow) - 2
    assert counts["synced"] + counts["dropped_outside_span"] + counts["dropped_timestamp_gate"] == len(slow)
    truth = analytic_poses(synced.stamps_ns)
    assert max(pose_error(synced.T_a, truth)) < 1e-9 and max(pose_error(synced.T_b, truth)) < 1e-9
    assert synced.describe() == {"reference": reference, "rate_a_hz": pytest.approx(rate_a, rel=0.05),
                                 "rate_b_hz": pytest.approx(rate_b, rel=0.05)}


def test_default_gate_follows_the_interpolated_streams_rate() -> None:
    assert default_max_dt_ns(10_000_000) == 100_000_000                 # 100 Hz: the paper's 0.1 s
    assert default_max_dt_ns(1_000_000_000) == 2_500_000_000            # 1 Hz: 2.5 steps
    a = analytic_stream(irregular_stamps(100, 30, seed=7))
    b_stamps = T0 + np.arange(30) * 1_000_000_000                      # 1 Hz
    b = analytic_stream(np.delete(b_stamps, [10, 20, 21]))              # one and two missing samples
    synced, counts = associate(b, a, method="interpolate")               # 100 Hz stream at 1 Hz stamps
    assert counts["dropped_timestamp_gate"] == 0
    synced, counts = associate(a, b, method="interpolate")              # 1 Hz stream at 100 Hz stamps
    q = a.stamps_ns
    span = (q >= b.stamps_ns[0]) & (q <= b.stamps_ns[-1])
    lo, hi = b_stamps[19], b_stamps[22]                                  # 3 s gap: ends beyond 2.5 s dropped
    dropped = (q > lo) & (q < hi) & (np.maximum(q - lo, hi - q) > 2_500_000_000)
    assert counts["dropped_timestamp_gate"] == int(dropped.sum()) > 0    # the 2 s gap is bridged
    np.testing.assert_array_equal(synced.stamps_ns, q[span & ~dropped])


def test_no_sample_through_the_gate_names_flags_and_rates() -> None:
    a = analytic_stream(irregular_stamps(100, 20, seed=1))
    b = analytic_stream(T0 + 500_000_000 + np.arange(20) * 1_000_000_000)
    with pytest.raises(DataError) as info:
        associate(a, b, method="interpolate", max_dt_ns=100_000_000)
    text = info.value.line(as_flags)                                  # as the CLI says it
    assert "a 100 Hz, b 1 Hz" in text and "--sync auto" in text and "--max-dt" in text and "max_dt 0.100 s" in text
    assert "sync." not in text and "gates." not in text


def test_synced_round_trips_matrices_and_selects() -> None:
    stamps = irregular_stamps(50, 2, seed=9)
    T = analytic_poses(stamps)
    s = Synced.from_matrices(stamps, T, T @ random_transform(np.random.default_rng(1), 0.2), np.zeros(len(T), int))
    np.testing.assert_allclose(s.T_a, T, atol=1e-12)
    part = s.select(np.arange(len(s)) % 3 == 0)
    np.testing.assert_allclose(part.T_b, s.T_b[::3], atol=1e-12)
    assert part.segment.shape == (len(part),) and part.reference == "a"
