"""The fit test: do the residuals at ``X`` fit a rigid rig under the streams' own noise?

Conventions: ``X = T_a_b`` (maps points from b to a); motions ``A_k X = X B_k`` with
``A_k = T_a(t_i)⁻¹ T_a(t_j)``; quaternions x-y-z-w; radians and metres inside, degrees in the
result document.

1. **Noise, independent of X.** Each synced sample of each stream gets a per-axis σ (rotation,
   translation) from that stream alone: for continuous tracking, its high-frequency jitter
   (:func:`~handeye_cli.analysis.stream_noise.stream_noise`) plus, for the stream read between its
   samples (interpolated or nearest), the error of doing so; for a station capture, the scatter of
   the samples averaged at each station divided by √(inliers) — the noise of the average. The noise
   model of the ``auto`` strategy is *not* used: it is fitted to the residuals at a probe ``X`` and
   would call any misfit noise.
2. **What that noise predicts.** The predicted residual of each pair is propagated exactly, by
   drawing: the rigid motions ``B̂_k = X⁻¹ A_k X`` and ``A_k`` get the four poses' noise as right
   perturbations (``_DRAWS`` seeded draws), and the residuals of ``A X = X B`` are taken at ``X``
   (:func:`~handeye_cli.analysis.residuals.residuals_batch`), so the lever arms of the rig and of each
   motion are in. ``s_k`` is the RMS of pair k's drawn residuals.
3. **The statistic** (rotation and translation apart): the median over pairs of ``r_k / s_k``, the
   actual residual in units of its prediction, divided by the same median of the drawn residuals:
   the *ratio* is 1 when the residuals are exactly as large as the jitter predicts.
4. **The threshold** is generous, :data:`THRESHOLD`: real residuals exceed the jitter's prediction by
   what the jitter cannot see — drift of odometry over a pair's span (simulated phone VIO: 2–4×),
   kinematic and target-detection errors of arms (real: up to ≈ 6×), stamp jitter, heavy tails —
   while a wrong unit, quaternion order, inversion, frame order or stream gives ratios of 30 to 10⁴.
   A capture whose noise cannot be estimated (sparse poses: one sample per station, no neighbours)
   is judged against :data:`SPARSE_SIGMA_DEG` / :data:`SPARSE_SIGMA_M` per pose, the noise of a poor
   target detector, so that only what no real rig produces is refused.

:meth:`FitTest.refusal` turns a failed test into a
:class:`~handeye_cli.errors.FitRejectedError` naming the likely causes in order, each with the flag
that tests it.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..errors import FitRejectedError
from ..geometry import dualquat as dq
from ..geometry import se3
from .residuals import Residuals, residuals_batch
from .stream_noise import StreamNoise, stream_noise

if TYPE_CHECKING:
    from ..options import Options
    from ..stages.pairs import Pairs
    from ..stages.stations import Stations
    from ..stages.sync import Synced
    from ..streams import PoseStream

__all__ = ["FitTest", "SampleNoise", "fit_test", "sample_noise", "THRESHOLD"]

#: refuse when a median residual exceeds this many times what the streams' noise predicts
THRESHOLD = 15.0
#: per-axis noise assumed per pose when a capture holds no neighbouring samples to estimate it from
SPARSE_SIGMA_DEG = 0.15
SPARSE_SIGMA_M = 0.0015
_FLOOR_RAD, _FLOOR_M = 1e-7, 1e-7     # numerical floor of σ (noise-free simulations)
_DRAWS = 8
_SEED = 0                              # the draws are fixed: a recording always gives one answer


@dataclass(frozen=True, eq=False)
class SampleNoise:
    """Per synced sample and stream, the per-axis σ of rotation [rad] and translation [m]:
    ``rot_a``, ``trans_a``, ``rot_b``, ``trans_b`` (N,), and where they came from (``source``)."""

    rot_a: FloatArray
    trans_a: FloatArray
    rot_b: FloatArray
    trans_b: FloatArray
    source: str
    streams: dict[str, Any]

    @property
    def measured(self) -> bool:
        """Both streams' noise is measured (False: assumed for sparse poses, :data:`SPARSE_SIGMA_M` — no
        measurement, and not in b's units)."""
        return not any(self.streams[k].get("assumed") for k in "ab")

    def translation_variances(self, i: IntArray, j: IntArray) -> tuple[FloatArray, FloatArray] | None:
        """Per pair of samples ``(i, j)``, the per-axis variance of a's and of b's relative translation
        [m², or b's units² for b], ``σ_i² + σ_j²``; None when either stream's noise is not :attr:`measured`."""
        if not self.measured:
            return None
        return self.trans_a[i] ** 2 + self.trans_a[j] ** 2, self.trans_b[i] ** 2 + self.trans_b[j] ** 2


