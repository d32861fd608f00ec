"""The calibration pipeline: two pose streams → time offset → sync → gates → pairs → solve → analysis.

:func:`calibrate_files` reads two streams from logs or text files and calibrates; :func:`calibrate`
does the same on streams already in memory. The extrinsic is ``T_a_b``: the pose of sensor b's
frame in sensor a's frame (maps points from b to a), where each stream holds ``T_world_sensor(t)``.
Options are the typed :class:`~handeye_cli.options.Options`; keyword arguments use the same flat
names as the command line.

Examples
--------
>>> import handeye_cli
>>> cal = handeye_cli.calibrate_files("sample_data/rig_a.tum", "sample_data/rig_b.tum", method="dqopt")
>>> cal.matrix.shape, cal.options.solver.method
((4, 4), 'dqopt')
"""
from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from .analysis import (
    BootstrapResult,
    Residuals,
    RobustResult,
    assess_observability,
    bootstrap,
    pair_residuals,
    robust_solve,
)
from .analysis.alpha import TIME_BLOCKS, noise_model_alpha, time_blocks
from .analysis.covariance import drift_check
from .analysis.diagnosis import data_warning, too_few_pairs
from .analysis.fit_test import FitTest, fit_test, sample_noise
from .analysis.inversion import InversionVerdict, check_inversion
from .analysis.observability import Observability
from .analysis.readings import (
    OrderChoice,
    OrderContradiction,
    choose_quaternion_order,
    contradicted_order,
    median_fit,
    scale_reading,
    spread_pairs,
)
from .analysis.selection import Selection, select_pairs
from .analysis.stream_noise import StreamNoise, stream_noise
from .analysis.subspace import ESTIMATED, Subspace, observable_subspace
from .analysis.verdict import Judged
from .config import load_options
from .errors import ConfigError, DataError, FitRejectedError, HandEyeError
from .geometry import se3
from .io.nominal import read_nominal
from .io.spec import StreamSpec, stream_source
from .options import FIELDS, Options, ReadOptions
from .solvers import Prior, Solution, solve
from .solvers.scale import drift_warning, scale_translations, solve_with_scale
from .stages.counts import SampleCounts
from .stages.gates import sync_and_gate
from .stages.pairs import Pairs, make_pairs
from .stages.stations import Stations, detect_stations
from .stages.sync import Synced, default_max_dt_ns, median_step_ns
from .streams import PoseStream

__all__ = ["Calibration", "Checks", "Diagnostics", "StreamSpec", "Uncertainty", "calibrate", "calibrate_files",
           "calibrate_read", "check_samples", "inverted_as_read", "read_streams", "refuse_unread", "stream_specs"]


@dataclass(frozen=True)
class Checks:
    """Which of :func:`calibrate_read`'s checks after the solve run (every one by default, as ``calibrate`` runs
    them). A rig skips those its own analysis replaces (:mod:`handeye_cli.rig.pairwise`).

    inversion: the inversion check (a stream recorded as ``T_sensor_world``).
    uncertainty: the uncertainty check (σ from blocks of time beside σ from independent samples: drift).
    """

    inversion: bool = True
    uncertainty: bool = True


@dataclass(frozen=True, eq=False)
class Uncertainty:
    """The 1σ spread of an extrinsic ``T_a_b``: ``rotation_std_deg`` (3,) [deg] about the axes of frame a,
    ``translation_std_m`` (3,) [m] along them; ``method``: ``"bootstrap"`` or ``"covariance"``."""

    rotation_std_deg: np.ndarray
    translation_std_m: np.ndarray
    method: str


@dataclass(frozen=True, eq=False)
class Diagnostics(Mapping[str, Any]):
    """What the analyses of one calibration found, built once when it ends and read-only after.

    The typed results that code reads back: ``fit`` (the fit test), ``observability`` (degenerate motion, the
    predicted covariance), ``subspace`` (each degree of freedom: estimated, from the prior or unobservable) and
    ``selection`` (the ``auto`` pairs' noise model; None for another strategy); ``poor_fit_accepted``: a refusal —
    the fit test's (the residuals, or a mount that moved between stations: the document's ``fit_test.passed``
    false), the inversion check's or a given quaternion order's contradiction — that ``accept_poor_fit``
    overrode, keeping the result (``handeye calibrate`` exits 3). As a read-only mapping it is the
    result document's diagnostic sections in order (``time_offset``, ``interpretation``, ``noise_model``,
    ``observability``, ``degrees_of_freedom``, ``residuals``, ``fit_test`` …: JSON-ready values, the keys of
    docs/reference/result-schema.md), so ``calibration.diagnostics["fit_test"]`` reads as the file does."""

    sections: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    fit: FitTest | None = None
    observability: Observability | None = None
    subspace: Subspace | None = None
    selection: Selection | None = None
    poor_fit_accepted: bool = False

    def __getitem__(self, key: str) -> Any:
        return self.sections[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.sections)

    def __len__(self) -> int:
        return len(self.sections)


