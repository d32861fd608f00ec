"""Per-pair residuals of ``A_i X = X B_i`` for an extrinsic ``X = T_a_b``, and their summary.

Conventions (see :mod:`handeye_cli.geometry.se3`): ``X = T_a_b`` maps points from frame b to frame a;
motions ``A_i = T_wa(t_i)⁻¹ T_wa(t_j)``, ``B_i = T_wb(t_i)⁻¹ T_wb(t_j)``. Quaternions are
Hamilton, x-y-z-w.

For one pair the residuals compare the two sides of ``A_i X = X B_i`` (paper eq 1):

* rotation [rad]: the geodesic angle between ``R_Ai R_X`` and ``R_X R_Bi``, computed from unit
  quaternions as ``4 asin(|p₁ ∓ p₂| / 2)`` (exact near 0, unlike ``acos``);
* translation [m]: ``|R_Ai t_X + t_Ai - R_X t_Bi - t_X|``, a vector in frame a.

Public values are in degrees and metres.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._typing import BoolArray, FloatArray
from ..geometry import dualquat as dq
from ..geometry import se3
from ..solvers.problem import validate_motions

__all__ = ["Residuals", "ResidualSummary", "extrinsic_error", "pair_residuals", "residuals_batch", "summarize"]


@dataclass(frozen=True)
class ResidualSummary:
    """Median, 95th percentile and maximum of the per-pair residuals (rotation [deg], translation [m])."""

    rotation_median_deg: float
    rotation_p95_deg: float
    rotation_max_deg: float
    translation_median_m: float
    translation_p95_m: float
    translation_max_m: float

    def as_dict(self) -> dict[str, float]:
        """Plain ``{name: float}`` for the result file."""
        return dict(self.__dict__)


@dataclass(frozen=True, eq=False)
class Residuals:
    """Per-pair residuals of ``A_i X = X B_i``: ``rotation_deg`` (N,) [deg], ``translation_m`` (N,) [m]."""

    rotation_deg: FloatArray
    translation_m: FloatArray

    def summary(self, mask: BoolArray | None = None) -> ResidualSummary:
        """Summary over all pairs, or over those selected by the boolean ``mask`` (e.g. inliers)."""
        return summarize(self, mask)


def _rotation_parts(T: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Unit quaternions x-y-z-w (w ≥ 0), rotation matrices and translations [m] of transforms (…, 4, 4)."""
    q, _ = dq.from_transforms(T)
    return q, T[..., :3, :3], T[..., :3, 3]


def residuals_batch(motions_a: FloatArray, motions_b: FloatArray,
                    X: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Residuals of every pair for every candidate extrinsic; no validation (internal, fast).

    Parameters
    ----------
    motions_a, motions_b:
        (N, 4, 4) motions of frames a and b.
    X:
        (H, 4, 4) candidate ``T_a_b``.

    Returns
    -------
    rotation [rad] and translation [m] residuals, each of shape (H, N).
    """
    qa, Ra, ta = _rotation_parts(motions_a)
    qb, _, tb = _rotation_parts(motions_b)
    qx, Rx, tx = _rotation_parts(X)
    n, h = len(qa), len(qx)
    p1 = qa @ np.swapaxes(dq.right(qx), 1, 2)                     # q_A ⊗ q_X = R(q_X) q_A   (H, N, 4)
    p2 = qb @ np.swapaxes(dq.left(qx), 1, 2)                      # q_X ⊗ q_B = L(q_X) q_B
    d2 = np.minimum(np.sum((p1 - p2) ** 2, axis=-1), np.sum((p1 + p2) ** 2, axis=-1))   # q ~ -q
    rot = 4.0 * np.arcsin(np.clip(0.5 * np.sqrt(d2), 0.0, 1.0))
    Ra_tx = (Ra.reshape(3 * n, 3) @ tx.T).T.reshape(h, n, 3)      # R_A t_X
    res_t = Ra_tx + ta[None] - tb @ np.swapaxes(Rx, 1, 2) - tx[:, None]
    return rot, np.sqrt(np.sum(res_t * res_t, axis=-1))


def pair_residuals(motions_a: FloatArray, motions_b: FloatArray, T_a_b: FloatArray) -> Residuals:
    """Rotation [deg] and translation [m] residual of each pair ``A_i X`` vs ``X B_i`` with ``X = T_a_b``.

    Raises :class:`~handeye_cli.errors.HandEyeError` on malformed motions.
    """
    A, B, _ = validate_motions(motions_a, motions_b)
    rot, trans = residuals_batch(A, B, np.asarray(T_a_b, dtype=np.float64)[None])
    return Residuals(np.rad2deg(rot[0]), trans[0])


def summarize(residuals: Residuals, mask: BoolArray | None = None) -> ResidualSummary:
    """Median, 95th percentile and maximum of rotation [deg] and translation [m] residuals."""
    r, t = residuals.rotation_deg, residuals.translation_m
    if mask is not None:
        r, t = r[mask], t[mask]
    pr = np.percentile(r, [50, 95, 100])
    pt = np.percentile(t, [50, 95, 100])
    return ResidualSummary(*(float(v) for v in pr), *(float(v) for v in pt))


def extrinsic_error(T_a_b: FloatArray, truth: FloatArray) -> tuple[float, float]:
    """Error of an estimate against the true ``T_a_b``: geodesic rotation [deg], Euclidean translation [m]."""
    X, Y = np.asarray(T_a_b, dtype=np.float64), np.asarray(truth, dtype=np.float64)
    rot = se3.rotation_angle(Y[:3, :3].T @ X[:3, :3])
    return float(np.rad2deg(rot)), float(np.linalg.norm(X[:3, 3] - Y[:3, 3]))
