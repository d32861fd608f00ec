"""A noise model of the recording: how the residual of a pair grows with its span.

Conventions: ``X = T_a_b`` (maps frame b to frame a), ``A_k X = X B_k`` with
``A_k = T_wa(t_i)⁻¹ T_wa(t_j)``; quaternions x-y-z-w; time in seconds, distances in metres,
angles in radians inside (degrees only in :meth:`NoiseModel.as_dict`).

The residuals are taken in the units of the solver's cost (8) (paper eqs 6–8), doubled so that
they read as radians and metres for small errors: ``r_rot = 2|E_k q|``, ``r_dual = 2|F_k q + E_k q'|``
(``r_dual`` is the translation residual plus the rotation residual times the motion's lever).
Their expected squares are modelled as linear in the pair's features with non-negative terms::

    E[r_rot²]  = ρ₀ + ρ_t Δt + ρ_s Δs
    E[r_dual²] = τ₀ + τ_t Δt + τ_s Δs + τ_l |t|² + τ_lt Δt |t|²

Δt is the span [s], Δs the path length of sensor a over it [m], |t| the translation of ``X B_k``
[m] (the lever that turns rotation noise into translation residual). ρ₀, τ₀, τ_l are the floor an
absolute source (motion capture, kinematics, a camera on a target) leaves; the Δt, Δs terms are
the drift of odometry (σ²(Δ) = σ₀² + k·Δ). The fit is non-negative least squares, weighted by the
predicted variance and iterated with the pairs beyond 6× their prediction trimmed (tracking
glitches, wrong associations). Residuals mix both streams' errors, so the model describes the
pair of sources; which of the two drifts is not separable from them.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..geometry import dualquat as dq
from ..numeric.nnls import nnls
from ..solvers.problem import pair_blocks

__all__ = ["NoiseModel", "PairFeatures", "pair_features", "cost_residuals", "fit_noise_model"]

_TRIM = 6.0                 # a pair beyond this many times its predicted variance is an outlier
_ITERATIONS = 4
_DRIFT_SHARE = 0.5          # drift terms above this share of the variance at the typical span: "drifting"
ROT_TERMS = ("floor", "per_second", "per_metre")
DUAL_TERMS = ("floor", "per_second", "per_metre", "lever", "lever_per_second")


@dataclass(frozen=True, eq=False)
class PairFeatures:
    """Per pair: span ``dt_s`` [s], path length of a ``path_m`` [m], squared lever ``lever2_m2`` [m²]."""

    dt_s: NDArray[np.float64]
    path_m: NDArray[np.float64]
    lever2_m2: NDArray[np.float64]

    def rot_design(self) -> NDArray[np.float64]:
        """(N, 3) columns of the rotation model, in the order of :data:`ROT_TERMS`."""
        return np.column_stack([np.ones_like(self.dt_s), self.dt_s, self.path_m])

    def dual_design(self) -> NDArray[np.float64]:
        """(N, 5) columns of the translation model, in the order of :data:`DUAL_TERMS`."""
        return np.column_stack([np.ones_like(self.dt_s), self.dt_s, self.path_m, self.lever2_m2,
                                self.dt_s * self.lever2_m2])


def pair_features(stamps_ns: NDArray[np.int64], path_m: NDArray[np.float64], i: NDArray[np.int64],
                  j: NDArray[np.int64], motions_b: NDArray[np.float64], T_a_b: NDArray[np.float64]) -> PairFeatures:
    """Features of pairs ``(i, j)`` of synced samples: ``path_m`` is a's cumulative path length per
    sample [m], ``motions_b`` (N, 4, 4) the motions ``B_k``, ``T_a_b`` the current estimate."""
    lever = T_a_b[:3, :3] @ motions_b[:, :3, 3].T + T_a_b[:3, 3:4]
    return PairFeatures((stamps_ns[j] - stamps_ns[i]) / 1e9, path_m[j] - path_m[i], np.sum(lever * lever, axis=0))


def cost_residuals(motions_a: NDArray[np.float64], motions_b: NDArray[np.float64], T_a_b: NDArray[np.float64]
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per pair ``(2|E q|, 2|F q + E q'|)``: cost-(8) residuals in radians and metres (small errors), each
    pair's signs agreed by ``T_a_b`` (as the solver agrees them)."""
    q, qd = dq.from_transforms(np.asarray(T_a_b, dtype=float))
    E, F = pair_blocks(motions_a, motions_b, reference=T_a_b)
    return 2.0 * np.linalg.norm(E @ q, axis=1), 2.0 * np.linalg.norm(F @ q + E @ qd, axis=1)


