"""Whole-rig calibration: every sensor's ``T_ref_k`` from one log, jointly consistent.

Pipeline: read all streams (one pass per log, :mod:`.read`) → per-stream clock offsets and
inversion → one optimal calibration per pair of streams (:mod:`.pairwise`: ``calibrate``'s
stages and default pair selection) → the streams' noise, each pair's relative drift (its bias
removed where significant, and bounded: :func:`.noise.bias_bound`) and the pairwise estimates'
joint covariance (:mod:`.noise`) → graph synchronisation (chordal rotation averaging,
translation least squares, :mod:`.graph`) → the χ² test of the pairwise estimates against each
other, naming the stream that spoils it (:func:`.joint.consistency`) → the generalised least
squares of all pairwise estimates under that covariance plus the bias bound (:mod:`.joint`; a
named stream informs no other sensor) → the
block bootstrap → :class:`RigResult`.

Frames: stream k holds ``T_wk_k(t)``; ``T_ref_k`` is the pose of sensor k in the reference
sensor's frame (maps points from k to ref); quaternions x-y-z-w; metres; int64 ns stamps.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..analysis.subspace import DOF_NAMES, FROM_PRIOR
from ..calibration import calibrate_read, check_samples
from ..errors import ConfigError, DataError, HandEyeError
from ..io.nominal import read_nominal
from ..options import FIELDS, Options
from ..streams import PoseStream
from .graph import loop_closures, synchronise
from .joint import CONSISTENCY_P_VALUE, Consistency, JointProblem, Motions, bootstrap_rig, consistency, refine
from .noise import Correction, bias_bound, drift_corrections, edge_covariance, edge_noise, stream_variances
from .pairwise import ClockOffset, Edge, clock_offsets, solve_edges
from .read import StreamSpec, parse_stream, read_rig
from .result import RigResult, transform_entry

__all__ = ["RigOptions", "RigResult", "StreamSpec", "calibrate_rig", "calibrate_rig_files", "check_prior",
           "parse_stream", "per_stream", "read_rig", "transform_entry"]


def _flag(text: str) -> dict[str, str]:
    """A RigOptions field's command-line flag, which the CLI names in its errors (``handeye_cli.cli._as_flags``)."""
    return {"flag": text}


@dataclass(frozen=True)
class RigOptions:
    """Settings of a rig calibration; per stream, by the stream's name, the options calibrate takes for its
    streams a and b (same values, same parsers: :data:`handeye_cli.options.FIELDS`).

    reference: name of the reference sensor (default: the first stream).
    time_offsets: per stream name, seconds its clock is ahead of the reference's, or ``'auto'`` (calibrate's
        ``time_offset``, whose default, auto, every stream not named gets); the key ``""`` sets every stream.
    invert: names of streams recorded as ``T_sensor_world`` (inverted before use; calibrate's ``invert_a=True``).
    not_inverted: names of streams the user says are not inverted (``invert_a=False``): a pair that fits only
        inverted is then refused in the user's words, as calibrate does.
    wxyz: per stream name, whether its text file stores quaternions w first (``wxyz_a``; unset: the format's).
    scales: per stream name, the scale of its translations [m per unit] or ``'auto'`` (``scale``): a number
        multiplies them; auto estimates it with that stream's extrinsic to the reference (to the first other
        stream for the reference itself), as calibrate's ``scale='auto'`` does, before the joint solve.
    block_s: block length [s] of the bootstrap.
    options: the settings of every pairwise calibration (time source, sync, gates, pairs, solver)
        and of the rig's own analysis (``bootstrap`` replicates, ``max_time_offset``, ``seed``); the
        single-pair keys (``time_offset``, ``invert_a/b``, ``wxyz_a/b``, ``scale``, ``name_a/b``) are the
        per-stream fields above (a stream's name is its frame's: ``name_a``). ``prior`` is the nominal of every
        sensor (frames named as the streams, read as ``--against`` reads it): each pair ``j, k`` takes the
        nominal's ``T_j_k`` as calibrate takes its prior, fixing only what that pair's motion leaves open
        (planar motion: z, roll, pitch); the joint solve and the bootstrap weigh the pairs by their data alone,
        so what no pair observes keeps the nominal's value.
    """

    reference: str | None = field(default=None, metadata=_flag("--reference"))
    time_offsets: Mapping[str, float | str] = field(default_factory=dict, metadata=_flag("--time-offset"))
    invert: tuple[str, ...] = field(default=(), metadata=_flag("--invert"))
    not_inverted: tuple[str, ...] = field(default=(), metadata=_flag("--no-invert"))
    wxyz: Mapping[str, bool] = field(default_factory=dict, metadata=_flag("--wxyz"))
    scales: Mapping[str, float | str] = field(default_factory=dict, metadata=_flag("--scale"))
    block_s: float = field(default=2.0, metadata=_flag("--block"))
    options: Options = field(default_factory=Options)


