"""Tests written to kill mutants that the rest of the suite let live (issue 12 item 6).

Each test checks the code against a value computed independently of it: the result document
rebuilt with scipy, the paper gate's limits at their edges, the bootstrap spread against a
Monte-Carlo spread over fresh noise, and the time offset's reported std against its real errors.
``scripts/mutation.py`` applies the mutants these tests were written against.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from _util import run, write_tum
from scipy.spatial.transform import Rotation

from handeye_cli.analysis import bootstrap
from handeye_cli.simulation import Rig, motion_pairs, random_transform, simulate_rig
from handeye_cli.solvers import solve
from handeye_cli.stages.gates import paper_gate
from handeye_cli.stages.sync import associate
from handeye_cli.stages.timeoffset import estimate_time_offset
from handeye_cli.streams import PoseStream

X_RIG = np.array([[0.0, -1.0, 0.0, 0.12], [1.0, 0.0, 0.0, -0.05], [0.0, 0.0, 1.0, 0.30], [0.0, 0.0, 0.0, 1.0]])


def _matrix(xyz: list[float], quat_xyzw: list[float]) -> np.ndarray:
    """4x4 from a translation [m] and an x-y-z-w quaternion, by scipy alone."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(quat_xyzw).as_matrix()
    T[:3, 3] = xyz
    return T


def _slow_rig(tmp_path: Path, glitch_b: dict[int, tuple[float, float]] | None = None) -> tuple[Path, Path]:
    """TUM files of a noise-free 30 Hz rig moving slowly (< 1 cm and < 0.5° per step); ``glitch_b[i] =
    (deg, metres)`` turns b's sample i by ``deg`` about its own axis (0, 0.6, 0.8) and shifts it by
    ``metres`` along the world's (0.6, 0.8, 0): a one-sample tracking glitch."""
    a, b = simulate_rig(Rig(X_RIG, 0), duration_s=40, rate_a=30, rate_b=30, speed=0.1, seed=4)
    xyz, rot = b.xyz.copy(), Rotation.from_quat(b.quat_xyzw)
    turns = np.zeros((len(b), 3))
    for i, (deg, metres) in (glitch_b or {}).items():
        turns[i] = np.deg2rad(deg) * np.array([0.0, 0.6, 0.8])
        xyz[i] += metres * np.array([0.6, 0.8, 0.0])
    quat = (rot * Rotation.from_rotvec(turns)).as_quat()
    b = PoseStream(b.stamps_ns, xyz, quat, b.frame_id, b.child_frame_id)
    return write_tum(tmp_path / "a.tum", a), write_tum(tmp_path / "b.tum", b)


# 1. The result document rebuilt independently ------------------------------------------------------------------

def test_quaternion_translation_and_ros_snippet_rebuild_the_matrix(capsys, tmp_path):
    a, b = _slow_rig(tmp_path)
    code, out, err = run(capsys, "calibrate", a, b, "--gate", "off")
    assert code == 0, err
    doc = yaml.safe_load(out)
    M = np.array(doc["matrix"])
    np.testing.assert_allclose(M, X_RIG, atol=1e-4)                      # noise-free: the truth
    np.testing.assert_allclose(_matrix(doc["translation"], doc["quaternion_xyzw"]), M, atol=1e-9)
    assert doc["quaternion_xyzw"][3] >= 0
    nums = dict(re.findall(r"--(x|y|z|qx|qy|qz|qw) (\S+)", doc["ros2_static_transform"]))
    assert len(nums) == 7
    xyz = [float(nums[k]) for k in ("x", "y", "z")]
    quat = [float(nums[k]) for k in ("qx", "qy", "qz", "qw")]
    np.testing.assert_allclose(_matrix(xyz, quat), M, atol=1e-9)
    frames = doc["frames"]                                 # T_a_b: a is the parent, b the child
    assert f"--frame-id {frames['a']} --child-frame-id {frames['b']}" in doc["ros2_static_transform"]


# 2. The paper gate's limits at their edges (10 cm, 11.5°) ------------------------------------------------------

GLITCHES = {"9cm": ((0.0, 0.09), 0), "11cm": ((0.0, 0.11), 1), "10deg": ((10.0, 0.0), 0), "13deg": ((13.0, 0.0), 1)}


@pytest.mark.parametrize("glitch", list(GLITCHES))
@pytest.mark.parametrize("via", ["flags", "config"])
def test_paper_gate_limits_at_their_edges(capsys, tmp_path, glitch, via):
    G, dropped = GLITCHES[glitch]
    a, b = _slow_rig(tmp_path, {300: G})
    if via == "flags":
        args = ["--gate", "paper", "--max-jump", "0.1", "--max-jump-deg", "11.5"]
    else:
        (tmp_path / "c.yaml").write_text("gate: paper\nmax_jump: 0.1\nmax_jump_deg: 11.5\n")
        args = ["--config", str(tmp_path / "c.yaml")]
    code, out, err = run(capsys, "calibrate", a, b, *args)
    assert code == 0, err
    samples = yaml.safe_load(out)["samples"]
    assert (samples["jumps_a"], samples["jumps_b"]) == (0, dropped), samples