@dataclass(frozen=True, eq=False)
class Calibration:
    """Everything a calibration produced.

    solution: the solver's result (``solution.matrix`` is ``T_a_b``).
    stream_a, stream_b: the streams as used (after inversion, before the time offset).
    synced: the samples that passed sync and gates; pairs: the motions solved.
    samples: what each stage read, kept and dropped; options: the options used.
    warnings: human-readable warnings; diagnostics: what the analyses found (:class:`Diagnostics`: typed,
    and the result's diagnostic keys: time offset, residuals…);
    inputs: what was read; residuals: per-pair residuals at the solution; weights: per-pair
    weights used (inlier mask with ``robust``, else None); robust, bootstrap: those analyses.
    """

    solution: Solution
    stream_a: PoseStream
    stream_b: PoseStream
    synced: Synced
    pairs: Pairs
    samples: SampleCounts
    options: Options
    residuals: Residuals
    warnings: list[str] = field(default_factory=list)
    diagnostics: Diagnostics = field(default_factory=Diagnostics)
    inputs: dict[str, Any] = field(default_factory=dict)
    weights: np.ndarray | None = None
    robust: RobustResult | None = None
    bootstrap: BootstrapResult | None = None
    config_file: str | None = None
    preset: str | None = None

    @property
    def matrix(self) -> np.ndarray:
        """``T_a_b`` (4x4)."""
        return self.solution.matrix

    @property
    def translation(self) -> np.ndarray:
        """Translation of ``T_a_b`` [m]: b's origin in frame a."""
        return self.solution.translation

    @property
    def quaternion_xyzw(self) -> np.ndarray:
        """Rotation of ``T_a_b`` as a unit quaternion x, y, z, w (w ≥ 0)."""
        return self.solution.quaternion_xyzw

    @property
    def uncertainty(self) -> Uncertainty | None:
        """The 1σ spread of ``T_a_b`` per axis of frame a: the bootstrap's where it ran (``bootstrap=N``), else
        the noise model's predicted (sandwich) covariance; None where neither could be formed."""
        if self.bootstrap is not None:
            return Uncertainty(self.bootstrap.rotation_std_deg, self.bootstrap.translation_std_m, "bootstrap")
        obs = self.diagnostics.observability
        if obs is None or obs.covariance is None:
            return None
        return Uncertainty(np.asarray(obs.covariance.rotation_std_deg, dtype=float),
                           np.asarray(obs.covariance.translation_std_m, dtype=float), "covariance")

    def __repr__(self) -> str:
        """One line: frames, translation, rotation angle, method, pairs, fit test and certificate."""
        return f"Calibration({self._line()})"

    def _line(self) -> str:
        f, t = self.frames, self.translation
        fit = self.diagnostics.fit
        cert = self.solution.certificate
        return (f"T_{f['a']}_{f['b']}: t=[{t[0]:.4f}, {t[1]:.4f}, {t[2]:.4f}] m, "
                f"rotation {np.rad2deg(float(se3.rotation_angle(self.matrix))):.3f}°, {self.solution.method} on "
                f"{self.solution.pairs} pairs, fit ratio {float('nan') if fit is None else fit.ratio:.3g}"
                f"{'' if cert is None else ', certified' if cert.certified else ', NOT certified'}, "
                f"{len(self.warnings)} warning(s)")

    def _repr_html_(self) -> str:
        """A small table for notebooks: the extrinsic, its spread and the checks."""
        import html

        rows = [("T_a_b", html.escape(self._line()))]
        unc = self.uncertainty
        if unc is not None:
            rows.append((f"σ ({unc.method})", f"rotation {np.array2string(unc.rotation_std_deg, precision=3)} °, "
                                              f"translation {np.array2string(unc.translation_std_m, precision=4)} m"))
        rows += [("warning", html.escape(w)) for w in self.warnings]
        body = "".join(f"<tr><th style='text-align:left'>{k}</th><td>{v}</td></tr>" for k, v in rows)
        return f"<table>{body}</table>"

    @property
    def frames(self) -> dict[str, str]:
        """Names of frames a and b: ``name_a``/``name_b`` if given, else the streams' child frames
        (as valid tf2 frame ids: no leading '/')."""
        a, b = frame_names(self.options, self.stream_a, self.stream_b)
        return {"a": a, "b": b}

    def judged(self) -> Judged:
        """What a drift verdict reads of this calibration (``--against``), from its typed parts: ``T_a_b``, the
        frames' names and the streams' topics, the degrees of freedom not estimated and the bootstrap's
        intervals."""
        topics = tuple(spec.get("topic") if isinstance(spec := self.inputs.get(k), dict) else None for k in "ab")
        sub = self.diagnostics.subspace
        open_dofs = {} if sub is None else {d.name: (d.status, d.reason) for d in sub.dofs if d.status != ESTIMATED}
        boot = self.bootstrap
        return Judged(np.asarray(self.matrix, dtype=float), (self.frames["a"], self.frames["b"]),
                      (topics[0], topics[1]), open_dofs,
                      None if boot is None else (boot.rotation_interval_deg, boot.translation_interval_m))

    def bootstrap_deviations(self) -> np.ndarray | None:
        """(K, 6) bootstrap deviations of X: rotation vector [deg] (3), translation [m] (3)."""
        if self.bootstrap is None:
            return None
        deviations: np.ndarray = np.c_[self.bootstrap.rotation_deltas_deg,
                                       self.bootstrap.translations_m - self.matrix[:3, 3]]
        return deviations

    def with_origin(self, config_file: str | Path | None, preset: str | None) -> Calibration:
        """The same calibration, recording the config file and preset its options came from."""
        return replace(self, config_file=None if config_file is None else str(config_file), preset=preset)

    def settings(self) -> dict[str, Any]:
        """The settings that produced this result: every option after preset, file and flag
        merging, and where the non-default ones came from."""
        return {"config_file": self.config_file, "preset": self.preset, "options": self.options.flat()}


Source = str | Path | StreamSpec | PoseStream


def stream_specs(inputs: Sequence[Source], *, stream_a: str | StreamSpec | None = None,
                 stream_b: str | StreamSpec | None = None, topic_a: str | None = None, topic_b: str | None = None,
                 frames_a: str | Sequence[str] | None = None, frames_b: str | Sequence[str] | None = None
                 ) -> tuple[StreamSpec | PoseStream, StreamSpec | PoseStream]:
    """Streams a and b of one calibration, as ``handeye calibrate`` / ``compare`` and :func:`calibrate_files` name
    them: ``inputs`` (a log; or one file, :class:`StreamSpec` or in-memory ``PoseStream`` per stream, a then b)
    and each stream's source in the shared spelling (``stream_a``: ``/topic``, ``tf:PARENT,CHILD`` or ``FILE``, or
    its synonyms ``topic_a``, ``frames_a`` = (PARENT, CHILD); :func:`~handeye_cli.io.spec.stream_source` parses
    them). A topic or TF chain is read from the log (a: the first input, b: the last); a FILE is a stream of its
    own and takes no input; a stream named by neither is its input, whole."""
    sources = (stream_source("stream_a", stream_a, topic=topic_a, frames=frames_a),
               stream_source("stream_b", stream_b, topic=topic_b, frames=frames_b))
    own = [s is not None and s.path is not None for s in sources]
    shown = " ".join(map(str, inputs)) or "no input"
    if len(inputs) > 2 - sum(own):
        raise ConfigError(f"{len(inputs)} inputs given for {2 - sum(own)} stream(s) read from them", shown,
                          "pass one log, or one file per stream (a then b); a stream named as a FILE "
                          "(--stream-a FILE) takes none")
    if not inputs and not all(own):
        raise ConfigError("no input given", "inputs", "pass a log, or one pose file per stream (a then b), or name "
                          "both streams as files (--stream-a FILE --stream-b FILE)")
    if len(inputs) == 1 and not any(own) and not all(s is not None for s in sources):
        raise ConfigError("one input needs a topic or a TF chain for each stream", shown,
                          "add --stream-a/--stream-b /topic or tf:PARENT,CHILD (see 'handeye inspect "
                          f"{inputs[0]}'), or pass two pose files")
    specs: list[StreamSpec | PoseStream] = []
    for k, source in enumerate(sources):
        if source is not None and source.path is not None:
            specs.append(source)
            continue
        item = inputs[0] if k == 0 else inputs[-1]
        if not isinstance(item, str | Path | PoseStream | StreamSpec):
            raise ConfigError(f"cannot read a stream from {type(item).__name__}", "calibrate_files",
                              "give a file path, a StreamSpec or a PoseStream")
        if isinstance(item, PoseStream | StreamSpec):
            if source is not None:
                raise ConfigError("a topic or TF chain was given for a stream that is not a file",
                                  f"stream_{'ab'[k]}", "name a stream's source only with a log's path")
            specs.append(item)
        else:
            specs.append(StreamSpec(str(item)) if source is None else replace(source, path=str(item)))
    if sum(isinstance(s, StreamSpec) and s.path == "-" for s in specs) > 1:
        raise ConfigError("stdin ('-') can feed only one stream", shown, "pass the other as a file")
    return specs[0], specs[1]