# calibrate's option of a stream that each per-stream field takes, and the stream names it holds
_PER_STREAM = {"time_offsets": "time_offset", "scales": "scale", "wxyz": "wxyz_a"}


def per_stream(options: RigOptions, names: list[str]) -> dict[str, dict[str, Any]]:
    """Each per-stream field by stream name, every value checked by calibrate's parser for that option (errors
    name the field, e.g. ``(scales)``); a key ``""`` (a bare ``--time-offset auto``) applies to every stream
    but the reference. Unknown names are refused naming the field."""
    out: dict[str, dict[str, Any]] = {}
    ref = names[0] if options.reference is None else options.reference
    for key in ("time_offsets", "scales", "wxyz", "invert", "not_inverted"):
        given = getattr(options, key)
        values = dict.fromkeys(given, True) if isinstance(given, tuple) else dict(given)
        unknown = sorted(set(values) - set(names) - {""})
        if unknown:
            raise ConfigError(f"unknown stream {unknown[0]!r}", key, f"use one of {', '.join(names)}")
        parse = FIELDS[_PER_STREAM[key]][1].parse if key in _PER_STREAM else None
        every = {n: values[""] for n in names if n != ref} if "" in values else {}
        out[key] = {n: parse(v, key) if parse else v for n, v in {**every, **values}.items() if n}
    both = sorted(set(options.invert) & set(options.not_inverted))
    if both:
        raise ConfigError(f"stream {both[0]!r} is both inverted and not inverted", "not_inverted",
                          "keep one of the two")
    if options.options.solver.scale != 1.0:
        raise ConfigError("scale is of one pair's stream b, not of a rig's streams", "scale",
                          "give a rig stream's scale by name (scales / ⟦scale=NAME=VALUE⟧)")
    return out


def check_prior(names: list[str], options: Options) -> None:
    """Refuse, before the work, a rig prior (``prior``: a nominal of the sensors, frames named as the streams)
    that names not every sensor (a rig of two may use a nominal of one transform under other names)."""
    if options.solver.prior is None:
        return
    from .verdicts import check_sensor_names

    try:
        check_sensor_names(names, read_nominal(options.solver.prior))
    except HandEyeError as e:                     # name the option that chose the file
        fix = (e.fix or "check the file").replace("⟦against⟧", "⟦prior⟧")
        raise type(e)(e.what, e.where.replace("⟦against⟧", "⟦prior⟧"),
                      fix if "⟦prior⟧" in fix else f"{fix}, or another ⟦prior⟧") from None


def _check(names: list[str], options: RigOptions) -> int:
    if len(names) < 2:
        raise ConfigError(f"{len(names)} stream(s) given", "streams", "name at least two streams (⟦streams⟧ NAME=…)")
    if len(set(names)) != len(names):
        raise ConfigError("stream names repeat", ", ".join(names), "give every ⟦streams⟧ a different NAME")
    if not options.block_s > 0:
        raise ConfigError(f"bad block length {options.block_s!r}", "block_s", "give a number of seconds > 0")
    if options.reference is not None and options.reference not in names:
        raise ConfigError(f"unknown reference {options.reference!r}", "reference", f"use one of {', '.join(names)}")
    return 0 if options.reference is None else names.index(options.reference)


