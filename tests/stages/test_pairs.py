"""Relative-motion pairs: every strategy, the cap, the minimum rotation, segments, the strategy
string, and that solving the pairs recovers a simulated rig's extrinsic."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from handeye_cli.analysis.selection import ladder, select_pairs
from handeye_cli.errors import HandEyeError
from handeye_cli.geometry import se3
from handeye_cli.simulation import Rig, random_transform, simulate_rig
from handeye_cli.solvers import solve
from handeye_cli.stages.gates import pose_jump_gate
from handeye_cli.stages.pairs import keyframes, make_pairs
from handeye_cli.stages.sync import Synced, associate

X = random_transform(np.random.default_rng(21), 0.3)
MIN_ROT = np.deg2rad(10)


@pytest.fixture(scope="module")
def synced() -> Synced:
    """About 300 noise-free samples at 15 Hz with two tracking segments."""
    a, b = simulate_rig(Rig(X), duration_s=20, rate_a=15, rate_b=45, seed=3)
    s, _ = associate(a, b)
    segment = (np.arange(len(s)) >= len(s) * 2 // 3).astype(np.int64)
    return replace(s, segment=segment)


def brute_force(s: Synced, min_rotation: float) -> set[tuple[int, int]]:
    """Every i < j in one segment whose motion of a rotates by ≥ ``min_rotation``."""
    i, j = np.triu_indices(len(s), 1)
    ok = (se3.rotation_angle(se3.relative(s.T_a[i], s.T_a[j])) >= min_rotation) & (s.segment[i] == s.segment[j])
    return set(zip(i[ok].tolist(), j[ok].tolist(), strict=True))


def check_motions(s: Synced, pairs) -> None:
    """The motions follow the convention, stay within a segment and satisfy A X = X B."""
    np.testing.assert_allclose(pairs.A, se3.inverse(s.T_a[pairs.i]) @ s.T_a[pairs.j], atol=1e-12)
    np.testing.assert_allclose(pairs.B, se3.inverse(s.T_b[pairs.i]) @ s.T_b[pairs.j], atol=1e-12)
    np.testing.assert_array_equal(pairs.t_i_ns, s.stamps_ns[pairs.i])
    assert (pairs.i < pairs.j).all()
    np.testing.assert_array_equal(s.segment[pairs.i], s.segment[pairs.j])
    np.testing.assert_allclose(pairs.A @ X, X @ pairs.B, atol=2e-3)     # interpolation error only


def test_consecutive_and_stride(synced: Synced) -> None:
    n, cut = len(synced), int(np.argmax(synced.segment))
    for strategy, step in (("consecutive", 1), ("stride:4", 4)):
        pairs, counts = make_pairs(synced, strategy)
        check_motions(synced, pairs)
        assert (pairs.j - pairs.i == step).all()
        assert counts["pairs"] == counts["candidate_pairs"] == n - step - step      # none across the cut
        assert not ((pairs.i < cut) & (pairs.j >= cut)).any()


def test_all_is_every_pair_rotating_enough(synced: Synced) -> None:
    pairs, counts = make_pairs(synced, "all", max_pairs=10**6)
    check_motions(synced, pairs)
    expected = brute_force(synced, MIN_ROT)
    assert set(zip(pairs.i.tolist(), pairs.j.tolist(), strict=True)) == expected
    assert counts["candidate_pairs"] == counts["pairs"] == len(expected) > 1000


def test_min_rotation_is_honoured_by_the_selective_strategies(synced: Synced) -> None:
    for strategy in ("keyframes", "all", "random:500"):
        for min_rot in (np.deg2rad(5), np.deg2rad(30)):
            pairs, _ = make_pairs(synced, strategy, min_rotation_rad=min_rot)
            assert len(pairs) > 0
            assert se3.rotation_angle(pairs.A).min() >= min_rot - 1e-9


def test_keyframes_move_enough_between_each_other(synced: Synced) -> None:
    rot, trans = np.deg2rad(20), 0.25
    kf = keyframes(synced, rot, trans)
    assert kf[0] == 0 and len(kf) < len(synced) / 2
    for k0, k1 in zip(kf[:-1], kf[1:], strict=True):
        moved = [se3.rotation_angle(se3.relative(T[k0], T[k1])) >= rot or
                 np.linalg.norm(T[k1, :3, 3] - T[k0, :3, 3]) >= trans for T in (synced.T_a, synced.T_b)]
        assert any(moved) or synced.segment[k1] != synced.segment[k0]
        for k in range(k0 + 1, k1):      # nothing in between qualified
            assert not any(se3.rotation_angle(se3.relative(T[k0], T[k])) >= rot or
                           np.linalg.norm(T[k, :3, 3] - T[k0, :3, 3]) >= trans for T in (synced.T_a, synced.T_b))
    pairs, counts = make_pairs(synced, keyframe_rotation_rad=rot, keyframe_translation_m=trans)
    check_motions(synced, pairs)
    assert counts["keyframes"] == len(kf)
    assert set(pairs.i.tolist()) | set(pairs.j.tolist()) <= set(kf.tolist())
    assert counts["pairs"] == min(2000, counts["candidate_pairs"])


def test_random_is_seeded(synced: Synced) -> None:
    first, counts = make_pairs(synced, "random:400", seed=7)
    again, _ = make_pairs(synced, "random:400", seed=7)
    other, _ = make_pairs(synced, "random:400", seed=8)
    check_motions(synced, first)
    assert len(first) == counts["pairs"] == 400
    keys = set(zip(first.i.tolist(), first.j.tolist(), strict=True))
    assert len(keys) == 400 and keys <= brute_force(synced, MIN_ROT)
    np.testing.assert_array_equal(first.i, again.i)
    np.testing.assert_array_equal(first.j, again.j)
    assert keys != set(zip(other.i.tolist(), other.j.tolist(), strict=True))


def test_cap_is_deterministic_and_spread_over_the_recording(synced: Synced) -> None:
    n = len(synced)
    for strategy in ("all", "keyframes", "consecutive"):
        pairs, counts = make_pairs(synced, strategy, max_pairs=120)
        assert counts["candidate_pairs"] > 120 and len(pairs) == 120
        again, _ = make_pairs(synced, strategy, max_pairs=120)
        np.testing.assert_array_equal(pairs.i, again.i)
        # Every tenth of the recording takes part in the pairs, about as much as any other.
        share = np.bincount(np.r_[pairs.i, pairs.j] * 10 // n, minlength=10)
        assert share.min() >= 0.4 * share.mean(), share


@pytest.mark.parametrize("bad", ["bogus", "stride", "stride:0", "stride:x", "stride:-2", "random:",
                                 "keyframes:3", "all:5", "stride:²"])
def test_bad_strategy_strings_are_errors(synced: Synced, bad: str) -> None:
    with pytest.raises(HandEyeError, match="unknown pair strategy"):
        make_pairs(synced, bad)


def test_empty_input_gives_no_pairs(synced: Synced) -> None:
    for strategy in ("keyframes", "consecutive", "all", "random:5"):
        pairs, counts = make_pairs(synced.select(np.zeros(len(synced), dtype=bool)), strategy)
        assert len(pairs) == 0 and counts["candidate_pairs"] == 0


def _solve_error(pairs) -> tuple[float, float]:
    """(rotation [rad], translation [m]) error of the dqopt solution of the pairs."""
    E = se3.inverse(X) @ solve(pairs.A, pairs.B).matrix
    return float(se3.rotation_angle(E)), float(np.linalg.norm(E[:3, 3]))


def test_pairs_of_a_noise_free_rig_recover_the_extrinsic() -> None:
    a, b = simulate_rig(Rig(X, 123_456_789), duration_s=20, rate_a=20, rate_b=500, seed=9)
    synced, _ = associate(a, b, time_offset_ns=123_456_789)
    for strategy in ("keyframes", "all", "stride:5"):
        rot, trans = _solve_error(make_pairs(pose_jump_gate(synced)[0], strategy)[0])
        assert rot < 1e-6 and trans < 1e-6, (strategy, rot, trans)    # b's interpolation error


def test_pairs_of_a_noisy_rig_with_jumps_recover_the_extrinsic_within_the_noise() -> None:
    sigma_r, sigma_t = np.deg2rad(0.1), 0.002
    a, b = simulate_rig(Rig(X), duration_s=30, rate_a=100, rate_b=30, seed=10, sigma_r=sigma_r,
                        sigma_t=sigma_t, jumps=5)
    kept, _ = pose_jump_gate(associate(a, b)[0])
    for strategy in ("keyframes", "all", "random:1000"):
        rot, trans = _solve_error(make_pairs(kept, strategy)[0])
        assert rot < sigma_r / 3 and trans < sigma_t / 2, (strategy, rot, trans)


def _keyframes_by_definition(s: Synced, rot: float, trans: float) -> list[int]:
    """Keyframes by a plain loop over the samples (the reference for the blocked implementation)."""
    out = [0]
    for k in range(1, len(s)):
        k0 = out[-1]
        if s.segment[k] != s.segment[k0] or any(
                se3.rotation_angle(se3.relative(T[k0], T[k])) >= rot or
                np.linalg.norm(T[k, :3, 3] - T[k0, :3, 3]) >= trans for T in (s.T_a, s.T_b)):
            out.append(k)
    return out


@pytest.mark.parametrize("rot, trans", [(np.deg2rad(5), 0.02), (np.deg2rad(20), 0.25), (np.deg2rad(90), 5.0)])
def test_keyframes_follow_the_definition(synced: Synced, rot: float, trans: float) -> None:
    """Small, medium and larger-than-the-block spacings (the row-wise search beyond a block)."""
    assert keyframes(synced, rot, trans).tolist() == _keyframes_by_definition(synced, rot, trans)


def test_sampled_candidates_beyond_the_exact_limit(synced: Synced, monkeypatch: pytest.MonkeyPatch) -> None:
    """Beyond _EXACT_LIMIT pairs the candidates are sampled, not counted: the pairs still obey the
    strategy, are spread, and the count is estimated within a few percent."""
    import handeye_cli.stages.pairs as pairs_module

    exact = brute_force(synced, MIN_ROT)
    monkeypatch.setattr(pairs_module, "_EXACT_LIMIT", 1000)
    pairs, counts = make_pairs(synced, "all", max_pairs=300)
    check_motions(synced, pairs)
    keys = set(zip(pairs.i.tolist(), pairs.j.tolist(), strict=True))
    assert len(keys) == len(pairs) == 300 and keys <= exact
    assert counts["candidate_pairs"] == pytest.approx(len(exact), rel=0.05)
    share = np.bincount(np.r_[pairs.i, pairs.j] * 10 // len(synced), minlength=10)
    assert share.min() >= 0.4 * share.mean(), share
    drawn, _ = make_pairs(synced, "random:200", seed=3)
    assert len(drawn) == 200 and set(zip(drawn.i.tolist(), drawn.j.tolist(), strict=True)) <= exact


def test_auto_is_not_a_make_pairs_strategy(synced: Synced) -> None:
    with pytest.raises(HandEyeError, match="select_pairs"):
        make_pairs(synced, "auto")


def test_auto_selection_keeps_to_segments_and_the_cap_and_recovers_the_extrinsic() -> None:
    sigma_r, sigma_t = np.deg2rad(0.1), 0.002
    a, b = simulate_rig(Rig(X), duration_s=30, rate_a=100, rate_b=30, seed=10, sigma_r=sigma_r,
                        sigma_t=sigma_t, jumps=5)
    kept, _ = pose_jump_gate(associate(a, b)[0])
    sel = select_pairs(kept, max_pairs=500)
    p = sel.pairs
    np.testing.assert_allclose(p.A, se3.inverse(kept.T_a[p.i]) @ kept.T_a[p.j], atol=1e-12)
    assert (p.i < p.j).all() and (kept.segment[p.i] == kept.segment[p.j]).all()
    assert 100 < len(sel.pairs) <= 500 and sel.rounds >= 1 and sel.model is not None
    assert np.all(np.isfinite(sel.weights) & (sel.weights > 0))
    assert set((sel.pairs.j - sel.pairs.i).tolist()) <= set(range(sel.strides[0], len(kept)))
    E = se3.inverse(X) @ solve(sel.pairs.A, sel.pairs.B, alpha=sel.alpha, weights=sel.weights).matrix
    assert se3.rotation_angle(E) < sigma_r / 3 and np.linalg.norm(E[:3, 3]) < sigma_t / 2
    d = sel.as_dict()
    assert d["kind"] == "absolute" and d["strides"] == list(sel.strides) and d["alpha"] == sel.alpha


def test_auto_ladder_is_geometric() -> None:
    assert ladder(1).tolist() == [] and ladder(2).tolist() == [1]
    assert ladder(100).tolist() == [1, 2, 3, 4, 6, 8, 11, 16, 23, 32, 45, 64, 91]