def read_streams(specs: Sequence[StreamSpec | PoseStream], options: Options | None = None, *,
                 quiet: bool = True, quaternion_orders: Sequence[str] | None = None) -> list[PoseStream]:
    """The streams of ``specs`` (a PoseStream is taken as it is), as the files hold them: the one read path of
    calibrate, rig and batch. Each input is detected once and every stream of one log read in one pass
    (:func:`~handeye_cli.io.read_specs`); ``options.read`` sets the time source, CSV columns and time unit of
    every file, ``wxyz_a`` / ``wxyz_b`` the quaternion order of the first / second stream (a rig's others: the
    format's, open to the fit), or ``quaternion_orders`` per spec (``auto``, ``xyzw``, ``wxyz``: a rig's, by stream
    name). :func:`calibrate_read` inverts them where the options say so."""
    from .io import read_specs  # mcap/rosbags: import only when reading

    read = (options or Options()).read
    wxyz = (read.wxyz_a, read.wxyz_b)
    files = [(k, s) for k, s in enumerate(specs) if isinstance(s, StreamSpec)]
    orders = [quaternion_orders[k] if quaternion_orders else "auto" if k > 1 or wxyz[k] is None
              else "wxyz" if wxyz[k] else "xyzw" for k, _ in files]
    read_now = read_specs([s for _, s in files], time_source=read.time_source,
                          columns=dict(read.csv_columns) if read.csv_columns else None, quaternion_orders=orders,
                          time_unit=read.time_unit, quiet=quiet)
    streams = dict(zip((k for k, _ in files), read_now, strict=True))
    return [s if isinstance(s, PoseStream) else streams[k] for k, s in enumerate(specs)]


def inverted_as_read(a: PoseStream, b: PoseStream, read: ReadOptions) -> tuple[PoseStream, PoseStream]:
    """Streams a and b inverted where ``invert_a`` / ``invert_b`` say so (``T_sensor_world`` → ``T_world_sensor``):
    after the quaternion order is chosen, which re-reads a file's columns (:func:`calibrate_read`)."""
    return (a.inverted() if read.invert_a else a), (b.inverted() if read.invert_b else b)


# The read options that only a file reader applies: the streams each concerns (a: 0, b: 1) and how to do
# without it. An in-memory PoseStream is already parsed, so these are refused for it, not recorded as applied.
_FILE_ONLY: dict[str, tuple[tuple[int, ...], str]] = {
    **{f"wxyz_{s}": ((k,), f"a PoseStream's quat_xyzw is x-y-z-w by definition: reorder the array "
                           f"(q_wxyz[:, [1, 2, 3, 0]]) and leave wxyz_{s} unset") for k, s in enumerate("ab")},
    "time_unit": ((0, 1), "a PoseStream's stamps are int64 nanoseconds (PoseStream.from_seconds converts "
                          "seconds): leave time_unit unset"),
    "csv_columns": ((0, 1), "a PoseStream has no columns: leave csv_columns unset"),
    "time_source": ((0, 1), "a PoseStream's stamps are the ones it was built with: leave time_source unset, or "
                            "read the log with calibrate_files"),
    **{name: ((0, 1), f"in-memory PoseStreams are read from no URL: leave {name} unset")
       for name in ("storage_option", "remote_timeout", "remote_retries")},
}


def refuse_unread(read: ReadOptions, in_memory: tuple[bool, bool]) -> None:
    """Refuse a read option (keyword or configuration key) set away from its default where no file reader
    reads the stream it concerns: ``in_memory`` says which of a, b are PoseStreams."""
    for name, (sides, fix) in _FILE_ONLY.items():
        value = getattr(read, name)
        if value != FIELDS[name][2] and all(in_memory[k] for k in sides):
            which = f"stream {'ab'[sides[0]]} is an in-memory PoseStream" if len(sides) == 1 else \
                "both streams are in-memory PoseStreams"
            shown = "***" if FIELDS[name][1].secret else repr(value)       # a credential is not repeated
            raise ConfigError(f"{name}={shown} applies to reading a file, but {which}", name, fix)


def _quaternion_order(a: PoseStream, b: PoseStream, options: Options) -> tuple[PoseStream, PoseStream,
                                                                               OrderChoice | None]:
    """Text streams in the quaternion order that fits (:func:`~.analysis.readings.choose_quaternion_order`),
    compared at the given clock offset (0 when it is still to be estimated)."""
    offset = options.sync.time_offset
    return choose_quaternion_order(a, b, time_offset_ns=0 if offset == "auto" else int(round(float(offset) * 1e9)),
                                   max_dt_ns=options.sync.max_dt_ns, seed=options.pairs.seed)


def _time_offset(a: PoseStream, b: PoseStream, options: Options) -> tuple[int, dict[str, Any], list[str]]:
    """The offset [ns] b's clock is ahead of a's, its report, and warnings about it.

    ``auto`` (the default) estimates it wherever the data allow, among the offsets within ``max_time_offset``
    (``auto``: the shorter stream's span, :func:`~handeye_cli.stages.timeoffset.search_bound_ns`), and applies the
    estimate when it is significant against its own σ (:attr:`~handeye_cli.stages.timeoffset.TimeOffset.significant`)
    and the correlation is unambiguous; otherwise the offset is 0 and the report says why. A significant
    estimate that is ambiguous (a second correlation peak, a weak one) is not applied but warned about:
    the warning names the estimate and the flag that applies it. An applied offset the user must hear about
    (:func:`_large_offset_warning`) is a warning too. A fixed value is used as given.

    Raises DataError (one line naming ``--max-time-offset``) when the streams' spans overlap at no offset within
    the bound, and when no offset could be estimated for streams that do not overlap as stamped: at 0 nothing
    could be synchronised."""
    value = options.sync.time_offset
    if value != "auto":
        return int(round(float(value) * 1e9)), {"seconds": float(value), "method": "fixed"}, []
    from .stages.timeoffset import SIGNIFICANT_SIGMA, estimate_time_offset, overlap_offsets_ns

    lo, hi = overlap_offsets_ns(a, b) if len(a) and len(b) else (0, 0)
    try:
        est = estimate_time_offset(a, b, max_offset_s=options.sync.max_time_offset)
    except HandEyeError as e:                 # too short, too gappy or too little rotation to tell: none applied
        if not lo <= 0 <= hi:                 # ... and at 0 the streams share no time: nothing to fall back on
            if "do not overlap" in e.what:
                raise
            raise DataError(f"the two streams' stamps do not overlap and no clock offset could be estimated "
                            f"({e.what})", "time offset", "give the offset with --time-offset SECONDS, or widen "
                            "--max-time-offset") from None
        return 0, {"seconds": 0.0, "method": "not estimated", "applied": False, "reason": str(e)}, []
    applied = est.applicable
    report = {"seconds": est.offset_ns / 1e9 if applied else 0.0, "applied": applied,
              "estimated_seconds": est.offset_ns / 1e9, "std_seconds": est.std_ns / 1e9,
              "coarse_seconds": est.coarse_ns / 1e9, "correlation": est.correlation, "method": est.method,
              "significant_sigma": SIGNIFICANT_SIGMA}
    warnings = [f"a clock offset of {est.offset_ns / 1e9:.6g} ± {est.std_ns / 1e9:.2g} s was estimated but not "
                f"applied ({'; '.join(est.warnings)}): if it is right, pass --time-offset {est.offset_ns / 1e9:.6g}"
                ] if est.significant and est.warnings else []
    return (est.offset_ns if applied else 0), report, warnings


