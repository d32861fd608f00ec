"""Estimate the clock offset between two rigidly attached pose streams, without knowing the extrinsic.

Sign convention (as :func:`handeye_cli.stages.sync.associate` and ``simulation.Rig``): ``offset_ns`` is
how far b's clock is ahead of a's; b's sample stamped ``s`` was taken at a's time ``s - offset``.

Method
------
1. Each stream's body angular velocity ω(t) [rad/s] is sampled on a uniform grid of step
   ``_GRID_NS`` in the stream's own clock: orientations are SLERPed at ``t ± w/2`` and
   ``ω = log(R(t-w/2)ᵀ R(t+w/2)) / w``; the window ``w`` (≥ 0.1 s, ≥ 3 sample intervals of the
   slower stream) averages out pose noise. ω is then smoothed by a Gaussian of σ = the slower
   stream's sample interval: without it the noise variance of ω varies with the phase between
   grid and samples (SLERP midway between two samples averages their noise), which would make the
   refinement cost depend on that phase and bias the offset by up to ~1 ms. Grid points whose
   window, widened by the smoothing kernel, touches a gap in the data or a tracking jump (a step
   far faster than its neighbours) are marked invalid.
2. Coarse, global: the angular speeds |ω| — equal for rigidly attached sensors whatever their
   frames — are cross-correlated over **every** lag with FFTs (masked, normalised per lag; at least
   a third of the shorter stream must overlap), so offsets of any size are found, even when the
   raw time spans do not overlap; ``max_offset_s`` bounds them (``"auto"``, the CLI's default: the
   shorter stream's span, :func:`search_bound_ns`). A parabola through the peak gives a sub-grid estimate. A peak
   correlation below ``MIN_CORRELATION`` (too little rotation, or unrelated streams) is an error;
   a weak peak, or a second peak elsewhere nearly as high (repetitive motion), is a warning.
3. Refinement: Brent's method on ``J(τ) = min_R Σ |ω_a(t) − R ω_b(t + τ)|²`` (the rotation R ≈
   R_a_b is refitted in closed form for each τ) within ±``_BRACKET_NS`` of the coarse estimate.
   Vectors carry more timing information than their norms.
4. Confidence: a sandwich (Gauss–Newton) variance of τ whose residual·gradient products are
   summed over 1 s blocks before squaring, which accounts for noise correlated within a window.

Slow streams. ω of a stream sampled seconds apart is an interpolation artefact, so the slower
stream's own steps are used instead (:class:`_StepRefiner`): the rotation vector of its motion
between consecutive samples equals, through ``R_a_b``, that of the faster stream between the same
instants. Below ~6.7 Hz the estimate of step 3 is refined on these steps; below 4 Hz steps 1–3 are
replaced by a scan of every allowed offset (0.25 s grid, median residual, so tracking jumps do not
count) and a refinement on the steps (measured on a 4-minute hand-held rig with tracking jumps,
100 Hz against 2–0.5 Hz in both orders: |error| < 0.07 ms, where ω alone erred by 3–90 ms at
1–0.5 Hz, or found no correlation).

Only numpy: the FFTs are numpy's, and the Gaussian, median and minimum filters (below) and Brent's
minimiser (:mod:`handeye_cli.numeric.minimize`) are those of ``scipy.ndimage`` and
``scipy.optimize``, which tests keep as their reference; importing scipy would cost a quarter of
a second of every estimate's start-up.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ..errors import DataError
from ..geometry import dualquat as dq
from ..geometry.lie import nearest_rotation
from ..numeric.minimize import minimize_bounded
from ..streams import PoseStream

__all__ = ["TimeOffset", "estimate_time_offset", "angular_velocity", "Grid", "grid_of", "MIN_CORRELATION",
           "SIGNIFICANT_SIGMA", "search_bound_ns", "overlap_offsets_ns"]

_GRID_NS = 5_000_000          # grid step of the ω signals [ns]
_MIN_WINDOW_NS = 100_000_000  # smallest differentiation window [ns]
_BRACKET_NS = 50_000_000      # refinement bracket around the coarse estimate [ns]
_MIN_OVERLAP = 1 / 3          # least overlap, as a fraction of the shorter signal, for a coarse lag
_MAX_GAP_NS = 500_000_000     # data gaps longer than this and than _GAP_STEPS median steps invalidate the grid
_GAP_STEPS = 2.5              # points across them (a slow stream's every step is not a gap)
_MIN_SPAN_NS = 2_000_000_000  # shortest stream [ns] whose rotation can be correlated
_STEP_REFINE_NS = 150_000_000  # slower than ~6.7 Hz: ω estimate refined on its own steps (_StepRefiner); at 10 Hz
#                               the ω refinement is better (a 10 Hz odometry stream: 22 ms bias on its steps)
_STEP_SCAN_NS = 250_000_000    # slower than 4 Hz: ω is too coarse to correlate, the steps are scanned instead
_SCAN_NS = 250_000_000         # grid spacing of that scan [ns]: the robust cost is unimodal within ±this
_SCAN_STEPS = 200              # steps the scan evaluates (evenly spread)
_STEP_OUTLIER = 10.0          # steps whose residual exceeds this many medians are left out of it
_TRUNCATE = 3.0               # the smoothing kernel reaches this many σ
MAX_GRID_POINTS = 65_536      # ω grid points per stream at most (bounded work: the module docstring's "Long
#                               recordings"): 328 s at _GRID_NS; a longer stream's coarse grid is coarser and
#                               its refinement reads _WINDOWS windows holding this many points in all
_WINDOWS = 8                  # refinement windows of a long recording, spread evenly over the streams' overlap
_MAX_SCAN_OFFSETS = 10_000    # offsets a slow stream's scan evaluates at most a level (a range of 2,500 s at
#                               _SCAN_NS; a wider one is scanned coarser first, each level around the last's best)
MIN_CORRELATION = 0.5         # a lower peak correlation of the angular speeds is an error
SIGNIFICANT_SIGMA = 3.0       # an estimate beyond this many of its σ from 0 is applied by --time-offset auto …
NEGLIGIBLE_NS = 100_000       # … and beyond 0.1 ms (at 1 rad/s a 0.006° error: identical clocks estimate ~1 ns ± 0.1);
#                               the fit must confirm it (handeye_cli/verify/policy.py: CONFIRMING_*)
_WEAK_CORRELATION = 0.8       # a lower one is a warning
_AMBIGUITY = 0.05             # warn when another peak comes within this of the best
_PEAK_SEPARATION_NS = 500_000_000   # peaks closer than this to the best are the same peak


@dataclass(frozen=True)
class TimeOffset:
    """Estimated clock offset of stream b relative to stream a.

    offset_ns: how far b's clock is ahead of a's [ns] (pass it to ``associate(time_offset_ns=…)``).
    std_ns: 1-σ uncertainty of ``offset_ns`` [ns].
    coarse_ns: the global cross-correlation estimate [ns].
    correlation: peak normalised correlation of the angular speeds (1 = identical; below
        ``MIN_CORRELATION`` the estimate is refused).
    method: what produced the estimate.
    warnings: reasons to distrust the estimate (weak or ambiguous correlation peak).
    """

    offset_ns: int
    std_ns: float
    coarse_ns: int
    correlation: float
    method: str
    warnings: tuple[str, ...] = ()

    @property
    def significant(self) -> bool:
        """Whether the offset differs from 0 by more than ``SIGNIFICANT_SIGMA`` of its own σ and more than
        ``NEGLIGIBLE_NS``: what the default ``--time-offset auto`` applies (a smaller one is noise, or too
        small to matter, and applying it or 0 is the same)."""
        return abs(self.offset_ns) > max(SIGNIFICANT_SIGMA * self.std_ns, NEGLIGIBLE_NS)

    @property
    def applicable(self) -> bool:
        """Whether ``--time-offset auto`` applies the estimate: :attr:`significant` and no reason to distrust
        it (no :attr:`warnings`). The one home of the rule ``calibrate`` and every rig stream follow."""
        return self.significant and not self.warnings


@dataclass(frozen=True)
class _Signal:
    """ω of one stream on a uniform grid: grid point k is at ``t0_ns + k·step_ns`` (stream clock)."""

    t0_ns: int
    omega: np.ndarray      # (M, 3) body angular velocity [rad/s]
    valid: np.ndarray      # (M,) bool
    step_ns: int = _GRID_NS

    def times_s(self) -> np.ndarray:
        return np.arange(len(self.valid)) * (self.step_ns / 1e9)


def _fast_len(n: int) -> int:
    """The least ``2^a·3^b·5^c ≥ n`` (n ≥ 1): a length numpy's FFTs transform fast, the size
    ``scipy.fft.next_fast_len(n, real=True)`` gives (tests check that they agree)."""
    best = 1 << (n - 1).bit_length()                       # the least power of two
    odd5 = 1
    while odd5 < best:
        odd = odd5
        while odd < best:                                  # odd = 3^b·5^c: times the least power of two reaching n
            best = min(best, odd << (-(-n // odd) - 1).bit_length())
            odd *= 3
        odd5 *= 5
    return best


def _gaussian_filter(x: np.ndarray, sigma: float) -> np.ndarray:
    """``x`` (M, C) smoothed along axis 0 by a Gaussian of σ = ``sigma`` samples reaching ``_TRUNCATE`` σ,
    the edge samples repeated beyond the ends: ``scipy.ndimage.gaussian_filter1d(x, sigma, axis=0,
    mode="nearest", truncate=_TRUNCATE)`` (same kernel and normalisation; tests check that they agree)."""
    radius = int(_TRUNCATE * sigma + 0.5)
    weights = np.exp(-0.5 / (sigma * sigma) * np.arange(-radius, radius + 1) ** 2)
    weights /= weights.sum()
    padded, m = np.pad(x, ((radius, radius), (0, 0)), mode="edge"), len(x)
    out: np.ndarray = padded[radius:radius + m] * weights[radius]
    for k in range(radius, 0, -1):                     # the outer pairs first, each pair summed, as scipy does
        out += (padded[radius - k:radius - k + m] + padded[radius + k:radius + k + m]) * weights[radius - k]
    return out


def _median_filter(x: np.ndarray, size: int) -> np.ndarray:
    """The median of each sample's ``size`` (odd) neighbours, the edge samples repeated beyond the
    ends: ``scipy.ndimage.median_filter(x, size, mode="nearest")`` for 1-D ``x`` (tests check that they agree)."""
    half = size // 2
    windows = sliding_window_view(np.pad(x, half, mode="edge"), size)
    return np.partition(windows, half, axis=1)[:, half]


def _erode(mask: np.ndarray, size: int) -> np.ndarray:
    """bool: ``mask`` true at every sample within ``size // 2`` (size odd) of each one, the window cut at
    the ends: ``scipy.ndimage.minimum_filter1d(mask, size)`` in mode "nearest" or "reflect" (tests check
    that they agree)."""
    n, half = len(mask), size // 2
    false = np.concatenate([[0], np.cumsum(~mask)])
    centre = np.arange(n)
    return np.asarray(false[np.minimum(centre + half + 1, n)] == false[np.maximum(centre - half, 0)])


def _step_rotvecs(quat: np.ndarray) -> np.ndarray:
    """(N-1, 3) rotation vectors [rad] of the motions between consecutive x-y-z-w quaternions (N, 4)."""
    return dq.to_rotvec(dq.relative(quat[:-1], quat[1:]))


def _bad_steps(stream: PoseStream) -> np.ndarray:
    """bool[N-1]: steps i→i+1 that are data gaps (longer than 0.5 s and 2.5 median steps) or tracking
    jumps (rate > 5× local median + 1 rad/s)."""
    dt = np.diff(stream.stamps_ns)
    rate = np.linalg.norm(_step_rotvecs(stream.quat_xyzw), axis=1) / np.maximum(dt, 1) * 1e9
    local = _median_filter(rate, 11)
    bad: np.ndarray = (dt > max(_MAX_GAP_NS, _GAP_STEPS * np.median(dt))) | (rate > 5 * local + 1.0)
    return bad


@dataclass(frozen=True, eq=False)
class Grid:
    """What ω needs of a stream whatever the window: its orientations SLERPed at ``stamps[0] + k·step_ns``
    (x-y-z-w, (K, 4), every grid point within its span) and the cumulative count of its bad steps
    (:func:`_bad_steps`) before each sample."""

    quat_xyzw: np.ndarray
    bad_before: np.ndarray
    step_ns: int = _GRID_NS


def grid_of(stream: PoseStream, step_ns: int = _GRID_NS) -> Grid:
    """:class:`Grid` of ``stream`` at grid step ``step_ns`` (a multiple of ``_GRID_NS``)."""
    stamps = stream.stamps_ns
    points = stamps[0] + np.arange((int(stamps[-1]) - int(stamps[0])) // step_ns + 1, dtype=np.int64) * step_ns
    return Grid(stream.sample(points).quat_xyzw, np.concatenate([[0], np.cumsum(_bad_steps(stream))]), step_ns)


def angular_velocity(stream: PoseStream, window_ns: int, smooth_ns: float,
                     grid: Callable[[PoseStream], Grid] = grid_of) -> _Signal:
    """Body angular velocity [rad/s] of ``stream`` on the uniform grid ``grid`` gives (see the module
    docstring), smoothed by a Gaussian of σ = ``smooth_ns``; ``window_ns`` is a multiple of two grid
    steps, so that the orientations at ``t ± w/2`` are those of one interpolation on the grid, ``w`` apart."""
    stamps = stream.stamps_ns
    on_grid = grid(stream)                              # grid point k at stamps[0] + k·step
    step = on_grid.step_ns
    half = window_ns // 2
    steps, rest = divmod(half, step)
    if rest or not steps:
        raise ValueError(f"window {window_ns} ns is not a positive multiple of {2 * step} ns")
    t0 = int(stamps[0]) + half
    centres = t0 + np.arange(max((int(stamps[-1]) - half - t0) // step + 1, 0), dtype=np.int64) * step
    if len(centres) < 2:
        raise DataError("pose stream too short for its sample rate to estimate a time offset", stream.source,
                           "record more samples while rotating, or give a fixed ⟦time_offset⟧")
    q = on_grid.quat_xyzw[:len(centres) + 2 * steps]
    omega = dq.to_rotvec(dq.relative(q[:-2 * steps], q[2 * steps:]))     # within [stamps[0], stamps[-1]]: all inside
    omega /= 2 * half / 1e9
    sigma = smooth_ns / step
    omega = _gaussian_filter(omega, sigma)
    bad = on_grid.bad_before
    first = np.searchsorted(stamps, centres - half, side="right") - 1
    last = np.searchsorted(stamps, centres + half, side="left")
    reach = 2 * int(np.ceil(_TRUNCATE * sigma)) + 1       # a smoothed point mixes this many grid points
    return _Signal(t0, omega, _erode(bad[last] == bad[first], reach), step)


def _masked_ncc(f: np.ndarray, mf: np.ndarray, g: np.ndarray, mg: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pearson correlation of ``f[k]`` and ``g[k + L]`` over the valid overlap, for every lag L.

    Returns ``(lags, ncc, overlap_count)``.
    """
    f = np.where(mf, f - f[mf].mean(), 0.0)
    g = np.where(mg, g - g[mg].mean(), 0.0)
    size = _fast_len(len(f) + len(g) - 1)
    # each signal's spectrum once (three of f's, three of g's), not once per correlation it enters (six)
    Mf, Ff, Ff2 = (np.fft.rfft(x, size) for x in (mf.astype(float), f, f * f))
    Mg, Gg, Gg2 = (np.fft.rfft(x, size) for x in (mg.astype(float), g, g * g))

    def xc(U: np.ndarray, V: np.ndarray) -> np.ndarray:
        return _from_spectra(V, U, size, len(g), len(f))

    n = np.round(xc(Mf, Mg))
    sf, sg = xc(Ff, Mg), xc(Mf, Gg)
    sff, sgg, sfg = xc(Ff2, Mg), xc(Mf, Gg2), xc(Ff, Gg)
    safe = np.maximum(n, 1)
    cov = sfg - sf * sg / safe
    var = np.maximum(sff - sf ** 2 / safe, 0) * np.maximum(sgg - sg ** 2 / safe, 0)
    ncc = np.where(var > 0, cov / np.sqrt(np.where(var > 0, var, 1)), 0.0)
    return np.arange(-(len(f) - 1), len(g)), ncc, n


