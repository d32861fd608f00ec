"""Drift verdicts: how far a calibrated extrinsic is from the nominal one, and whether that matters.

The result ``X = T_a_b`` and the nominal ``N = T_a_b`` (pose of frame b in frame a, maps points
from b to a) differ by the rotation angle of ``R_Nᵀ R_X`` [deg] and the translation distance
``|t_X − t_N|`` [m]. Each is *out of tolerance* above its limit. When the result carries a
bootstrap interval (``uncertainty.rotation_interval_deg`` of ``δθ = Log(R* R̂ᵀ)`` and
``uncertainty.translation_interval_m``, both (2, 3)), the difference is *significant* when the
nominal lies outside the interval on some axis. A sensor has **drifted** when its rotation or its
translation is out of tolerance and — where significance is known — significant.

Only the degrees of freedom the data determined are judged: when the result's
``degrees_of_freedom`` marks some ``from_prior`` or ``unobservable`` (planar motion, see
:mod:`.subspace`), the nominal takes the result's value in those (URDF x, y, z, roll, pitch, yaw)
before the comparison, and the verdict lists them as ``skipped`` with the reason.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import DataError
from ..geometry import dualquat as dq
from ..geometry import se3
from ..io.nominal import Nominal
from .subspace import ESTIMATED, with_values_of

__all__ = ["DEFAULT_MAX_ROTATION_DEG", "DEFAULT_MAX_TRANSLATION_M", "Intervals", "Judged", "Verdict", "compare",
           "intervals_of", "verdict_for"]

DEFAULT_MAX_ROTATION_DEG = 0.5
DEFAULT_MAX_TRANSLATION_M = 0.005


@dataclass(frozen=True)
class Verdict:
    """The comparison of a result with its nominal.

    rotation_deg, translation_m: angle of ``R_Nᵀ R_X`` [deg] and ``|t_X − t_N|`` [m].
    max_rotation_deg, max_translation_m: the tolerances.
    rotation_significant, translation_significant: whether the nominal lies outside the result's
    bootstrap interval (None without an interval); ``as_dict`` adds ``significant``, either of them.
    nominal: where the nominal came from (``source``, ``kind``) and its ``translation`` [m] and
    ``quaternion_xyzw``.
    skipped: the degrees of freedom not judged (not estimated from the data), with the reason.
    """

    rotation_deg: float
    translation_m: float
    max_rotation_deg: float
    max_translation_m: float
    rotation_significant: bool | None
    translation_significant: bool | None
    nominal: dict[str, Any]
    skipped: dict[str, str] = field(default_factory=dict)

    @property
    def rotation_out(self) -> bool:
        return self.rotation_deg > self.max_rotation_deg

    @property
    def translation_out(self) -> bool:
        return self.translation_m > self.max_translation_m

    @property
    def drift(self) -> bool:
        """Out of tolerance, and significant where significance is known (per component)."""
        return ((self.rotation_out and self.rotation_significant is not False)
                or (self.translation_out and self.translation_significant is not False))

    def as_dict(self) -> dict[str, Any]:
        """Plain values for the result document and batch records."""
        out: dict[str, Any] = {
            "drift": self.drift, "rotation_deg": self.rotation_deg, "translation_m": self.translation_m,
            "max_rotation_deg": self.max_rotation_deg, "max_translation_m": self.max_translation_m,
            "rotation_out_of_tolerance": self.rotation_out, "translation_out_of_tolerance": self.translation_out}
        if self.rotation_significant is not None:
            out["significant"] = bool(self.rotation_significant or self.translation_significant)
            out["rotation_significant"] = self.rotation_significant
            out["translation_significant"] = self.translation_significant
        if self.skipped:
            out["skipped"] = dict(self.skipped)
        return {**out, "nominal": self.nominal}

    def summary(self) -> str:
        """One human-readable line."""
        word = "DRIFT" if self.drift else "within tolerance" if not (self.rotation_out or self.translation_out) \
            else "out of tolerance but not significant"
        return (f"{word}: rotation {self.rotation_deg:.3f}° (max {self.max_rotation_deg:g}°), translation "
                f"{self.translation_m * 1000:.2f} mm (max {self.max_translation_m * 1000:g} mm) from the nominal "
                f"{self.nominal.get('source', '')}".rstrip()
                + (f"; not judged (not estimated from the data): {', '.join(self.skipped)}" if self.skipped else ""))


#: a bootstrap's 95 % intervals of one extrinsic: rotation (2, 3) [deg] of ``δθ = Log(R* R̂ᵀ)`` (lower, upper per
#: axis of frame a) and translation (2, 3) [m]
Intervals = tuple[NDArray[np.float64], NDArray[np.float64]]


def intervals_of(uncertainty: Any) -> Intervals | None:
    """The intervals of a result document's ``uncertainty`` block (a calibrate result's, or a rig sensor's), or
    None when it holds none: the one reading of them from a document, at the edge where it is read."""
    if not isinstance(uncertainty, Mapping):
        return None
    try:
        return (np.array(uncertainty["rotation_interval_deg"], dtype=np.float64).reshape(2, 3),
                np.array(uncertainty["translation_interval_m"], dtype=np.float64).reshape(2, 3))
    except (KeyError, TypeError, ValueError):
        return None


def _significance(X: NDArray[np.float64], N: NDArray[np.float64], intervals: Intervals | None) -> tuple[
        bool | None, bool | None]:
    """Whether N lies outside X's bootstrap intervals (rotation, translation), or (None, None)."""
    if intervals is None:
        return None, None
    (r_lo, r_hi), (t_lo, t_hi) = intervals
    d = np.rad2deg(dq.to_rotvec(dq.from_matrix(N[:3, :3] @ X[:3, :3].T)))
    t = N[:3, 3]
    return bool(((d < r_lo) | (d > r_hi)).any()), bool(((t < t_lo) | (t > t_hi)).any())


