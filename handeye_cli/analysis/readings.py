"""Readings of the input chosen by the fit: the quaternion order of text files, tested before anything else.

A text trajectory's quaternion order is a convention of its format (TUM x-y-z-w, EuRoC w-x-y-z, a CSV's
column names), and exporters get it wrong: a w-x-y-z file read as x-y-z-w still yields an extrinsic, tens of
degrees wrong, whose residuals are far above the noise. A heuristic on the values (is the first component
near ±1?) cannot tell: it fires on real ground truth that rotates little about one axis, and misses
large rotations. The fit can: :func:`choose_quaternion_order` solves the same sample pairs under each
reading of every stream whose order came from the format (:attr:`PoseStream.quaternion_order`, not the
user's ``--wxyz-*`` / ``--no-wxyz-*``), each also with either stream inverted (a camera's target detections
that also need ``--invert-*`` must not hide the order), and keeps

* the format's reading, unless another fits **decisively** better: its median rotation or translation
  residual lower at least ``BETTER``-fold (3, as the inversion check of :mod:`.inversion`) and neither
  higher by more than ``NOT_WORSE``;
* and refuses (:class:`~handeye_cli.errors.DataError`) when another reading fits **alike** (both medians
  within ``NOT_WORSE``) but gives another extrinsic (beyond ``ALIKE_DEG`` / ``ALIKE_M``, and beyond the
  fits' own median residuals): the data cannot decide, and the flag can. Two fits that are both far from any
  rigid rig (bad stations: medians of 84° and 86°) give extrinsics apart by less than their residuals, which
  says nothing about the order; the format's reading then stands and the fit test, with its outlier retry,
  judges it.

The comparison runs on nearest-sample association (no interpolation, so a reading's synced poses are
the raw ones reordered) at the given clock offset, on at most ``MAX_PAIRS`` sample pairs drawn with a
fixed seed, solved by dqopt at α 1 — milliseconds.

The other readings decided before the solve are typed here too, for the result to hold: b's clock offset as the
reading decided it (:class:`OffsetReading`, by :func:`handeye_cli.verify.reading.decide_reading`), a given
order the data contradict (:class:`OrderContradiction`) and b's units found by the fit (:class:`ScaleReading`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import product
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..errors import DataError, HandEyeError
from ..geometry import se3
from ..solvers import solve
from ..streams import PoseStream
from .residuals import extrinsic_error, pair_residuals

if TYPE_CHECKING:
    from ..stages.timeoffset import TimeOffset

__all__ = ["MedianFit", "OffsetReading", "OrderChoice", "OrderContradiction", "ScaleReading",
           "choose_quaternion_order", "contradicted_order", "median_fit", "scale_reading", "spread_pairs",
           "CHECKED_PAIRS", "BETTER", "NOT_WORSE", "SCALE_GAIN", "SCALE_FLOOR"]

BETTER = 3.0              # a reading whose median residual is this many times lower fits decisively better
NOT_WORSE = 1.25          # … if its other median is not higher by more than this; within it both: alike
ALIKE_DEG, ALIKE_M = 1.0, 0.01   # alike fits whose extrinsics differ by more than this: the data cannot decide
MAX_PAIRS = 400
CHECKED_PAIRS = 500       # pairs of a solved calibration its checks of a reading compare on (spread over them)
_TINY = (1e-9, 1e-12)     # floors [deg, m] so that noise-free fits compare as finite ratios
SCALE_FLOOR = 0.01        # b's translations scaled by less than 1 % off 1 are metric …
SCALE_GAIN = 1.25         # … and a scale that lowers the median translation residual less than this is not seen
_FLAGS = {"xyzw": "⟦wxyz_{}=False⟧", "wxyz": "⟦wxyz_{}=True⟧"}


_NOT_ASKED = "not asked"     # OffsetReading.confirmed_by of an estimate the fit was not asked about (not applied)


@dataclass(frozen=True, eq=False)
class OffsetReading:
    """b's clock offset as the reading decided it (the result's ``time_offset``, :meth:`as_dict`).

    seconds: how far b's clock is ahead of a's [s], as applied (0 unless applied); method: ``fixed``, ``not
    estimated`` or the estimator's; applied: whether an estimate is applied (None for a fixed value); reason: why
    none could be estimated; estimate: the estimator's figures (:class:`~handeye_cli.stages.timeoffset.TimeOffset`)
    and ``significant_sigma``, the σ it must be from 0; fits: the median fits (and samples) of the pairs with the
    estimate and without an offset, where the fit was asked; confirmed_by: ``fit``, ``no pairs without it`` or None
    (the fit did not confirm it)."""

    seconds: float
    method: str
    applied: bool | None = None
    reason: str = ""
    estimate: TimeOffset | None = None
    significant_sigma: float = 0.0
    fits: tuple[tuple[MedianFit, int], tuple[MedianFit, int]] | None = None
    confirmed_by: str | None = _NOT_ASKED

    @property
    def offset_ns(self) -> int:
        return int(round(self.seconds * 1e9))

    def as_dict(self) -> dict[str, Any]:
        if self.applied is None:
            return {"seconds": self.seconds, "method": self.method}
        if self.estimate is None:
            return {"seconds": self.seconds, "method": self.method, "applied": self.applied, "reason": self.reason}
        est = self.estimate
        out: dict[str, Any] = {"seconds": self.seconds, "applied": self.applied,
                               "estimated_seconds": est.offset_ns / 1e9, "std_seconds": est.std_ns / 1e9,
                               "coarse_seconds": est.coarse_ns / 1e9, "correlation": est.correlation,
                               "method": est.method, "significant_sigma": self.significant_sigma}
        if self.fits is not None:
            out["fit_median"] = {name: {"rotation_deg": f.rotation_deg, "translation_m": f.translation_m,
                                        "samples": n} for name, (f, n) in zip(("applied", "none"), self.fits,
                                                                             strict=True)}
        if self.confirmed_by != _NOT_ASKED:
            out["confirmed_by"] = self.confirmed_by
        return out


@dataclass(frozen=True, eq=False)
class MedianFit:
    """The dqopt solution of a set of motions and its median residuals: ``matrix`` (4x4 ``T_a_b``),
    ``rotation_deg`` [deg], ``translation_m`` [m]."""

    matrix: NDArray[np.float64]
    rotation_deg: float
    translation_m: float

    @property
    def medians(self) -> tuple[float, float]:
        """(rotation [deg], translation [m])."""
        return self.rotation_deg, self.translation_m

    @property
    def rank(self) -> tuple[float, float]:
        """The order in which readings are ranked: rotation times translation median (floored), then the rotation
        median (noise-free fits tie at the floors). Both count: on planar motion a stream read inverted fits the
        rotations as well as the right reading (the common axis only turns over), so the rotation alone picked an
        inversion whose translations were metres off, and a wrong quaternion order then looked decisively better
        (a 60-s diff-drive base's TUM files read as w-x-y-z). A fit decisively better than another ranks lower:
        its two gains multiply to at least BETTER / NOT_WORSE."""
        return max(self.rotation_deg, _TINY[0]) * max(self.translation_m, _TINY[1]), self.rotation_deg

    def gains_over(self, other: MedianFit) -> tuple[float, float]:
        """How many times lower this fit's medians are than ``other``'s (> 1: this one fits better)."""
        g = [max(o, tiny) / max(v, tiny) for o, v, tiny in zip(other.medians, self.medians, _TINY, strict=True)]
        return g[0], g[1]

    def decisively_better_than(self, other: MedianFit) -> bool:
        """One median lower at least ``BETTER``-fold, neither higher by more than ``NOT_WORSE``: the rule by
        which one reading of a recording replaces another (here and in :mod:`.inversion`)."""
        gains = self.gains_over(other)
        return max(gains) >= BETTER and min(gains) >= 1 / NOT_WORSE


def median_fit(A: NDArray[np.float64], B: NDArray[np.float64], *, method: str = "dqopt",
               alpha: float = 1.0) -> MedianFit | None:
    """Solve the motions ``A_i X = X B_i`` (N, 4, 4) and summarise the residuals at X; None when they do not
    determine X. The yardstick two readings of one recording are compared by."""
    try:
        X = solve(A, B, method=method, alpha=alpha).matrix
    except HandEyeError:
        return None
    s = pair_residuals(A, B, X).summary()
    return MedianFit(X, s.rotation_median_deg, s.translation_median_m)


@dataclass(frozen=True)
class OrderChoice:
    """The quaternion order of each stream (``"xyzw"`` / ``"wxyz"`` as the file's columns were read, or None
    where it was not open: a log, the user's flag, a stream in memory), how it was chosen (``"format"`` or
    ``"fit"``), and the fits of the reading used and of the best other one (``given``/``runner_up``:
    median rotation [deg], translation [m])."""

    orders: tuple[str | None, str | None]
    chosen_by: str
    used: tuple[float, float]
    runner_up: tuple[float, float] | None
    runner_up_orders: tuple[str | None, str | None] | None

    def message(self, a: PoseStream, b: PoseStream) -> str:
        """The warning when the fit overturned the format's order: which file, the two fits, the flag."""
        changed = [(name, s, o) for name, s, o in zip("ab", (a, b), self.orders, strict=True)
                   if self.runner_up_orders and o != self.runner_up_orders["ab".index(name)]]
        files = ", ".join(f"stream {name} ({s.source}) as {o[0]}-{o[1]}-{o[2]}-{o[3]}" for name, s, o in changed
                          if o)
        keep = " ".join(_FLAGS[_other(o)].format(name) for name, _, o in changed if o)
        assert self.runner_up is not None
        return (f"the quaternions were read in the order that fits: {files} (median residuals "
                f"{self.used[0]:.3g}° / {self.used[1]:.3g} m, against {self.runner_up[0]:.3g}° / "
                f"{self.runner_up[1]:.3g} m in the format's order); to read them in the format's order pass {keep}")

    def as_dict(self) -> dict[str, Any]:
        """Plain dict for the result's ``interpretation``."""
        out: dict[str, Any] = {"quaternion_order": {"a": self.orders[0], "b": self.orders[1]},
                               "chosen_by": self.chosen_by,
                               "fit_median": {"rotation_deg": self.used[0], "translation_m": self.used[1]}}
        if self.runner_up is not None and self.runner_up_orders is not None:
            out["runner_up"] = {"quaternion_order": {"a": self.runner_up_orders[0], "b": self.runner_up_orders[1]},
                                "rotation_deg": self.runner_up[0], "translation_m": self.runner_up[1]}
        return out


def _other(order: str) -> str:
    return "wxyz" if order == "xyzw" else "xyzw"


def _reread(quat_xyzw: NDArray[np.float64], order: str) -> NDArray[np.float64]:
    """x-y-z-w quaternions of a file's columns that were read in ``order``, read in the other order."""
    return quat_xyzw[:, [1, 2, 3, 0] if order == "xyzw" else [3, 0, 1, 2]]


def reordered(stream: PoseStream) -> PoseStream:
    """The stream with its file's four quaternion columns read in the other order (``quaternion_order``
    must be set): columns read as x-y-z-w become w-x-y-z, and back."""
    assert stream.quaternion_order is not None
    return replace(stream, quat_xyzw=_reread(stream.quat_xyzw, stream.quaternion_order),
                   quaternion_order=_other(stream.quaternion_order))


def _best_over_inversions(T_a: NDArray[np.float64], T_b: NDArray[np.float64], i: NDArray[np.int64],
                          j: NDArray[np.int64]) -> MedianFit | None:
    """The best fit of the pairs (i, j) with the streams as they are, a inverted, or b inverted."""
    fits = [median_fit(se3.relative(Ta[i], Ta[j]), se3.relative(Tb[i], Tb[j]))
            for Ta, Tb in ((T_a, T_b), (se3.inverse(T_a), T_b), (T_a, se3.inverse(T_b)))]
    found = [f for f in fits if f is not None]
    return min(found, key=lambda f: f.rank) if found else None


def _refuse_degenerate(T_a: NDArray[np.float64], T_b: NDArray[np.float64], i: NDArray[np.int64],
                       j: NDArray[np.int64]) -> None:
    """Raise the motion's own refusal when it leaves a direction of the extrinsic open that no reduced solve
    takes (one rotation axis oblique to frame a, as :mod:`.subspace` refuses it; pure translation): two readings
    then fit alike because the motion cannot tell their extrinsics apart, and the quaternion order is not what
    the user must give (kinhec's motion-000004 was refused naming ``--wxyz-a``)."""
    from .observability import assess_observability
    from .subspace import AXIS_Z_TOLERANCE_DEG

    oblique = np.cos(np.deg2rad(AXIS_Z_TOLERANCE_DEG))      # a ground robot's z: the reduced solve's, not refused
    findings = [w for w in assess_observability(se3.relative(T_a[i], T_a[j]), se3.relative(T_b[i], T_b[j])).warnings
                if w.code in ("single_axis", "planar", "pure_translation")
                and (w.direction_a is None or abs(w.direction_a[2]) < oblique)]
    if findings:
        raise findings[0].refusal()


def choose_quaternion_order(a: PoseStream, b: PoseStream, *, time_offset_ns: int = 0, max_dt_ns: int | None = None,
                            seed: int = 0) -> tuple[PoseStream, PoseStream, OrderChoice | None]:
    """Streams a and b in the quaternion order that fits (see the module docstring), and the choice; the
    streams unchanged and None when neither order is open or the streams cannot be paired here (then the
    later checks judge the fit). Raises DataError when another reading fits alike with another extrinsic."""
    from ..stages.sync import associate

    open_ = (a.quaternion_order is not None, b.quaternion_order is not None)
    if not any(open_):
        return a, b, None
    try:
        synced, _ = associate(a, b, method="nearest", max_dt_ns=max_dt_ns, time_offset_ns=time_offset_ns)
    except HandEyeError:
        return a, b, None
    n = len(synced)
    if n < 4:
        return a, b, None
    rng = np.random.default_rng(seed)
    i, j = rng.integers(0, n, size=(2, min(MAX_PAIRS, n * (n - 1) // 2)))
    keep = i != j
    i, j = i[keep], j[keep]
    poses = {"a": (synced.xyz_a, synced.quat_a), "b": (synced.xyz_b, synced.quat_b)}
    streams = {"a": a, "b": b}

    def matrices(name: str, order: str | None) -> NDArray[np.float64]:
        xyz, quat = poses[name]
        given = streams[name].quaternion_order
        if order is not None and given is not None and order != given:
            quat = _reread(quat, given)
        return se3.from_xyz_quat(xyz, quat)

    given_orders = (a.quaternion_order, b.quaternion_order)
    options = [[o, _other(o)] if o is not None else [None] for o in given_orders]
    fits: dict[tuple[str | None, str | None], MedianFit | None] = {
        (oa, ob): _best_over_inversions(matrices("a", oa), matrices("b", ob), i, j) for oa, ob in product(*options)}
    base = fits.pop(given_orders)
    others = sorted(((f, o) for o, f in fits.items() if f is not None), key=lambda fo: fo[0].rank)
    if base is None or not others:
        return a, b, None
    best, best_orders = others[0]
    gains = best.gains_over(base)
    if best.decisively_better_than(base):
        chosen = [reordered(s) if o != s.quaternion_order else s
                  for s, o in zip((a, b), best_orders, strict=True)]
        return chosen[0], chosen[1], OrderChoice(best_orders, "fit", best.medians, base.medians, given_orders)
    if all(1 / NOT_WORSE <= g <= NOT_WORSE for g in gains):
        rot_deg, trans_m = extrinsic_error(best.matrix, base.matrix)
        worst = np.maximum(base.medians, best.medians)
        if rot_deg > max(ALIKE_DEG, worst[0]) or trans_m > max(ALIKE_M, worst[1]):
            _refuse_degenerate(matrices("a", given_orders[0]), matrices("b", given_orders[1]), i, j)
            flags = " and ".join(f"{_FLAGS[g].format(name)} or {_FLAGS[o].format(name)}" for name, o, g
                                 in zip("ab", best_orders, given_orders, strict=True) if o and g and o != g)
            raise DataError("the quaternion order of the text input cannot be told from the data: the other order "
                            f"fits as well ({best.rotation_deg:.3g}° / {best.translation_m:.3g} m against "
                            f"{base.rotation_deg:.3g}° / {base.translation_m:.3g} m) and gives an extrinsic "
                            f"{rot_deg:.2g}° / {trans_m:.2g} m away", f"{a.source}, {b.source}",
                            f"say which with {flags}")
    return a, b, OrderChoice(given_orders, "format", base.medians, best.medians, best_orders)


@dataclass(frozen=True)
class OrderContradiction:
    """A quaternion order that was not open to the fit (a log's named fields, the user's ``--wxyz-*`` /
    ``--no-wxyz-*``, a :class:`PoseStream` built in memory, whose ``quat_xyzw`` is x-y-z-w by its name) and that
    the data contradict: re-reading ``stream``'s four components in the other order fits decisively better
    (:meth:`MedianFit.decisively_better_than`, the rule by which the fit chooses a text file's order). ``given``,
    ``reread``: the median residuals (rotation [deg], translation [m]) as given and re-read; ``order``: the
    order the stream was given in (``"xyzw"`` / ``"wxyz"``)."""

    stream: str
    order: str
    given: tuple[float, float]
    reread: tuple[float, float]

    def _evidence(self) -> str:
        other = _other(self.order)
        return (f"stream {self.stream}'s quaternions fit a rigid rig far better read {other[0]}-{other[1]}-"
                f"{other[2]}-{other[3]}: median residuals {self.reread[0]:.3g}° / {self.reread[1]:.3g} m, against "
                f"{self.given[0]:.3g}° / {self.given[1]:.3g} m as given ({self.order[0]}-{self.order[1]}-"
                f"{self.order[2]}-{self.order[3]})")

    def _fix(self) -> str:
        flag = _FLAGS[_other(self.order)].format(self.stream)
        return (f"rerun with {flag} if its file stores them that way (a PoseStream built in memory takes x-y-z-w "
                "quaternions, quat_xyzw; a log's message whose fields were filled out of order must be "
                "re-recorded)")

    def refusal(self) -> DataError:
        """The error refusing the result: an extrinsic from misread quaternions is tens of degrees wrong, while
        their residuals, on drifting odometry, can stay within the fit test's allowance for drift."""
        return DataError("the quaternion order given contradicts the data; no result was written",
                         self._evidence(),
                         f"{self._fix()}; to keep the result anyway: ⟦accept_poor_fit=True⟧ (exit code 3)")

    def message(self) -> str:
        """The warning when the result is kept anyway (``--accept-poor-fit``)."""
        return f"{self._evidence()}; {self._fix()}"

    def as_dict(self) -> dict[str, Any]:
        """Plain dict for the result's ``interpretation``."""
        return {"contradicted_quaternion_order": {"stream": self.stream, "given": self.order},
                "fit_median": {"rotation_deg": self.given[0], "translation_m": self.given[1]},
                "reread": {"rotation_deg": self.reread[0], "translation_m": self.reread[1]}}


def spread_pairs(i: NDArray[np.int64], j: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """At most ``CHECKED_PAIRS`` of the sample pairs ``(i, j)``, evenly spread over the list: the medians of such
    a subset decide a reading as well as all pairs do, and the comparison's solves stay cheap."""
    if len(i) <= CHECKED_PAIRS:
        return i, j
    keep = np.linspace(0, len(i) - 1, CHECKED_PAIRS).astype(np.int64)
    return i[keep], j[keep]


def contradicted_order(T_a: NDArray[np.float64], T_b: NDArray[np.float64], i: NDArray[np.int64],
                       j: NDArray[np.int64], orders: tuple[str | None, str | None], *, alpha: float = 1.0,
                       inverted: tuple[bool, bool] = (False, False)) -> OrderContradiction | None:
    """The stream whose given quaternion order the solved pairs ``(i, j)`` of the synced absolute poses
    ``T_a``, ``T_b`` (N, 4, 4) contradict (see :class:`OrderContradiction`), or None. ``orders``: per stream the
    order its quaternions were given in where it was not open to the fit, None where the fit already chose it
    (:func:`choose_quaternion_order`); ``inverted``: per stream, whether its poses were inverted after reading
    (the components are re-read in the poses as given). Dqopt at ``alpha`` on at most ``CHECKED_PAIRS`` pairs
    spread over the list."""
    i, j = spread_pairs(i, j)
    motions = {"a": se3.relative(T_a[i], T_a[j]), "b": se3.relative(T_b[i], T_b[j])}
    base = median_fit(motions["a"], motions["b"], alpha=alpha)
    if base is None:
        return None
    for name, T, order, flip in (("a", T_a, orders[0], inverted[0]), ("b", T_b, orders[1], inverted[1])):
        if order is None:
            continue
        given = se3.inverse(T) if flip else T
        other = se3.from_xyz_quat(given[:, :3, 3], _reread(se3.to_xyz_quat(given)[1], order))
        other = se3.inverse(other) if flip else other
        alt = dict(motions, **{name: se3.relative(other[i], other[j])})
        fit = median_fit(alt["a"], alt["b"], alpha=alpha)
        if fit is not None and fit.decisively_better_than(base):
            return OrderContradiction(name, order, base.medians, fit.medians)
    return None


@dataclass(frozen=True)
class ScaleReading:
    """Whether b's translations fit a rigid rig better in other units: ``scale`` [m per unit of b], the
    linear estimate with the solution's rotation; ``gain``: how many times lower the median translation
    residual is with it; ``medians_m``: (as given, scaled) [m]."""

    scale: float
    gain: float
    medians_m: tuple[float, float]

    @property
    def decisive(self) -> bool:
        """Far better scaled (``BETTER``-fold, and off 1 by more than ``SCALE_FLOOR``): monocular units."""
        return self.gain >= BETTER and abs(self.scale - 1) > SCALE_FLOOR

    @property
    def noticeable(self) -> bool:
        """Better scaled, but not decisively (metric SLAM whose scale is off by percents): a warning."""
        return not self.decisive and self.gain >= SCALE_GAIN and abs(self.scale - 1) > SCALE_FLOOR

    def as_dict(self) -> dict[str, Any]:
        """Plain dict for the result's ``interpretation``."""
        return {"linear_scale": self.scale, "translation_median_m": {"as_given": self.medians_m[0],
                                                                      "scaled": self.medians_m[1]},
                "gain": self.gain}


def scale_reading(A: NDArray[np.float64], B: NDArray[np.float64], X: NDArray[np.float64]) -> ScaleReading | None:
    """The scale reading of b's translations at the solution ``X`` = ``T_a_b`` of the motions (N, 4, 4);
    None when the translations do not determine a positive scale."""
    from ..solvers.scale import linear_scale, scale_translations

    t_X, s = linear_scale(A, B, X[:3, :3])
    if not (np.isfinite(s) and s > 0 and np.isfinite(t_X).all()):
        return None
    Xs = X.copy()
    Xs[:3, 3] = t_X
    given = pair_residuals(A, B, X).summary().translation_median_m
    scaled = pair_residuals(A, scale_translations(B, s), Xs).summary().translation_median_m
    return ScaleReading(float(s), max(given, _TINY[1]) / max(scaled, _TINY[1]), (given, scaled))