def _large_offset_warning(a: PoseStream, b: PoseStream, report: dict[str, Any]) -> str | None:
    """The warning an applied clock offset earns (after the fit confirmed it): one that makes streams overlap whose
    stamps did not, or one larger than ``LARGE_OFFSET_PERIODS`` median sample periods of the slower stream; it
    names the offset and its σ [s] and how to refuse it. None for an offset not applied, or a small one."""
    from .stages.timeoffset import LARGE_OFFSET_PERIODS, overlap_offsets_ns

    if not report.get("applied") or "std_seconds" not in report:
        return None
    offset_s = float(report["seconds"])
    lo, hi = overlap_offsets_ns(a, b)
    period_s = max(median_step_ns(a), median_step_ns(b)) / 1e9
    if lo <= 0 <= hi and abs(offset_s) <= LARGE_OFFSET_PERIODS * period_s:
        return None
    why = ("the streams' stamps did not overlap without it" if not lo <= 0 <= hi else
           f"more than {LARGE_OFFSET_PERIODS:g} sample periods of the slower stream ({period_s:.3g} s)")
    return (f"a clock offset of {offset_s:.6g} ± {float(report['std_seconds']):.2g} s was applied: {why}; pass "
            "--time-offset 0 if the clocks are known to agree")


_Paired = tuple[Synced, Pairs, SampleCounts, Stations | None, Selection | None]


def _confirmed_offset(a: PoseStream, b: PoseStream, options: Options, prior: Prior | None, report: dict[str, Any],
                      paired: _Paired) -> _Paired:
    """A significant clock-offset estimate is kept only when the fit confirms it: the pairs it gives must fit a
    rigid rig better (a median residual lower by ``CONFIRMING_MIN_GAIN``, neither higher by ``CONFIRMING_GAIN``)
    than the pairs without an offset; and where it leaves fewer than ``CONFIRMING_COVERAGE`` of the samples
    synchronised (an offset that is a large part of the recording), clearly better (by ``CONFIRMING_GAIN``), and
    only where the pairs without it misfit beyond their noise (:func:`_misfits`).
    It stands without a comparison when the streams do not pair without it (spans that do not overlap). An
    estimate the fit does not confirm (an alias of periodic motion on a short recording, an estimator's bias
    of a millisecond) is not applied: the report says so, with both fits, and the pairs without an offset
    are returned. ``paired`` is :func:`pairs_of` at the estimate;
    ``report`` is updated in place. The pairs without an offset are compared as the strides of the estimate's
    ``auto`` selection make them (like with like, and one selection, not two, where the offset is confirmed);
    a selection of their own is made only where they are returned."""
    from .stages.timeoffset import CONFIRMING_COVERAGE, CONFIRMING_GAIN, CONFIRMING_MIN_GAIN

    def without_offset() -> _Paired:
        return at_zero if paired[4] is None else pairs_of(a, b, options, 0, prior)

    try:
        at_zero = pairs_of(a, b, options, 0, prior, like=paired[4])
    except HandEyeError:
        report["confirmed_by"] = "no pairs without it"
        return paired
    est, zero = (median_fit(p[1].A, p[1].B) for p in (paired, at_zero))
    if est is None or zero is None:               # one of them does not determine X: the other stands
        report["confirmed_by"] = "fit" if zero is None else None
        if est is None:
            report.update(seconds=0.0, applied=False)
        return paired if zero is None else without_offset()
    gains = est.gains_over(zero)
    coverage = len(paired[0]) / max(len(at_zero[0]), 1)
    report["fit_median"] = {name: {"rotation_deg": f.rotation_deg, "translation_m": f.translation_m, "samples": n}
                            for name, f, n in (("applied", est, len(paired[0])), ("none", zero, len(at_zero[0])))}
    worse = min(gains) < 1 / CONFIRMING_GAIN
    needed = CONFIRMING_MIN_GAIN if coverage >= CONFIRMING_COVERAGE else CONFIRMING_GAIN
    dropping = coverage < CONFIRMING_COVERAGE              # ... must explain a misfit of the samples it drops
    if not worse and max(gains) >= needed and not (dropping and not _misfits(a, b, options, at_zero, zero.matrix)):
        report["confirmed_by"] = "fit"
        return paired
    report.update(seconds=0.0, applied=False, confirmed_by=None)
    return without_offset()


def _misfits(a: PoseStream, b: PoseStream, options: Options, paired: _Paired, X: np.ndarray) -> bool:
    """Whether the pairs of ``paired`` misfit ``X`` beyond what the streams' own noise predicts, by more than the
    gain an offset that drops samples must show (:func:`_confirmed_offset`): where they fit as their noise
    predicts, an offset has nothing to explain, and one that keeps fewer samples fitting them better is chance
    (a periodic arm capture's alias at -2.3 s kept 42 % of the samples, its residuals 0.75× the noise's, where
    without it every sample fit at 1.07×: applied, the extrinsic was 154° wrong)."""
    from .analysis.residuals import pair_residuals
    from .stages.timeoffset import CONFIRMING_GAIN

    synced, pairs, _, stations, _ = paired
    noise = sample_noise(a, b, synced, stations, options.sync.sync)
    test = fit_test(pairs, pair_residuals(pairs.A, pairs.B, X), X, noise)
    return test.ratio > CONFIRMING_GAIN


def frame_names(options: Options, stream_a: PoseStream, stream_b: PoseStream) -> tuple[str, str]:
    """Names of frames a and b: ``name_a``/``name_b`` if given, else the streams' child frames
    (as valid tf2 frame ids: no leading '/')."""
    out = options.output
    return (out.name_a or stream_a.child_frame_id.lstrip("/") or "a",
            out.name_b or stream_b.child_frame_id.lstrip("/") or "b")


def read_prior(options: Options, frames: tuple[str, str] | None = None) -> Prior | None:
    """The prior of the options (``prior``: any nominal :func:`~handeye_cli.io.nominal.read_nominal`
    reads, the transform between ``frames`` (a, b); ``prior_weights``: paper eq 26), or None."""
    s = options.solver
    if s.prior is None:
        return None
    try:
        T = read_nominal(s.prior).transform(*(frames or (None, None)))
    except HandEyeError as e:                 # name the flag that chose the file
        fix = e.fix.replace("--against", "--prior") if e.fix else "check --prior"
        raise type(e)(e.what, e.where, fix if "--prior" in fix else f"{fix} given with --prior") from None
    return Prior(T, *s.prior_weights)


