"""``handeye_cli.solve``: the solver on relative motion pairs, with the command line's options and defaults.

:func:`handeye_cli.solvers.solve` takes a numeric α; this is the public entry point that ``handeye solve``
also runs, so the two surfaces share one default (``alpha="auto"``, ``method="dqopt"``, from
:mod:`handeye_cli.options`) and one rule for values (the options' parsers: ``"DQopt"`` and ``"dqopt"`` alike).
"""
from __future__ import annotations

from typing import Any

from .._typing import FloatArray
from ..options import FIELDS
from ..solvers import Prior, Solution
from ..solvers import solve as solve_numeric
from .alpha import noise_model_alpha

__all__ = ["solve"]

_METHOD, _ALPHA = FIELDS["method"][2], FIELDS["alpha"][2]


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
