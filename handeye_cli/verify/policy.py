"""When handeye refuses, warns or retries: the one policy that decides whether a calibration may leave with exit 0.

A calibration's checks produce :class:`Finding` objects (:mod:`.findings`, :mod:`.reading`); :func:`policy` turns
them into one :class:`Outcome`:

* **refuse** — the first refusal in :data:`REFUSALS` order raises its error (exit 2):

  1. ``inversion``: a stream fits far better inverted (``T_sensor_world``), also against an explicit
     ``--invert-*`` / ``--no-invert-*``
     (:func:`handeye_cli.analysis.inversion.check_inversion`);
  2. ``order``: a quaternion order that was given (a log's fields, ``--wxyz-*``, a stream in memory) is
     contradicted by the other order fitting decisively better
     (:func:`handeye_cli.analysis.readings.contradicted_order`);
  3. ``undetermined``: the motion does not determine part of the extrinsic and no prior fixes it (no motion
     rotates, or cost (8) is flat in a direction: :func:`.findings.observability`);
  4. ``fit``: the residuals are beyond what the streams' own jitter predicts (the fit test,
     :mod:`handeye_cli.analysis.fit_test`, its limit ``THRESHOLD`` there) — **retried** first with outliers
     rejected, unless ``robust`` was asked for: the retry is kept only by :func:`retry_kept`;
  5. ``moved``: a station capture whose stations before one stamp fit another extrinsic than those after
     (:func:`handeye_cli.analysis.robust.moved_during`, each part ``MOVED_GAIN`` × better).

* **accept an override** — with ``accept_poor_fit`` every refusal is kept instead; the result is a poor fit
  accepted (``handeye calibrate`` exits 3) and, for ``order``, ``undetermined``, ``fit`` and ``moved``, the first
  warnings say so (an inversion's own message is the first warning after them).

* **warn** — every other finding is a warning, exit 0 (``--strict`` makes a warning fail). The warnings come out
  in :data:`WARNING_ORDER`: first what the user must act on (an accepted override, a suspect stream, a reading
  the fit chose), then what the readers and the clock offset said, then the analysis of the estimate.

The clock offset is a reading, decided before the solve (:mod:`.reading`): an estimate is applied when it is
significant and unambiguous (:attr:`handeye_cli.stages.timeoffset.TimeOffset.applicable`) and confirmed by the
fit by the ``CONFIRMING_*`` thresholds here; an applied one of more than ``LARGE_OFFSET_PERIODS`` sample periods
is a warning.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from ..errors import HandEyeError

__all__ = ["CONFIRMING_COVERAGE", "CONFIRMING_GAIN", "CONFIRMING_MIN_GAIN", "LARGE_OFFSET_PERIODS", "REFUSALS",
           "RETRY_MAX_RATIO", "RETRY_MAX_RUN", "RETRY_MIN_INLIERS", "WARNING_ORDER", "Finding", "Outcome",
           "ordered", "policy", "retry_kept"]

# --- the clock offset's confirmation by the fit (verify/reading.py) ---------------------------------------------
CONFIRMING_MIN_GAIN = 1.05    # an applied estimate's pairs must fit this much better (median residual) than the
#                               pairs without it (a biased 1.5 ± 0.25 ms estimate on a 500/30 Hz arm with no
#                               offset fit 0.99×, and made the rotation 5× worse), neither this much worse, and,
#                               when it synchronises
CONFIRMING_GAIN = 1.25        # fewer than this share of the samples, this much better (a 4-s periodic arm capture's
CONFIRMING_COVERAGE = 0.8     # alias at -2.3 s kept 42 % and fit 1.15× better in rotation, 1.29× worse in
#                               translation; a true 50 ms arm offset fit 4.5× better; 40 ms between drifting VIO
#                               streams 1.2–2.3× better, every sample kept), where the pairs without it misfit
#                               beyond their noise by this gain too (the fit test's ratio)
LARGE_OFFSET_PERIODS = 5.0
"""An applied clock offset of more than this many median sample periods of the slower stream is a warning naming it
and its σ (``--strict`` fails on it): jitter and transport delays are a period or two; beyond five, the two clocks
are different clocks (another time base, a recorder started late), which the user must hear about."""

# --- the outlier retry of a refused fit --------------------------------------------------------------------------
RETRY_MIN_INLIERS = 0.5
RETRY_MAX_RATIO = 3.0
RETRY_MAX_RUN = 0.25
"""A fit the fit test refuses is solved again with outliers rejected (as ``--robust``) and kept when at least
``RETRY_MIN_INLIERS`` of its pose samples agree with the consensus
(:func:`~handeye_cli.analysis.robust.consensus_share`) and the inliers fit as clean data do: a fit-test ratio
(residuals over what the streams' own noise predicts) of at most ``RETRY_MAX_RATIO``, where the test itself
refuses past 15. Inliers chosen from a wrong reading of the data (a quaternion order, a unit) are the pairs it
happens to fit least badly, and fit far worse than that: 14.5 on a simulated mocap pair read in the wrong order,
against 0.97 for a station capture with 20 % bad stations. The share is counted in samples, not pairs: every pair
of a bad station is bad, so k bad stations of n spoil 1 − (1 − k/n)² of the all-with-all pairs (kinhec
outliers-000003, 4 of 20 stations flipped and Student-t tails: 48 % inlier pairs, 70 % agreeing stations, a fit of
1.16 and 0.17° / 1.0 mm). Nor is it kept when the disagreeing samples hold a run of more than ``RETRY_MAX_RUN`` of
them (:func:`~handeye_cli.analysis.robust.longest_disagreement`): that is a sensor that moved during the
recording, whose consensus is one period's extrinsic; CI must see it refused. (A mount slipping 1° / 5 mm
half-way through a rig's stream was kept as 'outliers rejected'.)"""

# --- refusals and warnings ----------------------------------------------------------------------------------------
REFUSALS = ("inversion", "order", "undetermined", "fit", "moved")
"""The refusals, in the order they are decided: the first one found is the error."""

WARNING_ORDER = (
    "accepted",       # a refusal kept by accept_poor_fit (order, then fit, then moved)
    "suspect",        # a stream that looks inverted, or large residuals with the likely cause
    "scale",          # b's translations fit better in other units (estimated, or --scale auto suggested)
    "reading",        # the quaternion order the fit chose for a text file
    "read",           # the readers' own warnings, stream a's then b's (each names its file)
    "offset",         # a significant clock offset not applied (ambiguous), with the flag that applies it
    "large_offset",   # an applied clock offset the user must hear about
    "scale_drift",    # the scale's halves disagree: b's scale or translations drift
    "observability",  # degenerate motion: what is poorly determined
    "certificate",    # the solver's optimality certificate failed
    "subspace",       # planar motion: the degrees of freedom not estimated, and how to see them
    "refinement",     # --refine asked, but the optimum is the result (planar motion, too few samples)
    "uncertainty",    # σ over blocks of time far beyond σ of independent samples (drift)
)
"""The order warnings come out in, by kind; within a kind, in the order they were found. A refused fit that the
outlier retry recovers keeps the retry's warnings, after one naming what was dropped."""


@dataclass(frozen=True)
class Finding:
    """One thing a check found about a calibration: its ``kind`` (one of :data:`REFUSALS` or of
    :data:`WARNING_ORDER`), the human-readable ``message``, and for a refusal its ``error`` (the one line the
    user reads: what, where and the option that fixes it)."""

    kind: str
    message: str
    error: HandEyeError | None = None

    @staticmethod
    def warning(kind: str, message: str) -> Finding:
        """A warning of ``kind``."""
        return Finding(kind, message)

    @staticmethod
    def refusal(kind: str, error: HandEyeError, message: str) -> Finding:
        """A refusal of ``kind`` with its ``error``; ``message`` is the warning's text when it is accepted."""
        return Finding(kind, message, error)


@dataclass(frozen=True)
class Outcome:
    """What :func:`policy` decided: ``error`` (the refusal that stands; None: accepted), ``retry`` (the
    refusal is a misfit that outliers may explain: solve again with them rejected first), ``accepted`` (the
    kinds of refusal that ``accept_poor_fit`` kept: the result is a poor fit accepted, exit 3) and the
    ``warnings`` in :data:`WARNING_ORDER`."""

    error: HandEyeError | None
    retry: bool
    accepted: tuple[str, ...]
    warnings: tuple[str, ...]


_ACCEPTED_NOTE = ("order", "undetermined", "fit", "moved")   # refusals whose acceptance is a first warning of its own


def policy(findings: Sequence[Finding], *, accept_poor_fit: bool, robust: bool) -> Outcome:
    """The outcome of a calibration's ``findings`` under ``accept_poor_fit`` (keep a refused result, exit 3)
    and ``robust`` (outliers were rejected already: a refused fit is not retried)."""
    refusals = sorted((f for f in findings if f.error is not None), key=lambda f: REFUSALS.index(f.kind))
    if refusals and not accept_poor_fit:
        first = refusals[0]
        return Outcome(first.error, first.kind == "fit" and not robust, (), ())
    accepted = [Finding("accepted", f"poor fit accepted with ⟦accept_poor_fit=True⟧: {f.message}")
                for f in refusals if f.kind in _ACCEPTED_NOTE]
    warnings = [f for f in findings if f.error is None]
    return Outcome(None, False, tuple(f.kind for f in refusals), ordered([*accepted, *warnings]))


def ordered(findings: Sequence[Finding]) -> tuple[str, ...]:
    """The messages of warning ``findings`` in :data:`WARNING_ORDER` (stable: within a kind, as found)."""
    return tuple(f.message for f in sorted(findings, key=lambda f: WARNING_ORDER.index(f.kind)))


def retry_kept(consensus: float, longest_run: float, fit_ratio: float | None) -> bool:
    """Whether the outlier retry of a refused fit stands: at least ``RETRY_MIN_INLIERS`` of the samples agree with
    the consensus, no run of more than ``RETRY_MAX_RUN`` of them disagrees, and the inliers' fit-test ratio is
    within ``RETRY_MAX_RATIO`` (None: no fit test, not kept)."""
    return (consensus >= RETRY_MIN_INLIERS and longest_run <= RETRY_MAX_RUN
            and fit_ratio is not None and fit_ratio <= RETRY_MAX_RATIO)
