"""The defaults on real and third-party-generated recordings (issue 19), and the issue's goals.

Recordings (streams a, b; the extrinsic is X = T_a_b, the motions satisfy A X = X B):

* the ETH ASL corpus (``DATA/ethz_hand_eye_2017``, see its README): ``robot_arm_real``,
  ``prime_sense_1/2``, ``falcon_5``, the Tango phone triplets easy/hard C→M, M→N, N→C. Errors are
  against ``reference_extrinsics.json``: estimates good to about 2° / 3 cm, made with Park–Martin +
  LM on keyframe pairs, so they favour a rotation-first solver. The reference-free checks are the
  phones' loop closure ``X_CM · X_MN · X_NC = I`` and the agreement of the two PrimeSense recordings;
* kinhec sequences (synthetic, third-party generator, exact truth): ``DATA/kinhec_smoke_v1.1.0``
  (the published solver's error from that folder's README) and every ``KINHEC_DIR/kinhec-SEED/``
  written by ``benchmarks/make_kinhec.sh`` (the published solver's error computed there by kinhec's
  own Park–Martin + LM and protocol).

Per recording, in one run, through the Python API in-process (each file read once):

* **defaults**: ``handeye_cli.calibrate_files(a, b, **conventions)`` — the conventions are only the
  flags a user must give today (table :data:`CONVENTIONS`); ``--bare`` gives none of them;
* **park, same pairs**: the rotation-first solver (``method="park"``) on the defaults' pairs and weights;
* **dqopt unrefined**: dqopt on the defaults' pairs, α and weights (the paper's estimate, whatever refinement the
  defaults add); **park + LM**: Park–Martin then Levenberg–Marquardt as kinhec's ``refine_lm`` (:func:`park_lm`)
  on the pairs the defaults used; **OpenCV**: ``cv2.calibrateHandEye``'s five methods on those pairs' samples
  (:func:`opencv`; the conventions checked on noise-free captures at start, :func:`check_same_pairs`);
* **the grid**: per pair strategy one ``calibrate_files(..., pairs=S)`` (α auto, dqopt; a time offset
  the conventions estimate is fixed at the defaults' estimate, so ``pairs=auto`` is the defaults'
  own call), then on its pairs and weights dqopt at each fixed α and park
  (``calibrate_files(..., pairs=S, alpha=α)`` solves exactly these); a station capture has one row;
* the best fixed setting in hindsight (rotation and translation separately) and defaults ÷ best;
* the defaults with ``time_offset="auto"`` where the conventions do not already estimate it
  (not with ``--quick``, whose grid is smaller too).

Then the summary of issue 19's goals with PASS/FAIL, issue 35's per kinhec track (:func:`issue35`), and the wall time.

    python benchmarks/real.py [--bare] [--quick] [--data DIR] [--kinhec-dir DIR] [--only TEXT]
                              [--set NAME=VALUE ...]      (an option for every call: a candidate default)

Missing files are listed and skipped. Generate more kinhec sequences with
``benchmarks/make_kinhec.sh KINHEC_EXECUTABLE [SEED ...]`` (into ``~/.cache/handeye-bench``).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

import handeye_cli
from handeye_cli.analysis import extrinsic_error
from handeye_cli.geometry import se3
from handeye_cli.io import read_stream
from handeye_cli.solvers import solve
from handeye_cli.streams import PoseStream

FloatArray = np.ndarray
ROOT = Path(__file__).resolve().parents[1]
ETH = "ethz_hand_eye_2017"
SMOKE = "kinhec_smoke_v1.1.0"

# --- conventions: the flags each recording needs today, and which the tool should find itself ---------------
# The project is about to choose these from the fit; `--bare` passes none of them, to show what the defaults
# alone do. Every entry below is one the tool SHOULD find by itself (the right column says from what).
_TANGO = {"time_offset": "auto", "max_time_offset": "off"}       # clocks minutes apart (76 min on the hard set)
CONVENTIONS: dict[str, tuple[dict[str, Any], str]] = {
    # corpus recording: (keywords, what the tool should find by itself)
    "robot_arm_real": ({}, "nothing needed"),
    "prime_sense_1": ({}, "nothing needed (a ~30 ms offset the reference estimated: see 'offset auto')"),
    "prime_sense_2": ({}, "nothing needed (a ~15 ms offset: see 'offset auto')"),
    "falcon_5": ({"time_offset": "auto"}, "the clock offset (0.46 s): motion-correlated, estimable"),
    "tango_easy_C_M": (_TANGO, "the clock offset (minutes): the streams do not overlap at offset 0"),
    "tango_easy_M_N": (_TANGO, "the clock offset (minutes)"),
    "tango_easy_N_C": (_TANGO, "the clock offset (minutes)"),
    "tango_hard_C_M": (_TANGO, "the clock offset (minutes)"),
    "tango_hard_M_N": (_TANGO, "the clock offset (74 min)"),
    "tango_hard_N_C": (_TANGO, "the clock offset (76 min)"),
    # kinhec sequences: the flags follow from each sequence's ground truth (kinhec_conventions)
    "kinhec: every sequence": ({"time_unit": "s"}, "the unit: TUM stamps are seconds by the format; station "
                                                    "stamps seconds apart are otherwise read as ms"),
    "kinhec: eye_in_hand": ({"invert_b": True}, "the inversion: b records T_cam_target (the fit is 30x better)"),
    "kinhec: clock offset": ({"time_offset": "auto"}, "the clock offset (0.05 s)"),
    "kinhec: monocular": ({"scale": "auto"}, "b's scale (2.0): translations disagree by a constant factor"),
}

# The published solver's X error [deg, mm] on the corpus's kinhec sequences (DATA/kinhec_smoke_v1.1.0/README.md).
PUBLISHED_SMOKE: dict[str, tuple[float, float]] = {
    "noise-000000": (0.010, 0.09), "noise-000001": (0.19, 5.1), "noise-000002": (0.014, 0.37),
    "noise-000004": (0.011, 0.11), "noise-000006": (0.018, 0.29), "motion-000000": (0.97, 1768.0),
    "motion-000002": (0.10, 81.0), "temporal-000000": (0.06, 1.3), "outliers-000002": (9.1, 152.0),
    "monocular-000000": (0.03, 0.27), "robot_error-000001": (0.15, 0.81)}

# The issue's goals. Loop closures [deg, mm]: the published solver's figure and the goal (half of it).
LOOP_PUBLISHED = {"easy": (0.81, 11.3), "hard": (0.25, 22.7)}
LOOP_GOAL = {"easy": (0.40, 5.7), "hard": (0.12, 11.3)}
PRIMESENSE_GOAL = (1.2, 10.6)            # the published solver's agreement of the two recordings, the goal too
KINHEC_RATIO_GOAL = 1.5                  # defaults' error ≤ this × the published solver's, rotation and translation
VIO_RATIO_GOAL = 1.2                     # defaults' rotation ≤ this × park's on the same pairs

# The grid of fixed settings: pair strategy × α × method (park: α has no role in it).
STRATEGIES = ("auto", "all", "consecutive", "stride:10", "keyframes")
ALPHAS = ("auto", "0.3", "1", "3")
QUICK_STRATEGIES = ("auto", "all", "keyframes")
QUICK_ALPHAS = ("auto", "1")
PARK = "park"
STATIONS = "stations"        # the grid's one row for a station capture: its stations are paired all with all


# --- what is measured -----------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Recording:
    """Two pose files and the truth ``T_a_b`` (a reference estimate, or exact for kinhec)."""

    name: str
    kind: str                               # arm | mocap | vio | odometry | kinhec
    a: Path
    b: Path
    truth: FloatArray
    exact: bool
    conventions: Mapping[str, Any]
    published: tuple[float, float] | None = None      # the published solver's error [deg, mm]
    arm: bool = True                                   # kinhec: a robot arm (not the free-flying 'free6d')
    degenerate: bool = False                           # kinhec: parallel rotation axes (a direction unobservable)
    note: str = ""
    track: str = ""                                     # kinhec: the ground truth's track (noise, motion, …)


@dataclass(frozen=True, eq=False)
class Fit:
    """One estimate: ``T_a_b`` and its error against the truth [deg, mm], or why it failed."""

    matrix: FloatArray | None = None
    error: tuple[float, float] | None = None
    failure: str = ""
    alpha: float | None = None
    pairs: int = 0
    offset_s: float | None = None
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class Result:
    recording: Recording
    defaults: Fit
    park: Fit                                            # park on the defaults' pairs and weights
    grid: dict[tuple[str, str], Fit] = field(default_factory=dict)   # (strategy, α label or 'park') → fit
    offset_auto: Fit | None = None
    seconds: float = 0.0
    given: Mapping[str, Any] = field(default_factory=dict)          # the keywords every call got
    dqopt: Fit = field(default_factory=Fit)              # dqopt on the defaults' pairs, α and weights: no refinement
    park_lm: Fit = field(default_factory=Fit)            # Park + LM (kinhec's refine_lm) on the defaults' pairs
    opencv: dict[str, Fit] = field(default_factory=dict)  # cv2.calibrateHandEye on the defaults' pairs' samples


def _error(T: FloatArray, truth: FloatArray) -> tuple[float, float]:
    rot, trans = extrinsic_error(T, truth)
    return rot, 1e3 * trans


def _failure(e: Exception, ours: bool = True) -> Fit:
    """A failure as an outcome; an exception of ours that is not a HandEyeError is a bug (``ours``: raised by
    handeye_cli, not by scipy or OpenCV)."""
    ok = isinstance(e, handeye_cli.HandEyeError) or not ours
    kind = type(e).__name__ if ok else f"BUG {type(e).__name__}"
    return Fit(failure=f"{kind}: {(str(e).splitlines() or [''])[0]}")


def _fit(cal: handeye_cli.Calibration, truth: FloatArray) -> Fit:
    return Fit(cal.matrix, _error(cal.matrix, truth), alpha=cal.solution.alpha, pairs=len(cal.pairs),
               offset_s=cal.diagnostics["time_offset"]["seconds"], warnings=tuple(cal.warnings))


def _solve(cal: handeye_cli.Calibration, truth: FloatArray, method: str, alpha: float) -> Fit:
    try:
        T = solve(cal.pairs.A, cal.pairs.B, method=method, alpha=alpha, weights=cal.weights).matrix
    except Exception as e:                        # a failure is an outcome, printed
        return _failure(e)
    return Fit(T, _error(T, truth), alpha=alpha, pairs=len(cal.pairs))


def _calibrate(a: PoseStream, b: PoseStream, truth: FloatArray, **keywords: Any) -> tuple[Fit, Any]:
    try:
        cal = handeye_cli.calibrate_files(a, b, **keywords)
    except Exception as e:                        # a failure is an outcome, printed
        return _failure(e), None
    return _fit(cal, truth), cal


# --- the same pairs, other estimators (issue 35) ------------------------------------------------------------
OPENCV_METHODS = ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS")
OPENCV_MAX_SAMPLES = 150     # OpenCV pairs every sample with every later one: at most this many, spread in time


def _hat(w: FloatArray) -> FloatArray:
    """(N, 3, 3) skew matrices of (N, 3) vectors."""
    W = np.zeros((len(w), 3, 3))
    W[:, 0, 1], W[:, 0, 2], W[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    return W - np.swapaxes(W, 1, 2)


def _log_se3(E: FloatArray) -> FloatArray:
    """(N, 6) ``[ω, J_l(ω)⁻¹ t]`` of transforms E (N, 4, 4): SE(3)'s logarithm as kinhec.se3.log_se3 forms it."""
    w = Rotation.from_matrix(E[:, :3, :3]).as_rotvec()
    th = np.linalg.norm(w, axis=1)
    safe = np.where(th < 1e-8, 1.0, th)
    c = np.where(th < 1e-8, 1.0 / 12.0, (1.0 - 0.5 * safe / np.tan(0.5 * safe)) / safe**2)
    W = _hat(w)
    J_inv = np.eye(3) - 0.5 * W + c[:, None, None] * (W @ W)
    return np.concatenate((w, np.einsum("nij,nj->ni", J_inv, E[:, :3, 3])), axis=1)


