"""Diagnostics on top of the solvers: residuals, outlier rejection, observability, bootstrap, α choice.

Conventions throughout: ``X = T_a_b`` is the pose of frame b in frame a (maps points from b
to a); motions satisfy ``A_i X = X B_i``; quaternions are Hamilton x-y-z-w; metres and radians
inside, degrees in reported figures and messages.
"""
from __future__ import annotations

from .alpha import AlphaChoice, auto_alpha, residual_ratio_alpha
from .bootstrap import BootstrapResult, bootstrap
from .covariance import LinearCovariance, linear_covariance
from .observability import Observability, ObservabilityWarning, assess_observability, describe_direction
from .residuals import Residuals, ResidualSummary, extrinsic_error, pair_residuals, summarize
from .robust import RobustResult, robust_solve

__all__ = [
    "AlphaChoice", "auto_alpha", "residual_ratio_alpha",
    "BootstrapResult", "bootstrap",
    "LinearCovariance", "linear_covariance",
    "Observability", "ObservabilityWarning", "assess_observability", "describe_direction",
    "Residuals", "ResidualSummary", "extrinsic_error", "pair_residuals", "summarize",
    "RobustResult", "robust_solve",
]