def compare(X: NDArray[np.float64], N: NDArray[np.float64], max_rotation_deg: float, max_translation_m: float, *,
            intervals: Intervals | None = None, nominal: dict[str, Any] | None = None) -> Verdict:
    """The verdict on the result ``X`` against the nominal ``N`` (both 4x4 ``T_a_b``); ``intervals``: X's
    bootstrap intervals, for the significance (None: not known)."""
    if max_rotation_deg < 0 or max_translation_m < 0:
        raise DataError("negative tolerance", "max_rotation_deg/max_translation_m", "give limits ≥ 0")
    X, N = np.asarray(X, dtype=float), np.asarray(N, dtype=float)
    t, q = se3.to_xyz_quat(N)
    rot_sig, trans_sig = _significance(X, N, intervals)
    return Verdict(rotation_deg=float(np.rad2deg(se3.rotation_angle(N[:3, :3].T @ X[:3, :3]))),
                   translation_m=float(np.linalg.norm(X[:3, 3] - N[:3, 3])),
                   max_rotation_deg=float(max_rotation_deg), max_translation_m=float(max_translation_m),
                   rotation_significant=rot_sig, translation_significant=trans_sig,
                   nominal={**(nominal or {}), "translation": t.tolist(), "quaternion_xyzw": q.tolist()})


@dataclass(frozen=True, eq=False)
class Judged:
    """What a drift verdict reads of one result ``T_a_b``, typed: built from a calibration of this process
    (:meth:`handeye_cli.calibration.Calibration.judged`), or parsed once from a result document read back
    (:meth:`from_document`: ``handeye check``'s file, a batch record from a worker, a result file or the records
    file of an earlier run).

    matrix: (4, 4) ``T_a_b`` as the result states it (pose of frame b in frame a; metres).
    frames: the names of frames a and b; topics: the topic each stream was read from (None: a TF chain, a file).
    open_dofs: the degrees of freedom not estimated from the data (URDF x, y, z, roll, pitch, yaw), each with its
        status and reason (None: none given): the verdict does not judge them (:attr:`skipped`).
    intervals: the bootstrap's 95 % intervals (:data:`Intervals`), None without a bootstrap.
    """

    matrix: NDArray[np.float64]
    frames: tuple[str | None, str | None]
    topics: tuple[str | None, str | None] = (None, None)
    open_dofs: Mapping[str, tuple[str, str | None]] = field(default_factory=dict)
    intervals: Intervals | None = None

    @property
    def skipped(self) -> dict[str, str]:
        """Each degree of freedom not judged, with why: ``status: reason``."""
        return {name: f"{status}: {'' if reason is None else reason}".rstrip(": ")
                for name, (status, reason) in self.open_dofs.items()}

    @classmethod
    def from_document(cls, doc: Mapping[str, Any]) -> Judged:
        """The verdict's reading of a result document (``matrix``, ``frames``, ``inputs``, ``degrees_of_freedom``,
        ``uncertainty``), made once where the document enters. A missing ``matrix`` is a KeyError, as it was."""
        frames = doc.get("frames") or {}
        inputs = doc.get("inputs") or {}
        topics = tuple((inputs.get(k) or {}).get("topic") if isinstance(inputs.get(k), dict) else None
                       for k in "ab")
        dofs = doc.get("degrees_of_freedom") or {}
        open_dofs = {name: (str(d.get("status")), d.get("reason")) for name, d in dofs.items()
                     if isinstance(d, dict) and d.get("status") != ESTIMATED}
        return cls(np.asarray(doc["matrix"], dtype=float), (frames.get("a"), frames.get("b")),
                   (topics[0], topics[1]), open_dofs, intervals_of(doc.get("uncertainty")))


def verdict_for(result: Judged, nominal: Nominal, max_rotation_deg: float = DEFAULT_MAX_ROTATION_DEG,
                max_translation_m: float = DEFAULT_MAX_TRANSLATION_M) -> Verdict:
    """The verdict on a result (its ``T_a_b``, frames and intervals) against the nominal's transform between the
    result's frames a and b — or, for a frame the nominal does not name, the frame its stream's topic names
    (:meth:`~handeye_cli.io.nominal.Nominal.frames_for`; the verdict's ``nominal.frames`` says which were
    compared). The degrees of freedom ``result.skipped`` are not judged."""
    a, b = nominal.frames_for(result.frames[0], result.frames[1], result.topics)
    N = nominal.transform(a, b)
    X = result.matrix
    skipped = result.skipped
    v = compare(X, with_values_of(N, X, skipped), max_rotation_deg, max_translation_m,
                intervals=result.intervals, nominal={"source": nominal.source, "kind": nominal.kind,
                                                     **({"frames": [a, b]} if a and b else {})})
    return replace(v, skipped=skipped)