# 3. Bootstrap spread at small n against a Monte-Carlo spread over fresh noise -----------------------------------

def _range95(values: np.ndarray) -> np.ndarray:
    """Per column, the width of the central 95 % (robust to the rare datasets cost (8) fits badly)."""
    return np.diff(np.percentile(values, [2.5, 97.5], axis=0), axis=0)[0]


@pytest.mark.statistical
def test_bootstrap_spread_at_small_n_matches_the_monte_carlo_spread():
    """n = 20 pairs: the 95 % range of the bootstrap's rotation replicates against the 95 % range of the
    estimate's rotation error over 300 fresh datasets (fresh motions and noise, as the pairs bootstrap
    assumes); without the HC1 factor √(20/14) the ratio falls to about 0.83."""
    n, sigma_r, sigma_t = 20, np.deg2rad(0.5), 0.005
    ratios = []
    for seed in (3, 4):
        rng = np.random.default_rng(seed)
        X = random_transform(rng, 0.3)
        errors, boot = [], []
        for trial in range(300):
            A, B = motion_pairs(n, X, rng, "random", sigma_r, sigma_t)
            R = solve(A, B).matrix[:3, :3]
            errors.append(np.rad2deg(Rotation.from_matrix(R @ X[:3, :3].T).as_rotvec()))
            if trial < 30:
                boot.append(_range95(bootstrap(A, B, 200, seed=trial).rotation_deltas_deg))
        ratios.append(np.array(boot) / _range95(np.array(errors)))
    ratio = float(np.median(ratios))
    assert 0.9 < ratio < 1.2, ratio


# 4. The time offset's reported std against its errors across seeds ----------------------------------------------

@pytest.mark.statistical
def test_time_offset_std_is_calibrated_across_seeds():
    X = random_transform(np.random.default_rng(31), 0.3)
    z = []
    for seed in range(20):
        offset = int(1e9 * (seed - 10) * 0.37)
        a, b = simulate_rig(Rig(X, offset), duration_s=20, rate_a=100, rate_b=30, seed=100 + seed,
                            sigma_r=np.deg2rad(0.3), sigma_t=0.005)
        est = estimate_time_offset(a, b)
        z.append((est.offset_ns - offset) / est.std_ns)
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert 0.5 < rms < 2.0, (rms, z)


# 5. The timestamp gate is inclusive: a sample exactly --max-dt from its interpolation samples is kept ------------

def test_timestamp_gate_keeps_a_sample_exactly_at_max_dt():
    s = 1_000_000_000
    t0 = 1_700_000_000 * s

    def still(stamps: list[int]) -> PoseStream:
        n = len(stamps)
        return PoseStream(np.array(stamps, dtype=np.int64) + t0, np.zeros((n, 3)), np.tile([0.0, 0, 0, 1], (n, 1)))

    b = still([0, s, 2 * s, 4 * s, 5 * s])              # 3 s missing: 2.5 s and 3.5 s lie 1.5 s from one side
    a = still([s // 2, 9 * s // 4, 5 * s // 2, 7 * s // 2])      # 2.25 s lies 1.75 s from 4 s
    synced, counts = associate(a, b, method="interpolate", max_dt_ns=3 * s // 2)
    assert (synced.stamps_ns - t0).tolist() == [s // 2, 5 * s // 2, 7 * s // 2]
    assert counts["dropped_timestamp_gate"] == 1


# 6. A re-localisation behind dropped glitch samples still starts a new tracking segment --------------------------

@pytest.mark.parametrize("shift_m", [0.0, 0.5])
def test_relocalisation_across_dropped_glitches_starts_a_segment(shift_m):
    n = 100
    xyz = np.c_[0.001 * np.arange(n), np.zeros((n, 2))]          # 1 mm per sample
    xyz[52:, 1] += shift_m                                       # the tracking re-localises by shift_m …
    xyz[50:52, 2] = [1.0, 2.0]                                   # … behind two glitch samples
    stream = PoseStream(np.arange(n, dtype=np.int64) * 200_000_000, xyz, np.tile([0.0, 0, 0, 1], (n, 1)))
    keep, segment, accepted = paper_gate(stream)
    assert np.flatnonzero(~keep).tolist() == [50, 51]
    new = int(shift_m > 0)                                       # 0.5 m > 10 cm across the gap: a new segment
    assert accepted == new and segment[keep].tolist() == [0] * 50 + [new] * 48
