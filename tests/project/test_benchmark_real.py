"""benchmarks/real.py on a tiny generated corpus (never the real one): the script cannot rot.

The fake corpus has the layout the script reads — ``ethz_hand_eye_2017/reference_extrinsics.json``
naming TUM files of a simulated arm and of a simulated phone triplet C, M, N (so the loop closure
is measured), and a kinhec-style folder with one eye-in-hand sequence whose camera stream records
``T_cam_target`` (the inverse), its ground truth JSON and a published error."""
from __future__ import annotations

import importlib.util
import json
import sys

import numpy as np
import pytest
from _util import ROOT, write_tum

from handeye_cli.geometry import se3
from handeye_cli.simulation import random_transform
from handeye_cli.simulation.recordings import absolute, scenario, simulate_recording
from handeye_cli.streams import PoseStream


def _load():
    spec = importlib.util.spec_from_file_location("benchmark_real", ROOT / "benchmarks" / "real.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["benchmark_real"] = module          # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


real = _load()


FAST = {"max_pairs": 120}          # every call solves few pairs: the whole file runs in about a second


def _arm(seed: int):
    """A short arm recording at 10 Hz (kinematics against a target camera)."""
    rig = scenario("arm", seed, 1.0).rig
    return simulate_recording(rig, absolute(0.01, 0.0001), absolute(0.1, 0.001), duration_s=8.0, rate_a=10,
                              rate_b=10, seed=seed, speed=0.25)


def _moved(stream: PoseStream, T: np.ndarray) -> PoseStream:
    """The poses of a sensor rigidly attached at ``T`` (in ``stream``'s sensor frame)."""
    return PoseStream.from_matrices(stream.stamps_ns, stream.matrices() @ T)


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    """(data dir, kinhec dir, the arm's truth, the kinhec truth)."""
    root = tmp_path_factory.mktemp("bench")
    data, eth = root / "data", root / "data" / real.ETH
    eth.mkdir(parents=True)
    arm = _arm(3)
    files = {"arm/a.tum": arm.a, "arm/b.tum": arm.b}
    rng = np.random.default_rng(5)
    X_cm, X_mn = random_transform(rng, 0.3), random_transform(rng, 0.3)
    C = _arm(4).a
    M, N = _moved(C, X_cm), _moved(C, X_cm @ X_mn)
    files.update({"t/C.tum": C, "t/M.tum": M, "t/N.tum": N})
    for name, stream in files.items():
        (eth / name).parent.mkdir(exist_ok=True)
        write_tum(eth / name, stream)
    X_nc = np.linalg.inv(X_cm @ X_mn)
    ref = {"tango_loop_closure_deg_mm": {"easy": [0.8, 11.3]},
           "robot_arm_real": {"files": ["arm/a.tum", "arm/b.tum"], "X": arm.rig.T_a_b.tolist()},
           "tango_easy_C_M": {"files": ["t/C.tum", "t/M.tum"], "X": X_cm.tolist()},
           "tango_easy_M_N": {"files": ["t/M.tum", "t/N.tum"], "X": X_mn.tolist()},
           "tango_easy_N_C": {"files": ["t/N.tum", "t/C.tum"], "X": X_nc.tolist()},
           "prime_sense_1": {"files": ["ps/missing_a.csv", "ps/missing_b.csv"], "X": np.eye(4).tolist()}}
    (eth / "reference_extrinsics.json").write_text(json.dumps(ref))

    kin = root / "cache" / "kinhec-7"
    kin.mkdir(parents=True)
    seq = _arm(6)
    write_tum(kin / "noise-000000_robot.tum", seq.a)
    write_tum(kin / "noise-000000_camera.tum", seq.b.inverted())         # T_cam_target, as kinhec exports
    X = seq.rig.T_a_b
    xyz, q = X[:3, 3], se3.to_xyz_quat(X)[1]
    gt = {"sequence_id": "noise-000000", "configuration": "eye_in_hand", "sampling_mode": "continuous",
          "robot": "ur5e", "level": "robot=r2|camera=c1", "time_offset_s": 0.0, "scale": 1.0,
          "axis_scatter_lambda2": 0.2, **{f"X_p{k}": float(v) for k, v in zip("xyz", xyz, strict=True)},
          **{f"X_q{k}": float(v) for k, v in zip("xyzw", q, strict=True)}}
    (kin / "noise-000000_groundtruth.json").write_text(json.dumps(gt))
    (kin / "published.json").write_text(json.dumps({"X_error_deg_mm": {"noise-000000": [0.5, 5.0]}}))
    return data, root / "cache", arm.rig.T_a_b, X


def test_recordings_found_and_absent_files_named(corpus):
    data, cache, arm_truth, _ = corpus
    recs, absent, sources = real.all_recordings(data, cache)
    names = [r.name for r in recs]
    assert names == ["robot_arm_real", "tango_easy_C_M", "tango_easy_M_N", "tango_easy_N_C", "kinhec-7/noise-000000"]
    assert any("missing_a.csv" in a for a in absent)                      # named in the reference, not on disk
    assert any("prime_sense_2: not in" in a for a in absent)
    assert any(real.SMOKE in a for a in absent)
    assert any("kinhec-7: 1 sequences" in s for s in sources)
    kin = recs[-1]
    assert kin.conventions == {"time_unit": "s", "invert_b": True} and kin.published == (0.5, 5.0) and kin.arm
    np.testing.assert_allclose(recs[0].truth, arm_truth)


def test_run_measures_defaults_grid_and_park(corpus):
    data, cache, _, _ = corpus
    rec = real.all_recordings(data, cache)[0][-1]
    res = real.run(rec, quick=True, overrides=FAST)
    assert res.defaults.error is not None and res.defaults.error[0] < 0.5 and res.defaults.error[1] < 5.0
    assert res.park.error is not None and res.park.error[0] < 0.5
    assert set(res.grid) == {(s, a) for s in real.QUICK_STRATEGIES for a in (*real.QUICK_ALPHAS, real.PARK)}
    assert res.given == {**rec.conventions, **FAST}
    bare = real.run(rec, bare=True, quick=True, overrides=FAST)      # no invert_b: the camera stream is inverted
    assert bare.given == FAST
    assert bare.defaults.error is None or bare.defaults.error[0] > 5.0


def test_closure_of_a_loop():
    rng = np.random.default_rng(1)
    T = random_transform(rng, 0.5)
    assert real.closure([T, np.linalg.inv(T)]) == pytest.approx((0.0, 0.0), abs=1e-9)
    rot, trans = real.closure([T])
    assert rot == pytest.approx(np.rad2deg(se3.rotation_angle(T[:3, :3]))) and trans == pytest.approx(
        1e3 * np.linalg.norm(T[:3, 3]))


def test_main_prints_tables_and_goals(corpus, capsys):
    data, cache, _, _ = corpus
    assert real.main(["--data", str(data), "--kinhec-dir", str(cache), "--quick", "--only", "tango",
                      "--set", "max_pairs=120"]) == 0
    out = capsys.readouterr().out
    assert "== tango_easy_N_C" in out and "== robot_arm_real" not in out and "defaults÷best" in out
    assert "absent, skipped:" in out and "kinhec: " in out and "--set max_pairs=120" in out
    loop = next(line for line in out.splitlines() if "tango easy loop closure" in line)
    assert loop.rstrip().endswith("PASS")                # rigidly moved copies of one stream: the loop closes
    hard = next(line for line in out.splitlines() if "tango hard loop closure" in line)
    assert "absent" in hard and hard.rstrip().endswith("-")
    vio = next(line for line in out.splitlines() if "VIO rotation" in line)
    assert "3/3 pass" in vio or "FAIL" in vio                 # measured on the three phone pairs
    assert "wall time" in out