def _correlate(v: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``Σ_k v[k + L] u[k]`` for every lag ``L`` from ``-(len(u) - 1)`` to ``len(v) - 1``, by FFT: what
    ``scipy.signal.correlate(v, u, mode="full", method="fft")`` computes (tests check that they agree),
    with numpy's FFTs, without importing ``scipy.signal`` (1 s of start-up) or ``scipy.fft``."""
    n = _fast_len(len(v) + len(u) - 1)
    return _from_spectra(np.fft.rfft(v, n), np.fft.rfft(u, n), n, len(v), len(u))


def _from_spectra(V: np.ndarray, U: np.ndarray, n: int, len_v: int, len_u: int) -> np.ndarray:
    """:func:`_correlate` of ``v``, ``u`` (lengths ``len_v``, ``len_u``) from their real FFTs ``V``, ``U`` of
    length ``n ≥ len_v + len_u - 1``."""
    full = np.fft.irfft(V * np.conj(U), n)
    return np.concatenate((full[n - len_u + 1:], full[:len_v]))


def _prominent_peaks(x: np.ndarray, prominence: float, height: float) -> np.ndarray:
    """Indices of the local maxima of ``x`` at least ``height`` high and ``prominence`` prominent: the
    peaks ``scipy.signal.find_peaks(x, prominence=prominence)`` finds (tests check that they agree),
    of that height. A peak's prominence is its height above the higher of the lowest points on
    each side before the signal first rises above the peak (or ends)."""
    inner = np.flatnonzero((x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:])) + 1
    out = []
    for p in inner[x[inner] >= height]:
        right = p + 1 + int(np.argmax(x[p + 1:] != x[p]))     # the first sample past a plateau
        if x[right] >= x[p]:                                  # rises again, or flat to the end: no peak
            continue
        mid = (p + right - 1) // 2                            # a plateau's peak is its middle sample
        above_l, above_r = np.flatnonzero(x[:p] > x[p]), np.flatnonzero(x[right:] > x[p])
        left_min = x[(above_l[-1] + 1 if len(above_l) else 0):p + 1].min()
        right_min = x[right - 1:(right + above_r[0] if len(above_r) else len(x))].min()
        if x[p] - max(left_min, right_min) >= prominence:
            out.append(mid)
    return np.asarray(out, dtype=np.int64)