def pairs_of(stream_a: PoseStream, stream_b: PoseStream, options: Options, offset_ns: int,
             prior: Prior | None, like: Selection | None = None
             ) -> tuple[Synced, Pairs, SampleCounts, Stations | None, Selection | None]:
    """Sync, gates and pair formation: (kept samples, pairs, counts of every stage, stations, and for
    the ``auto`` strategy the selection: weights, α and noise model). ``prior`` is the options'
    prior, read once by the caller (:func:`read_prior`). ``like``: for the ``auto`` strategy, the pairs of
    that selection's strides instead of a selection (None: no weights to solve with; a comparison's pairs).

    A station capture (see :mod:`~handeye_cli.stages.stations`) skips sync and the pose-jump gate:
    its averaged stations are the samples, paired all with all."""
    sync, gates, p = options.sync, options.gates, options.pairs
    stations = None if p.stations == "off" else detect_stations(
        stream_a, stream_b, time_offset_ns=offset_ns,
        max_dt_ns=default_max_dt_ns(0) if sync.max_dt_ns is None else sync.max_dt_ns)
    if stations is not None:
        kept, strategy = stations.synced, "all"
        stage_counts = [{"read_a": len(stream_a), "read_b": len(stream_b), "synced": len(stations),
                         "synced_kept": len(stations)}]
    else:
        kept, gate_counts = sync_and_gate(stream_a, stream_b, sync=sync.sync, max_dt_ns=sync.max_dt_ns,
                                          time_offset_ns=offset_ns, gate=gates.gate,
                                          max_translation_m=gates.max_jump, max_rotation_rad=gates.max_jump_rad,
                                          min_samples=options.solver.min_pairs + 1)
        strategy, stage_counts = p.pairs, [gate_counts]
    selection = None
    if strategy == "auto" and like is not None:
        pairs = like.on(kept, p.max_pairs)
        pair_counts = {"keyframes": len(kept), "candidate_pairs": len(pairs), "pairs": len(pairs)}
    elif strategy == "auto":
        selection = select_pairs(kept, max_pairs=p.max_pairs, method=options.solver.method, prior=prior)
        pairs, pair_counts = selection.pairs, selection.counts(len(kept))
    else:
        pairs, pair_counts = make_pairs(kept, strategy, keyframe_rotation_rad=np.deg2rad(p.keyframe_rotation),
                                        keyframe_translation_m=p.keyframe_translation,
                                        min_rotation_rad=np.deg2rad(p.min_rotation), max_pairs=p.max_pairs,
                                        seed=p.seed)
    samples = SampleCounts.of(*stage_counts, pair_counts, duplicates_dropped_a=stream_a.duplicates_dropped,
                              duplicates_dropped_b=stream_b.duplicates_dropped,
                              recovered_truncated_a=stream_a.recovered_truncated,
                              recovered_truncated_b=stream_b.recovered_truncated)
    if len(pairs) < options.solver.min_pairs:
        raise too_few_pairs(len(pairs), samples, options)
    return kept, pairs, samples, stations, selection


def _with_scale(stream_a: PoseStream, stream_b: PoseStream, paired: _Paired, options: Options,
                diagnostics: dict[str, Any], noise_of: Callable[[PoseStream], StreamNoise | None],
                given: float = 1.0) -> tuple[Synced, Pairs]:
    """``--scale auto``: estimate b's scale with T_a_b on ``paired`` (made of ``stream_b``, in metres per ``given``
    unit) and return b's samples and motions in metres. The translation noise of both streams (their jitter, as
    the fit test reads it) weighs the residuals against the errors in variables (:mod:`~.solvers.scale`). With a
    ``selection`` made on b already scaled by ``given``, its α is used and the scale refined; not its weights,
    which favour short drifting pairs whose translations are mostly noise and so bias the scale low
    (errors in variables: 0.433 ± 0.021 weighted against 0.491 ± 0.004 unweighted for kinhec's 0.5)."""
    kept, pairs, _, stations, selection = paired
    alpha = 1.0 if options.solver.alpha == "auto" else float(options.solver.alpha)
    if selection is not None and options.solver.alpha == "auto":
        alpha = selection.alpha
    noise = sample_noise(stream_a, stream_b, kept, stations, options.sync.sync, noise_of)
    est = solve_with_scale(pairs.A, pairs.B, alpha=alpha, samples=(pairs.i, pairs.j),
                           translation_noise=noise.translation_variances(pairs.i, pairs.j))
    diagnostics["scale"] = est.as_dict(given)
    return (replace(kept, xyz_b=kept.xyz_b * est.scale),
            replace(pairs, B=scale_translations(pairs.B, est.scale)))


def _checked_poses(kept: Synced, pairs: Pairs) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(T_a, T_b, i, j): the absolute poses of the samples of the pairs a reading's check compares on
    (:func:`~.analysis.readings.spread_pairs`: at most ``CHECKED_PAIRS``), and those pairs as indices into them,
    so that a check builds and re-reads a thousand poses, not every synced sample's."""
    i, j = spread_pairs(pairs.i, pairs.j)
    rows, at = np.unique(np.r_[i, j], return_inverse=True)
    used = kept.select(rows)
    return used.T_a, used.T_b, at[:len(i)], at[len(i):]


def _inversion(kept: Synced, pairs: Pairs, options: Options, alpha: float,
               inputs: dict[str, Any]) -> tuple[InversionVerdict | None, bool]:
    """The inversion check and whether ``accept_poor_fit`` overrode its refusal; raises the refusal when the
    evidence is overwhelming (unless ``accept_poor_fit``: then it is the first warning after the override's, and
    the result a poor fit accepted, exit 3). ``inputs`` (what was
    read) names a TF stream's frame pair, whose fix is naming the frames the other way round."""
    read = options.read

    def frames(key: str) -> tuple[str, str] | None:
        pair = inputs.get(key, {}).get("frames")
        return (str(pair[0]), str(pair[1])) if pair else None

    verdict = check_inversion(*_checked_poses(kept, pairs), alpha=alpha,
                              inverted_now=(bool(read.invert_a), bool(read.invert_b)),
                              frames=(frames("a"), frames("b")))
    refusal = verdict and verdict.refusal(read.invert_a is not None or read.invert_b is not None)
    if refusal and not options.analysis.accept_poor_fit:
        raise refusal
    return verdict, bool(refusal)


def _contradicted_order(stream_a: PoseStream, stream_b: PoseStream, kept: Synced, pairs: Pairs,
                        options: Options) -> OrderContradiction | None:
    """The check of each quaternion order that was given, not chosen by the fit (a log's fields, ``--wxyz-*`` /
    ``--no-wxyz-*``, a stream in memory: :func:`~.analysis.readings.contradicted_order`), on the solved pairs."""
    read = options.read
    orders = tuple(None if s.quaternion_order is not None else "wxyz" if w else "xyzw"
                   for s, w in ((stream_a, read.wxyz_a), (stream_b, read.wxyz_b)))
    return contradicted_order(*_checked_poses(kept, pairs), (orders[0], orders[1]),
                              inverted=(bool(read.invert_a), bool(read.invert_b)))


def _scaled(stream_a: PoseStream, stream_b: PoseStream, paired: _Paired, options: Options, offset_ns: int,
            prior: Prior | None, diagnostics: dict[str, Any],
            noise_of: Callable[[PoseStream], StreamNoise | None]) -> _Paired:
    """``--scale auto`` (and b's units found by the fit): b's scale estimated with ``T_a_b`` on ``paired``
    (:func:`pairs_of`'s); with the ``auto`` pair strategy the pairs, weights and α are then chosen again on b
    scaled by that estimate, and the scale refined on them. Returns the pairing in metres."""
    kept, pairs = _with_scale(stream_a, stream_b, paired, options, diagnostics, noise_of)
    _, _, samples, stations, selection = paired
    if selection is None:
        return kept, pairs, samples, stations, selection
    scale = float(diagnostics["scale"]["value"])
    scaled_b = stream_b.scaled(scale)
    paired = pairs_of(stream_a, scaled_b, options, offset_ns, prior)
    kept, pairs = _with_scale(stream_a, scaled_b, paired, options, diagnostics, noise_of, scale)
    return kept, pairs, *paired[2:]


