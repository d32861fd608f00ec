"""The pose-jump gate: it drops the injected tracking jumps and only them, accepts a real
re-localisation as a new segment, and no motion pair spans a segment boundary."""
from __future__ import annotations

import numpy as np
import pytest

from handeye_cli import se3
from handeye_cli.errors import HandEyeError
from handeye_cli.simulation import Rig, random_transform, simulate_rig
from handeye_cli.stages.gates import pose_jump_gate, stream_jump_gate
from handeye_cli.stages.pairs import make_pairs
from handeye_cli.stages.sync import Synced, associate
from handeye_cli.streams import PoseStream

X = random_transform(np.random.default_rng(11), 0.3)
RIG = dict(duration_s=20, rate_a=100, rate_b=30, seed=5)


def jumped(clean: PoseStream, dirty: PoseStream) -> np.ndarray:
    """Which samples ``simulate_rig(jumps=…)`` displaced (noise-free: nothing else differs)."""
    return np.abs(clean.xyz - dirty.xyz).max(axis=1) + np.abs(clean.quat_xyzw - dirty.quat_xyzw).max(axis=1) > 1e-12


def shifted_from(stream: PoseStream, k: int, dx: float) -> PoseStream:
    """``stream`` with samples from ``k`` on displaced by ``dx`` [m] along x (a re-localisation)."""
    xyz = stream.xyz.copy()
    xyz[k:, 0] += dx
    return PoseStream(stream.stamps_ns, xyz, stream.quat_xyzw)


@pytest.mark.parametrize("method", ["interpolate", "nearest"])
def test_drops_the_injected_jumps_and_only_them(method: str) -> None:
    clean_a, clean_b = simulate_rig(Rig(X), **RIG)
    a, b = simulate_rig(Rig(X), jumps=6, **RIG)
    bad_a, bad_b = jumped(clean_a, a), jumped(clean_b, b)
    assert bad_a.sum() == bad_b.sum() == 6

    synced, _ = associate(a, b, method=method)
    kept, counts = pose_jump_gate(synced)
    assert counts == {"dropped_pose_jump": len(synced) - len(kept), "jumps_a": 6, "jumps_b": 6, "accepted_jumps": 0}
    np.testing.assert_array_equal(stream_jump_gate(a)[0], ~bad_a)
    np.testing.assert_array_equal(stream_jump_gate(b)[0], ~bad_b)
    # Exactly what associating the streams without the jumped samples gives: no smeared outlier left.
    expected, _ = associate(a.select(~bad_a), b.select(~bad_b), method=method)
    np.testing.assert_array_equal(kept.stamps_ns, expected.stamps_ns)
    np.testing.assert_allclose(kept.T_b, expected.T_b, atol=1e-12)
    assert not kept.segment.any()


def test_a_jump_in_b_does_not_leak_into_interpolated_neighbours() -> None:
    a, b = simulate_rig(Rig(X), **RIG, T_wb_wa=np.eye(4))
    quat = b.quat_xyzw.copy()
    xyz = b.xyz.copy()
    xyz[300] += [0.6, 0.0, 0.0]                   # one bad 30 Hz sample spans ~7 of a's stamps
    kept, counts = pose_jump_gate(associate(a, PoseStream(b.stamps_ns, xyz, quat))[0])
    assert counts["jumps_b"] == 1 and counts["dropped_pose_jump"] == 0
    err = np.linalg.norm(kept.T_b[:, :3, 3] - (kept.T_a @ X)[:, :3, 3], axis=1)
    assert err.max() < 5e-3                       # interpolation error only, not a share of 0.6 m


