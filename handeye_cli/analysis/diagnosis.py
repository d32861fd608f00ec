"""What went wrong, in words a user can act on: too few pairs, and data that look wrong.

Every fix names command-line flags (``--max-jump off``), never configuration keys.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import HandEyeError, TooFewPairsError
from ..solvers import solve
from .residuals import Residuals, pair_residuals

if TYPE_CHECKING:
    from ..options import Options
    from ..stages.counts import SampleCounts
    from ..streams import PoseStream

__all__ = ["too_few_pairs", "data_warning"]

# A result whose median residuals exceed these is almost certainly wrong data, not noise; a
# pose-jump gate that drops more than this fraction of the samples is fighting the data.
SUSPECT_ROTATION_DEG = 5.0
SUSPECT_TRANSLATION_M = 0.2
SUSPECT_GATE_FRACTION = 0.25


def too_few_pairs(n_pairs: int, samples: SampleCounts, options: Options) -> TooFewPairsError:
    """Say which stage left too few pairs, and which flags relax it."""
    s, p, need = samples, options.pairs, options.solver.min_pairs
    story = (f"a read {s.read_a}, b read {s.read_b}; timestamp gate dropped {s.dropped_timestamp_gate} and "
             f"{s.dropped_outside_span} were outside b's span; pose-jump gate dropped {s.dropped_pose_jump}; "
             f"{s.keyframes} samples/keyframes gave {s.candidate_pairs} candidate pairs with --pairs {p.pairs}")
    by_time = s.dropped_timestamp_gate + s.dropped_outside_span
    if s.candidate_pairs >= need:
        fix = f"the cap of {p.max_pairs} pairs keeps too few: raise --max-pairs"
    elif s.synced_kept >= 2 * need:
        fix = (f"the motion rotates too little between samples: lower --min-rotation (now {p.min_rotation:g}) "
               "or try --pairs all")
    elif s.dropped_pose_jump >= by_time:
        fix = ("the pose-jump gate dropped most samples: switch it off with --max-jump off --max-jump-deg off "
               "(station captures: --preset robot-arm)")
    else:
        fix = (f"the timestamp gate dropped most samples: widen --max-dt (now {options.sync.max_dt:g} s) or "
               "estimate the clock offset with --time-offset auto")
    return TooFewPairsError(f"only {n_pairs} motion pair(s) left, {need} needed", story, fix)


PairsFn = Callable[["PoseStream", "PoseStream"], tuple[Any, Any, "SampleCounts"]]


def data_warning(stream_a: PoseStream, stream_b: PoseStream, res: Residuals, weights: np.ndarray | None,
                 samples: SampleCounts, pairs_of: PairsFn) -> str | None:
    """A warning when the data look wrong, not just noisy: implausibly large residuals, or a
    pose-jump gate that drops much of the log. A stream of ``T_sensor_world`` given as
    ``T_world_sensor`` (the most common set-up mistake) causes both, so each stream is tried
    inverted (``pairs_of`` re-runs sync, gates and pairing) and named when that fits far better."""
    base = res.summary(None if weights is None else weights > 0)
    dropped = samples.dropped_pose_jump / max(samples.synced, 1)
    large = base.rotation_median_deg > SUSPECT_ROTATION_DEG or base.translation_median_m > SUSPECT_TRANSLATION_M
    if not (large or dropped > SUSPECT_GATE_FRACTION):
        return None
    for name, a, b in (("b", stream_a, stream_b.inverted()), ("a", stream_a.inverted(), stream_b)):
        try:
            _, pairs, alt_samples = pairs_of(a, b)
            alt = pair_residuals(pairs.A, pairs.B, solve(pairs.A, pairs.B).matrix).summary()
        except HandEyeError:
            continue
        better_fit = alt.rotation_median_deg < base.rotation_median_deg / 3
        more_kept = alt_samples.synced_kept > 1.5 * samples.synced_kept
        if (better_fit and alt_samples.synced_kept >= samples.synced_kept) or (
                more_kept and alt.rotation_median_deg <= base.rotation_median_deg):
            return (f"stream {name} looks inverted (T_sensor_world instead of T_world_sensor): inverted, the "
                    f"median residuals go from {base.rotation_median_deg:.2f}° / {base.translation_median_m:.3f} m "
                    f"to {alt.rotation_median_deg:.2f}° / {alt.translation_median_m:.3f} m and the pose-jump gate "
                    f"keeps {alt_samples.synced_kept} samples instead of {samples.synced_kept}; rerun with "
                    f"--invert-{name} (or --no-invert-{name} if it was inverted)")
    if large:
        return (f"large residuals (median {base.rotation_median_deg:.2f}° / {base.translation_median_m:.3f} m): the "
                "streams may not be rigidly attached, be mis-synchronised (try --time-offset auto) or come from "
                "the wrong topics")
    return (f"the pose-jump gate dropped {samples.dropped_pose_jump} of {samples.synced} samples "
            f"({100 * dropped:.0f} %): the sensors move faster than its limits allow at this rate; raise "
            "--max-jump / --max-jump-deg, or check the tracking")
