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
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np

from ..analysis import RobustResult, assess_observability, bootstrap, pair_residuals, robust_solve
from ..analysis.alpha import TIME_BLOCKS, noise_model_alpha, time_blocks
from ..analysis.covariance import drift_check
from ..analysis.fit_test import SampleNoise, fit_test, sample_noise
from ..analysis.readings import scale_reading
from ..analysis.robust import consensus_share, longest_disagreement
from ..analysis.selection import Selection
from ..analysis.stream_noise import stream_noise
from ..analysis.subspace import observable_subspace
from ..config import load_options
from ..errors import HandEyeError
from ..geometry import dualquat
from ..io.spec import StreamSpec
from ..options import Options
from ..solvers import Prior, Solution, solve
from ..solvers.scale import ScaleSolution, drift_warning
from ..stages.pairs import Pairs
from ..streams import PoseStream
from ..verify.findings import fit_refusal, inversion, moved_mount, order_contradiction, suspect_data
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
    times ``robust``'s inlier mask; None: unweighted) and ``--robust``'s RANSAC."""

    solution: Solution
    alpha: float
    weights: np.ndarray | None
    robust: RobustResult | None


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
    a, b, prior, paired = reading.stream_a, reading.stream_b, reading.prior, reading.paired
    findings, diagnostics = list(reading.findings), _reading_sections(reading)
    scale = None
    if opts.solver.scale == "auto":
        paired, scale = scaled(a, b, paired, opts, reading.offset_ns, prior, noise_of)
        diagnostics["scale"] = scale.as_dict()
    solved = _solve_and_analyse(paired.pairs, opts, prior, paired.selection, diagnostics)
    verdict, contradiction = None, None
    if checks.inversion:                                      # its thresholds are set at α 1
        verdict, refused = inversion(paired, opts, 1.0 if opts.solver.alpha == "auto" else solved.alpha, inputs)
        findings += [refused] if refused else []
    if verdict is None:
        contradiction, refused = order_contradiction(a, b, paired, opts)
        findings += [refused] if refused else []
    _decided(findings, opts)                                  # a misread stream is refused before any more work
    if contradiction is not None:
        diagnostics["interpretation"] = {**diagnostics.get("interpretation", {}), **contradiction.as_dict()}
    if verdict is not None:
        diagnostics["inversion"] = verdict.as_dict()
    elif scale_by_fit and opts.solver.scale == 1.0 and prior is None:   # inverted streams also fit "better scaled"
        paired, solved, scale = _scale_by_fit(a, b, reading, paired, solved, opts, diagnostics, findings, noise_of)
    drifting = drift_warning(scale)
    if drifting:
        findings.append(Finding.warning("scale_drift", drifting))
    pairs = paired.pairs
    A, B, ij = pairs.A, pairs.B, (pairs.i, pairs.j)
    if prior is not None:                                     # the prior only where the data leave something open
        free = _solve_and_analyse(pairs, opts, None, paired.selection, {})
        free_obs = assess_observability(A, B, free.solution.matrix, alpha=free.alpha, weights=free.weights,
                                        samples=ij)
        if free_obs.ok:
            solved, prior = free, None
            diagnostics["prior"] = "not used: the motion determines every degree of freedom"
    solution, alpha, weights = solved.solution, solved.alpha, solved.weights
    obs = assess_observability(A, B, solution.matrix, alpha=alpha, prior=prior, weights=weights, samples=ij)
    findings += [Finding.warning("observability", str(w)) for w in obs.warnings]
    findings += [Finding.warning("certificate", w) for w in solution.warnings]     # a failed optimality certificate
    diagnostics["observability"] = obs.as_dict()
    subspace = observable_subspace(A, B, solution.matrix, obs, weights=weights,
                                   nominal=None if prior is None else prior.T_a_b)
    if subspace.axis_a is not None:                           # planar: the reduced in-plane solve
        solution = replace(solution, matrix=subspace.matrix, problem=None, dual_quaternion=None,
                           optimum=solution)                 # its certificate: of the full solve (cost 8)
        findings += [Finding.warning("subspace", w) for w in
                     [f"not estimated: {k} ({v})" for k, v in subspace.skipped.items()] + list(subspace.advice)]
    diagnostics["degrees_of_freedom"] = subspace.as_dict()
    noise = sample_noise(a, b if scale is None else b.scaled(scale.scale), paired.synced, paired.stations,
                         opts.sync.sync, noise_of)
    refinement = None
    if opts.solver.refine:
        solution, refinement, skipped = _refined(solution, paired, pairs, weights, noise, reduced=subspace.axis_a
                                                 is not None)
        findings += [Finding.warning("refinement", skipped)] if skipped else []
    if checks.uncertainty and len(A) > 2 * TIME_BLOCKS:      # σ from independent samples beside σ from blocks (drift)
        check = drift_check(A, B, solution.matrix, time_blocks(pairs.t_i_ns, pairs.t_j_ns), alpha=alpha,
                            prior=prior, weights=weights, samples=ij)
        diagnostics["uncertainty_check"] = check.as_dict()
        if check.overconfident:
            findings.append(Finding.warning("uncertainty", check.warning()))
    res = pair_residuals(A, B, solution.matrix)
    diagnostics["residuals"] = res.summary(None if weights is None else weights > 0).as_dict()
    fit = fit_test(pairs, res, solution.matrix, noise, mask=None if weights is None else weights > 0)   # refuses
    diagnostics["fit_test"] = fit.as_dict()                                         # what no rigid rig gives
    misfit = fit_refusal(fit, opts, paired, inverted=verdict is not None)
    moved = None if misfit or paired.stations is None or opts.analysis.robust else moved_mount(
        paired, res, opts, alpha, prior)                      # a mount that slipped between two stations
    findings += [f for f in (misfit, moved, suspect_data(verdict, res, weights, paired)) if f is not None]
    outcome = policy(findings, accept_poor_fit=opts.analysis.accept_poor_fit, robust=opts.analysis.robust)
    if outcome.error is not None:
        recovered = _robust_retry(reading, opts, inputs, scale_by_fit, misfit, noise_of, checks) \
            if outcome.retry and misfit is not None else None
        if recovered is None:
            raise outcome.error
        return recovered
    if moved:                                                 # kept on request: the fit test failed, exit 3
        diagnostics["fit_test"] = {**diagnostics["fit_test"], "passed": False, "extrinsic_changed": moved.message}
    boot = None
    if opts.analysis.bootstrap > 0:
        boot = bootstrap(A, B, opts.analysis.bootstrap, alpha=alpha, prior=prior, weights=weights,
                         samples=ij, seed=opts.pairs.seed,
                         estimate=solution.matrix if opts.solver.method == "dqopt" else None)   # the same solve
        diagnostics["uncertainty"] = {"method": "bootstrap over pose samples", **boot.as_dict()}
    found = Diagnostics(MappingProxyType(diagnostics), fit=fit, observability=obs, subspace=subspace,
                        selection=paired.selection, scale=scale, poor_fit_accepted=bool(outcome.accepted))
    return Calibration(solution, a, b, paired.synced, pairs, paired.samples, opts, res,
                       warnings=list(outcome.warnings), diagnostics=found, inputs=inputs,
                       weights=weights, robust=solved.robust, bootstrap=boot, refinement=refinement)


def _refined(solution: Solution, paired: Paired, pairs: Pairs, weights: np.ndarray | None, noise: SampleNoise, *,
             reduced: bool) -> tuple[Solution, Refinement | None, str]:
    """The optimum ``solution`` refined by maximum likelihood (:func:`~handeye_cli.analysis.refinement.
    refine_calibration`): the refined solution (``optimum``: the one it started from, cost (8) at the refined
    pose), its account, and "" — or the solution as it was, None and why it was not refined (planar motion's
    reduced solve; samples too few or a noise model that says nothing)."""
    if reduced:
        return solution, None, ("not refined: planar motion leaves directions the likelihood cannot see (the "
                                "reduced in-plane solve is the result)")
    from ..analysis.refinement import refine_calibration  # scipy's optimiser and banded Cholesky: on request

    try:
        refinement = refine_calibration(paired.synced, pairs, weights, noise, solution.matrix)
    except HandEyeError as e:
        return solution, None, f"not refined: {e.what}; the optimum of cost (8) is the result"
    q, qd = dualquat.from_transforms(refinement.matrix)
    assert solution.problem is not None, "an optimum of cost (8) keeps its problem"
    return replace(solution, matrix=refinement.matrix, cost=solution.problem.cost(q, qd), problem=None,
                   dual_quaternion=None, optimum=solution), refinement, ""


def _decided(findings: list[Finding], opts: Options) -> None:
    """Raise the refusal the policy makes of the ``findings`` so far (a misread stream: there is nothing to
    retry), so that no more work is spent on a result that cannot leave."""
    error = policy(findings, accept_poor_fit=opts.analysis.accept_poor_fit, robust=opts.analysis.robust).error
    if error is not None:
        raise error


def _reading_sections(reading: Reading) -> dict[str, Any]:
    """The result's sections of the reading, in document order: ``time_offset``, ``interpretation`` (the
    quaternion order's choice), ``stations`` or ``sync``."""
    sections: dict[str, Any] = {"time_offset": reading.time_offset.as_dict()}
    if reading.order is not None:
        sections["interpretation"] = reading.order.as_dict()
    paired = reading.paired
    if paired.stations is not None:
        sections["stations"] = paired.stations.as_dict()
    else:
        sections["sync"] = paired.synced.describe()
    return sections


