"""Bounded scalar minimisation: Brent's method, for the time offset's one-dimensional refinements.

Brent's minimiser without derivatives (R. P. Brent, "Algorithms for Minimization without
Derivatives", 1973, ch. 5; the ``fmin`` of Forsythe, Malcolm and Moler, 1977): golden-section
steps, replaced by a parabola through the three best points whenever it steps inside the bracket
and less than half the step before last. It is the algorithm of
``scipy.optimize.minimize_scalar(method="bounded")``, step for step (the same tolerances, the same
order of evaluations), so it finds the same minimum. It is here, next to :mod:`.nnls` and for the
same reason, because importing ``scipy.optimize`` (with ``scipy.fft`` and ``scipy.ndimage``, the
time offset's other former imports) costs a quarter of a second of start-up on every
``handeye calibrate`` that estimates a clock offset; tests check that the two agree.
"""
from __future__ import annotations

import math
from collections.abc import Callable

__all__ = ["minimize_bounded"]

_SQRT_EPS = math.sqrt(2.2e-16)                  # relative resolution of the abscissa
_GOLDEN = 0.5 * (3.0 - math.sqrt(5.0))          # the golden-section fraction, 0.381966…


def _sign(x: float) -> float:
    """+1 for x ≥ 0, −1 below."""
    return 1.0 if x >= 0 else -1.0


def minimize_bounded(f: Callable[[float], float], lo: float, hi: float, *, xatol: float,
                     maxiter: int = 500) -> float:
    """The abscissa of a local minimum of ``f`` within ``[lo, hi]`` (any units: x has lo's).

    Converges when the bracket around the best point is within ``2·(√ε·|x| + xatol/3)`` of it; ``f``
    is evaluated at most ``maxiter`` times (the best point so far is returned then). ``f`` may return
    ``inf``; it is never evaluated at the bounds themselves.
    """
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
        raise ValueError(f"bounds [{lo}, {hi}] must be finite and ordered")
    a, b = lo, hi
    x = w = v = a + _GOLDEN * (b - a)           # best, second best, previous second best
    fx = fw = fv = f(x)
    step = before = 0.0                         # the last step, and the one before it
    calls = 1
    tol = _SQRT_EPS * abs(x) + xatol / 3.0
    while abs(x - 0.5 * (a + b)) > 2.0 * tol - 0.5 * (b - a) and calls < maxiter:
        mid = 0.5 * (a + b)
        golden = True
        if abs(before) > tol:                   # try a parabola through x, w, v
            r = (x - w) * (fx - fv)
            q = (x - v) * (fx - fw)
            p = (x - v) * q - (x - w) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = abs(q)
            last, before = before, step
            if abs(p) < abs(0.5 * q * last) and q * (a - x) < p < q * (b - x):
                golden = False
                step = p / q
                u = x + step
                if u - a < 2.0 * tol or b - u < 2.0 * tol:
                    step = tol * _sign(mid - x)
        if golden:
            before = (a - x) if x >= mid else (b - x)
            step = _GOLDEN * before
        u = x + _sign(step) * max(abs(step), tol)   # never closer than tol to x
        fu = f(u)
        calls += 1
        if fu <= fx:
            if u >= x:
                a = x
            else:
                b = x
            v, fv, w, fw, x, fx = w, fw, x, fx, u, fu
        else:
            if u < x:
                a = u
            else:
                b = u
            if fu <= fw or w == x:
                v, fv, w, fw = w, fw, u, fu
            elif fu <= fv or v in (x, w):
                v, fv = u, fu
        tol = _SQRT_EPS * abs(x) + xatol / 3.0
    return x
