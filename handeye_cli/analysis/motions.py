"""``handeye_cli.solve``: the solver on relative motion pairs, with the command line's options and defaults.

:func:`handeye_cli.solvers.solve` takes a numeric α; this is the public entry point that ``handeye solve``
also runs, so the two surfaces share one default (``alpha="auto"``, ``method="dqopt"``, from
:mod:`handeye_cli.options`) and one rule for values (the options' parsers: ``"DQopt"`` and ``"dqopt"`` alike).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._typing import FloatArray
from ..options import FIELDS
from ..solvers import Prior, Solution
from ..solvers import solve as solve_numeric
from .alpha import noise_model_alpha
from .bootstrap import BootstrapResult
from .bootstrap import bootstrap as bootstrap_pairs
from .robust import RobustResult, robust_solve
from .verdict import Judged

__all__ = ["PairsSolution", "solve", "solve_pairs"]

_METHOD, _ALPHA = FIELDS["method"][2], FIELDS["alpha"][2]
_ROBUST, _BOOTSTRAP, _SEED = FIELDS["robust"][2], FIELDS["bootstrap"][2], FIELDS["seed"][2]


def solve(motions_a: FloatArray, motions_b: FloatArray, method: str = _METHOD, alpha: Any = _ALPHA,
          prior: Prior | None = None, weights: FloatArray | None = None) -> Solution:
    """Solve ``A_i X = X B_i`` for ``X = T_a_b`` (paper eq 8), as ``handeye solve`` does.

    Parameters
    ----------
    motions_a, motions_b:
        (N, 4, 4) relative motions of sensors a and b over the same intervals [m].
    method:
        One of :data:`handeye_cli.solvers.METHODS`, in any case (default ``dqopt``, the global optimum).
    alpha:
        Weight of the translational residuals [1/m], or ``"auto"`` (the default): the maximum-likelihood
        α under a noise model fitted to the pairs' residuals.
    prior, weights:
        As :func:`handeye_cli.solvers.solve`.

    Raises
    ------
    ConfigError
        A method or α the options refuse; the message names the keyword (``method``, ``alpha``).
    """
    method = FIELDS["method"][1].parse(method, "method")
    alpha = FIELDS["alpha"][1].parse(alpha, "alpha")
    if alpha == "auto":
        alpha = noise_model_alpha(motions_a, motions_b, prior=prior, weights=weights).alpha
    return solve_numeric(motions_a, motions_b, method=method, alpha=float(alpha), prior=prior, weights=weights)


@dataclass(frozen=True, eq=False)
class PairsSolution:
    """What ``handeye solve`` computes on motion pairs: the solution (``T_a_b``), ``--robust``'s inliers (None
    without) and ``--bootstrap``'s spread (None without)."""

    solution: Solution
    robust: RobustResult | None = None
    bootstrap: BootstrapResult | None = None

    def judged(self) -> Judged:
        """What a drift verdict reads of it (``--against``): ``T_a_b`` of frames a, b and the bootstrap's intervals."""
        boot = self.bootstrap
        return Judged(np.asarray(self.solution.matrix, dtype=float), ("a", "b"),
                      intervals=None if boot is None else (boot.rotation_interval_deg, boot.translation_interval_m))

    def sections(self) -> dict[str, Any]:
        """The result document's sections of the analyses that ran (``robust``, ``uncertainty``), as calibrate's."""
        out: dict[str, Any] = {}
        if self.robust is not None:
            out["robust"] = self.robust.as_dict()
        if self.bootstrap is not None:
            out["uncertainty"] = {"method": "bootstrap over motion pairs", **self.bootstrap.as_dict()}
        return out


def solve_pairs(motions_a: FloatArray, motions_b: FloatArray, method: str = _METHOD, alpha: Any = _ALPHA,
                prior: Prior | None = None, weights: FloatArray | None = None, *, robust: Any = _ROBUST,
                bootstrap: Any = _BOOTSTRAP, seed: Any = _SEED) -> PairsSolution:
    """:func:`solve` with the analyses calibrate runs on its pairs, as ``handeye solve --robust --bootstrap N``:
    ``robust`` rejects outlier pairs first (RANSAC at α 1, then the weighted solve on the inliers), ``bootstrap``
    resamples the (inlier) pairs N times for the uncertainty of ``T_a_b``; ``seed`` seeds both. Values are checked
    by the options' parsers (errors name the keyword)."""
    robust = FIELDS["robust"][1].parse(robust, "robust")
    replicates = FIELDS["bootstrap"][1].parse(bootstrap, "bootstrap")
    seed = FIELDS["seed"][1].parse(seed, "seed")
    method = FIELDS["method"][1].parse(method, "method")
    found = None
    if robust:
        given = FIELDS["alpha"][1].parse(alpha, "alpha")
        found = robust_solve(motions_a, motions_b, method=method, alpha=1.0 if given == "auto" else float(given),
                             prior=prior, seed=seed)
        weights = found.inliers.astype(float) * (1.0 if weights is None else np.asarray(weights, dtype=float))
    solution = solve(motions_a, motions_b, method=method, alpha=alpha, prior=prior, weights=weights)
    spread = None
    if replicates > 0:
        spread = bootstrap_pairs(motions_a, motions_b, replicates, alpha=solution.alpha, prior=prior, weights=weights,
                                 seed=seed, estimate=solution.matrix if method == "dqopt" else None)
    return PairsSolution(solution, found, spread)

