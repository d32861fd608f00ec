"""How two streams are read, decided from the data before the solve: the quaternion order of a text file (by the
fit), the inversion the options ask for, b's fixed scale, and b's clock offset (estimated, then confirmed by the
fit); :func:`decide_reading` returns the :class:`Reading` and its pairs, made once.

Each stream holds ``T_world_sensor(t)`` (int64 ns stamps, positions [m], quaternions x-y-z-w); the offset is how
far b's clock is ahead of a's [ns]. The thresholds that decide it are in :mod:`.policy`.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from ..analysis.fit_test import fit_test, sample_noise
from ..analysis.readings import OffsetReading, OrderChoice, choose_quaternion_order, median_fit
from ..analysis.residuals import pair_residuals
from ..calibration.inputs import inverted_as_read, read_prior
from ..calibration.pairing import Paired, pairs_of
from ..calibration.result import frame_names
from ..errors import DataError, HandEyeError
from ..options import Options
from ..solvers import Prior
from ..stages.sync import median_step_ns
from ..streams import PoseStream
from .policy import CONFIRMING_COVERAGE, CONFIRMING_GAIN, CONFIRMING_MIN_GAIN, LARGE_OFFSET_PERIODS, Finding

if TYPE_CHECKING:
    from ..stages.timeoffset import TimeOffset

__all__ = ["Reading", "confirm_offset", "decide_reading", "estimated"]


@dataclass(frozen=True, eq=False)
class Reading:
    """How streams a and b are read, and their pairs under that reading.

    stream_a, stream_b: the streams as used — quaternion order chosen, inverted where the options say so, b scaled
    by a fixed ``scale`` — before the clock offset; order: the quaternion order's choice or check (None when
    nothing was open); offset_ns: b's clock offset applied [ns]; time_offset: how it was decided
    (:class:`~handeye_cli.analysis.readings.OffsetReading`); prior: the options' prior (eq 26), read once; paired:
    sync, gates and pairs at ``offset_ns``; findings: the warnings of the readers and of the reading."""

    stream_a: PoseStream
    stream_b: PoseStream
    order: OrderChoice | None
    offset_ns: int
    time_offset: OffsetReading
    prior: Prior | None
    paired: Paired
    findings: tuple[Finding, ...]


def decide_reading(stream_a: PoseStream, stream_b: PoseStream, opts: Options) -> Reading:
    """The reading of two streams as a reader produced them with ``opts.read`` (parsed, not yet inverted):
    [fixed scale of b] → quaternion order of text files (by the fit) → inversion (``invert_a`` / ``invert_b``) →
    time offset → the pairs at it, and an applied offset confirmed by the fit (:func:`_confirmed_offset`)."""
    if opts.solver.scale not in (1.0, "auto"):
        stream_b = stream_b.scaled(float(opts.solver.scale))
    stream_a, stream_b, order = _quaternion_order(stream_a, stream_b, opts)
    stream_a, stream_b = inverted_as_read(stream_a, stream_b, opts.read)
    offset_ns, report, offset_warnings = _time_offset(stream_a, stream_b, opts)
    findings = [*(Finding.warning("read", w) for w in (*stream_a.warnings, *stream_b.warnings)),
                *(Finding.warning("offset", w) for w in offset_warnings)]
    if order is not None and order.chosen_by == "fit":
        findings.append(Finding.warning("reading", order.message(stream_a, stream_b)))
    prior = read_prior(opts, frame_names(opts, stream_a, stream_b))       # the prior file is read once
    paired = pairs_of(stream_a, stream_b, opts, offset_ns, prior)
    if report.applied:
        paired, report = _confirmed_offset(stream_a, stream_b, opts, prior, report, paired)
        offset_ns = report.offset_ns
        large = _large_offset_warning(stream_a, stream_b, report)
        if large:
            findings.append(Finding.warning("large_offset", large))
    return Reading(stream_a, stream_b, order, offset_ns, report, prior, paired, tuple(findings))


def _quaternion_order(a: PoseStream, b: PoseStream, options: Options) -> tuple[PoseStream, PoseStream,
                                                                               OrderChoice | None]:
    """Text streams in the quaternion order that fits (:func:`~handeye_cli.analysis.readings.choose_quaternion_order`),
    compared at the given clock offset (0 when it is still to be estimated)."""
    offset = options.sync.time_offset
    return choose_quaternion_order(a, b, time_offset_ns=0 if offset == "auto" else int(round(float(offset) * 1e9)),
                                   max_dt_ns=options.sync.max_dt_ns, seed=options.pairs.seed)


def _time_offset(a: PoseStream, b: PoseStream, options: Options) -> tuple[int, OffsetReading, list[str]]:
    """The offset [ns] b's clock is ahead of a's, how it was decided, and warnings about it.

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
        return int(round(float(value) * 1e9)), OffsetReading(float(value), "fixed"), []
    from ..stages.timeoffset import estimate_time_offset, overlap_offsets_ns

    lo, hi = overlap_offsets_ns(a, b) if len(a) and len(b) else (0, 0)
    try:
        est = estimate_time_offset(a, b, max_offset_s=options.sync.max_time_offset)
    except HandEyeError as e:                 # too short, too gappy or too little rotation to tell: none applied
        if not lo <= 0 <= hi:                 # ... and at 0 the streams share no time: nothing to fall back on
            if "do not overlap" in e.what:
                raise
            raise DataError(f"the two streams' stamps do not overlap and no clock offset could be estimated "
                            f"({e.what})", "time offset", "give the offset with ⟦time_offset=SECONDS⟧, or widen "
                            "⟦max_time_offset⟧") from None
        return 0, OffsetReading(0.0, "not estimated", applied=False, reason=e.line()), []
    report = estimated(est)
    warnings = [f"a clock offset of {est.offset_ns / 1e9:.6g} ± {est.std_ns / 1e9:.2g} s was estimated but not "
                f"applied ({'; '.join(est.warnings)}): if it is right, pass ⟦time_offset={est.offset_ns / 1e9:.6g}⟧"
                ] if est.significant and est.warnings else []
    return report.offset_ns, report, warnings


