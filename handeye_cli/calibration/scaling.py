"""``--scale auto``, and b's units found by the fit: b's scale [m per unit of b] estimated with ``T_a_b`` on a
reading's pairs, and the pairs in metres (:mod:`handeye_cli.solvers.scale`)."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from ..analysis.fit_test import sample_noise
from ..analysis.stream_noise import StreamNoise
from ..options import Options
from ..solvers import Prior
from ..solvers.scale import ScaleSolution, scale_translations, solve_with_scale
from ..streams import PoseStream
from .pairing import Paired, pairs_of

__all__ = ["NoiseOf", "scaled"]

NoiseOf = Callable[[PoseStream], StreamNoise | None]
"""Each stream's jitter (the fit test's noise): :func:`~handeye_cli.analysis.stream_noise.stream_noise`, or a
rig's memo of it."""


def _with_scale(stream_a: PoseStream, stream_b: PoseStream, paired: Paired, options: Options, noise_of: NoiseOf,
                ) -> tuple[Paired, ScaleSolution]:
    """b's scale estimated with T_a_b on ``paired`` (made of ``stream_b``), and the pairing with b's samples and
    motions in metres. The translation noise of both streams (their jitter, as the fit test reads it) weighs the
    residuals against the errors in variables (:mod:`~handeye_cli.solvers.scale`). With a ``selection`` made on b
    already scaled, its α is used and the scale refined; not its weights, which favour short drifting pairs whose
    translations are mostly noise and so bias the scale low (errors in variables: 0.433 ± 0.021 weighted against
    0.491 ± 0.004 unweighted for kinhec's 0.5)."""
    pairs, selection = paired.pairs, paired.selection
    alpha = 1.0 if options.solver.alpha == "auto" else float(options.solver.alpha)
    if selection is not None and options.solver.alpha == "auto":
        alpha = selection.alpha
    noise = sample_noise(stream_a, stream_b, paired.synced, paired.stations, options.sync.sync, noise_of)
    est = solve_with_scale(pairs.A, pairs.B, alpha=alpha, samples=(pairs.i, pairs.j),
                           translation_noise=noise.translation_variances(pairs.i, pairs.j))
    return replace(paired, synced=replace(paired.synced, xyz_b=paired.synced.xyz_b * est.scale),
                   pairs=replace(pairs, B=scale_translations(pairs.B, est.scale))), est


def scaled(stream_a: PoseStream, stream_b: PoseStream, paired: Paired, options: Options, offset_ns: int,
           prior: Prior | None, noise_of: NoiseOf) -> tuple[Paired, ScaleSolution]:
    """b's scale estimated with ``T_a_b`` on ``paired`` (:func:`~.pairing.pairs_of`'s); with the ``auto`` pair
    strategy the pairs, weights and α are then chosen again on b scaled by that estimate, and the scale refined on
    them. Returns the pairing in metres and the estimate, its scales in b's units as given."""
    metric, est = _with_scale(stream_a, stream_b, paired, options, noise_of)
    if paired.selection is None:
        return metric, est
    scaled_b = stream_b.scaled(est.scale)
    again = pairs_of(stream_a, scaled_b, options, offset_ns, prior)
    metric, refined = _with_scale(stream_a, scaled_b, again, options, noise_of)
    return metric, refined.times(est.scale)