def _scaled(streams: list[PoseStream], names: list[str], ref: int, scales: Mapping[str, float | str],
            offsets: list[ClockOffset], cfg: Options) -> tuple[list[PoseStream], dict[str, Any]]:
    """The streams with their translations in metres: a given scale applied, an ``auto`` one estimated (with
    calibrate's ``scale='auto'``) on the pair of that stream with the reference (the reference's against the
    first other stream). Returns the streams and, per scaled stream, what was applied."""
    out, report = list(streams), {}
    for name, value in scales.items():
        k = names.index(name)
        if value == "auto":
            j = ref if k != ref else next(i for i in range(len(streams)) if i != k)
            pair = Options.from_flat(cfg, scale="auto", bootstrap=0, prior=None,
                                     time_offset=(offsets[k].offset_ns - offsets[j].offset_ns) / 1e9)
            est = calibrate_read(streams[j], streams[k], pair, scale_by_fit=False).diagnostics.scale
            assert est is not None, "scale='auto' estimates the scale"
            value = est.scale
            report[name] = {"value": value, "std": est.scale_std, "estimated_against": names[j]}
        else:
            report[name] = {"value": float(value)}
        out[k] = out[k].scaled(float(value))
    return out, report


def _prior_kept(correction: Correction, edge: Edge) -> Correction:
    """A pair's drift correction without its part along the translation the pair's motion leaves open (along the
    common rotation axis ``axis_a`` of frame j, e.g. z of planar motion) where the pair took it from the prior:
    there the data say nothing, and the prior's value stands."""
    sub = edge.calibration.diagnostics.subspace
    if sub is None or sub.axis_a is None or not any(d.status == FROM_PRIOR and d.name in DOF_NAMES[:3]
                                                     for d in sub.dofs):
        return correction
    bias = correction.bias.copy()
    bias[3:] -= (bias[3:] @ sub.axis_a) * sub.axis_a
    return replace(correction, bias=bias)


def _motions(edges: list[Edge], offsets: list[ClockOffset]) -> list[Motions]:
    """Per edge: motions, their start stamps in the reference's clock [ns], pair weights and α."""
    out: list[Motions] = []
    for e in edges:
        p, w = e.calibration.pairs, e.calibration.weights
        out.append((p.A, p.B, p.t_i_ns - offsets[e.j].offset_ns, np.ones(len(p)) if w is None else w,
                    e.calibration.solution.alpha))
    return out