@pytest.mark.parametrize("method", ["interpolate", "nearest"])
def test_relocalisation_starts_a_new_segment_and_no_pair_spans_it(method: str) -> None:
    a, b = simulate_rig(Rig(X), **RIG, T_wb_wa=np.eye(4))
    k = len(b) // 2
    b = shifted_from(b, k, 0.25)         # interpolating across it would hide it in 8 cm steps
    synced, _ = associate(a, b, method=method)
    kept, counts = pose_jump_gate(synced)
    assert counts["accepted_jumps"] == 1 and counts["jumps_b"] == 0
    truth = (kept.T_a @ X)[:, :3, 3] + np.outer(kept.segment, [0.25, 0.0, 0.0])
    tolerance = 5e-3 if method == "interpolate" else 0.1          # nearest: up to 1/60 s of motion
    assert np.linalg.norm(kept.T_b[:, :3, 3] - truth, axis=1).max() < tolerance   # nothing bridges the shift
    boundary = b.stamps_ns[k]
    np.testing.assert_array_equal(kept.segment, (kept.stamps_ns >= boundary if method == "interpolate"
                                                 else kept.segment > 0).astype(int))
    assert kept.segment[kept.stamps_ns < b.stamps_ns[k - 1]].max() == 0
    assert kept.segment[kept.stamps_ns > boundary].min() == 1
    for strategy in ("keyframes", "consecutive", "stride:7", "all", "random:300"):
        pairs, _ = make_pairs(kept, strategy, max_pairs=500)
        assert len(pairs) > 0
        np.testing.assert_array_equal(kept.segment[pairs.i], kept.segment[pairs.j])


def test_one_outlier_of_the_slower_stream_is_not_a_new_level_with_nearest() -> None:
    a, b = simulate_rig(Rig(X), **RIG)
    b = shifted_from(b, 200, 0.5)
    b = shifted_from(b, 201, -0.5)                # only sample 200 displaced; ~3 a stamps use it
    kept, counts = pose_jump_gate(associate(a, b, method="nearest")[0])
    assert counts["accepted_jumps"] == 0 and counts["jumps_b"] == 1
    assert not kept.segment.any()


def test_limits_can_be_switched_off_one_by_one() -> None:
    a, b = simulate_rig(Rig(X), **RIG)
    T = a.matrices()
    T[400] = T[400] @ se3.from_xyz_quat(np.zeros(3), [0.0, 0.0, np.sin(0.25), np.cos(0.25)])  # 28.6°, no shift
    a = PoseStream.from_matrices(a.stamps_ns, T)
    synced, _ = associate(a, b)
    assert pose_jump_gate(synced)[1]["jumps_a"] == 1
    assert pose_jump_gate(synced, max_translation_m=None)[1]["jumps_a"] == 1
    assert pose_jump_gate(synced, max_rotation_rad=None)[1]["jumps_a"] == 0
    kept, counts = pose_jump_gate(synced, max_translation_m=None, max_rotation_rad=None)
    assert counts["dropped_pose_jump"] == 0 and len(kept) == len(synced)


def test_gating_a_selection_keeps_only_its_samples() -> None:
    a, b = simulate_rig(Rig(X), jumps=3, **RIG)
    synced, _ = associate(a, b)
    part = synced.select(np.arange(len(synced)) % 2 == 0)
    kept, counts = pose_jump_gate(part)
    assert np.isin(kept.stamps_ns, part.stamps_ns).all()
    assert counts["dropped_pose_jump"] == len(part) - len(kept) > 0


def test_synced_built_without_source_is_gated_as_is() -> None:
    a, b = simulate_rig(Rig(X), **RIG)
    s, _ = associate(a, b)
    T_b = s.T_b.copy()
    T_b[50, :3, 3] += [0.0, 0.3, 0.0]
    bare = Synced(s.stamps_ns, s.T_a, T_b, s.dt_ns)
    kept, counts = pose_jump_gate(bare)
    assert counts["jumps_b"] == 1 and counts["dropped_pose_jump"] == 1
    np.testing.assert_array_equal(kept.stamps_ns, np.delete(s.stamps_ns, 50))
    np.testing.assert_allclose(kept.T_b, np.delete(T_b, 50, axis=0), atol=1e-12)


def test_accept_after_must_be_positive() -> None:
    a, _ = simulate_rig(Rig(X), **RIG)
    with pytest.raises(HandEyeError, match="accept_after"):
        stream_jump_gate(a, accept_after=0)