def _scale_by_fit(a: PoseStream, b: PoseStream, reading: Reading, paired: Paired, solved: _Solved, opts: Options,
                  diagnostics: dict[str, Any], findings: list[Finding], noise_of: NoiseOf
                  ) -> tuple[Paired, _Solved, ScaleSolution | None]:
    """b's translations in other units, found by the fit (:func:`~handeye_cli.analysis.readings.scale_reading` at
    the solution of the pairs): decisively better scaled (monocular units), the scale is estimated with ``T_a_b``
    as ``--scale auto`` does and the pairs re-solved — returned, with the estimate; noticeably better (a SLAM scale
    off by percents), a warning naming ``--scale auto``; else the pairs and solve as they were (and no estimate).
    ``diagnostics`` and ``findings`` are filled in."""
    pairs = paired.pairs
    found = scale_reading(pairs.A, pairs.B, solved.solution.matrix)
    if found is None or not (found.decisive or found.noticeable):
        return paired, solved, None
    diagnostics.setdefault("interpretation", {})["scale"] = {**found.as_dict(), "applied": found.decisive}
    if not found.decisive:
        findings.append(Finding.warning("scale", f"stream b's translations fit {found.gain:.3g}× better scaled by "
                                        f"{found.scale:.4g} (median residual {found.medians_m[0]:.3g} → "
                                        f"{found.medians_m[1]:.3g} m): if its scale is off (SLAM), pass "
                                        "⟦scale='auto'⟧"))
        return paired, solved, None
    paired, scale = scaled(a, b, paired, opts, reading.offset_ns, reading.prior, noise_of)
    diagnostics["scale"] = scale.as_dict()
    solved = _solve_and_analyse(paired.pairs, opts, reading.prior, paired.selection, diagnostics)
    findings.append(Finding.warning("scale", f"stream b's translations fit a rigid rig {found.gain:.3g}× better "
                                    f"scaled (median residual {found.medians_m[0]:.3g} m as given): its scale was "
                                    f"estimated with T_a_b, {scale.scale:.6g} ± {scale.scale_std:.2g} m per unit "
                                    "(⟦scale='auto'⟧); give it with ⟦scale=NUMBER⟧ to fix it"))
    return paired, solved, scale


def _solve_and_analyse(pairs: Pairs, options: Options, prior: Prior | None, selection: Selection | None,
                       diagnostics: dict[str, Any]) -> _Solved:
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
    return _Solved(solve(A, B, method=solver.method, alpha=alpha, prior=prior, weights=weights), alpha, weights,
                   robust)


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