def _fit(design: NDArray[np.float64], r2: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Non-negative terms of ``E[r²] = design @ terms``, robust: weighted by 1/prediction, trimmed."""
    keep = np.ones(len(r2), dtype=bool)
    scale = np.maximum(design.max(axis=0), 1e-300)        # columns on a common scale for NNLS
    terms = np.zeros(design.shape[1])
    terms[0] = max(float(np.median(r2)), 1e-300)
    for _ in range(_ITERATIONS):
        pred = np.maximum(design @ terms, 1e-300)
        keep = r2 <= _TRIM * pred
        w = 1.0 / pred[keep]
        sol, _ = nnls(design[keep] / scale * w[:, None], r2[keep] * w)
        if not np.any(sol > 0):
            break
        terms = sol / scale
    return terms, keep


@dataclass(frozen=True, eq=False)
class NoiseModel:
    """Fitted terms of the two variance models (see the module docstring for their units)."""

    rot_terms: NDArray[np.float64]
    dual_terms: NDArray[np.float64]
    typical_dt_s: float
    typical_path_m: float
    pairs: int
    outliers: int

    def rot_variance(self, f: PairFeatures) -> NDArray[np.float64]:
        """Predicted E[r_rot²] [rad²] per pair."""
        return np.maximum(f.rot_design() @ self.rot_terms, 1e-30)

    def dual_variance(self, f: PairFeatures) -> NDArray[np.float64]:
        """Predicted E[r_dual²] [m²] per pair."""
        return np.maximum(f.dual_design() @ self.dual_terms, 1e-30)

    def drift_share(self, f: PairFeatures) -> NDArray[np.float64]:
        """Per pair, the larger of the drift terms' shares of the rotation and translation variance."""
        rot_drift = f.rot_design()[:, 1:] @ self.rot_terms[1:]
        dual_drift = f.dual_design()[:, [1, 2, 4]] @ self.dual_terms[[1, 2, 4]]
        return np.maximum(rot_drift / self.rot_variance(f), dual_drift / self.dual_variance(f))

    @property
    def kind(self) -> str:
        """``"drifting"`` when drift dominates the variance at the typical span, else ``"absolute"``."""
        typical = PairFeatures(np.array([self.typical_dt_s]), np.array([self.typical_path_m]), np.zeros(1))
        return "drifting" if self.drift_share(typical)[0] > _DRIFT_SHARE else "absolute"

    def as_dict(self) -> dict[str, Any]:
        """The result file's ``noise_model``: σ floors and drift densities in deg/m, and the kind."""
        r, d = self.rot_terms, self.dual_terms
        return {"kind": self.kind,
                "rotation": {"floor_deg": float(np.rad2deg(np.sqrt(r[0]))),
                             "drift_deg2_per_s": float(np.rad2deg(np.rad2deg(r[1]))),
                             "drift_deg2_per_m": float(np.rad2deg(np.rad2deg(r[2])))},
                "translation": {"floor_m": float(np.sqrt(d[0])), "drift_m2_per_s": float(d[1]),
                                "drift_m2_per_m": float(d[2]), "lever_rad2": float(d[3]),
                                "lever_rad2_per_s": float(d[4])},
                "typical_span_s": self.typical_dt_s, "pairs": self.pairs, "outliers": self.outliers,
                "note": "variance of pair residuals vs span: floor + drift·span (+ rotation noise × lever); "
                        "the two streams' errors are not separable from the residuals"}


def fit_noise_model(r_rot: NDArray[np.float64], r_dual: NDArray[np.float64], features: PairFeatures) -> NoiseModel:
    """Fit both variance models to per-pair residuals [rad], [m] (see :func:`cost_residuals`)."""
    rot, keep_r = _fit(features.rot_design(), r_rot ** 2)
    dual, keep_d = _fit(features.dual_design(), r_dual ** 2)
    return NoiseModel(rot, dual, float(np.median(features.dt_s)), float(np.median(features.path_m)),
                      len(r_rot), int(np.count_nonzero(~(keep_r & keep_d))))