def _exp_se3(xi: FloatArray) -> FloatArray:
    """The 4x4 ``exp([ω, v])``: rotation exp(ω), translation J_l(ω) v (kinhec.se3.exp_se3)."""
    w, v = xi[:3], xi[3:]
    th, W = float(np.linalg.norm(w)), _hat(w[None])[0]
    a, b = (0.5, 1.0 / 6.0) if th < 1e-8 else ((1 - math.cos(th)) / th**2, (th - math.sin(th)) / th**3)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(w).as_matrix()
    T[:3, 3] = (np.eye(3) + a * W + b * (W @ W)) @ v
    return T


def park_lm(A: FloatArray, B: FloatArray) -> FloatArray:
    """Park–Martin then Levenberg–Marquardt, as kinhec 1.1.0's ``solvers.park_martin`` + ``solvers.refine_lm``
    (kinhec/solvers/axxb.py). Matched: park unweighted (every pair alike); the residual ``log_se3(inv(X B_k) A_k X)``
    per pair, its six components weighted 1 (rotation vector [rad], ``J_l(ω)⁻¹ t`` [m]: rot_weight = trans_weight
    = 1, linear loss); X = X0 exp(ξ) from ξ = 0. Not matched: kinhec runs least_squares' "trf" with max_nfev=200,
    this its "lm" (the issue's wording; the same unconstrained sum of squares, so the same minimum)."""
    X0 = solve(A, B, method=PARK).matrix

    def residuals(xi: FloatArray) -> FloatArray:
        X = X0 @ _exp_se3(xi)
        return _log_se3(se3.inverse(X @ B) @ (A @ X)).ravel()

    return X0 @ _exp_se3(least_squares(residuals, np.zeros(6), method="lm").x)


