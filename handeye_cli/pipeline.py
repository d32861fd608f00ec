"""The calibration pipeline: two pose streams → sync → gates → pairs → solver → result.

``calibrate(stream_a, stream_b, config)`` is the library entry point; ``read_streams`` reads the
two streams from logs or text files. The extrinsic is ``T_a_b``: the pose of sensor b's frame in
sensor a's frame (maps points from b to a), where each stream holds ``T_world_sensor(t)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .analysis import (
    BootstrapResult,
    Residuals,
    RobustResult,
    assess_observability,
    auto_alpha,
    bootstrap,
    pair_residuals,
    robust_solve,
)
from .config import load_config
from .errors import HandEyeError
from .io.pairfile import read_extrinsic
from .output.document import result_document
from .solvers import Prior, Solution, solve
from .stages.gates import pose_jump_gate
from .stages.pairs import Pairs, make_pairs
from .stages.sync import Synced, associate
from .streams import PoseStream

__all__ = ["Calibration", "StreamSpec", "calibrate", "calibrate_files", "read_streams"]


@dataclass(frozen=True)
class StreamSpec:
    """Where one stream comes from: a file (log or text) and a topic or a (parent, child) frame pair."""

    path: str
    topic: str | None = None
    frames: tuple[str, str] | None = None

    def describe(self) -> dict:
        out: dict = {"file": self.path}
        if self.topic:
            out["topic"] = self.topic
        if self.frames:
            out["frames"] = list(self.frames)
        return out


@dataclass(frozen=True, eq=False)
class Calibration:
    """Everything a calibration produced.

    solution: the solver's result (``solution.matrix`` is ``T_a_b``).
    stream_a, stream_b: the streams as used (after inversion, before the time offset).
    synced: the samples that passed sync and gates; pairs: the motions solved.
    samples: what each stage read, kept and dropped; warnings: human-readable warnings.
    diagnostics: extra result keys (time offset, residuals, …); inputs: what was read.
    residuals: per-pair residuals at the solution; weights: per-pair weights used (inlier mask
    with ``robust``, else None); robust, bootstrap: those analyses' results when asked for.
    """

    solution: Solution
    stream_a: PoseStream
    stream_b: PoseStream
    synced: Synced
    pairs: Pairs
    samples: dict
    config: dict
    residuals: Residuals
    warnings: list[str] = field(default_factory=list)
    diagnostics: dict = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)
    weights: np.ndarray | None = None
    robust: RobustResult | None = None
    bootstrap: BootstrapResult | None = None

    @property
    def matrix(self) -> np.ndarray:
        """``T_a_b`` (4x4)."""
        return self.solution.matrix

    @property
    def frames(self) -> dict:
        """Names of frames a and b: ``name_a``/``name_b`` from the config, else the streams' child frames."""
        return {"a": self.config["name_a"] or self.stream_a.child_frame_id or "a",
                "b": self.config["name_b"] or self.stream_b.child_frame_id or "b"}

    def bootstrap_deviations(self) -> np.ndarray | None:
        """(K, 6) bootstrap deviations of X: rotation vector [deg] (3), translation [m] (3)."""
        if self.bootstrap is None:
            return None
        return np.c_[self.bootstrap.rotation_deltas_deg, self.bootstrap.translations_m - self.matrix[:3, 3]]

    def document(self) -> dict:
        """The result in the schema of DESIGN.md (what ``handeye calibrate`` prints)."""
        return result_document(self.solution, frames=self.frames, inputs=self.inputs, samples=self.samples,
                               warnings=self.warnings, diagnostics=self.diagnostics)


