"""Whole-rig calibration (handeye_cli.rig): exactness, accuracy on simulated rigs of four sensors
with different rates, noise, drift and clock offsets, loop closures, the bad-stream diagnostic,
the bootstrap and the graph synchronisation."""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from _util import pose_error, signed_rank_p
from scipy.special import chdtrc

from handeye_cli.errors import ConfigError, as_flags
from handeye_cli.geometry import se3
from handeye_cli.geometry.lie import log_errors
from handeye_cli.options import Options
from handeye_cli.rig import RigOptions, calibrate_rig
from handeye_cli.rig.graph import chains, synchronise
from handeye_cli.rig.joint import CONSISTENCY_P_VALUE
from handeye_cli.rig.simulate import SimSensor, simulate_streams, with_fault
from handeye_cli.simulation import _smooth_trajectory, random_transform
from handeye_cli.streams import PoseStream

DEG = np.deg2rad(1.0)
OFFSETS_NS = (0, 15_000_000, -40_000_000, 70_000_000)


def _mounts(seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [np.eye(4)] + [random_transform(rng, 0.3) for _ in range(3)]


def _sensors(T: list[np.ndarray], *, drift: bool = True, bad_scale: float = 1.0) -> list[SimSensor]:
    """Four sensors: 30, 20, 10 and 50 Hz; 0.2–0.5° / 2–5 mm noise; clock offsets; drifting odometry."""
    d1 = (0, 0, 0.5 * DEG / 60, 0.01 / 60, 0, 0) if drift else (0.0,) * 6
    d2 = (0, 0, 1.0 * DEG / 60, 0.02 / 60, 0.01 / 60, 0) if drift else (0.0,) * 6
    return [SimSensor("cam0", T[0], 30, 0.2 * DEG, 0.002),
            SimSensor("cam1", T[1], 20, 0.3 * DEG, 0.003, OFFSETS_NS[1]),
            SimSensor("lidar", T[2], 10, 0.1 * DEG, 0.002, OFFSETS_NS[2], drift=d1),
            SimSensor("wheels", T[3], 50, 0.5 * DEG, 0.005, OFFSETS_NS[3], drift=d2, scale=bad_scale)]


KNOWN_OFFSETS = {"cam1": OFFSETS_NS[1] / 1e9, "lidar": OFFSETS_NS[2] / 1e9, "wheels": OFFSETS_NS[3] / 1e9}


@pytest.fixture(scope="module")
def noisy_rig():
    """A 4-sensor rig with auto clock offsets: (truth, result)."""
    T = _mounts(0)
    return T, calibrate_rig(simulate_streams(_sensors(T), duration_s=40, seed=0))


def test_noise_free_rig_is_exact() -> None:
    """Common stamps, no noise: every T_ref_k and every T_j_k to 1e-9, pairwise and joint."""
    T = _mounts(1)
    t = np.arange(0, 30, 0.05)
    T_w = _smooth_trajectory(0.5 * t, "3d", np.random.default_rng(2))
    rng = np.random.default_rng(3)
    stamps = 1_700_000_000_000_000_000 + np.round(t * 1e9).astype(np.int64)
    streams = {f"s{k}": PoseStream.from_matrices(stamps, random_transform(rng, 5.0) @ T_w @ Tk)
               for k, Tk in enumerate(T)}
    res = calibrate_rig(streams, RigOptions(time_offsets={f"s{k}": 0 for k in range(1, 4)}))
    for k in range(4):
        assert np.abs(res.matrices[k] - T[k]).max() < 1e-9
    for e in res.edges:
        assert np.abs(e.matrix - se3.inverse(T[e.j]) @ T[e.k]).max() < 1e-9
    assert max(c.rotation_deg for c in res.closures) < 1e-7 and res.consistency.suspect is None


def test_noisy_rig_recovered(noisy_rig) -> None:
    T, res = noisy_rig
    assert res.names == ["cam0", "cam1", "lidar", "wheels"] and len(res.edges) == 6
    for k in range(1, 4):
        rot, trans = pose_error(res.matrices[k], T[k])
        assert rot < 0.2 and trans < 0.01, (res.names[k], rot, trans)
        assert abs(res.offsets[k].offset_ns - OFFSETS_NS[k]) < 2_000_000     # auto, per stream
    assert res.consistency.suspect is None and not res.warnings


def test_joint_loop_closure_is_identity(noisy_rig) -> None:
    _, res = noisy_rig
    assert len(res.joint_closures) == 4
    assert max(c.rotation_deg for c in res.joint_closures) < 1e-9
    assert max(c.translation_m for c in res.joint_closures) < 1e-9
    assert max(c.rotation_deg for c in res.closures) > 1e-3       # the pairwise ones it replaced do not close
    doc = res.document()
    assert len(doc["loop_closures"]["pairwise_only"]) == 4 and doc["loop_closures"]["joint_max"]["rotation_deg"] < 1e-9


def test_joint_fits_pairs_almost_as_well_as_pairwise_only(noisy_rig) -> None:
    """Each pair's residuals at the joint result stay close to its own optimum (and never below it)."""
    _, res = noisy_rig
    for pair in res.document()["pairwise"]:
        joint, own = pair["residuals"]["joint"], pair["residuals"]["pairwise_only"]
        assert joint["rotation_median_deg"] < 1.1 * own["rotation_median_deg"] + 1e-3
        assert pair["difference"]["rotation_deg"] < 0.2
    costs = res.problem.edge_costs(res.matrices)
    own_costs = np.array([e.calibration.solution.cost for e in res.edges])
    assert np.all(costs >= own_costs * (1 - 1e-9))


def _chain_errors(res, truth: list[np.ndarray], k: int) -> dict[tuple[int, ...], tuple[float, float]]:
    """Error of every simple chain of pairwise-only results from the reference (0) to sensor k."""
    rel = {(e.j, e.k): e.matrix for e in res.edges}
    return {path: pose_error(X, truth[k]) for path, X in chains(rel, len(res.names), k).items()}


DURATION_S = 20.0
GAPS = (((1.5, 6.0),), ((6.0, 10.0),), ((10.0, 14.0),), ())     # cam0, cam1, lidar lose tracking
SEEDS = 20
SCALED, DRIFTING = 2, 3                                         # the lidar's scale is wrong, the wheels drift


def _mixed_sensors(seed: int) -> list[SimSensor]:
    """Rig ``seed`` (mounts :func:`_mounts`) of :func:`_sensors` with tracking gaps GAPS, the lidar's
    translations scaled by 0.8 (a bad stream) and the wheels' odometry drifting (1°/min, 2 cm/min)."""
    sensors = [replace(s, gaps=g) for s, g in zip(_sensors(_mounts(seed), drift=False), GAPS, strict=True)]
    sensors[SCALED] = replace(sensors[SCALED], scale=0.8)
    sensors[DRIFTING] = replace(sensors[DRIFTING], drift=(0, 0, 1.0 * DEG / 60, 0.02 / 60, 0.01 / 60, 0))
    return sensors


@pytest.fixture(scope="module")
def mixed_rigs():
    """20 simulated 20-s rigs (seeds 0–19, not chosen) of four sensors at different rates and noise
    levels with clock offsets (given), each camera and the lidar losing tracking once, the lidar badly
    scaled and the wheels drifting: [(truth, result)]. One set of rigs for every statistical test of
    the rig (accuracy, naming, the noise model): the tests' time budget."""
    out = []
    for seed in range(SEEDS):
        sensors = _mixed_sensors(seed)
        res = calibrate_rig(simulate_streams(sensors, duration_s=DURATION_S, seed=seed),
                            RigOptions(time_offsets=KNOWN_OFFSETS))
        out.append(([s.T_ref_k for s in sensors], res))
    return out


def _joint_against_chains(rigs) -> dict[tuple[int, int], tuple[float, float, tuple[int, ...]]]:
    """Per (sensor, 0 rotation / 1 translation): the joint's RMS error over the rigs ÷ the best chain's
    (the chain of pairwise-only results from the reference with the smallest RMS, chosen in hindsight),
    the p-value of the paired test that the joint is worse than that chain, and the chain."""
    out = {}
    for k in range(1, 4):
        joint = np.array([pose_error(res.matrices[k], T[k]) for T, res in rigs])
        chain: dict[tuple[int, ...], list[tuple[float, float]]] = {}
        for T, res in rigs:
            for path, err in _chain_errors(res, T, k).items():
                chain.setdefault(path, []).append(err)
        for c in (0, 1):
            rms = {path: float(_rms(np.array(v)[:, c])) for path, v in chain.items()}
            best = min(rms, key=rms.__getitem__)
            d = joint[:, c] - np.array(chain[best])[:, c]
            out[(k, c)] = (float(_rms(joint[:, c])) / rms[best], signed_rank_p(d), best)
    return out


def testsigned_rank_p() -> None:
    """The exact null distribution: all 2ⁿ sign patterns of ranks 1..n equally likely."""
    assert signed_rank_p(np.array([1.0, 2.0, 3.0])) == 1 / 8                # only +++ reaches W⁺ = 6
    assert signed_rank_p(np.array([-1.0, -2.0, -3.0])) == 1.0
    assert signed_rank_p(np.array([-1.0, 2.0, 3.0])) == 2 / 8              # W⁺ = 5: {2, 3}, {1, 2, 3}
    assert signed_rank_p(np.r_[np.arange(1.0, 11.0), -np.arange(11.0, 21.0)]) > 0.95  # W⁺ = 55 of 210


@pytest.mark.statistical
def test_joint_never_loses_to_a_pairwise_chain(mixed_rigs) -> None:
    """Every sensor, rotation and translation: the joint estimate is no worse than the best chain of
    pairwise-only results (chosen in hindsight, per sensor and component) by a paired one-sided test
    over the 20 rigs: exact Wilcoxon signed-rank on the per-rig differences of the errors, p > 0.01
    (a per-rig or RMS threshold would let sampling noise decide: cam1's direct pair holds nearly all
    its information, its RMS ratios are 1.006 / 0.93 here, 0.97 / 0.98 with other gaps). Measured
    (RMS joint ÷ best chain, p): cam1 1.01 (0.66) / 0.93 (0.59); the scaled lidar 1.07 (0.34) / 1.09
    (0.035): it is named (test below) and moves nobody, and its scale error is in every chain; the
    drifting wheels 0.69 (1.0) / 0.51 (1.0).

    Why it holds: the joint estimate is the generalised least squares of the pairwise estimates, and
    every chain is a linear unbiased combination of the same estimates (Gauss–Markov, to first
    order); the drift corrections remove the drifting pairs' first-order bias and the combination
    weighs each corrected pair with that bias as a bound of what it still carries
    (:func:`handeye_cli.rig.noise.bias_bound`), so the drifting wheels do not pull cam1."""
    found = _joint_against_chains(mixed_rigs)
    for (k, c), (ratio, p, best) in found.items():
        assert p > 0.01, (k, c, ratio, p, best, found)


@pytest.mark.statistical
def test_bad_stream_named_and_the_rest_consistent(mixed_rigs) -> None:
    """The badly scaled lidar is named on at least 19 of the 20 rigs (measured: 20), each rig is called
    inconsistent, and without the lidar's pairs the rest is consistent as a χ² would be under the
    noise model: at most two of 20 below CONSISTENCY_P_VALUE, median p above 0.05 (measured: 2, 0.11;
    the drifting wheels' corrected pairs keep a little bias the χ² does not model: the bound is in
    the combination, not in the test, so that the test keeps its power)."""
    named = [res.consistency.suspect for _, res in mixed_rigs]
    assert sum(s == SCALED for s in named) >= 19, named
    assert all(res.consistency.inconsistent for _, res in mixed_rigs)
    rest = []
    for _, res in mixed_rigs:
        c = res.consistency
        rest.append(float(chdtrc(c.dof - c.reduction_dof[SCALED], c.statistic - c.reductions[SCALED])))
    assert sum(p < CONSISTENCY_P_VALUE for p in rest) <= 2, rest
    assert np.median(rest) > 0.05, rest


def _faulty(seed: int, fault: str) -> tuple[int, object]:
    """Rig ``seed`` of :func:`_sensors` (20 s, gaps GAPS, lidar and wheels drifting, clock offsets given)
    with stream 1 + seed % 3 made bad by :func:`~handeye_cli.rig.simulate.with_fault`: (the bad
    stream's index, result)."""
    sensors = [replace(s, gaps=g) for s, g in zip(_sensors(_mounts(seed), drift=True), GAPS, strict=True)]
    bad = 1 + seed % 3
    sensors, wrong = with_fault(sensors, bad, fault, np.random.default_rng(1000 + seed), slip_s=DURATION_S / 2)
    offsets = {**KNOWN_OFFSETS, sensors[bad].name: KNOWN_OFFSETS[sensors[bad].name] + wrong}
    return bad, calibrate_rig(simulate_streams(sensors, duration_s=DURATION_S, seed=seed),
                              RigOptions(time_offsets=offsets))


FAULT_SEEDS = 6


@pytest.mark.statistical
@pytest.mark.parametrize("fault", ["offset", "slip"])
def test_bad_stream_named(fault: str) -> None:
    """A fixed clock offset 30 ms wrong, a mount that slips 1° / 5 mm half-way, on 6 gappy drifting rigs,
    the bad stream cam1, lidar or wheels by turn (twice each): it is named on at least 5 for the offset
    (measured 6) and 4 for the slip, and every rig is called inconsistent (the scaled stream:
    :func:`test_bad_stream_named_and_the_rest_consistent`). The slip is named on 14 of 18 seeds (15 of 18
    before the auto pairs rejoined the gate's segments at gaps): a rate near 0.8, at which 5 of 6 holds by
    chance two times in three, 4 of 6 nine in ten."""
    runs = [_faulty(seed, fault) for seed in range(FAULT_SEEDS)]
    named = [(bad, res.consistency.suspect) for bad, res in runs]
    assert sum(b == s for b, s in named) >= FAULT_SEEDS - (1 if fault == "offset" else 2), named
    assert all(res.consistency.inconsistent for _, res in runs)


def test_bad_reference_is_named() -> None:
    """The reference itself scaled by 0.8: it is named, and since every T_ref_k rests on its pairs the
    warning says to choose another reference."""
    T = _mounts(1)
    sensors = _sensors(T, drift=True)
    sensors[0] = replace(sensors[0], scale=0.8)
    res = calibrate_rig(simulate_streams(sensors, duration_s=30, seed=1), RigOptions(time_offsets=KNOWN_OFFSETS))
    assert res.consistency.suspect == 0
    assert any("stream cam0 is inconsistent" in w and "--reference NAME" in as_flags(w) for w in res.warnings)


def test_two_streams_have_nothing_to_test() -> None:
    """One pair has no redundancy: no degrees of freedom, no p-value (None in the document, valid JSON)."""
    T = _mounts(0)
    sensors = _sensors(T, drift=False)
    res = calibrate_rig(simulate_streams(sensors[:2], duration_s=20, seed=0),
                        RigOptions(time_offsets={"cam1": KNOWN_OFFSETS["cam1"]}))
    assert res.consistency.dof == 0 and not res.consistency.inconsistent and res.consistency.suspect is None
    cons = json.loads(json.dumps(res.document(), allow_nan=False))["consistency"]
    assert cons["p_value"] is None and cons["streams"]["cam1"] == {"reduction": None, "dof": 0, "p_value": None}


def test_three_streams_cannot_name_which() -> None:
    """A triangle of pairwise estimates can say that they disagree but not which stream spoils it (each
    stream's removal leaves one pair, consistent by itself): no stream is named, the warning says so."""
    T = _mounts(0)
    sensors = _sensors(T, drift=False, bad_scale=0.8)
    res = calibrate_rig(simulate_streams([sensors[0], sensors[1], sensors[3]], duration_s=30, seed=0),
                        RigOptions(time_offsets={"cam1": KNOWN_OFFSETS["cam1"], "wheels": KNOWN_OFFSETS["wheels"]}))
    c = res.consistency
    assert c.inconsistent and c.suspect is None and res.problem.excluded is None
    assert c.dof == 6 and c.reduction_dof == (6, 6, 6)
    assert any("no single stream explains it" in w for w in res.warnings)


def test_drift_bias_is_removed() -> None:
    """Little noise (0.05°, 0.5 mm), the wheels' odometry drifting 3°/min and 6 cm/min: every pair with the
    wheels shows a significant relative drift, its corrected estimate is closer to the truth in translation
    than its pairwise-only one, and over the three the corrected ones are at least twice as close (measured:
    0.68 against 1.97 mm in all; each pair 1.45–10 times closer: the pairwise estimates' drift-bounded pair
    choice already keeps much of the bias out; what is left is the noise and the drift's second order: 1.5°
    over the log); the pair of the two cameras (no relative drift) is left as it is. The result document
    carries each pair's test."""
    T = _mounts(4)
    sensors = [replace(s, sigma_r=0.05 * DEG, sigma_t=0.0005) for s in _sensors(T, drift=False)]
    sensors[3] = replace(sensors[3], drift=(0, 0, 3 * DEG / 60, 0.06 / 60, 0.03 / 60, 0))
    res = calibrate_rig(simulate_streams(sensors, duration_s=30, seed=4), RigOptions(time_offsets=KNOWN_OFFSETS))
    corrected, pairwise = [], []
    for e, (edge, corr) in enumerate(zip(res.edges, res.corrections, strict=True)):
        truth = se3.inverse(T[edge.j]) @ T[edge.k]
        if edge.k == 3:
            assert corr.applied and corr.p_value < 1e-6
            corrected.append(pose_error(res.problem.estimates[e], truth)[1])
            pairwise.append(pose_error(edge.matrix, truth)[1])
            assert corrected[-1] < pairwise[-1]
        if (edge.j, edge.k) == (0, 1):
            assert not corr.applied and np.array_equal(res.problem.estimates[e], edge.matrix)
    assert len(corrected) == 3 and 2 * sum(corrected) < sum(pairwise)
    drift = res.document()["pairwise"][2]["drift"]          # cam0-wheels: the bias removed is its error
    assert drift["corrected"] and drift["dof"] == 6 and drift["translation_m_per_s"] > 0.0005
    error = pose_error(res.edges[2].matrix, T[3])[1]
    assert 0.7 * error < drift["bias"]["translation_m"] < 1.3 * error


@pytest.mark.statistical
def test_noise_model_is_calibrated(mixed_rigs) -> None:
    """The noise model's predictions hold on the same rigs, where the bad lidar does not enter: each
    pairwise estimate of the two cameras is a χ² of 6 degrees of freedom against the truth under its
    predicted covariance (mean over 20 pairs near 6; measured 5.99); those of the drifting wheels'
    pairs, corrected, keep some bias, which the bound covers in part (mean χ² measured 69 and 43 under the
    noise alone, 14 and 13 with the bound), the predicted RMS errors of
    the joint cam1 and wheels are within 0.75–1.5 of the measured ones (measured ÷ predicted: cam1
    1.31 / 0.93, wheels 1.40 / 1.39; on clean gappy rigs it was within 0.75–1.3), and each stream's
    estimated pose noise (three-cornered hat over its pairs) is the simulated one: 3-D RMS angle σr,
    3-D RMS translation √3 σt."""
    chi2: dict[tuple[bool, bool], list[float]] = {}      # (drifting pair, with the bound) → χ² of its pairs
    predicted, measured, noise = [], [], []
    for T, res in mixed_rigs:
        for e, edge in enumerate(res.edges):
            if SCALED in (edge.j, edge.k):
                continue
            d = log_errors(edge.matrix @ se3.inverse(se3.inverse(T[edge.j]) @ T[edge.k]))
            for bound, C in ((False, res.problem.covariance), (True, res.problem.covariance + res.problem.bias)):
                block = C[6 * e:6 * e + 6, 6 * e:6 * e + 6]
                chi2.setdefault((DRIFTING in (edge.j, edge.k), bound), []).append(d @ np.linalg.solve(block, d))
        predicted.append([[np.trace(res.covariances[k][:3, :3]), np.trace(res.covariances[k][3:, 3:])] for k in (1, 3)])
        measured.append([np.square(log_errors(se3.inverse(T[k]) @ res.matrices[k])).reshape(2, 3).sum(axis=1)
                         for k in (1, 3)])
        noise.append([res.noise.std(k) for k in (0, 1, 3)])
    mean = {key: float(np.mean(v)) for key, v in chi2.items()}
    assert len(chi2[(False, False)]) == SEEDS and 4.5 < mean[(False, False)] < 7.5, mean
    assert mean[(True, True)] < 20 and mean[(True, False)] > 2 * mean[(True, True)], mean
    ratio = np.sqrt(np.mean(measured, axis=0) / np.mean(predicted, axis=0))       # (sensor, rot/trans)
    assert np.all((ratio > 0.75) & (ratio < 1.5)), ratio
    sims = _sensors(_mounts(0), drift=False)
    truth = np.array([[sims[k].sigma_r, np.sqrt(3) * sims[k].sigma_t] for k in (0, 1, 3)])
    assert np.allclose(np.mean(noise, axis=0) / truth, 1.0, atol=0.1), np.mean(noise, axis=0) / truth


def _rms(values: np.ndarray) -> np.ndarray:
    return np.asarray(np.sqrt(np.mean(np.square(values), axis=0)))

def test_bad_stream_is_named() -> None:
    """A stream whose translations are 20 % short (e.g. monocular VO scale) spoils every loop it is in:
    it is named by the χ² test (the result carries the statistic and p-values), the warning says
    what to check, it informs no other sensor, the others are recovered as well as without it, its
    own rotation too; the noise model charges it with the most translation noise, but within 3 times
    its simulated noise (the hat's short motions: from the solved pairs' own, it was ~40 times in
    variance, which hid the bias from the test)."""
    T = _mounts(0)
    res = calibrate_rig(simulate_streams(_sensors(T, bad_scale=0.8), duration_s=40, seed=0),
                        RigOptions(time_offsets=KNOWN_OFFSETS))
    assert res.names[res.consistency.suspect] == "wheels" and res.problem.excluded == 3
    warning = next(w for w in res.warnings if "stream wheels is inconsistent" in w)
    assert "--time-offset wheels=auto" in as_flags(warning) and "scale" in warning and "mount" in warning
    doc = res.document()
    cons = doc["consistency"]
    assert cons["suspect"] == "wheels" and doc["noise_model"]["excluded"] == "wheels"
    assert cons["dof"] == 18 and cons["p_value"] < cons["threshold"] and cons["statistic"] > 100
    assert cons["streams"]["wheels"]["dof"] == 12 and cons["streams"]["wheels"]["p_value"] < cons["threshold"]
    assert max(cons["streams"].values(), key=lambda v: v["reduction"]) is cons["streams"]["wheels"]
    for k in (1, 2):
        rot, trans = pose_error(res.matrices[k], T[k])
        assert rot < 0.05 and trans < 0.002, (res.names[k], rot, trans)
    assert pose_error(res.matrices[3], T[3])[0] < 0.1
    assert max(max(c.rotation_deg, c.translation_m) for c in res.joint_closures) < 1e-9    # still consistent
    noise = {s["name"]: s["noise"]["translation_m"] for s in doc["streams"]}
    assert max(noise, key=noise.get) == "wheels" and noise["wheels"] < 3 * np.sqrt(3) * 0.005


def test_bootstrap_uncertainty(noisy_rig) -> None:
    T, res = noisy_rig
    streams = simulate_streams(_sensors(T), duration_s=40, seed=0)
    boot = calibrate_rig(streams, RigOptions(time_offsets={n: o.offset_ns / 1e9 for n, o in
                                                           zip(res.names[1:], res.offsets[1:], strict=True)},
                                             options=Options.from_flat(bootstrap=40)))
    u = boot.uncertainty
    assert u is not None and u.replicates == 40
    assert np.all(u.rotation_std_deg[0] == 0) and np.all(u.translation_std_m[0] == 0)   # the reference
    for k in range(1, 4):
        assert np.all(u.rotation_std_deg[k] > 0) and np.all(u.translation_std_m[k] > 0)
        rot, trans = pose_error(boot.matrices[k], T[k])
        assert rot < 6 * np.linalg.norm(u.rotation_std_deg[k]) + 0.02
        lo, hi = u.rotation_interval_deg[k]                       # 95 % bounds of Log(R* R̂ᵀ), around 0
        assert np.all(lo < 0) and np.all(hi > 0) and np.all(hi - lo < 6 * u.rotation_std_deg[k])
        lo, hi = u.translation_interval_m[k]                      # 95 % bounds of the translation itself
        assert np.all(lo < boot.matrices[k][:3, 3]) and np.all(boot.matrices[k][:3, 3] < hi)
    sensors = boot.document()["uncertainty"]["sensors"]
    assert set(sensors) == {"cam1", "lidar", "wheels"}
    assert np.array(sensors["lidar"]["translation_interval_m"]).shape == (2, 3)


def test_inversion_flag_per_stream(noisy_rig) -> None:
    T, res = noisy_rig
    streams = simulate_streams(_sensors(T), duration_s=40, seed=0)
    streams["lidar"] = streams["lidar"].inverted()          # recorded as T_sensor_world
    fixed = calibrate_rig(streams, RigOptions(invert=("lidar",), time_offsets=KNOWN_OFFSETS))
    assert fixed.inverted == [False, False, True, False]
    assert pose_error(fixed.matrices[2], T[2])[0] < 0.2


def test_inversion_checked_against_the_reference_and_where_it_is_not_cleared(monkeypatch) -> None:
    """A stream's inversion is checked on its pair with the reference; its other pairs run the check only when
    that pair did not clear it: an inverted lidar, not flagged, is refused as inverted on every one of its pairs
    (without the check, lidar-wheels failed the fit test by 17.5× against its limit of 15×: too near to rest on),
    while of a clean rig's six pairs only the three with the reference run it."""
    from handeye_cli.calibration import run
    from handeye_cli.rig.pairwise import clock_offsets, solve_edges

    checked: list[int] = []
    inversion = run.inversion
    monkeypatch.setattr(run, "inversion",
                        lambda paired, *a: checked.append(len(paired.synced)) or inversion(paired, *a))
    streams = simulate_streams(_sensors(_mounts(0)), duration_s=40, seed=0)
    names, given = list(streams), {k: KNOWN_OFFSETS[n] for k, n in enumerate(streams) if n in KNOWN_OFFSETS}
    offsets = clock_offsets(list(streams.values()), 0, given, Options())
    edges, _ = solve_edges(list(streams.values()), names, offsets, Options(), reference=0)
    assert len(edges) == 6 and len(checked) == 3
    streams["lidar"] = streams["lidar"].inverted()            # recorded as T_sensor_world, not said
    edges, warnings = solve_edges(list(streams.values()), names, offsets, Options(), reference=0)
    assert [(names[e.j], names[e.k]) for e in edges] == [("cam0", "cam1"), ("cam0", "wheels"), ("cam1", "wheels")]
    refused = [w for w in warnings if "left out" in w]
    assert len(refused) == 3 and all("lidar" in w and "almost certainly inverted" in w for w in refused)


def test_reference_and_option_errors(noisy_rig) -> None:
    T, _ = noisy_rig
    streams = simulate_streams(_sensors(T), duration_s=10, seed=0)
    with pytest.raises(ConfigError, match="unknown reference"):
        calibrate_rig(streams, RigOptions(reference="radar"))
    with pytest.raises(ConfigError, match="unknown stream"):
        calibrate_rig(streams, RigOptions(invert=("radar",)))
    with pytest.raises(ConfigError, match="stream"):
        calibrate_rig({"cam0": streams["cam0"]})


def test_other_reference_gives_the_same_rig(noisy_rig) -> None:
    T, res = noisy_rig
    streams = simulate_streams(_sensors(T), duration_s=40, seed=0)
    offsets = {n: o.offset_ns / 1e9 for n, o in zip(res.names, res.offsets, strict=True)}
    other = calibrate_rig(streams, RigOptions(reference="lidar", time_offsets={
        n: v - offsets["lidar"] for n, v in offsets.items() if n != "lidar"}))
    assert np.abs(other.matrices[2] - np.eye(4)).max() < 1e-12
    rot, trans = pose_error(other.T("cam0", "wheels"), res.T("cam0", "wheels"))
    assert rot < 0.01 and trans < 5e-4


def test_synchronise_recovers_consistent_graph() -> None:
    rng = np.random.default_rng(9)
    T = np.stack([np.eye(4)] + [random_transform(rng, 1.0) for _ in range(4)])
    pairs = [(0, 1), (1, 2), (2, 3), (3, 4), (0, 4), (1, 3)]
    X = np.stack([se3.inverse(T[j]) @ T[k] for j, k in pairs])
    out = synchronise(5, pairs, X, np.array([1.0, 0.5, 2.0, 1.0, 0.1, 3.0]), reference=0)
    assert np.abs(out - T).max() < 1e-9


def test_an_insignificant_clock_offset_estimate_is_not_applied_and_the_result_says_so() -> None:
    """Issue 37: ``clock_offsets`` applied every estimate; ``calibrate`` applies one only when it is significant
    against its σ and unambiguous (``TimeOffset.applicable``) and the fit confirms it (``confirmed_by``). cam1
    shares the reference's clock here: its estimate (≈ 1.7 ± 0.7 ms) is noise and is not applied (offset 0, as
    calibrate's would be), the offsets that are there (−40 ms, 70 ms) are, confirmed by the fit; the result
    records, for each estimate, whether it was applied."""
    T = _mounts(0)
    sensors = _sensors(T)
    sensors[1] = replace(sensors[1], time_offset_ns=0)
    res = calibrate_rig(simulate_streams(sensors, duration_s=40, seed=0))
    cam1 = res.offsets[1]
    assert cam1.estimated_ns is not None and cam1.estimated_ns != 0 and not cam1.applied and cam1.offset_ns == 0
    for k in (2, 3):
        assert res.offsets[k].applied and res.offsets[k].offset_ns == res.offsets[k].estimated_ns
        assert abs(res.offsets[k].offset_ns - OFFSETS_NS[k]) < 2_000_000
    streams = {s["name"]: s["time_offset"] for s in res.document()["streams"]}
    assert streams["cam1"]["applied"] is False and streams["cam1"]["seconds"] == 0.0
    assert streams["cam1"]["estimated_seconds"] == cam1.estimated_ns / 1e9
    assert streams["lidar"]["applied"] is True and "applied" not in streams["cam0"]          # the reference's
    assert streams["lidar"]["confirmed_by"] == "fit" and "confirmed_by" not in streams["cam1"]   # as calibrate's
    for k in (1, 2, 3):
        rot, trans = pose_error(res.matrices[k], T[k])
        assert rot < 0.2 and trans < 0.01, (res.names[k], rot, trans)
