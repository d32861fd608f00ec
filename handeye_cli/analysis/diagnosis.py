"""What went wrong, in words a user can act on: too few pairs, and data that look wrong.

Every fix names options by key (``⟦gate='off'⟧``, :func:`~handeye_cli.errors.option`): the CLI says the flag,
Python the keyword.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import TooFewPairsError
from .residuals import Residuals

if TYPE_CHECKING:
    from ..options import Options
    from ..stages.counts import SampleCounts

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
             f"{s.keyframes} samples/keyframes gave {s.candidate_pairs} candidate pairs by the {p.pairs} pair strategy")
    by_time = s.dropped_timestamp_gate + s.dropped_outside_span
    if s.candidate_pairs >= need:
        fix = f"the cap of pairs keeps too few: raise ⟦max_pairs=N⟧ (now {p.max_pairs})"
    elif s.synced_kept >= 2 * need:
        fix = (f"the motion rotates too little between samples: lower ⟦min_rotation⟧ (now {p.min_rotation:g}) "
               "or try ⟦pairs='all'⟧")
    elif s.dropped_pose_jump >= by_time:
        fix = ("the pose-jump gate dropped most samples: try ⟦gate='auto'⟧ (it follows the sampling rate) or switch it "
               "off with ⟦gate='off'⟧ (station captures: ⟦preset='robot-arm'⟧)")
    else:
        fix = (f"the timestamp gate dropped most samples: widen ⟦max_dt⟧ (now {options.sync.max_dt}), let the slower "
               "stream set the sample times with ⟦sync='auto'⟧, or give the clock offset with ⟦time_offset=SECONDS⟧")
    return TooFewPairsError(f"only {n_pairs} motion pair(s) left, {need} needed", story, fix)


def data_warning(res: Residuals, weights: np.ndarray | None, samples: SampleCounts) -> str | None:
    """A warning when the data look wrong, not just noisy: implausibly large residuals, or a
    pose-jump gate that drops much of the log. (An inverted stream, the commonest cause of both,
    is named by :func:`handeye_cli.analysis.inversion.check_inversion` before this is asked.)"""
    base = res.summary(None if weights is None else weights > 0)
    dropped = samples.dropped_pose_jump / max(samples.synced, 1)
    large = base.rotation_median_deg > SUSPECT_ROTATION_DEG or base.translation_median_m > SUSPECT_TRANSLATION_M
    if not (large or dropped > SUSPECT_GATE_FRACTION):
        return None
    if large:
        return (f"large residuals (median {base.rotation_median_deg:.2f}° / {base.translation_median_m:.3f} m): the "
                "streams may not be rigidly attached, be mis-synchronised (give ⟦time_offset=SECONDS⟧), come from "
                "the wrong topics, or b's translations have another scale (monocular odometry: ⟦scale='auto'⟧)")
    return (f"the pose-jump gate dropped {samples.dropped_pose_jump} of {samples.synced} samples "
            f"({100 * dropped:.0f} %): the sensors move faster than its limits allow at this rate; try "
            "⟦gate='auto'⟧ (it follows the rate), widen ⟦gate='paper'⟧'s ⟦max_jump⟧ / ⟦max_jump_deg⟧, or check the "
            "tracking")