def _raw_stamps(streams: list[PoseStream], offsets: list[ClockOffset], e: Edge
                ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The raw stamps of edge e's streams in its own clock (stream j's): k's shifted by the pair's offset."""
    return streams[e.j].stamps_ns, streams[e.k].stamps_ns - (offsets[e.k].offset_ns - offsets[e.j].offset_ns)


def _consistency_warnings(cons: Consistency, names: list[str], reference: int) -> list[str]:
    """What the χ² test found, and what to check (empty when the rig is consistent)."""
    if not cons.inconsistent:
        return []
    rig = (f"the pairwise estimates disagree more than the streams' noise allows: χ² {cons.statistic:.4g} on "
           f"{cons.dof} degrees of freedom (p = {cons.p_value:.2g} < {CONSISTENCY_P_VALUE:g})")
    s = cons.suspect
    if s is None:
        return [f"{rig}, and no single stream explains it; check every stream's clock offset (⟦time_offset⟧), "
                "inversion (⟦invert⟧) and scale, whether a mount is loose, and whether an odometry drifts "
                "other than at a constant rate"]
    name = names[s]
    role = (f"; it is the reference, so every T_{name}_k rests on its pairs: choose another (⟦reference=NAME⟧)"
            if s == reference else ", so its pairs inform no other sensor")
    return [f"stream {name} is inconsistent with the others: {rig}; without {name}'s pairs it falls by "
            f"{cons.reductions[s]:.4g} on {cons.reduction_dof[s]} (p = {cons.reduction_p[s]:.2g}){role}. Check "
            f"{name}'s scale (monocular odometry?), its clock offset (⟦time_offset='{name}=auto'⟧), its inversion "
            f"(⟦invert⟧ {name}), and its mount: a loose mount changes the extrinsic mid-log (calibrate the log's "
            "halves apart and compare)"]


def calibrate_rig(streams: Mapping[str, PoseStream], options: RigOptions | None = None, *,
                  inputs: dict[str, Any] | None = None) -> RigResult:
    """Calibrate every ``T_ref_k`` of a rig from its pose streams ``{name: T_wk_k(t)}`` (in order;
    the first is the reference unless ``options.reference`` names another). Raises HandEyeError
    when a sensor cannot be calibrated against any other."""
    opts = options or RigOptions()
    names = list(streams)
    for name, stream in streams.items():
        check_samples(stream, f"stream {name!r}")
    n, ref = len(names), _check(names, opts)
    given = per_stream(opts, names)
    check_prior(names, opts.options)
    cfg = opts.options
    inverted = [name in opts.invert for name in names]
    used = [s.inverted() if inv else s for s, inv in zip(streams.values(), inverted, strict=True)]
    offsets = clock_offsets(used, ref, {names.index(k): v for k, v in given["time_offsets"].items()}, cfg)
    used, scales = _scaled(used, names, ref, given["scales"], offsets, cfg)
    chosen = [name in opts.invert or name in opts.not_inverted for name in names]
    edges, warnings = solve_edges(used, names, offsets, cfg, chosen, ref)
    warnings = [f"{names[k]}: time offset: {w}" for k, o in enumerate(offsets) for w in o.warnings] + warnings
    if not edges:
        raise DataError("no pair of streams could be calibrated", ", ".join(names), "see the warnings above")
    pairs = [(e.j, e.k) for e in edges]
    closures = loop_closures(n, {p: e.matrix for p, e in zip(pairs, edges, strict=True)})
    noise = [edge_noise(e, _raw_stamps(used, offsets, e)) for e in edges]
    variances = stream_variances(n, pairs, noise)
    corrections = [_prior_kept(c, e) for c, e in zip(drift_corrections(pairs, noise, variances), edges, strict=True)]
    steps = np.stack([c.step for c in corrections])
    X = steps @ np.stack([e.matrix for e in edges])
    problem = JointProblem(n, ref, pairs, X, edge_covariance(pairs, noise, variances, corrections),
                           np.stack([e.forms for e in edges]), steps, bias_bound(corrections))
    rot_std = problem.edge_std()[:, 0]
    T0 = synchronise(n, pairs, X, np.square(rot_std.min() / np.maximum(rot_std, 1e-300)), ref)
    cons = consistency(problem, T0)
    warnings += _consistency_warnings(cons, names, ref)
    if cons.suspect is not None:
        problem = replace(problem, excluded=cons.suspect)
    T, covariances = refine(problem, T0)
    joint = loop_closures(n, {p: Xj for p, Xj in zip(pairs, problem.relative(T), strict=True)})
    unc = None
    if cfg.analysis.bootstrap > 0:
        unc = bootstrap_rig(problem, T, _motions(edges, offsets), cfg.analysis.bootstrap,
                            block_s=opts.block_s, seed=cfg.pairs.seed)
    settings = {"reference": names[ref], "time_offsets": given["time_offsets"], "invert": list(opts.invert),
                "not_inverted": list(opts.not_inverted), "wxyz": given["wxyz"], "scales": scales,
                "block_seconds": opts.block_s, "options": cfg.flat()}
    return RigResult(names, ref, used, inverted, offsets, edges, corrections, problem, T0, T, closures, joint, cons,
                     variances, covariances, unc, warnings, dict(inputs or {}), settings)


def calibrate_rig_files(log: str | None, specs: Sequence[str | StreamSpec], options: RigOptions | None = None, *,
                        quiet: bool = True) -> RigResult:
    """Read the streams (:func:`read_rig`) and :func:`calibrate_rig`. ``specs``: named :class:`StreamSpec`\\ s or
    their command-line form (``"cam0=/cam0/pose"``, ``"imu=tf:odom,imu_link"``, ``"wheels=wheels.tum"``,
    :func:`parse_stream`)."""
    opts = options or RigOptions()
    read = opts.options.read
    named = [parse_stream(s) if isinstance(s, str) else s for s in specs]
    from ..io.remote import session_of

    names = [s.name or "" for s in named]
    check_prior(names, opts.options)                          # a bad prior fails before the read
    with session_of(read) as remote:
        streams = read_rig(log, named, opts.options, quiet=quiet,
                           wxyz=per_stream(opts, names)["wxyz"] if len(set(names)) == len(names) >= 2 else {})
    inputs: dict[str, Any] = {"log": log, "streams": {s.name: s.describe() for s in named},
                              "time_source": read.time_source}
    if remote.urls:
        inputs["bytes_fetched"] = remote.bytes_fetched      # [B] read from object storage (URL inputs)
    return calibrate_rig(streams, opts, inputs=inputs)