def read_streams(spec_a: StreamSpec, spec_b: StreamSpec, config: dict | None = None, *,
                 quiet: bool = True) -> tuple[PoseStream, PoseStream]:
    """Read streams a and b (``T_world_sensor``), inverted where the config says so."""
    from .io import detect_format, read_log_streams, read_stream  # mcap/rosbags: import only when reading
    from .io.detect import LOG_FORMATS

    cfg = config or load_config()
    if spec_a.path == spec_b.path and detect_format(spec_a.path) in LOG_FORMATS:     # one pass over the log
        a, b = read_log_streams(spec_a.path, [(spec_a.topic, spec_a.frames), (spec_b.topic, spec_b.frames)],
                                time_source=cfg["time_source"], quiet=quiet)
    else:
        a, b = (read_stream(spec.path, topic=spec.topic, frames=spec.frames, time_source=cfg["time_source"],
                            columns=cfg["csv_columns"], quiet=quiet) for spec in (spec_a, spec_b))
    return (a.inverted() if cfg["invert_a"] else a), (b.inverted() if cfg["invert_b"] else b)


def _time_offset(a: PoseStream, b: PoseStream, sync: dict) -> tuple[int, dict, list[str]]:
    """The offset [ns] b's clock is ahead of a's, its report, and warnings about it."""
    value = sync["time_offset"]
    if isinstance(value, str) and value.strip().lower() == "auto":
        from .stages.timeoffset import estimate_time_offset  # scipy.signal: import only when used

        est = estimate_time_offset(a, b, max_offset_s=sync["max_time_offset"])
        return est.offset_ns, {"seconds": est.offset_ns / 1e9, "std_seconds": est.std_ns / 1e9,
                               "coarse_seconds": est.coarse_ns / 1e9, "correlation": est.correlation,
                               "method": est.method}, list(est.warnings)
    try:
        seconds = float(value)
    except (TypeError, ValueError):
        raise HandEyeError(f"bad time offset {value!r}", "sync.time_offset",
                           "give seconds (b's clock ahead of a's) or 'auto'") from None
    return int(round(seconds * 1e9)), {"seconds": seconds, "method": "fixed"}, []


def _too_few(pairs: Pairs, samples: dict, cfg: dict) -> HandEyeError:
    """Say which stage left too few pairs, and what to relax."""
    p = cfg["pairs"]
    story = (f"a read {samples['read_a']}, b read {samples['read_b']}; timestamp gate dropped "
             f"{samples['dropped_timestamp_gate']} and {samples['dropped_outside_span']} were outside b's span; "
             f"pose-jump gate dropped {samples['dropped_pose_jump']}; {samples['keyframes']} samples/keyframes "
             f"gave {samples['candidate_pairs']} candidate pairs with strategy {p['strategy']}")
    stage = max((("the timestamp gate", samples["dropped_timestamp_gate"] + samples["dropped_outside_span"]),
                 ("the pose-jump gate", samples["dropped_pose_jump"])), key=lambda x: x[1])
    if samples["candidate_pairs"] >= cfg["solver"]["min_pairs"]:
        fix = f"the cap of {p['max_pairs']} pairs keeps too few: raise pairs.max_pairs (--max-pairs)"
    elif samples["synced_kept"] >= 2 * cfg["solver"]["min_pairs"]:
        fix = (f"the motion rotates too little between samples: lower pairs.min_rotation_deg "
               f"(now {p['min_rotation_deg']}) or try --pairs all / consecutive")
    else:
        fix = f"most samples were dropped by {stage[0]}: relax it (sync.max_dt, gates.*) or fix the time offset"
    return HandEyeError(f"only {len(pairs)} motion pair(s) left, {cfg['solver']['min_pairs']} needed", story, fix)


def _prior(solver: dict) -> Prior | None:
    if solver["prior"] is None:
        return None
    w = solver["prior_weights"]
    if not (isinstance(w, (list, tuple)) and len(w) == 2 and all(isinstance(v, (int, float)) for v in w)):
        raise HandEyeError(f"bad prior weights {w!r}", "solver.prior_weights", "give two numbers [a, b]")
    return Prior(read_extrinsic(solver["prior"]), float(w[0]), float(w[1]))


# A result whose median residuals exceed these is almost certainly wrong data, not noise; a
# pose-jump gate that drops more than this fraction of the samples is fighting the data.
_SUSPECT_ROTATION_DEG = 5.0
_SUSPECT_TRANSLATION_M = 0.2
_SUSPECT_GATE_FRACTION = 0.25


