"""Is one stream inverted? The commonest set-up mistake, caught before anything else is reported.

A stream of ``T_sensor_world`` given as ``T_world_sensor`` (e.g. a camera's target detections
``T_camera_target`` without ``--invert-b``) still yields an extrinsic, but a wrong one whose
residuals are far larger than the noise. With exactly one stream inverted, the relation
``T_a X = Y T_b`` between the absolute poses cannot hold; inverting that stream restores it.
(Both streams inverted satisfy the same relation with X and Y swapped: no fit can tell.)

:func:`check_inversion` re-solves the same sample pairs ``(i, j)`` with each stream's poses
inverted (relative rotation angles do not change, so the same pairs stay valid) and compares the
median residuals (rotation [deg], translation [m]) with those of the streams as given (on at most
``CHECKED_PAIRS`` pairs spread over the list, :func:`.readings.spread_pairs`):

* **inverted**: inverting the stream lowers one median at least ``BETTER``-fold and raises
  neither by more than ``NOT_WORSE`` (:meth:`.readings.MedianFit.decisively_better_than`, the rule every
  reading chosen by the fit follows);
* **overwhelming**: lower at least ``_OVERWHELMING``-fold, and the given fit is implausible for a
  rigid rig (median above ``_PLAUSIBLE_DEG`` or ``_PLAUSIBLE_M``);
* **contradicted**: inverted, the given fit implausible, and the reading as given chosen by an explicit
  ``--invert-*`` / ``--no-invert-*``: a flag the data decisively contradict is refused, not warned about
  (the real arm of the development corpus read with ``--invert-a``: 6.2× better the other way, given
  fit 1.0° / 15 mm, result 0.6 m wrong).

Policy (used by the pipeline): an inverted verdict is the first warning, so ``--strict`` exits 3.
An overwhelming one refuses the result (:meth:`InversionVerdict.refusal`, exit 2), also when the
user set an ``--invert-*`` / ``--no-invert-*`` flag explicitly: the data then contradict the flag,
and the message says so. An extrinsic computed from an inverted stream is not slightly off but
meaningless, and results are consumed by machines that do not read warnings; a ≥ 10-fold better fit
of the inverted stream does not occur on correct data (it needs residuals far above the noise that
vanish under inversion), so refusing costs a correct capture nothing. Inverting silently was
rejected: it would hide a set-up error that also affects other tools the user runs.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import DataError
from ..geometry import se3
from .readings import BETTER, MedianFit, median_fit, spread_pairs

__all__ = ["Candidate", "InversionVerdict", "check_inversion"]

_OVERWHELMING = 10.0
_PLAUSIBLE_DEG = 0.5
_PLAUSIBLE_M = 0.02


@dataclass(frozen=True)
class Candidate:
    """One stream whose inversion fits far better: ``stream`` ("a" or "b"), the median residuals with
    it inverted (rotation [deg], translation [m]), the improvement ``ratio`` (the larger of the two
    medians' factors) and the CLI ``flag`` that inverts it."""

    stream: str
    inverted: tuple[float, float]
    ratio: float
    flag: str

    def as_dict(self) -> dict[str, Any]:
        """Plain dict for the result file."""
        return {"stream": self.stream, "rotation_median_deg": self.inverted[0],
                "translation_median_m": self.inverted[1], "ratio": self.ratio, "flag": self.flag}


@dataclass(frozen=True)
class InversionVerdict:
    """A stream looks inverted.

    given: median residuals as given (rotation [deg], translation [m]). candidates: the streams whose
    inversion fits far better, best first; two when the fit cannot tell which stream is inverted
    (inverting the other one also satisfies ``T_a X = Y T_b``, with X and Y swapped: the result would
    be the transform between the two world frames). overwhelming, implausible (the given fit): see the
    module docstring.
    """

    given: tuple[float, float]
    candidates: tuple[Candidate, ...]
    overwhelming: bool
    implausible: bool = False

    @property
    def streams(self) -> tuple[str, ...]:
        """The candidate streams, best first."""
        return tuple(c.stream for c in self.candidates)

    def _evidence(self) -> str:
        alts = ", ".join(f"{c.inverted[0]:.3g}° / {c.inverted[1]:.3g} m with {c.stream} inverted "
                         f"({c.ratio:.3g}× better)" for c in self.candidates)
        return f"the median residuals go from {self.given[0]:.3g}° / {self.given[1]:.3g} m to {alts}"

    @staticmethod
    def _fix(candidates: tuple[Candidate, ...]) -> str:
        if len(candidates) == 1:
            return f"rerun with {candidates[0].flag}"
        return ("the fit cannot tell which one; rerun with the flag of the stream that holds T_sensor_world "
                f"(a camera's target detections do): {' or '.join(c.flag for c in candidates)}")

    def message(self) -> str:
        """The one-line warning, with the numbers and the flags."""
        who = f"stream {self.streams[0]}" if len(self.candidates) == 1 else "stream a or b"
        return (f"{who} looks inverted (T_sensor_world instead of T_world_sensor): {self._evidence()}; "
                f"{self._fix(self.candidates)}")

    def refusal(self, explicit: bool) -> DataError | None:
        """The error refusing the result when the verdict is overwhelming, or when the user set an invert flag
        (``explicit``: any of --invert-a/--no-invert-a/--invert-b/--no-invert-b) that the data decisively
        contradict with an implausible given fit; else None. Either way an extrinsic the data refute is not
        written."""
        if not (self.overwhelming or (explicit and self.implausible)):
            return None
        if explicit:
            return DataError("the ⟦invert_*⟧/⟦invert_*=False⟧ flags given contradict the data: a stream fits far "
                             "better the other way; no result was written", self._evidence(),
                             f"{self._fix(self.candidates)} (or drop the flag you gave); to keep the result "
                             "anyway: ⟦accept_poor_fit=True⟧ (exit code 3)")
        return DataError("a stream is almost certainly inverted (T_sensor_world instead of T_world_sensor); "
                         "no result was written", self._evidence(), self._fix(self.candidates))

    def as_dict(self) -> dict[str, Any]:
        """Plain dict for the result file."""
        return {"given_median": {"rotation_deg": self.given[0], "translation_m": self.given[1]},
                "candidates": [c.as_dict() for c in self.candidates], "overwhelming": self.overwhelming}


def _fit(T_a: NDArray[np.float64], T_b: NDArray[np.float64], i: NDArray[np.int64], j: NDArray[np.int64],
         method: str, alpha: float) -> MedianFit | None:
    """The fit of the pairs (i, j) of the absolute poses; None when unsolvable."""
    return median_fit(se3.relative(T_a[i], T_a[j]), se3.relative(T_b[i], T_b[j]), method=method, alpha=alpha)


def check_inversion(T_a: NDArray[np.float64], T_b: NDArray[np.float64], i: NDArray[np.int64],
                    j: NDArray[np.int64], *, method: str = "dqopt", alpha: float = 1.0,
                    inverted_now: tuple[bool, bool] = (False, False),
                    frames: tuple[tuple[str, str] | None, tuple[str, str] | None] = (None, None)
                    ) -> InversionVerdict | None:
    """Whether stream a or b fits far better inverted (see the module docstring).

    Parameters
    ----------
    T_a, T_b: (N, 4, 4) synced absolute poses ``T_wa_a``, ``T_wb_b`` (samples or stations).
    i, j: int64 (M,) the sample pairs the calibration used (motions ``T(t_i)⁻¹ T(t_j)``).
    method, alpha: the solver used for the comparison fits.
    inverted_now: whether streams a and b were already inverted by the user (to name the right flag).
    frames: the (parent, child) TF frame pair each stream was read as, if any: inverting such a stream is
        naming its frames the other way round, and that is the flag named (``--stream-a tf:CHILD,PARENT``).

    Returns the verdict (both streams as candidates when their inversions fit alike), or None.
    """
    i, j = spread_pairs(i, j)
    base = _fit(T_a, T_b, i, j, method, alpha)
    if base is None:
        return None
    found = []
    for name, Ta, Tb, now, pair in (("a", se3.inverse(T_a), T_b, inverted_now[0], frames[0]),
                                    ("b", T_a, se3.inverse(T_b), inverted_now[1], frames[1])):
        alt = _fit(Ta, Tb, i, j, method, alpha)
        if alt is None:
            continue
        if alt.decisively_better_than(base):
            flag = (f"⟦stream_{name}='tf:{pair[1]},{pair[0]}'⟧ (tf:PARENT,CHILD, the parent first)" if pair and
                    not now else f"⟦invert_{name}=False⟧" if now else f"⟦invert_{name}=True⟧")
            found.append(Candidate(name, alt.medians, float(max(alt.gains_over(base))), flag))
    if not found:
        return None
    found.sort(key=lambda c: -c.ratio)
    found = [c for c in found if c.ratio >= found[0].ratio / BETTER]       # alike fits: the data cannot tell
    implausible = base.rotation_deg > _PLAUSIBLE_DEG or base.translation_m > _PLAUSIBLE_M
    return InversionVerdict(base.medians, tuple(found), bool(found[0].ratio >= _OVERWHELMING and implausible),
                            bool(implausible))