def _scale_by_fit(stream_a: PoseStream, stream_b: PoseStream, paired: _Paired, X: np.ndarray, options: Options,
                  offset_ns: int, prior: Prior | None, diagnostics: dict[str, Any], warnings: list[str],
                  noise_of: Callable[[PoseStream], StreamNoise | None]
                  ) -> tuple[_Paired, tuple[Solution, float, np.ndarray | None, RobustResult | None]] | None:
    """b's translations in other units, found by the fit (:func:`~.analysis.readings.scale_reading` at the
    solution ``X`` of the pairs): decisively better scaled (monocular units), the scale is estimated with
    ``T_a_b`` as ``--scale auto`` does and the pairs re-solved — returned; noticeably better (a SLAM scale off by
    percents), a warning naming ``--scale auto``; else None. ``diagnostics`` and ``warnings`` are filled in."""
    pairs = paired[1]
    reading = scale_reading(pairs.A, pairs.B, X)
    if reading is None or not (reading.decisive or reading.noticeable):
        return None
    diagnostics.setdefault("interpretation", {})["scale"] = {**reading.as_dict(), "applied": reading.decisive}
    if not reading.decisive:
        warnings.insert(0, f"stream b's translations fit {reading.gain:.3g}× better scaled by {reading.scale:.4g} "
                           f"(median residual {reading.medians_m[0]:.3g} → {reading.medians_m[1]:.3g} m): if its "
                           "scale is off (SLAM), pass --scale auto")
        return None
    paired = _scaled(stream_a, stream_b, paired, options, offset_ns, prior, diagnostics, noise_of)
    solved = _solve_and_analyse(paired[1], options, prior, paired[4], diagnostics)
    warnings.insert(0, f"stream b's translations fit a rigid rig {reading.gain:.3g}× better scaled (median residual "
                       f"{reading.medians_m[0]:.3g} m as given): its scale was estimated with T_a_b, "
                       f"{diagnostics['scale']['value']:.6g} ± {diagnostics['scale']['std']:.2g} m per unit "
                       "(--scale auto); give it with --scale NUMBER to fix it")
    return paired, solved


def _solve_and_analyse(pairs: Pairs, options: Options, prior: Prior | None, selection: Selection | None,
                       diagnostics: dict[str, Any]) -> tuple[Solution, float, np.ndarray | None, RobustResult | None]:
    """[robust: RANSAC inliers] → [α auto] → the weighted solve; diagnostics filled in place.

    With the ``auto`` strategy the pairs carry the noise model's weights, and α auto is its ML α."""
    A, B, solver = pairs.A, pairs.B, options.solver
    auto = solver.alpha == "auto"
    alpha = (selection.alpha if selection else 1.0) if auto else float(solver.alpha)
    weights = None if selection is None else selection.weights
    robust = None
    if options.analysis.robust:
        robust = robust_solve(A, B, method=solver.method, alpha=alpha, prior=prior, seed=options.pairs.seed)
        weights = robust.inliers.astype(float) * (1.0 if weights is None else weights)
        t0 = min(pairs.t_i_ns.min(), pairs.t_j_ns.min())    # readable: seconds since the first paired sample
        diagnostics["robust"] = {**robust.as_dict(), "rejected_spans_since_start_s": [
            [round((pairs.t_i_ns[k] - t0) / 1e9, 6), round((pairs.t_j_ns[k] - t0) / 1e9, 6)] for k in robust.rejected]}
    if selection is not None:
        diagnostics["noise_model"] = selection.as_dict()
    if auto and selection is None:
        choice = noise_model_alpha(A, B, prior=prior, weights=weights, spans_s=(pairs.t_j_ns - pairs.t_i_ns) / 1e9)
        alpha = choice.alpha
        diagnostics["alpha_auto"] = choice.as_dict()
    elif auto:
        diagnostics["alpha_auto"] = {"alpha": alpha, "method": "noise-model"}
    return solve(A, B, method=solver.method, alpha=alpha, prior=prior, weights=weights), alpha, weights, robust


def calibrate(stream_a: PoseStream, stream_b: PoseStream, options: Options | None = None, *,
              inputs: dict[str, Any] | None = None, **overrides: Any) -> Calibration:
    """Calibrate ``T_a_b`` from two pose streams ``T_wa_a(t)``, ``T_wb_b(t)`` (int64 ns stamps,
    positions [m], quaternions x-y-z-w). ``options`` (default: the defaults), updated by
    ``overrides`` given by flat option name (``method="dqopt"``, ``gate="off"``…). Raises a
    :class:`~handeye_cli.errors.HandEyeError` subclass on data that cannot be calibrated.

    Every option acts as in :func:`calibrate_files` given the same poses in files: ``invert_a`` /
    ``invert_b`` invert the streams first; the options only a file reader applies (``wxyz_a``,
    ``wxyz_b``, ``time_unit``, ``csv_columns``, ``time_source``) are refused with a
    :class:`~handeye_cli.errors.ConfigError` when set, since a PoseStream is already parsed.
    """
    opts = Options.from_flat(options, **overrides) if overrides else (options or Options())
    refuse_unread(opts.read, (True, True))
    return calibrate_read(stream_a, stream_b, opts, inputs={**(inputs or {}), **_inversion_inputs(opts.read)})


def _inversion_inputs(read: ReadOptions) -> dict[str, bool]:
    """The result's ``inputs`` record of the streams inverted before use."""
    return {key: True for key in ("invert_a", "invert_b") if getattr(read, key)}