def _coarse(sa: _Signal, sb: _Signal, max_offset_ns: int | None) -> tuple[float, float, tuple[str, ...]]:
    """Global search: (offset [ns] from the parabola through the peak, peak correlation, warnings)."""
    if not (sa.valid.any() and sb.valid.any()):   # every ω point touches a gap or a jump: nothing to correlate
        raise DataError("the streams are too short or too gappy to correlate their rotations", "time offset",
                        "give a fixed ⟦time_offset⟧, or widen ⟦max_time_offset⟧")
    speed_a, speed_b = np.linalg.norm(sa.omega, axis=1), np.linalg.norm(sb.omega, axis=1)
    lags, ncc, n = _masked_ncc(speed_a, sa.valid, speed_b, sb.valid)
    offsets = (sb.t0_ns - sa.t0_ns) + lags.astype(np.int64) * sa.step_ns
    allowed = n >= _MIN_OVERLAP * min(sa.valid.sum(), sb.valid.sum())
    if max_offset_ns is not None:
        allowed &= np.abs(offsets) <= max_offset_ns
    if not allowed.any():
        raise DataError("the streams are too short or too gappy to correlate their rotations", "time offset",
                           "give a fixed ⟦time_offset⟧, or widen ⟦max_time_offset⟧")
    score = np.where(allowed, ncc, -np.inf)
    k = int(np.argmax(score))
    best = float(score[k])
    if best < MIN_CORRELATION:
        raise DataError(
            f"the two streams' angular speeds do not correlate (peak {best:.2f} < {MIN_CORRELATION})",
            "time offset", "the sensors must rotate (linear motion carries no timing information) and "
            "record the same motion; otherwise give a fixed ⟦time_offset⟧")
    warnings = []
    if best < _WEAK_CORRELATION:
        warnings.append(f"weak angular-speed correlation {best:.2f}: the time offset may be wrong")
    peaks = _prominent_peaks(np.where(allowed, ncc, -1.0), _AMBIGUITY, best - _AMBIGUITY)
    rivals = peaks[np.abs(offsets[peaks] - offsets[k]) > _PEAK_SEPARATION_NS]
    if len(rivals) and score[rivals].max() >= best - _AMBIGUITY:
        r = rivals[np.argmax(score[rivals])]
        warnings.append(f"ambiguous time offset: {offsets[r] / 1e9:.3f} s correlates almost as well "
                        f"({score[r]:.3f} vs {best:.3f}; repetitive or too short motion)")
    frac = 0.0
    if 0 < k < len(score) - 1 and np.isfinite(score[k - 1]) and np.isfinite(score[k + 1]):
        den = score[k - 1] - 2 * score[k] + score[k + 1]
        frac = 0.5 * (score[k - 1] - score[k + 1]) / den if den < 0 else 0.0
    return float(offsets[k]) + frac * sa.step_ns, best, tuple(warnings)