def _pairs(stream_a: PoseStream, stream_b: PoseStream, cfg: dict, offset_ns: int) -> tuple[Synced, Pairs, dict]:
    """Sync, gates and pair formation: (kept samples, pairs, counts of every stage)."""
    sync, gates, pc = cfg["sync"], cfg["gates"], cfg["pairs"]
    synced, counts = associate(stream_a, stream_b, method=sync["method"],
                               max_dt_ns=int(round(float(sync["max_dt"]) * 1e9)), time_offset_ns=offset_ns)
    max_rot = gates["max_rotation_deg"]
    kept, jump_counts = pose_jump_gate(synced, max_translation_m=gates["max_translation"],
                                       max_rotation_rad=None if max_rot is None else np.deg2rad(max_rot))
    pairs, pair_counts = make_pairs(kept, pc["strategy"], keyframe_rotation_rad=np.deg2rad(pc["keyframe_rotation_deg"]),
                                    keyframe_translation_m=pc["keyframe_translation"],
                                    min_rotation_rad=np.deg2rad(pc["min_rotation_deg"]),
                                    max_pairs=int(pc["max_pairs"]), seed=int(pc["seed"]))
    samples = {**counts, "duplicates_dropped_a": stream_a.duplicates_dropped,
               "duplicates_dropped_b": stream_b.duplicates_dropped, **jump_counts,
               "synced_kept": len(kept), **pair_counts}
    if len(pairs) < max(int(cfg["solver"]["min_pairs"]), 2):
        raise _too_few(pairs, samples, cfg)
    return kept, pairs, samples


def _data_warning(stream_a: PoseStream, stream_b: PoseStream, cfg: dict, offset_ns: int,
                  res: Residuals, weights: np.ndarray | None, samples: dict) -> str | None:
    """A warning when the data look wrong, not just noisy: implausibly large residuals, or a
    pose-jump gate that drops much of the log. A stream of ``T_sensor_world`` given as
    ``T_world_sensor`` (the most common set-up mistake) causes both, so each stream is tried
    inverted and named when that fits far better."""
    base = res.summary(None if weights is None else weights > 0)
    dropped = samples["dropped_pose_jump"] / max(samples["synced"], 1)
    large = base.rotation_median_deg > _SUSPECT_ROTATION_DEG or base.translation_median_m > _SUSPECT_TRANSLATION_M
    if not (large or dropped > _SUSPECT_GATE_FRACTION):
        return None
    for name, a, b in (("b", stream_a, stream_b.inverted()), ("a", stream_a.inverted(), stream_b)):
        try:
            _, pairs, alt_samples = _pairs(a, b, cfg, offset_ns)
            alt = pair_residuals(pairs.A, pairs.B, solve(pairs.A, pairs.B).matrix).summary()
        except HandEyeError:
            continue
        better_fit = alt.rotation_median_deg < base.rotation_median_deg / 3
        more_kept = alt_samples["synced_kept"] > 1.5 * samples["synced_kept"]
        if (better_fit and alt_samples["synced_kept"] >= samples["synced_kept"]) or (
                more_kept and alt.rotation_median_deg <= base.rotation_median_deg):
            return (f"stream {name} looks inverted (T_sensor_world instead of T_world_sensor): inverted, the "
                    f"median residuals go from {base.rotation_median_deg:.2f}° / {base.translation_median_m:.3f} m to "
                    f"{alt.rotation_median_deg:.2f}° / {alt.translation_median_m:.3f} m and the pose-jump gate keeps "
                    f"{alt_samples['synced_kept']} samples instead of {samples['synced_kept']}; rerun with "
                    f"--invert-{name} (or --no-invert-{name} if it was inverted)")
    if large:
        return (f"large residuals (median {base.rotation_median_deg:.2f}° / {base.translation_median_m:.3f} m): the "
                "streams may not be rigidly attached, be mis-synchronised (try --time-offset auto) or come from "
                "the wrong topics")
    return (f"the pose-jump gate dropped {samples['dropped_pose_jump']} of {samples['synced']} samples "
            f"({100 * dropped:.0f} %): the sensors move faster than its limits allow at this rate; raise "
            "--max-jump / --max-jump-deg, or check the tracking")