def estimated(estimate: TimeOffset) -> OffsetReading:
    """The reading of an estimate before the fit is asked: applied where it is significant and unambiguous
    (:attr:`~handeye_cli.stages.timeoffset.TimeOffset.applicable`), else 0."""
    from ..stages.timeoffset import SIGNIFICANT_SIGMA

    applied = estimate.applicable
    return OffsetReading(estimate.offset_ns / 1e9 if applied else 0.0, estimate.method, applied=applied,
                         estimate=estimate, significant_sigma=SIGNIFICANT_SIGMA)


def confirm_offset(a: PoseStream, b: PoseStream, options: Options, estimate: TimeOffset) -> OffsetReading:
    """b's clock offset to a's as ``calibrate`` decides it from an ``estimate`` made already (a rig's, of a
    stream against its reference): applied only when significant, unambiguous and confirmed by the fit of the
    pairs it gives (:func:`_confirmed_offset`, the thresholds of :mod:`.policy`); the reading says which."""
    report = estimated(estimate)
    if not report.applied:
        return report
    try:
        paired = pairs_of(a, b, options, report.offset_ns, None)
    except HandEyeError:                      # no pairs at the estimate: nothing confirms it
        return replace(report, seconds=0.0, applied=False, confirmed_by=None)
    return _confirmed_offset(a, b, options, None, report, paired)[1]


def _large_offset_warning(a: PoseStream, b: PoseStream, report: OffsetReading) -> str | None:
    """The warning an applied clock offset earns (after the fit confirmed it): one that makes streams overlap whose
    stamps did not, or one larger than ``LARGE_OFFSET_PERIODS`` median sample periods of the slower stream; it
    names the offset and its σ [s] and how to refuse it. None for an offset not applied, or a small one."""
    from ..stages.timeoffset import overlap_offsets_ns

    if not report.applied or report.estimate is None:
        return None
    offset_s = report.seconds
    lo, hi = overlap_offsets_ns(a, b)
    period_s = max(median_step_ns(a), median_step_ns(b)) / 1e9
    if lo <= 0 <= hi and abs(offset_s) <= LARGE_OFFSET_PERIODS * period_s:
        return None
    why = ("the streams' stamps did not overlap without it" if not lo <= 0 <= hi else
           f"more than {LARGE_OFFSET_PERIODS:g} sample periods of the slower stream ({period_s:.3g} s)")
    return (f"a clock offset of {offset_s:.6g} ± {report.estimate.std_ns / 1e9:.2g} s was applied: {why}; pass "
            "⟦time_offset=0⟧ if the clocks are known to agree")


