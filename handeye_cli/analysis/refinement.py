"""The maximum-likelihood refinement of a calibration (issue 35): from the certified optimum of cost (8) to the
most likely ``X = T_a_b`` under a noise model of the samples, fitted to them.

Conventions: ``X = T_a_b`` (maps points from b to a); poses ``T_wa_a``, ``T_wb_b`` of the synced samples;
rotation noise a rotation vector in the sensor frame (right perturbation), per axis; radians and metres inside,
degrees in the result document; quaternions x-y-z-w.

1. **The samples.** Those the solved pairs use (a pair of weight 0, an outlier ``--robust`` dropped, does not
   bring its samples), in time order, at most :data:`CHAIN_SAMPLES` spread evenly; their consecutive motions
   within each tracking segment form the chain (:class:`~handeye_cli.solvers.refine.Chain`). Any pair of the
   samples is a product of consecutive motions, so the chain carries what every pair does, and its
   neighbours' correlation (the pose they share) is exact.
2. **The noise model**, as variance components of the chain's residuals, each one's scale ``θ ≥ 0``:
   per stream, white rotation and translation noise of each pose, shaped per sample by the streams' own noise
   (:func:`~handeye_cli.analysis.fit_test.sample_noise`: the jitter, or a station's scatter over √inliers), and
   a drift of rotation and of translation growing with each motion's span (a random walk's increments,
   independent from motion to motion). The θ are fitted by maximum likelihood (Gaussian, log-determinant
   included) to the chain's residuals at the optimum: what the streams' jitter cannot see — a robot's
   kinematic errors, a target detector's bias, odometry drift — is measured rather than assumed. A white
   component is never below the streams' measured noise (θ ≥ 1): the poses are no better than their jitter.
3. **The refinement**: :func:`~handeye_cli.solvers.refine.refine_poses` from the optimum, under that noise.
   The covariance it returns is the inverse Fisher information under the fitted model.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import minimize

from .._typing import FloatArray
from ..errors import DataError
from ..geometry import se3
from ..solvers.refine import Chain, Refined, band_factor, gaussian_terms, refine_poses
from ..stages.pairs import Pairs
from ..stages.sync import Synced
from .fit_test import SampleNoise

__all__ = ["CHAIN_SAMPLES", "Refinement", "refine_calibration"]

CHAIN_SAMPLES = 2000         # samples in the chain at most, spread evenly over those the pairs use
_COMPONENTS = ("white rotation a", "white translation a", "white rotation b", "white translation b",
               "drift rotation", "drift translation")
_WHITE = 4                   # the first four components are the poses' white noise
_MAX_LOG_SCALE = np.log(1e6)  # a component at most this many times its base (variance)
_UNMEASURED_FLOOR = 1e-4     # the white floor when the streams' noise is only assumed (sparse poses)


@dataclass(frozen=True, eq=False)
class Refinement:
    """The refinement of one calibration: ``refined`` (:class:`~handeye_cli.solvers.refine.Refined`: the matrix,
    its costs, iterations, covariance of ``(ω [rad], v [m])`` in frame b), the chain's ``samples`` and ``motions``,
    the fitted noise per stream (per-axis σ, median over the samples, rotation [rad], translation [m]) and the
    drift variances per second [rad²/s, m²/s], the optimum it started from (4, 4), and the time it took [s] (the
    noise model's fit and the refinement)."""

    refined: Refined
    samples: int
    motions: int
    sigma_a: tuple[float, float]
    sigma_b: tuple[float, float]
    drift: tuple[float, float]
    optimum: FloatArray
    seconds: float

    @property
    def matrix(self) -> FloatArray:
        return self.refined.matrix

    def as_dict(self) -> dict[str, Any]:
        """The result's ``solver.refined``: what was refined from what, under which noise, and what it changed."""
        r, change = self.refined, se3.inverse(self.optimum) @ self.refined.matrix
        sd = np.sqrt(np.diag(r.covariance))
        return {"method": "maximum likelihood of the samples' consecutive motions, from the optimum of cost (8)",
                "samples": self.samples, "motions": self.motions, "iterations": r.iterations,
                "converged": r.converged, "cost_at_optimum": r.cost_start, "cost": r.cost,
                "change_from_optimum": {"rotation_deg": float(np.rad2deg(se3.rotation_angle(change))),
                                        "translation_m": float(np.linalg.norm(change[:3, 3]))},
                "noise_model": {
                    "a": {"sigma_rotation_deg": float(np.rad2deg(self.sigma_a[0])),
                          "sigma_translation_m": self.sigma_a[1]},
                    "b": {"sigma_rotation_deg": float(np.rad2deg(self.sigma_b[0])),
                          "sigma_translation_m": self.sigma_b[1]},
                    "drift": {"rotation_deg2_per_s": float(np.rad2deg(np.rad2deg(self.drift[0]))),
                              "translation_m2_per_s": self.drift[1]},
                    "note": "per axis, per pose; fitted to the samples, floored at the streams' own noise"},
                "sigma": {"rotation_deg": [float(np.rad2deg(x)) for x in sd[:3]],
                          "translation_m": [float(x) for x in sd[3:6]], "frame": "b"}}


def _chain_rows(synced: Synced, pairs: Pairs, weights: FloatArray | None) -> FloatArray:
    """The synced samples the pairs of weight > 0 use, in time order, at most :data:`CHAIN_SAMPLES`."""
    keep = slice(None) if weights is None else weights > 0
    rows = np.unique(np.r_[pairs.i[keep], pairs.j[keep]])
    if len(rows) > CHAIN_SAMPLES:
        rows = rows[np.unique(np.linspace(0, len(rows) - 1, CHAIN_SAMPLES).round().astype(np.int64))]
    return rows


def _white(sigma: FloatArray, rotation: bool) -> FloatArray:
    """Per sample (S, 6, 6): a pose's white noise of per-axis σ (S,) in rotation or in translation."""
    out = np.zeros((len(sigma), 6, 6))
    k = np.arange(3) if rotation else np.arange(3, 6)
    out[:, k, k] = (sigma ** 2)[:, None]
    return out


def refine_calibration(synced: Synced, pairs: Pairs, weights: FloatArray | None, noise: SampleNoise,
                       optimum: FloatArray) -> Refinement:
    """Refine ``optimum`` (4, 4), the certified optimum of the pairs' cost (8), by the maximum likelihood of the
    synced samples the pairs use, under the noise model fitted to them (module docstring)."""
    start = time.perf_counter()
    rows = _chain_rows(synced, pairs, weights)
    T_a = se3.from_xyz_quat(synced.xyz_a[rows], synced.quat_a[rows])
    T_b = se3.from_xyz_quat(synced.xyz_b[rows], synced.quat_b[rows])
    chain = Chain.of(T_a, T_b, synced.segment[rows])
    spans = (synced.stamps_ns[rows][chain.start + 1] - synced.stamps_ns[rows][chain.start]) / 1e9
    whites = [_white(noise.rot_a[rows], True), _white(noise.trans_a[rows], False),
              _white(noise.rot_b[rows], True), _white(noise.trans_b[rows], False)]
    typical = max(float(np.median(spans)), 1e-9)
    base_r = float(np.median(noise.rot_a[rows] ** 2 + noise.rot_b[rows] ** 2)) / typical
    base_t = float(np.median(noise.trans_a[rows] ** 2 + noise.trans_b[rows] ** 2)) / typical
    drifts = [np.c_[spans * base_r, np.zeros_like(spans)], np.c_[np.zeros_like(spans), spans * base_t]]
    theta = _fitted_scales(chain, optimum, whites, drifts, measured=noise.measured)
    noise_a = theta[0] * whites[0] + theta[1] * whites[1]
    noise_b = theta[2] * whites[2] + theta[3] * whites[3]
    drift = theta[4] * drifts[0] + theta[5] * drifts[1]
    refined = refine_poses(chain, optimum, noise_a, noise_b, drift_a=drift)
    median = [float(np.median(np.sqrt(theta[k]) * s[rows])) for k, s in
              enumerate((noise.rot_a, noise.trans_a, noise.rot_b, noise.trans_b))]
    return Refinement(refined, len(rows), len(chain.A), (median[0], median[1]), (median[2], median[3]),
                      (theta[4] * base_r, theta[5] * base_t), optimum, time.perf_counter() - start)


def _fitted_scales(chain: Chain, X: FloatArray, whites: list[FloatArray], drifts: list[FloatArray], *,
                   measured: bool) -> FloatArray:
    """The components' scales θ (6,) maximising the Gaussian likelihood of the chain's residuals at ``X``: the
    white ones at least 1 (the streams' measured noise; :data:`_UNMEASURED_FLOOR` when it is only assumed), the
    drifts at least 0 (e⁻³⁰ of their base)."""
    r, Ja, Jb = chain.residuals(X)
    pose_blocks = [chain.blocks(Ja, Jb, w, None) for w in whites[:2]] + \
                  [chain.blocks(Ja, Jb, None, w) for w in whites[2:]]
    drift_blocks = [chain.blocks(Ja, Jb, None, None, drift_a=d) for d in drifts]
    parts = pose_blocks + drift_blocks
    floor = 0.0 if measured else np.log(_UNMEASURED_FLOOR)

    def nll(u: FloatArray) -> float:
        scales = np.exp(u)
        D = sum(s * p[0] for s, p in zip(scales, parts, strict=True))
        U = sum(s * p[1] for s, p in zip(scales, parts, strict=True))
        try:
            return sum(gaussian_terms(r, band_factor(D, U)))
        except DataError:                                      # a singular covariance: not a candidate
            return float("inf")

    bounds = [(floor, _MAX_LOG_SCALE)] * _WHITE + [(-30.0, _MAX_LOG_SCALE)] * (len(parts) - _WHITE)
    start = np.r_[np.full(_WHITE, max(floor, 0.0)), np.full(len(parts) - _WHITE, -5.0)]
    fit = minimize(nll, start, method="L-BFGS-B", bounds=bounds)
    return np.asarray(np.exp(fit.x), dtype=np.float64)
