"""Pairwise stage of a rig: per-stream clock offsets, then one optimal calibration per pair of streams.

Streams are ``T_wk_k(t)`` (int64 ns stamps in each sensor's own clock). The clock offset ``o_k``
of stream k is how far its clock is ahead of the reference's (the sign convention of
:func:`handeye_cli.stages.sync.associate`); pair (j, k) is then calibrated with the offset
``o_k - o_j`` by :func:`handeye_cli.calibration.calibrate` (sync → gates → pairs → solver, the same
stages and settings as ``handeye calibrate``), giving ``T_j_k`` (pose of k in j; maps points
from k to j) and its motion pairs ``A_i X = X B_i``.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..analysis.stream_noise import StreamNoise, stream_noise
from ..calibration import Calibration, Checks, calibrate_read
from ..errors import ConfigError, HandEyeError
from ..options import Options
from ..solvers.problem import pair_forms
from ..streams import PoseStream, StreamMemo
from ..verify.reading import confirm_offset

__all__ = ["ClockOffset", "Edge", "clock_offsets", "solve_edges"]


@dataclass(frozen=True)
class ClockOffset:
    """How far a stream's clock is ahead of the reference's: ``offset_ns`` [ns] (the one the pairs use), its 1-σ
    ``std_ns`` (None when fixed), and ``method`` (``fixed``, ``reference`` or the estimator's). An estimated
    offset also has ``estimated_ns`` and ``applied``: whether the estimate is applied — calibrate's rule,
    significant, unambiguous and confirmed by the fit of the stream's pairs with the reference
    (:func:`~handeye_cli.verify.reading.confirm_offset`; ``confirmed_by`` says how) — one that is not leaves
    ``offset_ns`` 0."""

    offset_ns: int
    std_ns: float | None
    method: str
    warnings: tuple[str, ...] = ()
    estimated_ns: int | None = None
    applied: bool = True
    confirmed_by: str | None = None

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"seconds": self.offset_ns / 1e9, "method": self.method}
        if self.std_ns is not None:
            out["std_seconds"] = self.std_ns / 1e9
        if self.estimated_ns is not None:
            out.update(applied=self.applied, estimated_seconds=self.estimated_ns / 1e9)
        if self.confirmed_by is not None:
            out["confirmed_by"] = self.confirmed_by
        return out


@dataclass(frozen=True, eq=False)
class Edge:
    """The pairwise-only result of streams ``j < k`` (indices into the rig's stream list).

    calibration: what :func:`~handeye_cli.calibration.calibrate` returned (``matrix`` = ``T_j_k``).
    forms: (2, 8, 8) the rotational and dual parts of its cost (8) (``[q'; q]`` order, its α and
    per-pair weights): the pair's cost of any ``T_j_k`` is ``Σ_p [q'; q]ᵀ forms[p] [q'; q]``.
    """

    j: int
    k: int
    calibration: Calibration
    forms: NDArray[np.float64]

    @property
    def matrix(self) -> NDArray[np.float64]:
        """``T_j_k`` from this pair alone."""
        return self.calibration.matrix


def clock_offsets(streams: list[PoseStream], reference: int, given: Mapping[int, float | str], options: Options
                  ) -> list[ClockOffset]:
    """Each stream's clock offset to the reference: ``given[k]`` seconds, or estimated (``'auto'``,
    the default) from the angular velocities of stream k and the reference (within ``options``'
    ``max_time_offset``), and applied where ``calibrate`` would apply it — significant, unambiguous and confirmed
    by the fit of the pairs it gives (:func:`~handeye_cli.verify.reading.confirm_offset`, paired with ``options``)
    — else 0."""
    from ..stages.timeoffset import estimate_time_offset, grid_of

    out, grid = [], StreamMemo(grid_of)                # the reference's ω grid once per step, not once per stream
    for k, stream in enumerate(streams):
        value = given.get(k, "auto")
        if k == reference:
            out.append(ClockOffset(0, None, "reference"))
        elif isinstance(value, str) and value.strip().lower() == "auto":
            est = estimate_time_offset(streams[reference], stream, max_offset_s=options.sync.max_time_offset,
                                       grid=grid)
            reading = confirm_offset(streams[reference], stream, options, est)
            out.append(ClockOffset(reading.offset_ns, est.std_ns, est.method, tuple(est.warnings), est.offset_ns,
                                   bool(reading.applied), reading.confirmed_by if est.applicable else None))
        else:
            try:
                out.append(ClockOffset(int(round(float(value) * 1e9)), None, "fixed"))
            except (TypeError, ValueError):
                raise ConfigError(f"bad time offset {value!r}", stream.source or f"stream {k}",
                                  "give seconds (the stream's clock ahead of the reference's) or 'auto'") from None
    return out


def _edge(streams: list[PoseStream], j: int, k: int, offsets: list[ClockOffset], options: Options,
          chosen: list[bool], noise: StreamMemo[StreamNoise | None], names: tuple[str, str], checks: Checks) -> Edge:
    # the rig's bootstrap resamples all pairs at once. A stream whose inversion the user gave (inverted by the
    # rig already, or said not to be) is "not inverted (again), by the user's word": the inversion check then
    # refuses in those words, as calibrate's --no-invert-a does. A prior (the rig's nominal) is read for the
    # pair's frames, the sensors' names: T_j_k = T_ref_j⁻¹ T_ref_k of the nominal
    said: dict[str, Any] = {key: False for key, c in (("invert_a", chosen[j]), ("invert_b", chosen[k])) if c}
    if options.solver.prior is not None:
        said.update(name_a=names[0], name_b=names[1])
    opts = Options.from_flat(options, time_offset=(offsets[k].offset_ns - offsets[j].offset_ns) / 1e9,
                             bootstrap=0, **said)
    cal = calibrate_read(streams[j], streams[k], opts, scale_by_fit=False,   # the rig's reader applied the read
                         noise_of=noise, checks=checks)       # options; a badly scaled stream is named by the rig
    A, B, w = cal.pairs.A, cal.pairs.B, cal.weights
    forms = pair_forms(A, B, cal.solution.alpha, cal.matrix)   # weighed by einsum, not by a (threaded) product
    return Edge(j, k, cal, forms.sum(axis=0) if w is None else np.einsum("n,npij->pij", w, forms))


def solve_edges(streams: list[PoseStream], names: list[str], offsets: list[ClockOffset],
                options: Options, chosen: list[bool] | None = None, reference: int = 0) -> tuple[list[Edge], list[str]]:
    """Calibrate every pair ``j < k`` with ``options`` (sync, gates, pairs, solver; the time offset
    is the pair's, from ``offsets``; ``chosen``: per stream, whether the user said whether it is inverted); a
    pair that cannot be calibrated (the fit test or the inversion check refuses it, too few pairs, …) is left
    out with a warning.

    Each pair runs ``calibrate``'s stages and fit test, not every check after the solve
    (:class:`~handeye_cli.calibration.Checks`). The pairs with the ``reference`` are solved first, each with the
    inversion check; a pair without it runs the check only when one of its streams is not cleared by its
    pair with the reference (calibrated there with no inversion suspected): that pair tested the same stream
    already. No pair runs calibrate's uncertainty check (σ from blocks of time): the rig's noise model,
    drift test and bias bound are its pairs' uncertainty.
    Returns the edges and the warnings (each pair's own warnings prefixed with its names), in the order
    of the pairs ``j < k``."""
    n = len(streams)
    order = sorted(((j, k) for j in range(n) for k in range(j + 1, n)), key=lambda p: reference not in p)
    done: dict[tuple[int, int], tuple[Edge | None, list[str]]] = {}
    noise = StreamMemo(stream_noise)                          # each stream's jitter once, not once per pair
    cleared = {reference}
    for j, k in order:
        checks = Checks(inversion=reference in (j, k) or not {j, k} <= cleared, uncertainty=False)
        try:
            edge = _edge(streams, j, k, offsets, options, chosen or [False] * n, noise, (names[j], names[k]),
                         checks)
        except HandEyeError as refused:
            done[j, k] = None, [f"pair {names[j]}-{names[k]} left out: {refused}"]
            continue
        if reference in (j, k) and edge.calibration.diagnostics.inversion is None:
            cleared.add(k if j == reference else j)
        done[j, k] = edge, [f"pair {names[j]}-{names[k]}: {w}" for w in edge.calibration.warnings]
    return ([e for p in sorted(done) if (e := done[p][0]) is not None],
            [w for p in sorted(done) for w in done[p][1]])