def _used(cal: handeye_cli.Calibration) -> np.ndarray:
    """Which of the defaults' pairs they solved with: weight > 0 (a robust run's inliers), else all."""
    return np.ones(len(cal.pairs), dtype=bool) if cal.weights is None else np.asarray(cal.weights) > 0


def pair_samples(cal: handeye_cli.Calibration, limit: int = OPENCV_MAX_SAMPLES) -> tuple[FloatArray, FloatArray]:
    """The absolute poses (T_wa_a, T_wb_b) of the synced samples the defaults' used pairs join (inverted, offset
    and scaled as the pairs are), at most ``limit`` of them spread evenly in time."""
    used = _used(cal)
    rows = np.unique(np.r_[cal.pairs.i[used], cal.pairs.j[used]])
    rows = rows[np.unique(np.linspace(0, len(rows) - 1, min(limit, len(rows))).round().astype(int))]
    used = cal.synced.select(rows)
    return used.T_a, used.T_b


def opencv(T_a: FloatArray, T_b: FloatArray, method: str) -> FloatArray:
    """``cv2.calibrateHandEye``'s X = T_a_b from absolute poses: a as gripper→base (``T_wa_a``), b as target→cam
    (``T_wb_b⁻¹``); its cam→gripper is then T_a_b."""
    import cv2

    T_tc = se3.inverse(T_b)
    R, t = cv2.calibrateHandEye(list(T_a[:, :3, :3]), list(T_a[:, :3, 3]), list(T_tc[:, :3, :3]),
                                list(T_tc[:, :3, 3]), method=getattr(cv2, f"CALIB_HAND_EYE_{method}"))
    X = np.eye(4)
    X[:3, :3], X[:3, 3] = R, np.ravel(t)
    if not np.all(np.isfinite(X)):
        raise ValueError("non-finite result")
    return X


def _attempt(make: Any, truth: FloatArray, pairs: int, ours: bool = True) -> Fit:
    """``make()``'s T_a_b as a fit, or its failure (an outcome, printed)."""
    try:
        T = make()
    except Exception as e:
        return _failure(e, ours)
    return Fit(T, _error(T, truth), pairs=pairs)


def same_pairs(cal: handeye_cli.Calibration | None, truth: FloatArray) -> tuple[Fit, Fit, dict[str, Fit]]:
    """On the defaults' pairs: dqopt unrefined (the defaults' α and weights); Park + LM on the pairs they used
    (weight > 0: a robust run's inliers), each alike; OpenCV's five methods on those pairs' samples."""
    if cal is None:
        failed = Fit(failure="defaults failed")
        return failed, failed, {m: failed for m in OPENCV_METHODS}
    A, B, n = cal.pairs.A, cal.pairs.B, len(cal.pairs)
    dq = _attempt(lambda: solve(A, B, "dqopt", cal.solution.alpha, weights=cal.weights).matrix, truth, n)
    used = _used(cal)
    plm = _attempt(lambda: park_lm(A[used], B[used]), truth, int(used.sum()), ours=False)
    T_a, T_b = pair_samples(cal)
    cv = {m: _attempt(lambda m=m: opencv(T_a, T_b, m), truth, len(T_a), ours=False) for m in OPENCV_METHODS}
    return dq, plm, cv


