"""The checks of a solved calibration, each turned into :class:`~.policy.Finding` objects for the policy: the
inversion check, a given quaternion order's check, what the motion leaves undetermined, the fit test, a station
capture's moved mount, and the suspect-data warning. Each check's numbers live in :mod:`handeye_cli.analysis`; what
they mean for exit 0 is decided once, by :func:`~.policy.policy`.

``X`` is ``T_a_b`` (maps points from b to a); rotations [deg] in messages, translations [m].
"""
from __future__ import annotations

import numpy as np

from ..analysis import Residuals
from ..analysis.diagnosis import data_warning
from ..analysis.fit_test import FitTest
from ..analysis.inversion import InversionVerdict, check_inversion
from ..analysis.observability import Observability
from ..analysis.readings import OrderContradiction, contradicted_order
from ..calibration.inputs import Inputs
from ..calibration.pairing import Paired, checked_poses
from ..errors import FitRejectedError
from ..options import Options
from ..solvers import Prior
from ..streams import PoseStream
from .policy import Finding

__all__ = ["fit_refusal", "inversion", "moved_mount", "observability", "order_contradiction", "suspect_data"]


def inversion(paired: Paired, options: Options, alpha: float,
              inputs: Inputs) -> tuple[InversionVerdict | None, Finding | None]:
    """The inversion check on the solved pairs (its thresholds are set at ``alpha``) and, when its evidence is
    overwhelming or contradicts an explicit ``--invert-*``, its refusal. ``inputs`` (what was read) names a TF
    stream's frame pair, whose fix is naming the frames the other way round."""
    read = options.read
    verdict = check_inversion(*checked_poses(paired), alpha=alpha,
                              inverted_now=(bool(read.invert_a), bool(read.invert_b)),
                              frames=(inputs.frames("a"), inputs.frames("b")))
    if verdict is None:
        return None, None
    refusal = verdict.refusal(read.invert_a is not None or read.invert_b is not None)
    return verdict, (None if refusal is None else Finding.refusal("inversion", refusal, verdict.message()))


def order_contradiction(stream_a: PoseStream, stream_b: PoseStream, paired: Paired,
                        options: Options) -> tuple[OrderContradiction | None, Finding | None]:
    """The check of each quaternion order that was given, not chosen by the fit (a log's fields, ``--wxyz-*`` /
    ``--no-wxyz-*``, a stream in memory: :func:`~handeye_cli.analysis.readings.contradicted_order`), on the solved
    pairs of the streams as used, and its refusal."""
    read = options.read
    orders = tuple(None if s.quaternion_order is not None else "wxyz" if w else "xyzw"
                   for s, w in ((stream_a, read.wxyz_a), (stream_b, read.wxyz_b)))
    found = contradicted_order(*checked_poses(paired), (orders[0], orders[1]),
                               inverted=(bool(read.invert_a), bool(read.invert_b)))
    return found, (None if found is None else Finding.refusal("order", found.refusal(), found.message()))


UNDETERMINED = ("pure_translation", "unobservable")
"""The observability findings a result cannot leave with unless a prior fixes what they name: no motion rotates
(the translation is open along every axis), or cost (8) is flat in a direction. Motion about one axis is the
subspace's (:mod:`handeye_cli.analysis.subspace`: a ground robot's z from the prior or marked unobservable, an
oblique axis refused), a direction merely poorly determined a warning."""


def observability(obs: Observability, prior: Prior | None) -> list[Finding]:
    """The observability findings as the policy reads them: each a warning, except, without a ``prior`` (which
    determines it), the first of :data:`UNDETERMINED`: the refusal ``undetermined`` of a result that rests on what
    the motion does not determine, its text said once (as the accepted note under ``accept_poor_fit``)."""
    refused = None if prior is not None else next((w for w in obs.warnings if w.code in UNDETERMINED), None)
    return [Finding.refusal("undetermined", w.refusal(), str(w)) if w is refused
            else Finding.warning("observability", str(w)) for w in obs.warnings]


def fit_refusal(fit: FitTest, options: Options, paired: Paired, *, inverted: bool) -> Finding | None:
    """The fit test's refusal (residuals far beyond the streams' own noise), its causes ordered by the evidence
    (``inverted``: the inversion check found a stream that fits better inverted); None when it passed."""
    error = fit.refusal(options, paired.stations is not None, inverted=inverted)
    return None if error is None else Finding.refusal("fit", error, fit.summary())


def moved_mount(paired: Paired, res: Residuals, options: Options, alpha: float,
                prior: Prior | None) -> Finding | None:
    """A station capture's refusal when the stations before one stamp fit another extrinsic than those after it
    (:func:`~handeye_cli.analysis.robust.moved_during`): the fit test's noise of sparse stations is an assumed one,
    lenient enough that a mount slipping 10° / 5 cm between two stations passes it."""
    from ..analysis.robust import moved_during

    pairs = paired.pairs
    found = moved_during(pairs.A, pairs.B, pairs.i, pairs.j, res, method=options.solver.method, alpha=alpha,
                         prior=prior)
    if found is None:
        return None
    cut, gain = found
    stamps = paired.synced.stamps_ns
    what = (f"the extrinsic changed during the capture: the stations from number {cut + 1} at "
            f"{(stamps[cut] - stamps[0]) / 1e9:.1f} s since the first station on "
            f"fit another T_a_b, and each part fits its own {gain:.3g}× better than one fits both")
    return Finding.refusal("moved", FitRejectedError(
        what, "fit test", "check that the sensor is rigidly mounted and calibrate the stations before "
        "and after apart; to keep this result anyway: ⟦accept_poor_fit=True⟧ (exit code 3)"), what)


def suspect_data(verdict: InversionVerdict | None, res: Residuals, weights: np.ndarray | None,
                 paired: Paired) -> Finding | None:
    """The first warning about the data themselves: a stream that looks inverted, else implausibly large residuals
    or a pose-jump gate that dropped much of the log (:func:`~handeye_cli.analysis.diagnosis.data_warning`)."""
    message = verdict.message() if verdict else data_warning(res, weights, paired.samples)
    return Finding.warning("suspect", message) if message else None