@dataclass(frozen=True)
class _Part:
    """One half of the test: statistic (median r/s), expected (the same of the draws), ratio."""

    statistic: float
    expected: float

    @property
    def ratio(self) -> float:
        return self.statistic / self.expected if self.expected > 0 else float("inf")

    def as_dict(self, median: float, predicted: float, unit: str) -> dict[str, float]:
        return {"statistic": self.statistic, "expected": self.expected, "ratio": self.ratio,
                f"median_residual_{unit}": median, f"predicted_median_{unit}": predicted}


@dataclass(frozen=True)
class FitTest:
    """The fit test's figures (module docstring) and verdict."""

    rotation: _Part
    translation: _Part
    medians: tuple[float, float, float, float]     # residual and predicted median: rot [deg], trans [m]
    threshold: float
    source: str
    streams: dict[str, Any]
    pairs: int

    @property
    def ratio(self) -> float:
        """The larger of the rotation and translation ratios."""
        return max(self.rotation.ratio, self.translation.ratio)

    @property
    def passed(self) -> bool:
        return bool(self.ratio <= self.threshold)

    def as_dict(self) -> dict[str, Any]:
        """The result's ``fit_test`` entry."""
        r_med, r_pred, t_med, t_pred = self.medians
        return {"passed": self.passed, "ratio": self.ratio, "threshold": self.threshold,
                "rotation": self.rotation.as_dict(r_med, r_pred, "deg"),
                "translation": self.translation.as_dict(t_med, t_pred, "m"),
                "noise_source": self.source, "noise": self.streams, "pairs": self.pairs,
                "note": "ratio: median residual in units of what each stream's own noise (jitter, or the "
                        "scatter at stations) predicts for the pair, over the same median of simulated "
                        "noise; 1 = as predicted"}

    def summary(self) -> str:
        """One line: the medians, the ratio and the threshold."""
        r_med, r_pred, t_med, t_pred = self.medians
        return (f"median residuals {r_med:.3g}° / {1e3 * t_med:.3g} mm where the streams' noise predicts "
                f"{r_pred:.2g}° / {1e3 * t_pred:.2g} mm: {self.ratio:.3g}× (limit {self.threshold:g}×)")

    def refusal(self, options: Options, stations: bool, *, inverted: bool = False) -> FitRejectedError | None:
        """The error refusing this result (None when it passed): the causes ordered by the evidence —
        ``stations`` (a station capture: a wrong time unit merges or splits stations first),
        ``inverted`` (the inversion check found a stream that fits better inverted)."""
        if self.passed:
            return None
        return FitRejectedError(f"the result does not fit a rigid rig: {self.summary()}",
                                "fit test", _causes(options, stations, inverted, self))