def calibrate(stream_a: PoseStream, stream_b: PoseStream, config: dict | None = None, *,
              inputs: dict | None = None) -> Calibration:
    """Calibrate ``T_a_b`` from two pose streams ``T_wa_a(t)``, ``T_wb_b(t)`` (int64 ns stamps,
    positions [m], quaternions x-y-z-w); ``config`` as :func:`handeye_cli.config.load_config`
    returns (default: the defaults). Raises HandEyeError on data that cannot be calibrated.

    Order: time offset → sync → gates → pairs → [robust: RANSAC inliers] → [α auto] → weighted
    solve → observability warnings, residuals → [bootstrap].
    """
    cfg = config or load_config()
    solver, analysis, seed = cfg["solver"], cfg["analysis"], int(cfg["pairs"]["seed"])
    offset_ns, offset_report, warnings = _time_offset(stream_a, stream_b, cfg["sync"])
    kept, pairs, samples = _pairs(stream_a, stream_b, cfg, offset_ns)
    A, B, prior = pairs.A, pairs.B, _prior(solver)
    diagnostics: dict = {"time_offset": offset_report}
    auto = isinstance(solver["alpha"], str) and solver["alpha"].strip().lower() == "auto"
    alpha = 1.0 if auto else float(solver["alpha"])

    weights = robust = None
    if analysis["robust"]:
        robust = robust_solve(A, B, method=solver["method"], alpha=alpha, prior=prior, seed=seed)
        weights = robust.inliers.astype(float)
        diagnostics["robust"] = {**robust.as_dict(), "rejected_times_s": [
            [pairs.t_i_ns[k] / 1e9, pairs.t_j_ns[k] / 1e9] for k in robust.rejected]}
    if auto:
        choice = auto_alpha(A, B, prior=prior, weights=weights)
        alpha = choice.alpha
        diagnostics["alpha_auto"] = choice.as_dict()
    solution = solve(A, B, method=solver["method"], alpha=alpha, prior=prior, weights=weights)

    ij = (pairs.i, pairs.j)
    obs = assess_observability(A, B, solution.matrix, alpha=alpha, prior=prior, weights=weights, samples=ij)
    warnings += [str(w) for w in obs.warnings]
    diagnostics["observability"] = obs.as_dict()
    res = pair_residuals(A, B, solution.matrix)
    diagnostics["residuals"] = res.summary(None if weights is None else weights > 0).as_dict()
    data_warning = _data_warning(stream_a, stream_b, cfg, offset_ns, res, weights, samples)
    if data_warning:
        warnings.append(data_warning)
    boot = None
    if int(analysis["bootstrap"]) > 0:
        boot = bootstrap(A, B, int(analysis["bootstrap"]), alpha=alpha, prior=prior, weights=weights,
                         samples=ij, seed=seed)
        diagnostics["uncertainty"] = {"method": "bootstrap over pose samples", **boot.as_dict()}
    return Calibration(solution, stream_a, stream_b, kept, pairs, samples, cfg, res, warnings=warnings,
                       diagnostics=diagnostics, inputs=dict(inputs or {}), weights=weights, robust=robust,
                       bootstrap=boot)


def calibrate_files(spec_a: StreamSpec, spec_b: StreamSpec, config: dict | None = None, *,
                    quiet: bool = True) -> Calibration:
    """Read both streams (see :func:`read_streams`) and :func:`calibrate`."""
    cfg = config or load_config()
    a, b = read_streams(spec_a, spec_b, cfg, quiet=quiet)
    inputs = {"a": spec_a.describe(), "b": spec_b.describe(), "time_source": cfg["time_source"]}
    for key in ("invert_a", "invert_b"):
        if cfg[key]:
            inputs[key] = True
    return calibrate(a, b, cfg, inputs=inputs)