def _confirmed_offset(a: PoseStream, b: PoseStream, options: Options, prior: Prior | None, report: OffsetReading,
                      paired: Paired) -> tuple[Paired, OffsetReading]:
    """A significant clock-offset estimate is kept only when the fit confirms it: the pairs it gives must fit a
    rigid rig better (a median residual lower by ``CONFIRMING_MIN_GAIN``, neither higher by ``CONFIRMING_GAIN``)
    than the pairs without an offset; and where it leaves fewer than ``CONFIRMING_COVERAGE`` of the samples
    synchronised (an offset that is a large part of the recording), clearly better (by ``CONFIRMING_GAIN``), and
    only where the pairs without it misfit beyond their noise (:func:`_misfits`).
    It stands without a comparison when the streams do not pair without it (spans that do not overlap). An
    estimate the fit does not confirm (an alias of periodic motion on a short recording, an estimator's bias
    of a millisecond) is not applied: the reading returned says so, with both fits, and the pairs without an
    offset are returned. ``paired`` is :func:`pairs_of` at the estimate. The pairs without an offset are compared
    as the strides of the estimate's
    ``auto`` selection make them (like with like, and one selection, not two, where the offset is confirmed);
    a selection of their own is made only where they are returned."""

    def without_offset() -> Paired:
        return at_zero if paired.selection is None else pairs_of(a, b, options, 0, prior)

    try:
        at_zero = pairs_of(a, b, options, 0, prior, like=paired.selection)
    except HandEyeError:
        return paired, replace(report, confirmed_by="no pairs without it")
    est, zero = (median_fit(p.pairs.A, p.pairs.B) for p in (paired, at_zero))
    if est is None or zero is None:               # one of them does not determine X: the other stands
        if est is None:
            return without_offset(), replace(report, seconds=0.0, applied=False, confirmed_by=None)
        return paired, replace(report, confirmed_by="fit")
    gains = est.gains_over(zero)
    coverage = len(paired.synced) / max(len(at_zero.synced), 1)
    report = replace(report, fits=((est, len(paired.synced)), (zero, len(at_zero.synced))))
    worse = min(gains) < 1 / CONFIRMING_GAIN
    needed = CONFIRMING_MIN_GAIN if coverage >= CONFIRMING_COVERAGE else CONFIRMING_GAIN
    dropping = coverage < CONFIRMING_COVERAGE              # ... must explain a misfit of the samples it drops
    if not worse and max(gains) >= needed and not (dropping and not _misfits(a, b, options, at_zero, zero.matrix)):
        return paired, replace(report, confirmed_by="fit")
    return without_offset(), replace(report, seconds=0.0, applied=False, confirmed_by=None)


def _misfits(a: PoseStream, b: PoseStream, options: Options, paired: Paired, X: np.ndarray) -> bool:
    """Whether the pairs of ``paired`` misfit ``X`` beyond what the streams' own noise predicts, by more than the
    gain an offset that drops samples must show (:func:`_confirmed_offset`): where they fit as their noise
    predicts, an offset has nothing to explain, and one that keeps fewer samples fitting them better is chance
    (a periodic arm capture's alias at -2.3 s kept 42 % of the samples, its residuals 0.75× the noise's, where
    without it every sample fit at 1.07×: applied, the extrinsic was 154° wrong)."""
    pairs = paired.pairs
    noise = sample_noise(a, b, paired.synced, paired.stations, options.sync.sync)
    test = fit_test(pairs, pair_residuals(pairs.A, pairs.B, X), X, noise)
    return test.ratio > CONFIRMING_GAIN

