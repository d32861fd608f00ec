"""The calibration run: two pose streams → reading (order, inversion, time offset) → sync → gates → pairs → solve
→ analysis → the policy's verdict.

:func:`calibrate_files` reads two streams from logs or text files and calibrates; :func:`calibrate`
does the same on streams already in memory; :func:`calibrate_read` is the run itself. The extrinsic is ``T_a_b``:
the pose of sensor b's frame in sensor a's frame (maps points from b to a), where each stream holds
``T_world_sensor(t)``. Options are the typed :class:`~handeye_cli.options.Options`; keyword arguments use the same
flat names as the command line. Whether the result may leave, and with which warnings, is decided by
:func:`handeye_cli.verify.policy.policy` alone.

Examples
--------
>>> import handeye_cli
>>> cal = handeye_cli.calibrate_files("sample_data/rig_a.tum", "sample_data/rig_b.tum", method="dqopt")
>>> cal.matrix.shape, cal.options.solver.method
((4, 4), 'dqopt')
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..analysis import BootstrapResult, RobustResult, assess_observability, bootstrap, pair_residuals, robust_solve
from ..analysis.alpha import TIME_BLOCKS, AlphaChoice, noise_model_alpha, time_blocks
from ..analysis.covariance import DriftCheck, drift_check
from ..analysis.fit_test import SampleNoise, fit_test, sample_noise
from ..analysis.inversion import InversionVerdict
from ..analysis.observability import Observability
from ..analysis.readings import OrderContradiction, ScaleReading, scale_reading
from ..analysis.robust import consensus_share, longest_disagreement
from ..analysis.selection import Selection
from ..analysis.stream_noise import stream_noise
from ..analysis.subspace import Subspace, observable_subspace
from ..config import load_options
from ..errors import HandEyeError
from ..geometry import dualquat
from ..io.spec import StreamSpec
from ..options import Options
from ..solvers import Prior, Solution, solve
from ..solvers.scale import ScaleSolution, drift_warning
from ..stages.pairs import Pairs
from ..streams import PoseStream
from ..verify.findings import fit_refusal, inversion, moved_mount, observability, order_contradiction, suspect_data
from ..verify.policy import Finding, policy, retry_kept
from ..verify.reading import Reading, decide_reading
from .inputs import Inputs, Source, check_samples, inverted, read_streams, refuse_unread, stream_specs
from .pairing import Paired
from .result import Calibration, Checks, Diagnostics
from .scaling import NoiseOf, scaled

if TYPE_CHECKING:
    from ..analysis.refinement import Refinement

__all__ = ["calibrate", "calibrate_files", "calibrate_read"]

@dataclass(frozen=True, eq=False)
class _Solved:
    """The weighted solve of a reading's pairs: the solution, the α used, the per-pair weights (the selection's,
    times ``robust``'s inlier mask; None: unweighted), ``--robust``'s RANSAC and α auto's source (the noise model's
    choice, or the selection whose α it is; None for a given α)."""

    solution: Solution
    alpha: float
    weights: np.ndarray | None
    robust: RobustResult | None
    alpha_auto: AlphaChoice | Selection | None


def calibrate_read(stream_a: PoseStream, stream_b: PoseStream, opts: Options, *,
                   inputs: Inputs = Inputs(), scale_by_fit: bool = True,  # noqa: B008 (frozen: immutable)
                   noise_of: NoiseOf = stream_noise,
                   checks: Checks = Checks()) -> Calibration:  # noqa: B008 (frozen: immutable)
    """:func:`calibrate` streams as a reader produced them with ``opts.read`` (parsed, not yet inverted: the
    file-only read options are recorded in the settings, not applied again), e.g. by
    :func:`~.inputs.read_streams` or a rig's reader (which inverts its streams itself and sets no
    ``invert_a``/``invert_b``).

    Order: the reading (:func:`~handeye_cli.verify.reading.decide_reading`: [fixed scale of b] → quaternion order
    of text files → inversion → time offset, confirmed by the fit → stations, or sync → gates → pairs) →
    [scale auto] → [robust] → [α auto] → weighted solve → the reading's checks (inversion, a given quaternion
    order) → [b's units by the fit] → observability, degrees of freedom, residuals, fit test → the policy
    (:func:`~handeye_cli.verify.policy.policy`: refuse, retry with outliers rejected, or accept with its warnings)
    → [bootstrap]. ``scale_by_fit``: b's translations found in other units by the fit are estimated with
    ``T_a_b`` (``handeye rig`` passes False: its consistency test names such a stream). ``noise_of``: each
    stream's jitter for the fit test (a rig passes a memo: its streams are in several pairs). ``checks``: which
    checks after the solve run (:class:`~.result.Checks`; the fit test always does).
    """
    check_samples(stream_a, "stream a")
    check_samples(stream_b, "stream b")
    return _calibrated(decide_reading(stream_a, stream_b, opts), opts, inputs, scale_by_fit, noise_of, checks)


def _calibrated(reading: Reading, opts: Options, inputs: Inputs, scale_by_fit: bool,
                noise_of: NoiseOf, checks: Checks) -> Calibration:
    """The calibration under ``reading`` (:func:`calibrate_read`'s steps after the reading); a refused fit's retry
    with outliers rejected runs it again on the same reading, which does not depend on ``robust``."""
    a, b, prior, findings = reading.stream_a, reading.stream_b, reading.prior, list(reading.findings)
    paired, scale = scaled(a, b, reading.paired, opts, reading.offset_ns, prior, noise_of) \
        if opts.solver.scale == "auto" else (reading.paired, None)
    solved = _weighted_solve(paired, opts, prior)
    verdict, contradiction = _reading_checked(a, b, paired, solved, opts, inputs, checks, findings)
    found = None
    if verdict is None and scale_by_fit and opts.solver.scale == 1.0 and prior is None:  # inverted: "better scaled" too
        paired, solved, scale, found = _scale_by_fit(reading, paired, solved, opts, findings, noise_of)
    findings += [Finding.warning("scale_drift", w) for w in (drift_warning(scale),) if w]
    pairs = paired.pairs
    noise = sample_noise(a, b if scale is None else b.scaled(scale.scale), paired.synced, paired.stations,
                         opts.sync.sync, noise_of)
    jitter = noise.rot_a[pairs.i] ** 2 + noise.rot_a[pairs.j] ** 2        # per pair: a's rotation variance [rad²]
    solved, prior = _prior_needed(paired, solved, opts, prior, jitter)  # the solve the result is, with or without
    solution, obs, subspace = _observed(pairs, solved, prior, findings, jitter)
    solution, refinement = _refined(solution, paired, solved.weights, noise, opts, subspace, findings)
    check = _uncertainty_check(pairs, solution, solved, prior, checks, findings)
    res = pair_residuals(pairs.A, pairs.B, solution.matrix)
    used = None if solved.weights is None else solved.weights > 0
    fit = fit_test(pairs, res, solution.matrix, noise, mask=used)            # refuses what no rigid rig gives
    misfit = fit_refusal(fit, opts, paired, inverted=verdict is not None)
    moved = None if misfit or paired.stations is None or opts.analysis.robust else moved_mount(
        paired, res, opts, solved.alpha, prior)                  # a mount that slipped between two stations
    findings += [f for f in (misfit, moved, suspect_data(verdict, res, solved.weights, paired)) if f is not None]
    outcome = policy(findings, accept_poor_fit=opts.analysis.accept_poor_fit, robust=opts.analysis.robust)
    if outcome.error is not None:
        recovered = _robust_retry(reading, opts, inputs, scale_by_fit, misfit, noise_of, checks) \
            if outcome.retry and misfit is not None else None
        if recovered is None:
            raise outcome.error
        return recovered
    boot = _bootstrap(pairs, solution, solved, prior, opts)
    sampling = reading.paired.synced if reading.paired.stations is None else reading.paired.stations
    diagnostics = Diagnostics(
        time_offset=reading.time_offset, order=reading.order, contradiction=contradiction, sampling=sampling,
        scale=scale, scale_found=found, robust=solved.robust, pair_stamps_ns=(pairs.t_i_ns, pairs.t_j_ns),
        selection=paired.selection, alpha_auto=solved.alpha_auto, inversion=verdict,
        prior_unused=prior is None and reading.prior is not None, observability=obs, subspace=subspace,
        uncertainty_check=check, residuals=res.summary(used), fit=fit, mount_moved=None if moved is None else
        moved.message, bootstrap=boot, poor_fit_accepted=bool(outcome.accepted))
    return Calibration(solution, a, b, paired.synced, pairs, paired.samples, opts, res,
                       warnings=list(outcome.warnings), diagnostics=diagnostics, inputs=inputs,
                       weights=solved.weights, refinement=refinement)


def _reading_checked(a: PoseStream, b: PoseStream, paired: Paired, solved: _Solved, opts: Options, inputs: Inputs,
                     checks: Checks, findings: list[Finding]) -> tuple[InversionVerdict | None,
                                                                       OrderContradiction | None]:
    """The reading's checks on the solved pairs: the inversion check (its thresholds set at α 1), else the check of
    each quaternion order that was given; their refusals added to ``findings``, and a misread stream refused here,
    before any more work (:func:`_decided`). Returns the inversion verdict and the order contradiction."""
    verdict, contradiction = None, None
    if checks.inversion:
        verdict, refused = inversion(paired, opts, 1.0 if opts.solver.alpha == "auto" else solved.alpha, inputs)
        findings += [refused] if refused else []
    if verdict is None:
        contradiction, refused = order_contradiction(a, b, paired, opts)
        findings += [refused] if refused else []
    _decided(findings, opts)
    return verdict, contradiction


def _prior_needed(paired: Paired, solved: _Solved, opts: Options, prior: Prior | None,
                  jitter: np.ndarray) -> tuple[_Solved, Prior | None]:
    """The prior only where the data leave something open: the solve without it, and no prior, when the motion
    determines every degree of freedom; else ``solved`` and ``prior`` as they were (``jitter``: a's per-pair
    rotation variance [rad²], see :func:`~handeye_cli.analysis.observability.assess_observability`)."""
    if prior is None:
        return solved, prior
    free = _weighted_solve(paired, opts, None)
    pairs = paired.pairs
    free_obs = assess_observability(pairs.A, pairs.B, free.solution.matrix, alpha=free.alpha, weights=free.weights,
                                    samples=(pairs.i, pairs.j), rotation_noise=jitter)
    return (free, None) if free_obs.ok else (solved, prior)


def _observed(pairs: Pairs, solved: _Solved, prior: Prior | None, findings: list[Finding],
              jitter: np.ndarray) -> tuple[Solution, Observability, Subspace]:
    """Observability and the degrees of freedom at the solution, their warnings (or the refusal of what the motion
    leaves open and no prior fixes; and a failed optimality certificate's warnings) added to ``findings``: the
    solution (planar motion: the reduced in-plane solve, its certificate the full solve's), the observability and
    the subspace."""
    solution, ij = solved.solution, (pairs.i, pairs.j)
    obs = assess_observability(pairs.A, pairs.B, solution.matrix, alpha=solved.alpha, prior=prior,
                               weights=solved.weights, samples=ij, rotation_noise=jitter)
    findings += observability(obs, prior)                    # what the motion leaves open: warned, or refused
    findings += [Finding.warning("certificate", w) for w in solution.warnings]     # a failed optimality certificate
    subspace = observable_subspace(pairs.A, pairs.B, solution.matrix, obs, weights=solved.weights,
                                   nominal=None if prior is None else prior.T_a_b)
    if subspace.axis_a is not None:                           # planar: the reduced in-plane solve
        solution = replace(solution, matrix=subspace.matrix, problem=None, dual_quaternion=None,
                           optimum=solution)                 # its certificate: of the full solve (cost 8)
        findings += [Finding.warning("subspace", w) for w in
                     [f"not estimated: {k} ({v})" for k, v in subspace.skipped.items()] + list(subspace.advice)]
    return solution, obs, subspace


def _uncertainty_check(pairs: Pairs, solution: Solution, solved: _Solved, prior: Prior | None, checks: Checks,
                       findings: list[Finding]) -> DriftCheck | None:
    """σ from independent samples beside σ from blocks of time (drift), where asked and the pairs are enough; an
    overconfident σ's warning added to ``findings``."""
    if not checks.uncertainty or len(pairs.A) <= 2 * TIME_BLOCKS:
        return None
    check = drift_check(pairs.A, pairs.B, solution.matrix, time_blocks(pairs.t_i_ns, pairs.t_j_ns), alpha=solved.alpha,
                        prior=prior, weights=solved.weights, samples=(pairs.i, pairs.j))
    if check.overconfident:
        findings.append(Finding.warning("uncertainty", check.warning()))
    return check


def _bootstrap(pairs: Pairs, solution: Solution, solved: _Solved, prior: Prior | None,
               opts: Options) -> BootstrapResult | None:
    """``--bootstrap N``'s resampling of the pose samples (dqopt's: the same solve, started at the solution)."""
    if opts.analysis.bootstrap <= 0:
        return None
    return bootstrap(pairs.A, pairs.B, opts.analysis.bootstrap, alpha=solved.alpha, prior=prior,
                     weights=solved.weights, samples=(pairs.i, pairs.j), seed=opts.pairs.seed,
                     estimate=solution.matrix if opts.solver.method == "dqopt" else None)


def _refined(solution: Solution, paired: Paired, weights: np.ndarray | None, noise: SampleNoise, opts: Options,
             subspace: Subspace, findings: list[Finding]) -> tuple[Solution, Refinement | None]:
    """With ``--refine``, the optimum ``solution`` refined by maximum likelihood (:func:`~handeye_cli.analysis.
    refinement.refine_calibration`): the refined solution (``optimum``: the one it started from, cost (8) at the
    refined pose) and its account — or the solution as it was and None, and why it was not refined added to
    ``findings`` (planar motion's reduced solve; samples too few or a noise model that says nothing)."""
    if not opts.solver.refine:
        return solution, None
    if subspace.axis_a is not None:
        findings.append(Finding.warning("refinement", "not refined: planar motion leaves directions the likelihood "
                                        "cannot see (the reduced in-plane solve is the result)"))
        return solution, None
    from ..analysis.refinement import refine_calibration  # scipy's optimiser and banded Cholesky: on request

    try:
        refinement = refine_calibration(paired.synced, paired.pairs, weights, noise, solution.matrix)
    except HandEyeError as e:
        findings.append(Finding.warning("refinement", f"not refined: {e.what}; the optimum of cost (8) is the result"))
        return solution, None
    q, qd = dualquat.from_transforms(refinement.matrix)
    assert solution.problem is not None, "an optimum of cost (8) keeps its problem"
    return replace(solution, matrix=refinement.matrix, cost=solution.problem.cost(q, qd), problem=None,
                   dual_quaternion=None, optimum=solution), refinement


def _decided(findings: list[Finding], opts: Options) -> None:
    """Raise the refusal the policy makes of the ``findings`` so far (a misread stream: there is nothing to
    retry), so that no more work is spent on a result that cannot leave."""
    error = policy(findings, accept_poor_fit=opts.analysis.accept_poor_fit, robust=opts.analysis.robust).error
    if error is not None:
        raise error


def _scale_by_fit(reading: Reading, paired: Paired, solved: _Solved, opts: Options, findings: list[Finding],
                  noise_of: NoiseOf) -> tuple[Paired, _Solved, ScaleSolution | None, ScaleReading | None]:
    """b's translations in other units, found by the fit (:func:`~handeye_cli.analysis.readings.scale_reading` at
    the solution of the pairs): decisively better scaled (monocular units), the scale is estimated with ``T_a_b``
    as ``--scale auto`` does and the pairs re-solved — returned, with the estimate; noticeably better (a SLAM scale
    off by percents), a warning naming ``--scale auto``; else the pairs and solve as they were (and no estimate).
    The fit's finding is returned where it is decisive or noticeable (else None); ``findings`` are filled in."""
    pairs = paired.pairs
    found = scale_reading(pairs.A, pairs.B, solved.solution.matrix)
    if found is None or not (found.decisive or found.noticeable):
        return paired, solved, None, None
    if not found.decisive:
        findings.append(Finding.warning("scale", f"stream b's translations fit {found.gain:.3g}× better scaled by "
                                        f"{found.scale:.4g} (median residual {found.medians_m[0]:.3g} → "
                                        f"{found.medians_m[1]:.3g} m): if its scale is off (SLAM), pass "
                                        "⟦scale='auto'⟧"))
        return paired, solved, None, found
    paired, scale = scaled(reading.stream_a, reading.stream_b, paired, opts, reading.offset_ns, reading.prior,
                           noise_of)
    solved = _weighted_solve(paired, opts, reading.prior)
    findings.append(Finding.warning("scale", f"stream b's translations fit a rigid rig {found.gain:.3g}× better "
                                    f"scaled (median residual {found.medians_m[0]:.3g} m as given): its scale was "
                                    f"estimated with T_a_b, {scale.scale:.6g} ± {scale.scale_std:.2g} m per unit "
                                    "(⟦scale='auto'⟧); give it with ⟦scale=NUMBER⟧ to fix it"))
    return paired, solved, scale, found


def _weighted_solve(paired: Paired, options: Options, prior: Prior | None) -> _Solved:
    """[robust: RANSAC inliers] → [α auto] → the weighted solve of ``paired``'s pairs.

    With the ``auto`` strategy the pairs carry the noise model's weights, and α auto is its ML α."""
    pairs, selection, solver = paired.pairs, paired.selection, options.solver
    A, B = pairs.A, pairs.B
    auto = solver.alpha == "auto"
    alpha = (selection.alpha if selection else 1.0) if auto else float(solver.alpha)
    weights = None if selection is None else selection.weights
    robust = None
    if options.analysis.robust:
        robust = robust_solve(A, B, method=solver.method, alpha=alpha, prior=prior, seed=options.pairs.seed)
        weights = robust.inliers.astype(float) * (1.0 if weights is None else weights)
    choice: AlphaChoice | Selection | None = selection if auto else None
    if auto and selection is None:
        choice = noise_model_alpha(A, B, prior=prior, weights=weights, spans_s=(pairs.t_j_ns - pairs.t_i_ns) / 1e9)
        alpha = choice.alpha
    return _Solved(solve(A, B, method=solver.method, alpha=alpha, prior=prior, weights=weights), alpha, weights,
                   robust, choice)


def _robust_retry(reading: Reading, opts: Options, inputs: Inputs, scale_by_fit: bool,
                  refused: Finding, noise_of: NoiseOf, checks: Checks) -> Calibration | None:
    """A fit the fit test refused (``refused``: its finding), solved again with outliers rejected, as ``--robust``
    does (RANSAC on minimal sets, then the weighted optimal solve on the inliers): kept, with the settings saying
    ``robust`` and a first warning naming what was dropped, when the policy keeps it
    (:func:`~handeye_cli.verify.policy.retry_kept`); else None (the refusal stands). A stream with a few bad poses
    (a station seen wrongly, a tracking glitch) gives a verified result, a wrong convention or streams that are
    not rigidly attached do not."""
    try:
        cal = _calibrated(reading, replace(opts, analysis=replace(opts.analysis, robust=True)), inputs,
                          scale_by_fit, noise_of, checks)
    except HandEyeError:
        return None
    if cal.robust is None:
        return None
    inliers, i, j = cal.robust.inliers, cal.pairs.i, cal.pairs.j
    if not retry_kept(consensus_share(inliers, i, j), longest_disagreement(inliers, i, j),
                      None if cal.diagnostics.fit is None else cal.diagnostics.fit.ratio):
        return None
    n, kept = len(inliers), int(inliers.sum())
    note = (f"outliers rejected: the fit of all pairs was refused ({refused.message}); {n - kept} of {n} pairs did "
            f"not fit the consensus of the others and were dropped, as ⟦robust=True⟧ does, and the {kept} left fit as "
            "clean data do (robust.rejected lists them; ⟦accept_poor_fit=True⟧ keeps the fit of all pairs, exit 3)")
    return replace(cal, warnings=[note, *cal.warnings])


def calibrate(stream_a: PoseStream, stream_b: PoseStream, options: Options | None = None, *,
              inputs: Inputs | None = None, **overrides: Any) -> Calibration:
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
    return calibrate_read(stream_a, stream_b, opts, inputs=replace(inputs or Inputs(), inverted=inverted(opts.read)))


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
    (:func:`~.inputs.stream_specs`; ``topic_a`` and ``frames_a=(PARENT, CHILD)`` are synonyms). Options:
    ``options`` < ``preset`` < ``config_file`` < ``overrides`` by flat name (e.g. ``method="dqopt", alpha="auto"``).
    """
    opts = load_options(config_file, preset, base=options, **overrides)
    spec_a, spec_b = stream_specs(tuple(x for x in (a, b) if x is not None), stream_a=stream_a, stream_b=stream_b,
                                  topic_a=topic_a, topic_b=topic_b, frames_a=frames_a, frames_b=frames_b)
    return calibrate_specs(spec_a, spec_b, opts, quiet=quiet).with_origin(config_file, preset)


def calibrate_specs(spec_a: StreamSpec | PoseStream, spec_b: StreamSpec | PoseStream, opts: Options, *,
                    quiet: bool = True) -> Calibration:
    """Read streams a and b, named already (:func:`~.inputs.stream_specs`) with ``opts`` loaded already, and
    :func:`calibrate_read` ``T_a_b``: the step :func:`calibrate_files` and the commands share, so each parses
    the streams' names and the options once."""
    refuse_unread(opts.read, (isinstance(spec_a, PoseStream), isinstance(spec_b, PoseStream)))
    from ..io.remote import session_of

    with session_of(opts.read) as remote:
        read_a, read_b = read_streams([spec_a, spec_b], opts, quiet=quiet)
    inputs = Inputs.of(spec_a, spec_b, opts.read, remote.bytes_fetched if remote.urls else None)
    return calibrate_read(read_a, read_b, opts, inputs=inputs)
