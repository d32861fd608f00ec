"""One reading's pairs: sync (or stations), gates and pair formation, computed once as a frozen :class:`Paired`
and reused by every step that reads them (the solve, the checks of the reading, the fit test).

The motions are ``A_k = T_a(t_i)⁻¹ T_a(t_j)``, ``B_k`` likewise, with ``A_k X = X B_k`` for ``X = T_a_b``
(positions [m], int64 ns stamps, quaternions x-y-z-w).
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..analysis.diagnosis import too_few_pairs
from ..analysis.readings import spread_pairs
from ..analysis.selection import Selection, select_pairs
from ..options import Options
from ..solvers import Prior
from ..stages.counts import SampleCounts
from ..stages.gates import sync_and_gate
from ..stages.pairs import Pairs, make_pairs
from ..stages.stations import Stations, detect_stations
from ..stages.sync import Synced, default_max_dt_ns
from ..streams import PoseStream

__all__ = ["Paired", "checked_poses", "pairs_of"]


@dataclass(frozen=True, eq=False)
class Paired:
    """What :func:`pairs_of` made of two streams at one clock offset.

    synced: the samples kept by sync and the gates (a station capture: its averaged stations);
    pairs: the motions solved; samples: what every stage read, kept and dropped; stations: the station capture
    (None for continuous streams); selection: the ``auto`` strategy's pair selection (weights, α, noise model;
    None for another strategy, or for pairs made like another selection's)."""

    synced: Synced
    pairs: Pairs
    samples: SampleCounts
    stations: Stations | None
    selection: Selection | None


_KNOWN: weakref.WeakKeyDictionary[PoseStream, weakref.WeakKeyDictionary[PoseStream, dict[tuple[Any, ...], Paired]]] \
    = weakref.WeakKeyDictionary()
"""Each pair of streams' pairings without a prior or a selection to follow, by clock offset and the options they
read, while the streams live: ``handeye rig`` confirms a stream's clock offset with the fit of its pairs with the
reference (:func:`~handeye_cli.verify.reading.confirm_offset`), then calibrates that same pair at that offset."""


def pairs_of(stream_a: PoseStream, stream_b: PoseStream, options: Options, offset_ns: int,
             prior: Prior | None, like: Selection | None = None) -> Paired:
    """Sync, gates and pair formation at b's clock offset ``offset_ns`` [ns] (:func:`_paired`), made once per pair of
    streams, offset and the options it reads where neither a ``prior`` nor ``like`` is given."""
    if prior is not None or like is not None:
        return _paired(stream_a, stream_b, options, offset_ns, prior, like)
    key = (int(offset_ns), options.sync.sync, options.sync.max_dt_ns, options.gates, options.pairs,
           options.solver.min_pairs, options.solver.method)
    known = _KNOWN.setdefault(stream_a, weakref.WeakKeyDictionary()).setdefault(stream_b, {})
    if key not in known:
        known[key] = _paired(stream_a, stream_b, options, offset_ns, prior, like)
    return known[key]


def _paired(stream_a: PoseStream, stream_b: PoseStream, options: Options, offset_ns: int,
            prior: Prior | None, like: Selection | None = None) -> Paired:
    """Sync, gates and pair formation at b's clock offset ``offset_ns`` [ns]. ``prior`` is the options'
    prior, read once by the caller (:func:`~.inputs.read_prior`). ``like``: for the ``auto`` strategy, the pairs of
    that selection's strides instead of a selection (None: no weights to solve with; a comparison's pairs).

    A station capture (see :mod:`~handeye_cli.stages.stations`) skips sync and the pose-jump gate:
    its averaged stations are the samples, paired all with all. Raises the too-few-pairs error
    (:func:`~handeye_cli.analysis.diagnosis.too_few_pairs`) naming the stage that dropped them."""
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
    return Paired(kept, pairs, samples, stations, selection)


def checked_poses(paired: Paired) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(T_a, T_b, i, j): the absolute poses of the samples of the pairs a reading's check compares on
    (:func:`~handeye_cli.analysis.readings.spread_pairs`: at most ``CHECKED_PAIRS``), and those pairs as indices
    into them, so that a check builds and re-reads a thousand poses, not every synced sample's."""
    i, j = spread_pairs(paired.pairs.i, paired.pairs.j)
    rows, at = np.unique(np.r_[i, j], return_inverse=True)
    used = paired.synced.select(rows)
    return used.T_a, used.T_b, at[:len(i)], at[len(i):]