def check_same_pairs(seed: int = 0) -> float:
    """The largest error [deg or mm] of :func:`same_pairs`' estimators (dqopt, Park + LM, OpenCV's five) on
    noise-free simulated captures, eye-in-hand and eye-to-hand, through the defaults and :func:`pair_samples`:
    ≈ 0 (1e-12) when the conventions are right. Raises AssertionError when one fails or exceeds 1e-6."""
    from handeye_cli.simulation.arm import simulate_arm

    worst = 0.0
    for setup in ("eye-in-hand", "eye-to-hand"):
        cap = simulate_arm(12, setup=setup, sparse=True, camera_sigma_r=0.0, camera_sigma_t=0.0, joint_noise=0.0,
                           dh_error=0.0, seed=seed)
        cal = handeye_cli.calibrate_files(cap.robot, cap.camera, invert_a=cap.invert_a, invert_b=cap.invert_b)
        dq, plm, cv = same_pairs(cal, cap.truth)
        for name, f in [("dqopt", dq), ("park + LM", plm), *cv.items()]:
            if f.error is None or max(f.error) > 1e-6:
                raise AssertionError(f"{name} on a noise-free {setup} capture: {f.failure or fmt(f.error)}")
            worst = max(worst, *f.error)
    return worst


def run(rec: Recording, *, bare: bool = False, quick: bool = False,
        overrides: Mapping[str, Any] | None = None) -> Result:
    """Defaults, park on the same pairs, the grid and the offset diagnostic of one recording;
    ``overrides`` (flat option names) go to every call, e.g. a candidate default (``--set``)."""
    t0 = time.perf_counter()
    conv = {**({} if bare else rec.conventions), **(overrides or {})}
    unit = conv.pop("time_unit", "auto")          # a reader's option: applied here, refused for in-memory streams
    a, b = (read_stream(p, time_unit=unit) for p in (rec.a, rec.b))     # raw; the inversion is a convention
    defaults, cal = _calibrate(a, b, rec.truth, **conv)
    park = _solve(cal, rec.truth, PARK, 1.0) if cal is not None else Fit(failure="defaults failed")
    dqopt, plm, cv = same_pairs(cal, rec.truth)
    fixed = dict(conv)
    if conv.get("time_offset") == "auto" and defaults.offset_s is not None:
        fixed.update(time_offset=defaults.offset_s, max_time_offset="off")
    grid: dict[tuple[str, str], Fit] = {}
    stations = cal is not None and "stations" in cal.diagnostics        # stations: all with all, whatever pairs
    for strategy in (STATIONS,) if stations else QUICK_STRATEGIES if quick else STRATEGIES:
        if strategy in ("auto", STATIONS) and conv.get("pairs", "auto") == "auto":
            fit, cal_s = defaults, cal                    # the same call: the offset fixed at its estimate
        else:
            fit, cal_s = _calibrate(a, b, rec.truth, **{**fixed, "pairs": strategy})
        for label in QUICK_ALPHAS if quick else ALPHAS:
            grid[strategy, label] = fit if label == "auto" or cal_s is None else _solve(
                cal_s, rec.truth, "dqopt", float(label))
        grid[strategy, PARK] = fit if cal_s is None else _solve(cal_s, rec.truth, PARK, 1.0)
    offset_auto = None if quick or conv.get("time_offset") == "auto" else _calibrate(
        a, b, rec.truth, **{**conv, "time_offset": "auto"})[0]
    given = {**({"time_unit": unit} if unit != "auto" else {}), **conv}
    return Result(rec, defaults, park, grid, offset_auto, time.perf_counter() - t0, given, dqopt, plm, cv)


# --- which recordings exist ---------------------------------------------------------------------------------
def corpus_recordings(data: Path) -> tuple[list[Recording], list[str]]:
    """The ETH recordings listed in ``reference_extrinsics.json`` (and in :data:`CONVENTIONS`), and
    the files that are absent."""
    ref_path = data / ETH / "reference_extrinsics.json"
    if not ref_path.is_file():
        return [], [f"{ref_path} (every ETH recording skipped)"]
    ref = json.loads(ref_path.read_text())
    out, absent = [], []
    for name, (conventions, _) in CONVENTIONS.items():
        if name.startswith("kinhec"):
            continue
        if name not in ref:
            absent.append(f"{name}: not in {ref_path}")
            continue
        a, b = (data / ETH / f for f in ref[name]["files"])
        missing = [str(p) for p in (a, b) if not p.is_file()]
        if missing:
            absent += missing
            continue
        kind = ("arm" if name.startswith("robot") else "mocap" if name.startswith("prime")
                else "odometry" if name.startswith("falcon") else "vio")
        out.append(Recording(name, kind, a, b, np.asarray(ref[name]["X"], dtype=float), False, conventions))
    return out, absent


def kinhec_conventions(truth: Mapping[str, Any]) -> dict[str, Any]:
    """The flags a kinhec sequence needs (from its ground truth), per :data:`CONVENTIONS`."""
    out = dict(CONVENTIONS["kinhec: every sequence"][0])
    if truth["configuration"] == "eye_in_hand":
        out.update(CONVENTIONS["kinhec: eye_in_hand"][0])
    if float(truth["time_offset_s"]) != 0.0:
        out.update(CONVENTIONS["kinhec: clock offset"][0])
    if float(truth["scale"]) != 1.0:
        out.update(CONVENTIONS["kinhec: monocular"][0])
    return out


def kinhec_recordings(folder: Path, label: str,
                      published: Mapping[str, Any]) -> tuple[list[Recording], list[str]]:
    """Every ``ID_groundtruth.json`` with its ``ID_robot.tum`` (a) and ``ID_camera.tum`` (b) in ``folder``."""
    out, absent = [], []
    for gt_path in sorted(folder.glob("*_groundtruth.json")):
        g = json.loads(gt_path.read_text())
        sid = g["sequence_id"]
        a, b = folder / f"{sid}_robot.tum", folder / f"{sid}_camera.tum"
        if not (a.is_file() and b.is_file()):
            absent.append(f"{a} or {b}")
            continue
        truth = se3.from_xyz_quat(np.array([g["X_px"], g["X_py"], g["X_pz"]]),
                                 np.array([g["X_qx"], g["X_qy"], g["X_qz"], g["X_qw"]]))
        pub = published.get(sid)
        note = f"{g['configuration']}, {g['sampling_mode']}, {g['robot']}, {g['level']}"
        out.append(Recording(f"{label}/{sid}", "kinhec", a, b, truth, True, kinhec_conventions(g),
                             (float(pub[0]), float(pub[1])) if isinstance(pub, list | tuple) else None,
                             arm=g["robot"] != "free6d", degenerate=float(g["axis_scatter_lambda2"]) < 1e-6,
                             note=note, track=str(g.get("track", ""))))
    return out, absent


