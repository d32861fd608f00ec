"""Every method on the same motion pairs: what ``handeye compare`` tabulates, for Python too.

A calibration's pairs (and weights, at its α) are solved by every solver of
:data:`~handeye_cli.solvers.METHODS` — the optimal dqopt, the paper's approximations, Daniilidis and the
classical Tsai–Lenz, Park–Martin, Horaud–Dornaika, Andreff — and its synchronised absolute poses by the
robot-world methods; with ``refine`` also the calibration's maximum-likelihood refinement of dqopt's optimum
(``dqopt refined``). Each :class:`MethodResult` holds that method's ``T_a_b``, its cost (8) on the pairs at
the same α, the residual medians, its difference to dqopt and the time taken.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from .analysis import extrinsic_error, pair_residuals
from .calibration import Calibration
from .geometry import dualquat as dq
from .solvers import METHODS, build_problem, solve
from .solvers.robot_world import RW_METHODS, robot_world

__all__ = ["MethodResult", "compare_methods"]


@dataclass(frozen=True, eq=False)
class MethodResult:
    """One method on a calibration's pairs: ``matrix`` (4x4 ``T_a_b``), ``cost`` (8) at the calibration's α,
    the median residuals [deg] / [m], the difference to dqopt's extrinsic [deg] / [m] and the time [s]."""

    method: str
    matrix: np.ndarray
    cost: float
    rotation_median_deg: float
    translation_median_m: float
    vs_dqopt_deg: float
    vs_dqopt_m: float
    seconds: float

    @property
    def rotation_vector_deg(self) -> np.ndarray:
        """The rotation of ``T_a_b`` as a rotation vector [deg] (axis times angle)."""
        return np.rad2deg(dq.to_rotvec(dq.from_matrix(self.matrix[:3, :3])))

    def as_dict(self) -> dict[str, Any]:
        """The row of ``handeye compare --format yaml/json``."""
        return {"method": self.method, "translation": self.matrix[:3, 3].tolist(),
                "rotation_vector_deg": self.rotation_vector_deg.tolist(), "cost": self.cost,
                "rotation_median_deg": self.rotation_median_deg, "translation_median_m": self.translation_median_m,
                "vs_dqopt_deg": self.vs_dqopt_deg, "vs_dqopt_m": self.vs_dqopt_m, "milliseconds": 1e3 * self.seconds}


def compare_methods(cal: Calibration) -> list[MethodResult]:
    """Every method (see the module docstring) on the pairs and synchronised poses of ``cal``, dqopt first."""
    A, B, w, alpha = cal.pairs.A, cal.pairs.B, cal.weights, cal.solution.alpha
    solved: dict[str, tuple[np.ndarray, float]] = {}
    for method in METHODS:
        t0 = time.perf_counter()
        solved[method] = (solve(A, B, method=method, alpha=alpha, weights=w).matrix, time.perf_counter() - t0)
    for method in RW_METHODS:
        t0 = time.perf_counter()
        X = robot_world(cal.synced.T_a, cal.synced.T_b, method=method, alpha=alpha).X
        solved[f"{method} (robot-world)"] = (X, time.perf_counter() - t0)
    if cal.refinement is not None:                     # --refine: the calibration's own estimate, from dqopt's
        solved["dqopt refined"] = (cal.refinement.matrix, cal.refinement.seconds)
    best = solved["dqopt"][0]
    problem = build_problem(A, B, alpha, weights=w)
    mask = None if w is None else w > 0
    out = []
    for name, (X, seconds) in solved.items():
        res = pair_residuals(A, B, X).summary(mask)
        rot, trans = extrinsic_error(X, best)
        out.append(MethodResult(name, X, float(problem.cost(*dq.from_transforms(X))), res.rotation_median_deg,
                                res.translation_median_m, rot, trans, seconds))
    return out