def check_samples(stream: PoseStream, label: str) -> None:
    """A stream built in memory whose samples hold a NaN or infinite value or a zero-norm quaternion is
    refused naming the first as the user indexes the arrays (``label``, e.g. ``stream b``, then ``sample 10``,
    0-based), not as a
    motion later (``motions_b[401]``). Streams read from files have such samples dropped already
    (with a warning), so this is quiet for them."""
    quat = stream.quat_xyzw
    bad = ~(np.isfinite(stream.xyz).all(axis=1) & np.isfinite(quat).all(axis=1)) | ~(np.abs(quat) > 0).any(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise DataError(f"{label}, sample {k} (0-based: xyz[{k}] {stream.xyz[k].tolist()}, quat_xyzw[{k}] "
                        f"{quat[k].tolist()}) has a NaN or infinite value or a zero-norm quaternion; "
                        f"{int(bad.sum())} such sample(s) in all", stream.source or label,
                        "remove or repair those samples (a file's are dropped with a warning)")


def calibrate_read(stream_a: PoseStream, stream_b: PoseStream, opts: Options, *,
                   inputs: dict[str, Any] | None = None, scale_by_fit: bool = True,
                   noise_of: Callable[[PoseStream], StreamNoise | None] = stream_noise,
                   checks: Checks = Checks()) -> Calibration:
    """:func:`calibrate` streams as a reader produced them with ``opts.read`` (parsed, not yet inverted: the
    file-only read options are recorded in the settings, not applied again), e.g. by :func:`read_streams`
    or a rig's reader (which inverts its streams itself and sets no ``invert_a``/``invert_b``).

    Order: [fixed scale of b] → quaternion order of text files (by the fit) → inversion (``invert_a`` /
    ``invert_b``) → time offset → stations, or sync → gates → pairs → [scale auto] →
    [robust] → [α auto] → weighted solve → observability warnings, residuals, inversion check
    (first warning; refuses the result when overwhelming) → fit test (refuses residuals far beyond
    the streams' own noise unless ``accept_poor_fit``; see :mod:`~handeye_cli.analysis.fit_test`)
    → [bootstrap]. After the solve, b's translations found in other units by the fit are estimated with
    ``T_a_b`` (``scale_by_fit``; ``handeye rig`` passes False: its consistency test names such a stream).
    ``noise_of``: each stream's jitter for the fit test (a rig passes a memo: its streams are in several pairs).
    ``checks``: which checks after the solve run (:class:`Checks`; the fit test always does).
    """
    check_samples(stream_a, "stream a")
    check_samples(stream_b, "stream b")
    given = stream_a, stream_b                                 # as read: what a second reading starts from
    if opts.solver.scale not in (1.0, "auto"):
        stream_b = stream_b.scaled(float(opts.solver.scale))
    stream_a, stream_b, order = _quaternion_order(stream_a, stream_b, opts)
    stream_a, stream_b = inverted_as_read(stream_a, stream_b, opts.read)
    offset_ns, offset_report, offset_warnings = _time_offset(stream_a, stream_b, opts)
    warnings = [*stream_a.warnings, *stream_b.warnings, *offset_warnings]       # readers' warnings name their file
    if order is not None and order.chosen_by == "fit":
        warnings.insert(0, order.message(stream_a, stream_b))
    prior = read_prior(opts, frame_names(opts, stream_a, stream_b))       # the prior file is read once
    kept, pairs, samples, stations, selection = pairs_of(stream_a, stream_b, opts, offset_ns, prior)
    if offset_report.get("applied"):
        kept, pairs, samples, stations, selection = _confirmed_offset(
            stream_a, stream_b, opts, prior, offset_report, (kept, pairs, samples, stations, selection))
        offset_ns = int(round(offset_report["seconds"] * 1e9))
        large = _large_offset_warning(stream_a, stream_b, offset_report)
        if large:
            warnings.append(large)
    diagnostics: dict[str, Any] = {"time_offset": offset_report}
    if order is not None:
        diagnostics["interpretation"] = order.as_dict()
    if stations is not None:
        diagnostics["stations"] = stations.as_dict()
    else:
        diagnostics["sync"] = kept.describe()
    if opts.solver.scale == "auto":
        kept, pairs, samples, stations, selection = _scaled(stream_a, stream_b, (kept, pairs, samples, stations,
                                                            selection), opts, offset_ns, prior, diagnostics,
                                                            noise_of)
    solution, alpha, weights, robust = _solve_and_analyse(pairs, opts, prior, selection, diagnostics)
    verdict, inversion_overridden = (None, False) if not checks.inversion else _inversion(
        kept, pairs, opts, 1.0 if opts.solver.alpha == "auto" else alpha, inputs or {})   # thresholds set at α 1
    contradiction = None if verdict is not None else _contradicted_order(stream_a, stream_b, kept, pairs, opts)
    if contradiction is not None:
        if not opts.analysis.accept_poor_fit:
            raise contradiction.refusal()
        diagnostics["interpretation"] = {**diagnostics.get("interpretation", {}), **contradiction.as_dict()}
    if verdict is not None:
        diagnostics["inversion"] = verdict.as_dict()
    elif scale_by_fit and opts.solver.scale == 1.0 and prior is None:   # inverted streams also fit "better scaled"
        scaled = _scale_by_fit(stream_a, stream_b, (kept, pairs, samples, stations, selection), solution.matrix,
                               opts, offset_ns, prior, diagnostics, warnings, noise_of)
        if scaled is not None:
            (kept, pairs, samples, stations, selection), (solution, alpha, weights, robust) = scaled
    drifting = drift_warning(diagnostics.get("scale", {}))
    if drifting:
        warnings.append(drifting)
    A, B, ij = pairs.A, pairs.B, (pairs.i, pairs.j)
    if prior is not None:                                     # the prior only where the data leave something open
        free = _solve_and_analyse(pairs, opts, None, selection, {})
        free_obs = assess_observability(A, B, free[0].matrix, alpha=free[1], weights=free[2], samples=ij)
        if free_obs.ok:
            (solution, alpha, weights, robust), prior = free, None
            diagnostics["prior"] = "not used: the motion determines every degree of freedom"
    obs = assess_observability(A, B, solution.matrix, alpha=alpha, prior=prior, weights=weights, samples=ij)
    warnings += [str(w) for w in obs.warnings]
    warnings += solution.warnings                             # a failed optimality certificate
    diagnostics["observability"] = obs.as_dict()
    subspace = observable_subspace(A, B, solution.matrix, obs, weights=weights,
                                   nominal=None if prior is None else prior.T_a_b)
    if subspace.axis_a is not None:                           # planar: the reduced in-plane solve
        solution = replace(solution, matrix=subspace.matrix, problem=None, dual_quaternion=None,
                           full_solve=solution)              # its certificate: of the full solve (cost 8)
        warnings += [f"not estimated: {k} ({v})" for k, v in subspace.skipped.items()] + list(subspace.advice)
    diagnostics["degrees_of_freedom"] = subspace.as_dict()
    if checks.uncertainty and len(A) > 2 * TIME_BLOCKS:      # σ from independent samples beside σ from blocks (drift)
        check = drift_check(A, B, solution.matrix, time_blocks(pairs.t_i_ns, pairs.t_j_ns), alpha=alpha,
                            prior=prior, weights=weights, samples=ij)
        diagnostics["uncertainty_check"] = check.as_dict()
        if check.overconfident:
            warnings.append(check.warning())
    res = pair_residuals(A, B, solution.matrix)
    diagnostics["residuals"] = res.summary(None if weights is None else weights > 0).as_dict()
    scale = diagnostics.get("scale", {}).get("value")        # b's jitter in metres, as its samples now are
    metric_b = stream_b if scale is None else stream_b.scaled(scale)
    noise = sample_noise(stream_a, metric_b, kept, stations, opts.sync.sync, noise_of)
    fit = fit_test(pairs, res, solution.matrix, noise, mask=None if weights is None else weights > 0)   # refuses
    diagnostics["fit_test"] = fit.as_dict()                                         # what no rigid rig gives
    rejected = fit.refusal(opts, stations is not None, inverted=verdict is not None)
    if rejected and not opts.analysis.accept_poor_fit:
        recovered = _robust_retry(*given, opts, inputs, scale_by_fit, fit.summary(), noise_of, checks)
        if recovered is None:
            raise rejected
        return recovered
    moved = None if rejected or stations is None or opts.analysis.robust else _moved(kept, pairs, res, opts, alpha,
                                                                                     prior)
    if moved and not opts.analysis.accept_poor_fit:             # a mount that slipped between two stations
        raise moved
    suspect = verdict.message() if verdict else data_warning(res, weights, samples)
    if suspect:
        warnings.insert(0, suspect)
    if moved:                                                   # kept on request: the fit test failed, exit 3
        diagnostics["fit_test"] = {**diagnostics["fit_test"], "passed": False, "extrinsic_changed": moved.what}
        warnings.insert(0, f"poor fit accepted with --accept-poor-fit: {moved.what}")
    if rejected:
        warnings.insert(0, f"poor fit accepted with --accept-poor-fit: {fit.summary()}")
    if contradiction is not None:
        warnings.insert(0, f"poor fit accepted with --accept-poor-fit: {contradiction.message()}")
    boot = None
    if opts.analysis.bootstrap > 0:
        boot = bootstrap(A, B, opts.analysis.bootstrap, alpha=alpha, prior=prior, weights=weights,
                         samples=ij, seed=opts.pairs.seed,
                         estimate=solution.matrix if opts.solver.method == "dqopt" else None)   # the same solve
        diagnostics["uncertainty"] = {"method": "bootstrap over pose samples", **boot.as_dict()}
    found = Diagnostics(MappingProxyType(diagnostics), fit=fit, observability=obs, subspace=subspace,
                        selection=selection,
                        poor_fit_accepted=bool(rejected or moved or contradiction or inversion_overridden))
    return Calibration(solution, stream_a, stream_b, kept, pairs, samples, opts, res, warnings=warnings,
                       diagnostics=found, inputs=dict(inputs or {}), weights=weights, robust=robust,
                       bootstrap=boot)


def _moved(kept: Synced, pairs: Pairs, res: Residuals, opts: Options, alpha: float,
           prior: Prior | None) -> FitRejectedError | None:
    """A station capture's refusal when the stations before one stamp fit another extrinsic than those after it
    (:func:`moved_during`; ``kept``: the stations, which ``pairs`` index): the fit test's noise of sparse stations
    is an assumed one, lenient enough that a mount slipping 10° / 5 cm between two stations passes it."""
    from .analysis.robust import moved_during

    found = moved_during(pairs.A, pairs.B, pairs.i, pairs.j, res, method=opts.solver.method, alpha=alpha,
                         prior=prior)
    if found is None:
        return None
    cut, gain = found
    when = (kept.stamps_ns[cut] - kept.stamps_ns[0]) / 1e9
    return FitRejectedError(f"the extrinsic changed during the capture: the stations from number {cut + 1} at "
                            f"{when:.1f} s since the first station on "
                            f"fit another T_a_b, and each part fits its own {gain:.3g}× better than one fits both",
                            "fit test", "check that the sensor is rigidly mounted and calibrate the stations before "
                            "and after apart; to keep this result anyway: --accept-poor-fit (exit code 3)")


def _robust_retry(stream_a: PoseStream, stream_b: PoseStream, opts: Options, inputs: dict[str, Any] | None,
                  scale_by_fit: bool, refused: str, noise_of: Callable[[PoseStream], StreamNoise | None],
                  checks: Checks) -> Calibration | None:
    """A fit the fit test refused (``refused``: its figures), solved again with outliers rejected, as ``--robust``
    does (RANSAC on minimal sets, then the weighted optimal solve on the inliers): kept, with the settings saying
    ``robust`` and a first warning naming what was dropped, when at least ``RETRY_MIN_INLIERS`` of the samples
    agree with the consensus (``consensus_share``), no run of more than ``RETRY_MAX_RUN`` of them disagrees (a
    sensor that moved) and the inliers fit as clean data do (a fit-test ratio within ``RETRY_MAX_RATIO``); else
    None (the refusal stands). Not tried when ``robust`` was asked for already: a stream with a few bad poses (a
    station seen wrongly, a tracking glitch) gives a verified result, a wrong convention or streams that are not
    rigidly attached do not."""
    from .analysis.robust import (
        RETRY_MAX_RATIO,
        RETRY_MAX_RUN,
        RETRY_MIN_INLIERS,
        consensus_share,
        longest_disagreement,
    )

    if opts.analysis.robust:
        return None
    try:
        cal = calibrate_read(stream_a, stream_b, replace(opts, analysis=replace(opts.analysis, robust=True)),
                             inputs=inputs, scale_by_fit=scale_by_fit, noise_of=noise_of, checks=checks)
    except HandEyeError:
        return None
    if (cal.robust is None or consensus_share(cal.robust.inliers, cal.pairs.i, cal.pairs.j) < RETRY_MIN_INLIERS
            or longest_disagreement(cal.robust.inliers, cal.pairs.i, cal.pairs.j) > RETRY_MAX_RUN
            or cal.diagnostics.fit is None or not cal.diagnostics.fit.ratio <= RETRY_MAX_RATIO):
        return None
    n, kept = len(cal.robust.inliers), int(cal.robust.inliers.sum())
    note = (f"outliers rejected: the fit of all pairs was refused ({refused}); {n - kept} of {n} pairs did not fit "
            f"the consensus of the others and were dropped, as --robust does, and the {kept} left fit as clean data do "
            "(robust.rejected lists them; --accept-poor-fit keeps the fit of all pairs, exit 3)")
    return replace(cal, warnings=[note, *cal.warnings])


def calibrate_files(a: Source | None = None, b: Source | None = None, *, stream_a: str | StreamSpec | None = None,
                    stream_b: str | StreamSpec | None = None, topic_a: str | None = None, topic_b: str | None = None,
                    frames_a: Sequence[str] | None = None, frames_b: Sequence[str] | None = None,
                    options: Options | None = None, config_file: str | Path | None = None,
                    preset: str | None = None, quiet: bool = True, **overrides: Any) -> Calibration:
    """Read two streams and :func:`calibrate` ``T_a_b``.

    ``a``, ``b``: file paths (str or Path; a log, or one text pose file per stream; ``-`` is
    stdin), :class:`StreamSpec` or in-memory :class:`~handeye_cli.streams.PoseStream`. With one
    log, ``b`` may be omitted and the streams are named by ``stream_a``/``stream_b`` in the spelling every
    command shares: ``"/topic"``, ``"tf:PARENT,CHILD"`` (the parent first) or a ``"FILE"`` of its own
    (:func:`stream_specs`; ``topic_a`` and ``frames_a=(PARENT, CHILD)`` are synonyms). Options: ``options`` <
    ``preset`` < ``config_file`` < ``overrides`` by flat name (e.g. ``method="dqopt", alpha="auto"``).
    """
    opts = load_options(config_file, preset, base=options, **overrides)
    spec_a, spec_b = stream_specs(tuple(x for x in (a, b) if x is not None), stream_a=stream_a, stream_b=stream_b,
                                  topic_a=topic_a, topic_b=topic_b, frames_a=frames_a, frames_b=frames_b)
    refuse_unread(opts.read, (isinstance(spec_a, PoseStream), isinstance(spec_b, PoseStream)))
    from .io.remote import session_of

    with session_of(opts.read) as remote:
        read_a, read_b = read_streams([spec_a, spec_b], opts, quiet=quiet)
    inputs: dict[str, Any] = {"a": _describe(spec_a), "b": _describe(spec_b), "time_source": opts.read.time_source,
                              **_inversion_inputs(opts.read)}
    if remote.urls:
        inputs["bytes_fetched"] = remote.bytes_fetched      # [B] read from object storage (URL inputs)
    return calibrate_read(read_a, read_b, opts, inputs=inputs).with_origin(config_file, preset)



def _describe(spec: StreamSpec | PoseStream) -> dict[str, Any]:
    return spec.describe() if isinstance(spec, StreamSpec) else {"stream": spec.source or "in memory"}

