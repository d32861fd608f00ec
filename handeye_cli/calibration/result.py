"""The typed results of one calibration: :class:`Calibration` with its frozen :class:`Diagnostics`, the
:class:`Uncertainty` of ``T_a_b``, the :class:`Checks` a run makes after the solve, and the frames' names.

``T_a_b`` is the pose of sensor b's frame in sensor a's frame (maps points from b to a); quaternions are
x-y-z-w; translations in metres. The result document is built from these at the output edge
(:func:`handeye_cli.output.document.calibration_document`).
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np

from ..analysis import BootstrapResult, Residuals, RobustResult
from ..analysis.alpha import AlphaChoice
from ..analysis.covariance import DriftCheck
from ..analysis.fit_test import FitTest
from ..analysis.inversion import InversionVerdict
from ..analysis.observability import Observability
from ..analysis.readings import OffsetReading, OrderChoice, OrderContradiction, ScaleReading
from ..analysis.residuals import ResidualSummary
from ..analysis.selection import Selection
from ..analysis.subspace import ESTIMATED, Subspace
from ..analysis.verdict import Judged
from ..errors import as_keywords
from ..geometry import se3
from ..options import Options
from ..solvers import Solution
from ..solvers.scale import ScaleSolution
from ..stages.counts import SampleCounts
from ..stages.pairs import Pairs
from ..stages.stations import Stations
from ..stages.sync import Synced
from ..streams import PoseStream
from .inputs import Inputs

if TYPE_CHECKING:
    from ..analysis.refinement import Refinement

__all__ = ["Calibration", "Checks", "Diagnostics", "Uncertainty", "frame_names"]


@dataclass(frozen=True)
class Checks:
    """Which of :func:`~.run.calibrate_read`'s checks after the solve run (every one by default, as ``calibrate`` runs
    them). A rig skips those its own analysis replaces (:mod:`handeye_cli.rig.pairwise`).

    inversion: the inversion check (a stream recorded as ``T_sensor_world``).
    uncertainty: the uncertainty check (σ from blocks of time beside σ from independent samples: drift).
    """

    inversion: bool = True
    uncertainty: bool = True


@dataclass(frozen=True, eq=False)
class Uncertainty:
    """The 1σ spread of an extrinsic ``T_a_b``: ``rotation_std_deg`` (3,) [deg] about the axes of frame a,
    ``translation_std_m`` (3,) [m] along them; ``method``: ``"bootstrap"`` or ``"covariance"``."""

    rotation_std_deg: np.ndarray
    translation_std_m: np.ndarray
    method: str


@dataclass(frozen=True, eq=False)
class Diagnostics(Mapping[str, Any]):
    """What the reading and the analyses of one calibration found, as the typed results they returned, frozen
    when it ends.

    The reading: ``time_offset`` (b's clock offset as decided), ``order`` (the quaternion order's choice; None when
    nothing was open), ``contradiction`` (a given quaternion order the data contradict, kept by
    ``accept_poor_fit``), ``sampling`` (the reading's station capture, or its sync); ``scale``: b's scale estimated
    with ``T_a_b``, in b's units as given (``--scale auto``, or found by the fit: ``scale_found``, the fit's finding
    that b's translations fit better in other units, decisive or noticeable; else None). The weighted solve:
    ``robust`` (``--robust``'s RANSAC) with ``pair_stamps_ns`` (the solved pairs' ``(t_i, t_j)`` [ns], where its
    rejected pairs lie), ``selection`` (the ``auto`` pairs' noise model; None for another strategy),
    ``alpha_auto`` (α auto's source: the noise model's :class:`~handeye_cli.analysis.alpha.AlphaChoice`, or the
    selection whose α it is; None for a given α). ``inversion``: the inversion check's verdict (a stream fits better
    inverted); ``prior_unused``: the prior was not used, the motion determining every degree of freedom. The
    analyses: ``observability`` (degenerate motion, the predicted covariance), ``subspace`` (each degree of freedom:
    estimated, from the prior or unobservable), ``uncertainty_check`` (σ from blocks of time beside σ from
    independent samples), ``residuals`` (the summary of the pairs solved, robust's outliers left out), ``fit``
    (the fit test), ``mount_moved`` (a station capture's mount that moved, kept by ``accept_poor_fit``: the fit test
    failed), ``bootstrap``. ``poor_fit_accepted``: a refusal — the fit test's (the residuals, or a mount that moved
    between stations), the inversion check's or a given quaternion order's contradiction — that
    ``accept_poor_fit`` overrode, keeping the result (``handeye calibrate`` exits 3).

    As a read-only mapping it is the result document's diagnostic sections in order (``time_offset``,
    ``interpretation``, ``noise_model``, ``observability``, ``degrees_of_freedom``, ``residuals``, ``fit_test`` …:
    JSON-ready values, the keys of docs/reference/result-schema.md), built once, on first reading, from these typed
    results (:attr:`sections`), so ``calibration.diagnostics["fit_test"]`` reads as the file does."""

    time_offset: OffsetReading | None = None
    order: OrderChoice | None = None
    contradiction: OrderContradiction | None = None
    sampling: Stations | Synced | None = None
    scale: ScaleSolution | None = None
    scale_found: ScaleReading | None = None
    robust: RobustResult | None = None
    pair_stamps_ns: tuple[np.ndarray, np.ndarray] | None = None
    selection: Selection | None = None
    alpha_auto: AlphaChoice | Selection | None = None
    inversion: InversionVerdict | None = None
    prior_unused: bool = False
    observability: Observability | None = None
    subspace: Subspace | None = None
    uncertainty_check: DriftCheck | None = None
    residuals: ResidualSummary | None = None
    fit: FitTest | None = None
    mount_moved: str | None = None
    bootstrap: BootstrapResult | None = None
    poor_fit_accepted: bool = False

    @cached_property
    def sections(self) -> Mapping[str, Any]:
        """The result document's diagnostic sections, in the order a run found them (:func:`_sections`)."""
        return MappingProxyType(_sections(self))

    def __getitem__(self, key: str) -> Any:
        return self.sections[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.sections)

    def __len__(self) -> int:
        return len(self.sections)