def all_recordings(data: Path, kinhec_dir: Path) -> tuple[list[Recording], list[str], list[str]]:
    """(recordings, absent files, where the kinhec sequences come from)."""
    recs, absent = corpus_recordings(data)
    sources = []
    smoke = data / SMOKE
    if smoke.is_dir():
        r, a = kinhec_recordings(smoke, "smoke", PUBLISHED_SMOKE)
        recs, absent = recs + r, absent + a
        sources.append(f"{smoke}: {len(r)} sequences (corpus; published errors from its README)")
    else:
        absent.append(f"{smoke} (its kinhec sequences skipped)")
    folders = sorted(kinhec_dir.glob("kinhec-*")) if kinhec_dir.is_dir() else []
    for folder in folders:
        pub_path = folder / "published.json"
        pub = json.loads(pub_path.read_text())["X_error_deg_mm"] if pub_path.is_file() else {}
        r, a = kinhec_recordings(folder, folder.name, pub)
        recs, absent = recs + r, absent + a
        sources.append(f"{folder}: {len(r)} sequences (generated by benchmarks/make_kinhec.sh; published errors "
                       f"{'from its published.json' if pub else 'ABSENT'})")
    if not folders:
        absent.append(f"{kinhec_dir}/kinhec-*/ (no generated kinhec sequences: run benchmarks/make_kinhec.sh)")
    return recs, absent, sources


# --- the reference-free checks -------------------------------------------------------------------------------
def closure(Ts: Iterable[FloatArray]) -> tuple[float, float]:
    """How far the product of the transforms is from I: rotation [deg], translation [mm]."""
    P = np.eye(4)
    for T in Ts:
        P = P @ T
    return math.degrees(se3.rotation_angle(P[:3, :3])), 1e3 * float(np.linalg.norm(P[:3, 3]))


def _loop(results: Mapping[str, Result], level: str, pick: Any) -> tuple[float, float] | str:
    names = [f"tango_{level}_{p}" for p in ("C_M", "M_N", "N_C")]
    if any(n not in results for n in names):
        return "absent"
    fits = [pick(results[n]) for n in names]
    if any(f is None or f.matrix is None for f in fits):
        return "a pair failed"
    return closure(f.matrix for f in fits)


def _agreement(results: Mapping[str, Result], pick: Any) -> tuple[float, float] | str:
    if "prime_sense_1" not in results or "prime_sense_2" not in results:
        return "absent"
    f1, f2 = pick(results["prime_sense_1"]), pick(results["prime_sense_2"])
    if f1 is None or f2 is None or f1.matrix is None or f2.matrix is None:
        return "a recording failed"
    return _error(f1.matrix, f2.matrix)


# --- printing -----------------------------------------------------------------------------------------------
def fmt(e: tuple[float, float] | str | None) -> str:
    """``rot°/trans mm`` with three significant digits, or the reason there is none."""
    if e is None or isinstance(e, str):
        return e or "-"
    return f"{e[0]:.3g}°/{e[1]:.3g}"


def _cell(f: Fit) -> str:
    return fmt(f.error) if f.error else "fail"


def _outcome(f: Fit, width: int = 100) -> str:
    return _cell(f) if f.error else f.failure[:width]


def _best(grid: Mapping[tuple[str, str], Fit], m: int) -> tuple[float, tuple[str, str]] | None:
    scored = [(f.error[m], k) for k, f in grid.items() if f.error is not None]
    return min(scored) if scored else None


def _setting(key: tuple[str, str]) -> str:
    pairs = "stations" if key[0] == STATIONS else f"pairs {key[0]}"
    return f"{pairs}, park" if key[1] == PARK else f"{pairs}, α {key[1]}, dqopt"


def _ratio(x: float, y: float) -> float:
    return x / y if y > 0 else math.inf


def print_grid(cells: Mapping[tuple[str, str], str], title: str, indent: str = "   ") -> None:
    """A table of (strategy, α label or park) → text: strategies down, α and park across."""
    strategies = list(dict.fromkeys(k[0] for k in cells))
    labels = list(dict.fromkeys(k[1] for k in cells))
    print(indent + f"{title:<12}" + "".join(f" {'α ' + x if x != PARK else 'park':>15}" for x in labels))
    for s in strategies:
        print(indent + f"{s:<12}" + "".join(f" {cells.get((s, x), '-'):>15}" for x in labels))