def _interp(t: np.ndarray, grid: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear interpolation of (M, 3) ``values`` on ``grid`` at times ``t``."""
    return np.stack([np.interp(t, grid, values[:, c]) for c in range(values.shape[1])], axis=1)


class _Refiner:
    """The cost ``J(τ) = min_R Σ |ω_a − R ω_b(· + τ)|²`` over a fixed set of a's grid points, those whose
    partners in b are valid within ±``bracket_ns`` of the coarse estimate."""

    def __init__(self, sa: _Signal, sb: _Signal, coarse_ns: float, bracket_ns: int = _BRACKET_NS) -> None:
        self.base_ns = sb.t0_ns - sa.t0_ns          # offset = base + τ, τ in seconds below
        self.tb, self.wb, self.step_s = sb.times_s(), sb.omega, sb.step_ns / 1e9
        erode = 2 * bracket_ns // sb.step_ns + 3
        valid_b = _erode(sb.valid, erode)
        ta = sa.times_s()
        tau0 = (coarse_ns - self.base_ns) / 1e9
        idx_b = np.round((ta + tau0) / self.step_s).astype(np.int64)
        inside = (idx_b >= 0) & (idx_b < len(valid_b))
        keep = sa.valid & inside
        keep[keep] &= valid_b[idx_b[keep]]
        if keep.sum() < 10:
            raise DataError("too little overlap to refine the time offset", "time offset",
                               "give a fixed ⟦time_offset⟧")
        self.ta, self.wa = ta[keep], sa.omega[keep]

    def _fit(self, tau_s: float) -> tuple[np.ndarray, np.ndarray, float]:
        """(R, ω_b at the shifted times, J(τ)) with R the best rotation in closed form (Kabsch)."""
        wb = _interp(self.ta + tau_s, self.tb, self.wb)
        H = self.wa.T @ wb
        R = nearest_rotation(H)
        total = np.sum(self.wa ** 2) + np.sum(wb ** 2) - 2 * np.sum(R * H)      # tr(Rᵀ H) = s₁ + s₂ ± s₃
        return R, wb, float(total) / len(self.ta)

    def cost(self, tau_s: float) -> float:
        """Mean squared residual per evaluation time [rad²/s²] at offset ``base + tau_s``."""
        return self._fit(tau_s)[2]

    def sandwich(self, tau_s: float) -> tuple[float, float]:
        """The parts of τ's sandwich variance: (Σ over 1 s blocks of the summed residual·gradient products,
        squared; Σ of the squared gradients)."""
        R, wb, _ = self._fit(tau_s)
        resid = self.wa - wb @ R.T
        grad = _interp(self.ta + tau_s, self.tb, np.gradient(self.wb, self.step_s, axis=0)) @ R.T
        score = np.einsum("ij,ij->i", resid, grad)
        block = np.floor(self.ta).astype(np.int64)
        per_block = np.bincount(block - block.min(), weights=score)
        return float(np.sum(per_block ** 2)), float(np.sum(grad ** 2))


class _Refiners:
    """The ω refinement over one or several windows of the streams (:class:`_Refiner` each): ``J`` is the mean
    over every window's grid points, τ that of the first window (the others' τ differ by their grid bases)."""

    def __init__(self, parts: list[_Refiner]) -> None:
        self.parts = parts
        self.base_ns = parts[0].base_ns
        self.shift_s = [(self.base_ns - p.base_ns) / 1e9 for p in parts]
        self.counts = np.array([len(p.ta) for p in parts], dtype=np.float64)

    def cost(self, tau_s: float) -> float:
        """Mean squared residual per evaluation time [rad²/s²] at offset ``base + tau_s``."""
        if len(self.parts) == 1:
            return self.parts[0].cost(tau_s)
        costs = [p.cost(tau_s + d) for p, d in zip(self.parts, self.shift_s, strict=True)]
        return float(np.dot(costs, self.counts) / self.counts.sum())

    def std_s(self, tau_s: float) -> float:
        """1-σ of τ [s]: a sandwich estimate with residual-gradient products summed over 1 s blocks,
        so noise that is correlated within a window (and model error) is accounted for."""
        parts = np.array([p.sandwich(tau_s + d) for p, d in zip(self.parts, self.shift_s, strict=True)])
        return float(np.sqrt(parts[:, 0].sum()) / max(parts[:, 1].sum(), 1e-300))


class _StepRefiner:
    """The cost ``J(τ) = min_R mean |r_fast,k(τ) − R r_slow,k|²`` over the slower stream's own steps.

    ``r_slow,k`` is the rotation vector of the slower stream's motion between its samples k and
    k+1, ``r_fast,k(τ)`` that of the faster stream between the same instants given the offset τ
    (interpolated, accurate because its samples are close). For a rigid rig ``r_a = R_a_b r_b``.
    Unlike ω sampled on a grid, nothing of the slower stream is interpolated, so the estimate
    stays accurate when its samples are seconds apart. Steps across gaps or tracking jumps are
    left out, and so are (:meth:`drop_outliers`) steps whose residual exceeds ``_STEP_OUTLIER`` ×
    the median at a good offset.
    """

    def __init__(self, a: PoseStream, b: PoseStream) -> None:
        self.slow_is_b = _median_step(b) > _median_step(a)
        slow, self.fast = (b, a) if self.slow_is_b else (a, b)
        self.stamps = slow.stamps_ns
        self.r_slow = _step_rotvecs(slow.quat_xyzw)
        self.keep = ~_bad_steps(slow)

    def offset_range(self, max_offset_ns: int | None) -> tuple[float, float]:
        """Offsets [ns] at which at least a third of the shorter stream's span overlaps the other."""
        fast = self.fast.stamps_ns
        third = min(self.stamps[-1] - self.stamps[0], fast[-1] - fast[0]) / 3
        lo, hi = fast[0] - self.stamps[-1] + third, fast[-1] - self.stamps[0] - third   # shift of slow stamps
        lo, hi = (-hi, -lo) if self.slow_is_b else (lo, hi)
        if max_offset_ns is not None:
            lo, hi = max(lo, -max_offset_ns), min(hi, max_offset_ns)
        return float(lo), float(hi)

    def _residuals(self, offset_ns: float) -> tuple[np.ndarray, np.ndarray] | None:
        """(kept steps k inside the faster stream's span, residuals ``r_fast − R r_slow``) at ``offset_ns``,
        or None when fewer than a third of the kept steps (or 10) are inside."""
        t = self.stamps + int(round(-offset_ns if self.slow_is_b else offset_ns))    # in the fast stream's clock
        at = self.fast.sample(t)
        inside, quat = at.inside, at.quat_xyzw
        both = inside[:-1] & inside[1:] & self.keep
        if both.sum() < max(10, self.keep.sum() / 3):
            return None
        q = np.zeros((len(t), 4))
        q[inside] = quat
        k = np.flatnonzero(both)
        r_fast = dq.to_rotvec(dq.relative(q[k], q[k + 1]))
        return k, r_fast - self.r_slow[k] @ nearest_rotation(r_fast.T @ self.r_slow[k]).T

    def cost(self, offset_ns: float) -> float:
        """Mean squared residual [rad²] (``inf`` without enough overlap)."""
        found = self._residuals(offset_ns)
        return np.inf if found is None else float(np.mean(found[1] ** 2))

    def robust_cost(self, offset_ns: float) -> float:
        """Median squared residual norm [rad²]: tracking jumps do not move it (``inf`` without enough overlap)."""
        found = self._residuals(offset_ns)
        return np.inf if found is None else float(np.median(np.sum(found[1] ** 2, axis=1)))

    def scan(self, max_offset_ns: int | None) -> float:
        """The offset [ns] of the least median squared residual on a grid over every allowed offset.

        Vectorised over blocks of offsets, on at most ``_SCAN_STEPS`` evenly spread kept steps. Bounded work:
        at most ``_MAX_SCAN_OFFSETS`` offsets a level: a range wider than that many ``_SCAN_NS`` is scanned at a
        coarser spacing first, then each level within ±its spacing of its best, down to ``_SCAN_NS``."""
        lo, hi = self.offset_range(max_offset_ns)
        spacing = max(float(_SCAN_NS), (hi - lo) / _MAX_SCAN_OFFSETS)
        grid = np.arange(lo, hi + spacing, spacing)
        steps = np.flatnonzero(self.keep)
        steps = steps[np.linspace(0, len(steps) - 1, min(len(steps), _SCAN_STEPS)).astype(np.int64)]
        if len(grid) == 0 or len(steps) < 10:
            raise DataError("the streams are too short or too gappy to correlate their rotations", "time offset",
                               "give a fixed ⟦time_offset⟧, or widen ⟦max_time_offset⟧")
        best = self._scan_grid(grid, steps)
        while spacing > _SCAN_NS:
            finer = max(float(_SCAN_NS), 2 * spacing / _MAX_SCAN_OFFSETS)
            best = self._scan_grid(np.arange(max(lo, best - spacing), min(hi, best + spacing) + finer, finer), steps)
            spacing = finer
        return best

    def _scan_grid(self, grid: np.ndarray, steps: np.ndarray) -> float:
        """The offset of ``grid`` [ns] with the least median squared residual on ``steps``."""
        block = max(1, 50_000 // len(steps))
        costs = np.concatenate([self._median_costs(grid[i:i + block], steps) for i in range(0, len(grid), block)])
        return float(grid[int(np.argmin(costs))])

    def _median_costs(self, offsets: np.ndarray, steps: np.ndarray) -> np.ndarray:
        """:meth:`robust_cost` at each of ``offsets`` [ns] on the given steps (``inf`` where fewer than a
        third of them lie inside the faster stream's span)."""
        sign = -1 if self.slow_is_b else 1
        t = self.stamps[np.r_[steps, steps + 1]][None, :] + np.round(sign * offsets).astype(np.int64)[:, None]
        at = self.fast.sample(t.ravel())
        inside, quat = at.inside, at.quat_xyzw
        q = np.zeros((t.size, 4))
        q[:, 3] = 1.0
        q[inside] = quat
        pairs = q.reshape(len(offsets), 2, len(steps), 4)
        ok = np.asarray(inside.reshape(len(offsets), 2, len(steps)).all(axis=1))
        r_fast = dq.to_rotvec(dq.relative(pairs[:, 0], pairs[:, 1]))            # (offsets, steps, 3)
        r_slow = np.where(ok[..., None], self.r_slow[steps][None], 0.0)
        R = nearest_rotation(np.einsum("gsi,gsj->gij", r_fast, r_slow))
        resid = np.sum((r_fast - np.einsum("gij,gsj->gsi", R, r_slow)) ** 2, axis=2)
        enough = ok.sum(axis=1) >= len(steps) / 3
        cost = np.full(len(offsets), np.inf)
        cost[enough] = np.nanmedian(np.where(ok[enough], resid[enough], np.nan), axis=1)
        return cost

    def drop_outliers(self, offset_ns: float) -> None:
        """Leave out the steps whose residual at ``offset_ns`` exceeds ``_STEP_OUTLIER`` × the median."""
        found = self._residuals(offset_ns)
        if found is not None:
            norm = np.linalg.norm(found[1], axis=1)
            self.keep[found[0][norm > _STEP_OUTLIER * np.median(norm)]] = False

    def correlation(self, offset_ns: float) -> float:
        """Pearson correlation of the two streams' step angles at ``offset_ns``."""
        found = self._residuals(offset_ns)
        if found is None:
            return 0.0
        k, resid = found
        slow = np.linalg.norm(self.r_slow[k], axis=1)
        fast = np.linalg.norm(resid + self.r_slow[k] @ np.eye(3), axis=1)    # |r_fast| (R preserves norms)
        return float(np.corrcoef(fast, slow)[0, 1]) if np.std(slow) > 0 and np.std(fast) > 0 else 0.0

    def refine(self, offset_ns: float, span_ns: float) -> tuple[int, float]:
        """(offset [ns], 1-σ [ns]): Brent's method within ±``span_ns`` of ``offset_ns``, first on the
        robust cost, then, without the outlying steps there, on the mean within a tenth of the span."""
        rough = minimize_bounded(self.robust_cost, offset_ns - span_ns, offset_ns + span_ns, xatol=1e3)
        self.drop_outliers(rough)
        best = minimize_bounded(self.cost, rough - span_ns / 10, rough + span_ns / 10, xatol=1e3)
        return int(round(best)), self.std_ns(best)

    def std_ns(self, offset_ns: float) -> float:
        """1-σ [ns] by Gauss–Newton: residual variance over the squared sensitivity to the offset."""
        h = 1e6                                                    # 1 ms finite difference
        f0, f1 = self._residuals(offset_ns), self._residuals(offset_ns + h)
        if f0 is None or f1 is None or f0[1].shape != f1[1].shape:
            return float("nan")
        r0, grad = f0[1], (f1[1] - f0[1]) / h
        dof = max(r0.size - 4, 1)
        return float(np.sqrt(np.sum(r0 ** 2) / dof / max(np.sum(grad ** 2), 1e-300)))


def _median_step(stream: PoseStream) -> float:
    return float(np.median(np.diff(stream.stamps_ns)))


def _on_steps(a: PoseStream, b: PoseStream, max_offset_ns: int | None) -> TimeOffset:
    """The estimate for a slow stream (< 4 Hz): scan and refine on its own steps (:class:`_StepRefiner`)."""
    ref = _StepRefiner(a, b)
    coarse = ref.scan(max_offset_ns)
    offset_ns, std_ns = ref.refine(coarse, _SCAN_NS)
    corr = ref.correlation(offset_ns)
    if corr < MIN_CORRELATION:
        raise DataError(
            f"the two streams' step rotations do not correlate (peak {corr:.2f} < {MIN_CORRELATION})",
            "time offset", "the sensors must rotate (linear motion carries no timing information) and "
            "record the same motion; otherwise give a fixed ⟦time_offset⟧")
    warnings = (f"weak step-rotation correlation {corr:.2f}: the time offset may be wrong",) \
        if corr < _WEAK_CORRELATION else ()
    return TimeOffset(offset_ns=offset_ns, std_ns=std_ns, coarse_ns=int(round(coarse)), correlation=corr,
                      method="scan + refinement on the slower stream's step rotations", warnings=warnings)


def _between(stream: PoseStream, first_ns: int, last_ns: int) -> PoseStream:
    """The samples of ``stream`` stamped within ``[first_ns, last_ns]`` (found by bisection, not a mask of all)."""
    lo = np.searchsorted(stream.stamps_ns, np.int64(first_ns), side="left")
    hi = np.searchsorted(stream.stamps_ns, np.int64(last_ns), side="right")
    return stream.select(np.arange(lo, hi))


def _windowed_refiners(a: PoseStream, b: PoseStream, coarse_ns: float, window_ns: int, smooth_ns: float,
                       bracket_ns: int) -> list[_Refiner]:
    """:class:`_Refiner` s of a long recording: ``_WINDOWS`` windows of a, ``MAX_GRID_POINTS`` grid points in
    all, spread evenly over its overlap with b at the coarse estimate (the overlap whole when it is shorter),
    each with the stretch of b it needs (±``bracket_ns`` and the differentiation and smoothing reach)."""
    first = max(int(a.stamps_ns[0]), int(b.stamps_ns[0] - coarse_ns))      # the overlap, in a's clock
    last = min(int(a.stamps_ns[-1]), int(b.stamps_ns[-1] - coarse_ns))
    length = MAX_GRID_POINTS * _GRID_NS // _WINDOWS
    if last - first <= MAX_GRID_POINTS * _GRID_NS:
        spans = [(first, last)]
    else:
        starts = first + (np.arange(_WINDOWS) * ((last - first - length) / (_WINDOWS - 1))).astype(np.int64)
        spans = [(int(s), int(s) + length) for s in starts]
    reach = window_ns // 2 + int(2 * _TRUNCATE * smooth_ns) + _GRID_NS
    out = []
    for lo, hi in spans:
        part_a = _between(a, lo - reach, hi + reach)
        shift = int(round(coarse_ns))
        part_b = _between(b, lo + shift - reach - bracket_ns, hi + shift + reach + bracket_ns)
        try:
            out.append(_Refiner(angular_velocity(part_a, window_ns, smooth_ns),
                                angular_velocity(part_b, window_ns, smooth_ns), coarse_ns, bracket_ns))
        except DataError:                                  # a window too short or too gappy: the others refine
            continue
    if not out:
        raise DataError("too little overlap to refine the time offset", "time offset", "give a fixed ⟦time_offset⟧")
    return out


def overlap_offsets_ns(a: PoseStream, b: PoseStream) -> tuple[int, int]:
    """(lo, hi) [ns]: the clock offsets (b ahead of a) at which the streams' spans overlap at all: b's stamps
    ``s`` at a's times ``s - offset`` meet a's span for ``b[0] - a[-1] ≤ offset ≤ b[-1] - a[0]``."""
    return int(b.stamps_ns[0]) - int(a.stamps_ns[-1]), int(b.stamps_ns[-1]) - int(a.stamps_ns[0])


def search_bound_ns(a: PoseStream, b: PoseStream, max_offset_s: float | str | None) -> int | None:
    """The bound [ns] on |offset| that ``max_offset_s`` means: seconds as given; ``"auto"`` (the option's
    default) the shorter stream's span (first to last stamp), so that an offset larger than the recording,
    which a correlation can only find between streams that share no time, is searched only when asked for;
    ``None`` no bound (any lag)."""
    if max_offset_s is None:
        return None
    if max_offset_s == "auto":
        return min(int(s.stamps_ns[-1]) - int(s.stamps_ns[0]) for s in (a, b))
    return int(round(float(max_offset_s) * 1e9))


def _check_reachable(a: PoseStream, b: PoseStream, max_ns: int | None, auto: bool) -> None:
    """Refuse, in one line naming ``--max-time-offset``, streams whose spans overlap by the search's least share
    (``_MIN_OVERLAP`` of the shorter span) at no offset within ±``max_ns``: no correlation could find one."""
    lo, hi = overlap_offsets_ns(a, b)
    least = _MIN_OVERLAP * min(int(s.stamps_ns[-1]) - int(s.stamps_ns[0]) for s in (a, b))
    if max_ns is None or (lo + least <= max_ns and hi - least >= -max_ns):
        return
    need, every = min(abs(lo), abs(hi)) / 1e9, int(np.ceil(max(abs(lo), abs(hi)) / 1e9))   # [s]
    bound = f"±{max_ns / 1e9:.6g} s" + (", the shorter stream's span" if auto else "")
    span = {n: f"{s.stamps_ns[0] / 1e9:.3f}–{s.stamps_ns[-1] / 1e9:.3f} s" for n, s in (("a", a), ("b", b))}
    raise DataError(f"the two streams' stamps do not overlap (by a third of the shorter, as the search needs) at "
                    f"any clock offset searched ({bound}): a spans "
                    f"{span['a']}, b spans {span['b']}, {need:.6g} s apart", "time offset",
                    f"if the clocks differ by that much, widen ⟦max_time_offset=SECONDS⟧ ({every} covers every "
                    f"offset at which they overlap) or give the offset with ⟦time_offset=SECONDS⟧; otherwise "
                    "the two inputs are not of one recording")


def estimate_time_offset(a: PoseStream, b: PoseStream, *, max_offset_s: float | str | None = None,
                         grid: Callable[..., Grid] = grid_of) -> TimeOffset:
    """Estimate how far b's clock is ahead of a's (see the module docstring for the method).

    Parameters
    ----------
    a, b: pose streams of two rigidly attached sensors (any frames; the extrinsic is not needed).
    max_offset_s: optional bound [s] on |offset|; ``"auto"`` the shorter stream's span (the default of
        ``--max-time-offset``, :func:`search_bound_ns`); ``None`` searches every lag.
    grid: each stream's orientations on the ω grid, called as :func:`grid_of` (``grid(stream)`` at
        ``_GRID_NS``, ``grid(stream, step_ns)`` on a long recording's coarse level), or a
        :class:`~handeye_cli.streams.StreamMemo` of it that a rig shares between the estimates against its
        reference (the windows of a long recording's refinement are each pair's own: not shared).

    Raises
    ------
    DataError: when the streams' spans overlap at no offset within the bound (the message names
        ``--max-time-offset``), a stream spans less than 2 s, the streams are too short or too gappy
        to correlate, or their angular speeds do not correlate (too little rotation).
    """
    for name, stream in (("a", a), ("b", b)):
        span = stream.stamps_ns[-1] - stream.stamps_ns[0] if len(stream) else 0
        if span < _MIN_SPAN_NS:
            raise DataError(f"pose stream {name} spans {span / 1e9:.2f} s ({len(stream)} samples), too short "
                               "to estimate a time offset", stream.source or f"stream {name}",
                               f"record at least {_MIN_SPAN_NS / 1e9:.0f} s of rotation, or give a fixed ⟦time_offset⟧")
    intervals = [np.median(np.diff(s.stamps_ns)) for s in (a, b)]
    max_ns = search_bound_ns(a, b, max_offset_s)
    _check_reachable(a, b, max_ns, max_offset_s == "auto")
    if max(intervals) > _STEP_SCAN_NS:
        return _on_steps(a, b, max_ns)
    window = int(max(_MIN_WINDOW_NS, 3 * max(intervals)))
    window -= window % (2 * _GRID_NS)
    smooth = float(max(intervals))
    longest = max(int(s.stamps_ns[-1]) - int(s.stamps_ns[0]) for s in (a, b))
    method = "angular-speed FFT cross-correlation + angular-velocity refinement"
    if longest <= MAX_GRID_POINTS * _GRID_NS:
        sa, sb = angular_velocity(a, window, smooth, grid), angular_velocity(b, window, smooth, grid)
        coarse_ns, corr, warnings = _coarse(sa, sb, max_ns)
        ref, bracket_ns = _Refiners([_Refiner(sa, sb, coarse_ns)]), _BRACKET_NS
    else:                                               # bounded work: a coarser grid, then windows at full rate
        step = _GRID_NS * -(-longest // (MAX_GRID_POINTS * _GRID_NS))
        on_step = lambda stream: grid(stream, step)         # noqa: E731 - the coarse level's grid
        wide = -(-window // (2 * step)) * 2 * step
        sa, sb = (angular_velocity(s, wide, max(smooth, step), on_step) for s in (a, b))
        coarse_ns, corr, warnings = _coarse(sa, sb, max_ns)
        bracket_ns = max(_BRACKET_NS, 2 * step)
        ref = _Refiners(_windowed_refiners(a, b, coarse_ns, window, smooth, bracket_ns))
        method = f"angular-speed FFT cross-correlation on a {step / 1e6:g} ms grid + angular-velocity " \
                 f"refinement on {len(ref.parts)} windows of {MAX_GRID_POINTS * _GRID_NS / 1e9 / _WINDOWS:g} s"
    tau0 = (coarse_ns - ref.base_ns) / 1e9
    span = bracket_ns / 1e9
    tau = minimize_bounded(ref.cost, tau0 - span, tau0 + span, xatol=1e-6)
    offset_ns, std_ns = int(ref.base_ns + round(tau * 1e9)), ref.std_s(tau) * 1e9
    if max(intervals) > _STEP_REFINE_NS:
        offset_ns, std_ns = _StepRefiner(a, b).refine(offset_ns, _BRACKET_NS)
        method += " + refinement on the slower stream's step rotations"
    return TimeOffset(offset_ns=offset_ns, std_ns=std_ns, coarse_ns=int(round(coarse_ns)), correlation=corr,
                      method=method, warnings=warnings)