_PRIOR_UNUSED = "not used: the motion determines every degree of freedom"


def _sections(d: Diagnostics) -> dict[str, Any]:
    """``d``'s sections in document order: the reading's (``time_offset``, ``interpretation`` when the quaternion
    order was chosen, ``stations`` or ``sync``), [``scale`` of ``--scale auto``], the weighted solve's
    (``robust``, ``noise_model``, ``alpha_auto``), the checks of the reading (``interpretation`` when only they
    found one, ``inversion``, [``scale`` found by the fit]), ``prior``, then the analyses (``observability``,
    ``degrees_of_freedom``, ``uncertainty_check``, ``residuals``, ``fit_test``, ``uncertainty``). Absent: left out."""
    interpretation = {**({} if d.order is None else d.order.as_dict()),
                      **({} if d.contradiction is None else d.contradiction.as_dict()),
                      **({} if d.scale_found is None else
                         {"scale": {**d.scale_found.as_dict(), "applied": d.scale_found.decisive}})} or None
    by_fit = d.scale_found is not None and d.scale_found.decisive
    scale = None if d.scale is None else d.scale.as_dict()
    stations = d.sampling if isinstance(d.sampling, Stations) else None
    fit = None if d.fit is None else {**d.fit.as_dict(), **({} if d.mount_moved is None else
                                                           {"passed": False, "extrinsic_changed": d.mount_moved})}
    sections = [
        ("time_offset", None if d.time_offset is None else d.time_offset.as_dict()),
        ("interpretation", interpretation if d.order is not None else None),
        ("stations", None if stations is None else stations.as_dict()),
        ("sync", d.sampling.describe() if isinstance(d.sampling, Synced) else None),
        ("scale", None if by_fit else scale),
        ("robust", _robust_section(d.robust, d.pair_stamps_ns)),
        ("noise_model", None if d.selection is None else d.selection.as_dict()),
        ("alpha_auto", d.alpha_auto.as_dict() if isinstance(d.alpha_auto, AlphaChoice) else
         None if d.alpha_auto is None else {"alpha": d.alpha_auto.alpha, "method": "noise-model"}),
        ("interpretation", interpretation if d.order is None else None),
        ("inversion", None if d.inversion is None else d.inversion.as_dict()),
        ("scale", scale if by_fit else None),
        ("prior", _PRIOR_UNUSED if d.prior_unused else None),
        ("observability", None if d.observability is None else d.observability.as_dict()),
        ("degrees_of_freedom", None if d.subspace is None else d.subspace.as_dict()),
        ("uncertainty_check", None if d.uncertainty_check is None else d.uncertainty_check.as_dict()),
        ("residuals", None if d.residuals is None else d.residuals.as_dict()),
        ("fit_test", fit),
        ("uncertainty", None if d.bootstrap is None else
         {"method": "bootstrap over pose samples", **d.bootstrap.as_dict()})]
    return {key: value for key, value in sections if value is not None}


