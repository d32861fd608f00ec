"""The χ² survival function for an even number of degrees of freedom, in logarithms.

For ``dof = 2a`` (a a positive integer) ``P(χ²_dof > x) = e^{-x/2} Σ_{k<a} (x/2)^k / k!`` exactly (the
regularised upper incomplete gamma function ``Q(a, x/2)`` of integer ``a``), summed here in logarithms
(log-sum-exp), so it stays finite far into the tail where the probability underflows, and improbable
statistics still rank. The rig's tests have 6 degrees of freedom per pairwise extrinsic, always even.
It is here so that ``handeye rig`` imports no ``scipy.special`` (0.05 s of start-up); tests check it
against :func:`scipy.special.chdtrc`, its reference.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["chi2_log_sf", "chi2_sf"]


def chi2_log_sf(dof: int, x: float) -> float:
    """``log P(χ²_dof > x)`` for an even ``dof`` ≥ 2 and ``x`` ≥ 0 (0 for ``x`` ≤ 0). Raises ValueError for
    another ``dof``."""
    if dof < 2 or dof % 2:
        raise ValueError(f"χ² survival function: {dof} degrees of freedom, not an even number ≥ 2")
    y = float(x) / 2
    if y <= 0:
        return 0.0
    k = np.arange(dof // 2)
    terms = k * math.log(y) - np.array([math.lgamma(i + 1.0) for i in k])
    top = float(terms.max())
    return min(0.0, -y + top + math.log(float(np.exp(terms - top).sum())))


def chi2_sf(dof: int, x: float) -> float:
    """``P(χ²_dof > x)`` for an even ``dof`` (:func:`chi2_log_sf`)."""
    return math.exp(chi2_log_sf(dof, x))