def _causes(options: Options, stations: bool, inverted: bool, test: FitTest) -> str:
    """The likely causes, most likely first, each with the flag that tests it."""
    read, solver = options.read, options.solver
    unit = f"stamps in another unit (⟦time_unit='s|ms|us|ns'⟧; now {read.time_unit})"
    wxyz = ("quaternions not stored w first after all (drop ⟦wxyz_a=True⟧ / ⟦wxyz_b=True⟧)"
            if read.wxyz_a or read.wxyz_b
            else "quaternions stored w first (⟦wxyz_a=True⟧ / ⟦wxyz_b=True⟧)")
    invert = ("a stream recorded as T_sensor_world (⟦invert_a=True⟧ / ⟦invert_b=True⟧"
              + (", or drop the one given)" if read.invert_a or read.invert_b else ")"))
    causes = [invert, wxyz, unit] if inverted else [unit, wxyz, invert] if stations else [wxyz, invert, unit]
    causes.append("TF frames in the wrong order (⟦stream_a='tf:PARENT,CHILD'⟧, the parent first)")
    if options.sync.time_offset != "auto":
        causes.append("a clock offset (⟦time_offset='auto'⟧, with ⟦max_time_offset=SECONDS⟧ for a large one)")
    if solver.scale == 1.0:
        scale = "b's translations in another unit (⟦scale='auto'⟧)"
        causes.insert(0 if test.translation.ratio > 3 * test.rotation.ratio else len(causes), scale)
    if not options.analysis.robust:
        causes.append("outliers (⟦robust=True⟧)")
    causes.append("streams that are not rigidly attached, or the wrong topics")
    return ("check " + "; ".join(f"{k + 1}. {c}" for k, c in enumerate(causes))
            + "; to keep this result anyway: ⟦accept_poor_fit=True⟧ (exit code 3)")


def _stream_sigmas(stream: PoseStream, noise: StreamNoise | None, interpolated: str | None, n: int
                   ) -> tuple[FloatArray, FloatArray, dict[str, Any]]:
    if noise is None:
        report: dict[str, Any] = {"sigma_rotation_deg": SPARSE_SIGMA_DEG, "sigma_translation_m": SPARSE_SIGMA_M,
                                  "samples": 0, "assumed": True}
        return np.full(n, np.deg2rad(SPARSE_SIGMA_DEG)), np.full(n, SPARSE_SIGMA_M), report
    rot, trans = noise.sigma_rotation_rad, noise.sigma_translation_m
    report = noise.as_dict()
    if interpolated:
        ir, it = noise.interpolation_sigma(interpolated)
        rot, trans = float(np.hypot(rot, ir)), float(np.hypot(trans, it))
        report["read_between_samples"] = interpolated
        report["with_interpolation_deg_m"] = [float(np.rad2deg(rot)), trans]
    return np.full(n, rot), np.full(n, trans), report


def sample_noise(stream_a: PoseStream, stream_b: PoseStream, synced: Synced, stations: Stations | None,
                 sync_method: str, noise_of: Callable[[PoseStream], StreamNoise | None] = stream_noise
                 ) -> SampleNoise:
    """Per-axis σ of every synced sample of both streams, from the streams alone (module docstring, 1);
    ``noise_of``: a stream's jitter (:func:`stream_noise`, or a memo of it that a rig shares between pairs)."""
    n = len(synced)
    if stations is not None:
        out: list[FloatArray] = []
        streams: dict[str, Any] = {}
        for name, spread, inliers, raw in (("a", stations.spread_a, stations.inliers_a, stream_a),
                                           ("b", stations.spread_b, stations.inliers_b, stream_b)):
            jitter = noise_of(raw)
            known = (inliers > 1) & (spread[:, 0] > 0)
            per = spread / np.sqrt(3.0) / np.sqrt(np.maximum(inliers, 1))[:, None]     # 3D RMS → per axis, /√n
            if not known.any():
                rot, trans, streams[name] = _stream_sigmas(raw, jitter, None, n)
            else:
                fill = np.median(per[known], axis=0)
                per[~known] = fill
                rot, trans = np.deg2rad(per[:, 0]), per[:, 1]
                streams[name] = {"sigma_rotation_deg": float(np.rad2deg(np.median(rot))),
                                 "sigma_translation_m": float(np.median(trans)), "from": "station scatter"}
            out += [rot, trans]
        source = "station scatter" if all(streams[k].get("from") for k in "ab") else "mixed"
        return SampleNoise(out[0], out[1], out[2], out[3], source, streams)
    method = "nearest" if sync_method == "nearest" else "interpolate"
    ra, ta, rep_a = _stream_sigmas(stream_a, noise_of(stream_a), method if synced.reference == "b" else None, n)
    rb, tb, rep_b = _stream_sigmas(stream_b, noise_of(stream_b), method if synced.reference == "a" else None, n)
    assumed = rep_a.get("assumed") or rep_b.get("assumed")
    return SampleNoise(ra, ta, rb, tb, "assumed (sparse poses)" if assumed else "stream jitter",
                       {"a": rep_a, "b": rep_b})