def _robust_section(robust: RobustResult | None, stamps_ns: tuple[np.ndarray, np.ndarray] | None
                    ) -> dict[str, Any] | None:
    """``--robust``'s section: its summary, and each rejected pair's span in seconds since the first paired sample
    (readable beside a plot of the streams)."""
    if robust is None or stamps_ns is None:
        return None
    t_i, t_j = stamps_ns
    t0 = min(t_i.min(), t_j.min())
    return {**robust.as_dict(), "rejected_spans_since_start_s": [
        [round((t_i[k] - t0) / 1e9, 6), round((t_j[k] - t0) / 1e9, 6)] for k in robust.rejected]}


@dataclass(frozen=True, eq=False)
class Calibration:
    """Everything a calibration produced.

    solution: the solver's result (``solution.matrix`` is ``T_a_b``).
    stream_a, stream_b: the streams as used (after inversion, before the time offset).
    synced: the samples that passed sync and gates; pairs: the motions solved.
    samples: what each stage read, kept and dropped; options: the options used.
    warnings: human-readable warnings, each option they name marked as its keyword argument (``⟦max_dt⟧``,
    ``⟦gate='off'⟧``: :func:`~handeye_cli.errors.option`; :func:`handeye_cli.document` drops the marks, the CLI
    writes flags); diagnostics: what the analyses found (:class:`Diagnostics`: typed,
    and the result's diagnostic keys: time offset, residuals…);
    inputs: what was read (:class:`~.inputs.Inputs`); residuals: per-pair residuals at the solution; weights: per-pair
    weights used (inlier mask with ``robust``, else None); robust, bootstrap: those analyses (the diagnostics'
    own); refinement: the maximum-likelihood refinement whose matrix ``solution`` holds (``solution.optimum``: the
    optimum it started from), or None.
    """

    solution: Solution
    stream_a: PoseStream
    stream_b: PoseStream
    synced: Synced
    pairs: Pairs
    samples: SampleCounts
    options: Options
    residuals: Residuals
    warnings: list[str] = field(default_factory=list)
    diagnostics: Diagnostics = field(default_factory=Diagnostics)
    inputs: Inputs = field(default_factory=Inputs)
    weights: np.ndarray | None = None
    refinement: Refinement | None = None
    config_file: str | None = None
    preset: str | None = None

    @property
    def robust(self) -> RobustResult | None:
        """``--robust``'s RANSAC (the weighted solve's, as the document's ``robust`` describes it), or None."""
        return self.diagnostics.robust

    @property
    def bootstrap(self) -> BootstrapResult | None:
        """``--bootstrap N``'s replicates (the document's ``uncertainty``), or None."""
        return self.diagnostics.bootstrap

    @property
    def matrix(self) -> np.ndarray:
        """``T_a_b`` (4x4)."""
        return self.solution.matrix

    @property
    def translation(self) -> np.ndarray:
        """Translation of ``T_a_b`` [m]: b's origin in frame a."""
        return self.solution.translation

    @property
    def quaternion_xyzw(self) -> np.ndarray:
        """Rotation of ``T_a_b`` as a unit quaternion x, y, z, w (w ≥ 0)."""
        return self.solution.quaternion_xyzw

    @property
    def uncertainty(self) -> Uncertainty | None:
        """The 1σ spread of ``T_a_b`` per axis of frame a: the bootstrap's where it ran (``bootstrap=N``), else
        the noise model's predicted (sandwich) covariance; None where neither could be formed."""
        if self.bootstrap is not None:
            return Uncertainty(self.bootstrap.rotation_std_deg, self.bootstrap.translation_std_m, "bootstrap")
        obs = self.diagnostics.observability
        if obs is None or obs.covariance is None:
            return None
        return Uncertainty(np.asarray(obs.covariance.rotation_std_deg, dtype=float),
                           np.asarray(obs.covariance.translation_std_m, dtype=float), "covariance")

    def __repr__(self) -> str:
        """One line: frames, translation, rotation angle, method, pairs, fit test and certificate."""
        return f"Calibration({self._line()})"

    def _line(self) -> str:
        f, t = self.frames, self.translation
        fit = self.diagnostics.fit
        cert = (self.solution.optimum or self.solution).certificate     # a refined or reduced estimate: its optimum's
        return (f"T_{f['a']}_{f['b']}: t=[{t[0]:.4f}, {t[1]:.4f}, {t[2]:.4f}] m, "
                f"rotation {np.rad2deg(float(se3.rotation_angle(self.matrix))):.3f}°, {self.solution.method} on "
                f"{self.solution.pairs} pairs, fit ratio {float('nan') if fit is None else fit.ratio:.3g}"
                f"{'' if cert is None else ', certified' if cert.certified else ', NOT certified'}, "
                f"{len(self.warnings)} warning(s)")

    def _repr_html_(self) -> str:
        """A small table for notebooks: the extrinsic, its spread and the checks."""
        import html

        rows = [("T_a_b", html.escape(self._line()))]
        unc = self.uncertainty
        if unc is not None:
            rows.append((f"σ ({unc.method})", f"rotation {np.array2string(unc.rotation_std_deg, precision=3)} °, "
                                              f"translation {np.array2string(unc.translation_std_m, precision=4)} m"))
        rows += [("warning", html.escape(as_keywords(w))) for w in self.warnings]
        body = "".join(f"<tr><th style='text-align:left'>{k}</th><td>{v}</td></tr>" for k, v in rows)
        return f"<table>{body}</table>"

    @property
    def frames(self) -> dict[str, str]:
        """Names of frames a and b: ``name_a``/``name_b`` if given, else the streams' child frames
        (as valid tf2 frame ids: no leading '/')."""
        a, b = frame_names(self.options, self.stream_a, self.stream_b)
        return {"a": a, "b": b}

    def judged(self) -> Judged:
        """What a drift verdict reads of this calibration (``--against``), from its typed parts: ``T_a_b``, the
        frames' names and the streams' topics, the degrees of freedom not estimated and the bootstrap's
        intervals."""
        topics = self.inputs.topics()
        sub = self.diagnostics.subspace
        open_dofs = {} if sub is None else {d.name: (d.status, d.reason) for d in sub.dofs if d.status != ESTIMATED}
        boot = self.bootstrap
        return Judged(np.asarray(self.matrix, dtype=float), (self.frames["a"], self.frames["b"]),
                      (topics[0], topics[1]), open_dofs,
                      None if boot is None else (boot.rotation_interval_deg, boot.translation_interval_m))

    def bootstrap_deviations(self) -> np.ndarray | None:
        """(K, 6) bootstrap deviations of X: rotation vector [deg] (3), translation [m] (3)."""
        if self.bootstrap is None:
            return None
        deviations: np.ndarray = np.c_[self.bootstrap.rotation_deltas_deg,
                                       self.bootstrap.translations_m - self.matrix[:3, 3]]
        return deviations

    def with_origin(self, config_file: str | Path | None, preset: str | None) -> Calibration:
        """The same calibration, recording the config file and preset its options came from."""
        return replace(self, config_file=None if config_file is None else str(config_file), preset=preset)

    def settings(self) -> dict[str, Any]:
        """The settings that produced this result: every option after preset, file and flag
        merging, and where the non-default ones came from."""
        return {"config_file": self.config_file, "preset": self.preset, "options": self.options.flat()}



def frame_names(options: Options, stream_a: PoseStream, stream_b: PoseStream) -> tuple[str, str]:
    """Names of frames a and b: ``name_a``/``name_b`` if given, else the streams' child frames
    (as valid tf2 frame ids: no leading '/')."""
    out = options.output
    return (out.name_a or stream_a.child_frame_id.lstrip("/") or "a",
            out.name_b or stream_b.child_frame_id.lstrip("/") or "b")