def report(res: Result) -> None:
    """One recording's fixed-width table."""
    rec, d = res.recording, res.defaults
    truth = "exact truth" if rec.exact else "reference estimate (~2°/3 cm)"
    conv = ", ".join(f"{k}={v}" for k, v in res.given.items()) or "none"
    print(f"\n== {rec.name} [{rec.kind}{'; ' + rec.note if rec.note else ''}]  vs {truth}; {res.seconds:.1f} s")
    print(f"   conventions: {conv}")
    if d.error is None:
        print(f"   defaults        FAILED  {d.failure[:160]}")
    else:
        off = "" if d.offset_s in (None, 0.0) else f", offset {d.offset_s:.4f} s"
        print(f"   defaults        {fmt(d.error):<18} α {d.alpha:.3g}, {d.pairs} pairs{off}")
        for w in d.warnings[:2]:
            print(f"     warning: {w[:150]}")
    print(f"   park same pairs {_outcome(res.park)}")
    print(f"   dqopt unrefined {_outcome(res.dqopt)}")
    print(f"   park + LM       {_outcome(res.park_lm)}")
    print("   OpenCV          " + "  ".join(f"{m.lower()} {_outcome(f, 40)}" for m, f in res.opencv.items()))
    if res.offset_auto is not None:
        o = res.offset_auto
        tail = f"(offset {o.offset_s:.4f} s)" if o.error else o.failure[:100]
        print(f"   offset auto     {_cell(o):<18} {tail}")
    if rec.published:
        print(f"   published       {fmt(rec.published):<18} (Park-Martin + LM as kinhec runs it)")
    print_grid({k: _cell(f) for k, f in res.grid.items()}, "grid °/mm")
    failures = sorted({f.failure for f in res.grid.values() if f.failure})
    for msg in failures[:2]:
        print(f"     grid failure: {msg[:150]}")
    best = [_best(res.grid, m) for m in (0, 1)]
    if best[0] and best[1]:
        print(f"   best fixed      rot {best[0][0]:.3g}° ({_setting(best[0][1])}); "
              f"trans {best[1][0]:.3g} mm ({_setting(best[1][1])})")
        if d.error:
            print(f"   defaults÷best   rot {_ratio(d.error[0], best[0][0]):.2f}  "
                  f"trans {_ratio(d.error[1], best[1][0]):.2f}")