def _perturbations(rng: np.random.Generator, sigma_rot: FloatArray, sigma_trans: FloatArray) -> FloatArray:
    """(K, N, 4, 4) right perturbations: rotation vector and translation per axis normal(0, σ) [rad], [m]."""
    shape = (_DRAWS, len(sigma_rot), 3)
    D = np.tile(np.eye(4), (_DRAWS, len(sigma_rot), 1, 1))
    D[..., :3, :3] = dq.to_matrix(dq.from_rotvec(rng.normal(size=shape) * sigma_rot[None, :, None]))
    D[..., :3, 3] = rng.normal(size=shape) * sigma_trans[None, :, None]
    return D


def fit_test(pairs: Pairs, residuals: Residuals, X: FloatArray, noise: SampleNoise, *,
             mask: BoolArray | None = None, threshold: float = THRESHOLD) -> FitTest:
    """The fit test of the residuals of ``pairs`` at ``X = T_a_b`` under the per-sample ``noise``
    (module docstring); ``mask`` selects the pairs judged (the inliers of ``--robust``)."""
    keep = np.ones(len(pairs), dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    i, j, A = pairs.i[keep], pairs.j[keep], pairs.A[keep]
    X = np.asarray(X, dtype=np.float64)
    B_rigid = se3.inverse(X) @ A @ X
    rng = np.random.default_rng(_SEED)

    def floor(s: FloatArray, f: float) -> FloatArray:
        return np.maximum(s, f)

    Dai = _perturbations(rng, floor(noise.rot_a[i], _FLOOR_RAD), floor(noise.trans_a[i], _FLOOR_M))
    Daj = _perturbations(rng, floor(noise.rot_a[j], _FLOOR_RAD), floor(noise.trans_a[j], _FLOOR_M))
    Dbi = _perturbations(rng, floor(noise.rot_b[i], _FLOOR_RAD), floor(noise.trans_b[i], _FLOOR_M))
    Dbj = _perturbations(rng, floor(noise.rot_b[j], _FLOOR_RAD), floor(noise.trans_b[j], _FLOOR_M))
    A_drawn = se3.inverse(Dai) @ A[None] @ Daj
    B_drawn = se3.inverse(Dbi) @ B_rigid[None] @ Dbj
    rot, trans = residuals_batch(A_drawn.reshape(-1, 4, 4), B_drawn.reshape(-1, 4, 4), X[None])
    rot, trans = rot.reshape(_DRAWS, -1), trans.reshape(_DRAWS, -1)
    s_rot, s_trans = np.sqrt(np.mean(rot ** 2, axis=0)), np.sqrt(np.mean(trans ** 2, axis=0))
    r_rot, r_trans = np.deg2rad(residuals.rotation_deg[keep]), residuals.translation_m[keep]
    parts = [_Part(float(np.median(r / s)), float(np.median(d / s)))
             for r, d, s in ((r_rot, rot, s_rot), (r_trans, trans, s_trans))]
    medians = (float(np.rad2deg(np.median(r_rot))), float(np.rad2deg(np.median(rot))),
               float(np.median(r_trans)), float(np.median(trans)))
    return FitTest(parts[0], parts[1], medians, threshold, noise.source, noise.streams, int(keep.sum()))
