"""The calibration pipeline: two pose streams → sync → gates → pairs → solver → result.

``calibrate(stream_a, stream_b, config)`` is the library entry point; ``read_streams`` reads the
two streams from logs or text files. The extrinsic is ``T_a_b``: the pose of sensor b's frame in
sensor a's frame (maps points from b to a), where each stream holds ``T_world_sensor(t)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .config import load_config
from .errors import HandEyeError
from .gates import pose_jump_gate
from .output import result_document
from .pairfile import read_extrinsic
from .pairs import Pairs, make_pairs
from .solvers import Prior, Solution, solve
from .streams import PoseStream
from .sync import Synced, associate
from .timeoffset import estimate_time_offset

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
    diagnostics: extra result keys (time offset, …); inputs: what was read.
    """

    solution: Solution
    stream_a: PoseStream
    stream_b: PoseStream
    synced: Synced
    pairs: Pairs
    samples: dict
    config: dict
    warnings: list[str] = field(default_factory=list)
    diagnostics: dict = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)

    @property
    def matrix(self) -> np.ndarray:
        """``T_a_b`` (4x4)."""
        return self.solution.matrix

    @property
    def frames(self) -> dict:
        return {"a": self.stream_a.child_frame_id or "a", "b": self.stream_b.child_frame_id or "b"}

    def document(self) -> dict:
        """The result in the schema of DESIGN.md (what ``handeye calibrate`` prints)."""
        return result_document(self.solution, frames=self.frames, inputs=self.inputs, samples=self.samples,
                               warnings=self.warnings, diagnostics=self.diagnostics)


def read_streams(spec_a: StreamSpec, spec_b: StreamSpec, config: dict | None = None, *,
                 quiet: bool = True) -> tuple[PoseStream, PoseStream]:
    """Read streams a and b (``T_world_sensor``), inverted where the config says so."""
    from .io import read_stream      # the readers pull in mcap/rosbags: import them only when reading

    cfg = config or load_config()
    streams = []
    for spec, invert in ((spec_a, cfg["invert_a"]), (spec_b, cfg["invert_b"])):
        s = read_stream(spec.path, topic=spec.topic, frames=spec.frames, time_source=cfg["time_source"],
                        columns=cfg["csv_columns"], quiet=quiet)
        streams.append(s.inverted() if invert else s)
    return streams[0], streams[1]


def _time_offset(a: PoseStream, b: PoseStream, sync: dict) -> tuple[int, dict, list[str]]:
    """The offset [ns] b's clock is ahead of a's, its report, and warnings about it."""
    value = sync["time_offset"]
    if isinstance(value, str) and value.strip().lower() == "auto":
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
    if samples["synced_kept"] >= 2 * cfg["solver"]["min_pairs"]:
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


def calibrate(stream_a: PoseStream, stream_b: PoseStream, config: dict | None = None, *,
              inputs: dict | None = None) -> Calibration:
    """Calibrate ``T_a_b`` from two pose streams ``T_wa_a(t)``, ``T_wb_b(t)`` (int64 ns stamps,
    positions [m], quaternions x-y-z-w); ``config`` as :func:`handeye_cli.config.load_config`
    returns (default: the defaults). Raises HandEyeError on data that cannot be calibrated."""
    cfg = config or load_config()
    sync, gates, pc, solver = cfg["sync"], cfg["gates"], cfg["pairs"], cfg["solver"]
    offset_ns, offset_report, warnings = _time_offset(stream_a, stream_b, sync)
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
    if len(pairs) < max(int(solver["min_pairs"]), 2):
        raise _too_few(pairs, samples, cfg)
    solution = solve(pairs.A, pairs.B, method=solver["method"], alpha=float(solver["alpha"]),
                     prior=_prior(solver))
    return Calibration(solution, stream_a, stream_b, kept, pairs, samples, cfg, warnings=warnings,
                       diagnostics={"time_offset": offset_report}, inputs=dict(inputs or {}))


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