def _verdict(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def _within(e: tuple[float, float] | str, goal: tuple[float, float]) -> bool:
    return not isinstance(e, str) and e[0] <= goal[0] and e[1] <= goal[1]


def _check_grid(check: Any, keys: Sequence[tuple[str, str]]) -> None:
    """A reference-free check of every grid setting (the same setting on every recording it
    combines), as a table, and the best setting (rotation; translation)."""
    values = {k: check(lambda r, k=k: r.grid.get(k)) for k in keys}
    scored = [(e, k) for k, e in values.items() if not isinstance(e, str)]
    if not scored:
        print("    best fixed setting               -")
        return
    r = min(scored, key=lambda s: s[0][0])
    t = min(scored, key=lambda s: s[0][1])
    print(f"    best fixed setting               rot {r[0][0]:.3g}° ({_setting(r[1])}); "
          f"trans {t[0][1]:.3g} mm ({_setting(t[1])})")
    print_grid({k: fmt(e) if not isinstance(e, str) else "fail" for k, e in values.items()}, "°/mm", "      ")


def _vs_published(r: Result) -> str:
    pub, d = r.recording.published, r.defaults.error
    assert pub is not None
    why = (f"{fmt(d)} vs {fmt(pub)}: ×{_ratio(d[0], pub[0]):.2f} rot, ×{_ratio(d[1], pub[1]):.2f} trans"
           if d else r.defaults.failure[:90])
    return why + ("  [degenerate]" if r.recording.degenerate else "")


def summary(results: Sequence[Result], mode: str = "") -> list[tuple[str, bool | None]]:
    """Print the goals' block (``mode``: how the defaults were run); return (goal, passed or None
    when it could not be measured)."""
    by_name = {r.recording.name: r for r in results}
    keys = list(dict.fromkeys(k for r in results for k in r.grid if k[0] != STATIONS))
    verdicts: list[tuple[str, bool | None]] = []
    print("\n" + "=" * 100 + f"\nGOALS (issue 19): the defaults{', ' + mode if mode else ''}")
    for level in ("easy", "hard"):
        e = _loop(by_name, level, lambda r: r.defaults)
        goal, pub = LOOP_GOAL[level], LOOP_PUBLISHED[level]
        ok = None if isinstance(e, str) and e == "absent" else _within(e, goal)
        name = f"tango {level} loop closure"
        print(f"  {name:<34} {fmt(e):<20} goal ≤ {fmt(goal):<14} published {fmt(pub):<14} "
              f"{'-' if ok is None else _verdict(ok)}")
        print(f"    park on the defaults' pairs      {fmt(_loop(by_name, level, lambda r: r.park))}")
        _check_grid(lambda p, lv=level: _loop(by_name, lv, p), keys)
        verdicts.append((name, ok))
    e = _agreement(by_name, lambda r: r.defaults)
    ok = None if isinstance(e, str) and e == "absent" else _within(e, PRIMESENSE_GOAL)
    print(f"  {'prime_sense 1 vs 2':<34} {fmt(e):<20} goal ≤ {fmt(PRIMESENSE_GOAL):<14} published "
          f"{fmt(PRIMESENSE_GOAL):<14} {'-' if ok is None else _verdict(ok)}")
    print(f"    park on the defaults' pairs      {fmt(_agreement(by_name, lambda r: r.park))}")
    _check_grid(lambda p: _agreement(by_name, p), keys)
    verdicts.append(("prime_sense 1 vs 2", ok))

    arms = [r for r in results if r.recording.kind == "kinhec" and r.recording.arm and r.recording.published]
    no_pub = [r.recording.name for r in results if r.recording.kind == "kinhec" and not r.recording.published]
    fails, refused = [], []
    for r in arms:
        p_err, d = r.recording.published, r.defaults.error
        assert p_err is not None
        if d is None and r.recording.degenerate and r.defaults.failure.startswith("UnderdeterminedError"):
            refused.append(r)                # the goal's other branch: refused, naming the cause
        elif d is None or d[0] > KINHEC_RATIO_GOAL * p_err[0] or d[1] > KINHEC_RATIO_GOAL * p_err[1]:
            fails.append(r)
    name = f"kinhec arm sequences ≤ {KINHEC_RATIO_GOAL}× published"
    ok = None if not arms else not fails
    print(f"  {name:<34} {len(arms) - len(fails)}/{len(arms)} pass ({len(refused)} refused as degenerate)"
          f" ({sum(r.recording.degenerate for r in fails)} of the failures degenerate)"
          f"{'':<8} {'-' if ok is None else _verdict(ok)}")
    for r in refused:
        print(f"    refused, degenerate motion named: {r.recording.name:<28} {r.defaults.failure[:70]}")
    for r in fails:
        print(f"    FAIL {r.recording.name:<28} {_vs_published(r)}")
    for r in results:
        if r.recording.kind == "kinhec" and not r.recording.arm and r.recording.published:
            print(f"    not an arm, not counted: {r.recording.name:<28} {_vs_published(r)}")
    if no_pub:
        print(f"    no published figure (not counted): {', '.join(no_pub)}")
    verdicts.append((name, ok))

    vio = [r for r in results if r.recording.kind in ("vio", "odometry")]
    vio_fail = [r for r in vio if r.defaults.error is None or r.park.error is None
                or r.defaults.error[0] > VIO_RATIO_GOAL * r.park.error[0]]
    name = f"VIO rotation ≤ {VIO_RATIO_GOAL}× park, same pairs"
    ok = None if not vio else not vio_fail
    print(f"  {name:<34} {len(vio) - len(vio_fail)}/{len(vio)} pass (vs the reference, itself Park-Martin+LM)"
          f"  {'-' if ok is None else _verdict(ok)}")
    for r in vio:
        d, p = r.defaults.error, r.park.error
        ratio = f"×{_ratio(d[0], p[0]):.2f}" if d and p else "failed"
        print(f"    {r.recording.name:<20} defaults {fmt(d) if d else 'fail':<16} park {fmt(p) if p else 'fail':<16} "
              f"{ratio}")
    verdicts.append((name, ok))
    for level in ("easy", "hard"):
        dl, pl = _loop(by_name, level, lambda r: r.defaults), _loop(by_name, level, lambda r: r.park)
        name = f"VIO rotation, {level} loop closure"
        ok, ratio = None, ""
        if not isinstance(dl, str) and not isinstance(pl, str):
            ok, ratio = dl[0] <= VIO_RATIO_GOAL * pl[0], f"×{_ratio(dl[0], pl[0]):.2f}"
        print(f"  {name:<34} defaults {fmt(dl):<12} park same pairs {fmt(pl):<12} {ratio:<6} (reference-free)"
              f"{'':<4} {'-' if ok is None else _verdict(ok)}")
        verdicts.append((name, ok))
    return verdicts


# --- issue 35: statistically efficient by default --------------------------------------------------------------
ISSUE35_WORSE = 1.5          # no sequence's defaults worse than this × the better of Park + LM and dqopt unrefined
Error = tuple[float, float] | None


def _columns(results: Sequence[Result]) -> dict[str, Any]:
    """The medians block's columns: name → (result → its error or None)."""
    cols: dict[str, Any] = {"default": lambda r: r.defaults.error, "dqopt unref.": lambda r: r.dqopt.error,
                            "park+LM": lambda r: r.park_lm.error, "published": lambda r: r.recording.published}
    for m in OPENCV_METHODS:
        cols[f"cv {m.lower()}"] = lambda r, m=m: r.opencv[m].error if m in r.opencv else None
    return cols


def _median(errors: Sequence[Error]) -> tuple[tuple[float, float] | None, int]:
    """(median rotation, median translation) of the errors that exist, and how many do not."""
    ok = [e for e in errors if e is not None]
    medians = (float(np.median([e[0] for e in ok])), float(np.median([e[1] for e in ok]))) if ok else None
    return medians, len(errors) - len(ok)


def _grid_error(r: Result, key: tuple[str, str]) -> Error:
    """A grid setting's error; a station capture's one row stands for every pair strategy (all with all)."""
    f = r.grid.get(key) or r.grid.get((STATIONS, key[1]))
    return None if f is None else f.error


def _best_fixed(group: Sequence[Result]) -> str:
    """The grid setting with the smallest median error over the group (rotation; translation), in hindsight,
    among the settings with the fewest failures."""
    every = list(dict.fromkeys(k for r in group for k in r.grid))
    keys = [k for k in every if k[0] != STATIONS] or every              # station captures only: their rows
    med = {k: _median([_grid_error(r, k) for r in group]) for k in keys}
    fewest = min((missing for m, missing in med.values() if m is not None), default=None)
    scored = [(m, k) for k, (m, missing) in med.items() if m is not None and missing == fewest]
    if not scored:
        return "-"
    (rot, kr), (trans, kt) = min((m[0], k) for m, k in scored), min((m[1], k) for m, k in scored)
    failed = f" ({fewest} failed)" if fewest else ""
    return f"rot {rot:.3g}° ({_setting(kr)}); trans {trans:.3g} mm ({_setting(kt)}){failed}"


def _medians_row(label: str, group: Sequence[Result], cols: Mapping[str, Any]) -> None:
    cells = []
    for pick in cols.values():
        m, missing = _median([pick(r) for r in group])
        cells.append(f"{fmt(m)}{f' ({missing}✗)' if missing else ''}")
    seeds = len({r.recording.name.split('/')[0] for r in group})
    print(f"  {label:<22} {len(group):>3} {seeds:>2}" + "".join(f" {c:>17}" for c in cells))


def _better(r: Result) -> Error:
    """Per component, the smaller error of Park + LM and dqopt unrefined (None: both failed)."""
    errs = [e for e in (r.park_lm.error, r.dqopt.error) if e is not None]
    return (min(e[0] for e in errs), min(e[1] for e in errs)) if errs else None


def _track_goals(group: Sequence[Result]) -> None:
    """The issue's goals on one track: the median ratios over the sequences where the defaults, Park + LM and
    dqopt unrefined all have an estimate, and every sequence worse than ISSUE35_WORSE× (refusals apart)."""
    both = [r for r in group if r.defaults.error and r.park_lm.error and r.dqopt.error]
    if both:
        d, _ = _median([r.defaults.error for r in both])
        p, _ = _median([r.park_lm.error for r in both])
        q, _ = _median([r.dqopt.error for r in both])
        assert d and p and q
        rot, trans = _ratio(d[0], p[0]), _ratio(d[1], min(p[1], q[1]))
        print(f"    {_verdict(rot <= 1.0)} median rotation ≤ 1.0× park+LM's: {d[0]:.3g}° vs {p[0]:.3g}° (×{rot:.2f})"
              f"   over {len(both)}/{len(group)}")
        print(f"    {_verdict(trans <= 1.0)} median translation ≤ 1.0× the better of park+LM, dqopt: {d[1]:.3g} mm "
              f"vs {p[1]:.3g}, {q[1]:.3g} (×{trans:.2f})")
    else:
        print("    - medians: no sequence where the defaults, park+LM and dqopt all have an estimate")
    refused = [r for r in group if r.defaults.error is None]
    worse = []
    for r in group:
        d, b = r.defaults.error, _better(r)
        if d is not None and b is not None:
            ratios = (_ratio(d[0], b[0]), _ratio(d[1], b[1]))
            if max(ratios) > ISSUE35_WORSE:
                worse.append((r, ratios))
    print(f"    {_verdict(not worse)} no sequence > {ISSUE35_WORSE}× the better of park+LM, dqopt (rotation or "
          f"translation): {len(worse)} worse, {len(refused)} refused")
    for r, (kr, kt) in worse:
        print(f"      worse {r.recording.name:<30} rot ×{kr:.2f}  trans ×{kt:.2f}   defaults {fmt(r.defaults.error)}"
              f" better {fmt(_better(r))}{'  [degenerate]' if r.recording.degenerate else ''}")
    for r in refused:
        print(f"      refused {r.recording.name:<28} {r.defaults.failure[:110]}")


def issue35(results: Sequence[Result]) -> None:
    """The issue-35 block: per generated kinhec track (every seed present) the medians of every column and the
    best fixed setting in hindsight, the goals' PASS/FAIL, the sequences worse than ISSUE35_WORSE×; then the
    same medians on the smoke corpus and on the ETH corpus (against its reference)."""
    cols = _columns(results)
    generated = [r for r in results if r.recording.kind == "kinhec" and r.recording.name.startswith("kinhec-")]
    tracks = sorted({r.recording.track for r in generated})
    print("\n" + "=" * 100)
    print("ISSUE 35 GOALS: the defaults against dqopt unrefined and Park + LM on the defaults' pairs")
    print("  medians °/mm (n✗: failures, not in the median); n sequences, s seeds")
    print(f"  {'group':<22} {'n':>3} {'s':>2}" + "".join(f" {c:>17}" for c in cols))
    groups = {f"kinhec {t}": [r for r in generated if r.recording.track == t] for t in tracks}
    groups |= {"kinhec all generated": generated,
               "smoke corpus": [r for r in results if r.recording.name.startswith("smoke/")],
               "ETH (vs reference)": [r for r in results if r.recording.kind != "kinhec"]}
    for label, group in groups.items():
        if group:
            _medians_row(label, group, cols)
    for label, group in groups.items():
        if group:
            print(f"  {label}: best fixed in hindsight (median over the group): {_best_fixed(group)}")
    for t in tracks:
        group = groups[f"kinhec {t}"]
        seeds = len({r.recording.name.split("/")[0] for r in group})
        print(f"  track {t} ({len(group)} sequences, {seeds} seeds{'' if seeds >= 3 else '; the goal asks ≥ 3'})")
        _track_goals(group)


def _default_data() -> Path:
    """The corpus: ``data`` in the folder ``shared`` beside the repository (or beside the worktrees' folder)."""
    for base in (ROOT.parent, ROOT.parent.parent):
        if (base / "shared" / "data").is_dir():
            return base / "shared" / "data"
    return ROOT.parent / "shared" / "data"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    parser.add_argument("--data", type=Path, default=_default_data(), help="the corpus [%(default)s]")
    parser.add_argument("--kinhec-dir", type=Path, default=Path.home() / ".cache" / "handeye-bench",
                        help="generated kinhec sequences, one kinhec-SEED/ folder per seed [%(default)s]")
    parser.add_argument("--bare", action="store_true", help="no convention flags: the defaults alone")
    parser.add_argument("--quick", action="store_true",
                        help=f"a smaller grid: pairs {', '.join(QUICK_STRATEGIES)} × α {', '.join(QUICK_ALPHAS)}")
    parser.add_argument("--only", default="", help="only recordings whose name contains this text")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="an option for every call (try a candidate default), e.g. --set max_pairs=500")
    args = parser.parse_args(argv)
    overrides = dict(item.split("=", 1) for item in args.set)
    t0 = time.perf_counter()
    recs, absent, sources = all_recordings(args.data, args.kinhec_dir)
    recs = [r for r in recs if args.only in r.name]
    print(f"benchmarks/real.py — handeye {handeye_cli.__version__}; corpus {args.data}; "
          f"{'--bare: NO convention flags' if args.bare else 'with the convention flags below'}"
          f"{'; --quick' if args.quick else ''}{'; --set ' + ' '.join(args.set) if args.set else ''}")
    print(f"conventions ({'NOT given: --bare' if args.bare else 'the flags given per recording'}; each one the "
          "tool should find by itself, from):")
    for name, (kw, why) in CONVENTIONS.items():
        print(f"  {name:<24} {', '.join(f'{k}={v}' for k, v in kw.items()) or '-':<42} {why}")
    for s in sources:
        print(f"kinhec: {s}")
    print(f"same-pairs estimators (dqopt, park + LM, OpenCV's five) on noise-free simulated captures: largest error "
          f"{check_same_pairs():.1e} (°, mm)")
    for a in absent:
        print(f"absent, skipped: {a}")
    results = []
    for rec in recs:
        res = run(rec, bare=args.bare, quick=args.quick, overrides=overrides)
        report(res)
        results.append(res)
        sys.stdout.flush()
    summary(results, "--bare (no convention flags)" if args.bare else "with the convention flags")
    issue35(results)
    print(f"\nwall time {time.perf_counter() - t0:.1f} s for {len(results)} recordings")
    return 0


if __name__ == "__main__":
    sys.exit(main())
