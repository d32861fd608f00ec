"""The rig result and its document (YAML/JSON).

Every transform is listed as ``{parent, child, translation, quaternion_xyzw}``: the pose of the
child sensor's frame in the parent's (maps points from child to parent), translation [m],
Hamilton quaternion x-y-z-w with w ≥ 0. ``transforms`` holds every ``T_ref_k`` (the writers of
URDF / TF-static launch files take this list); ``pairwise`` every ``T_j_k`` (j < k) of the joint
result beside the pair's own (pairwise-only) result, with both residual summaries.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..analysis import extrinsic_error, pair_residuals
from ..geometry import se3
from ..output.document import plain
from ..output.formats import Frame
from ..streams import PoseStream
from ..version import __version__
from .graph import Closure
from .joint import CONSISTENCY_P_VALUE, Consistency, JointProblem, RigUncertainty
from .noise import Correction, StreamNoise
from .pairwise import ClockOffset, Edge

__all__ = ["RigResult", "transform_entry"]

Array = NDArray[np.float64]


def transform_entry(parent: str, child: str, T: Array) -> dict[str, Any]:
    """``{parent, child, translation, quaternion_xyzw}`` of ``T_parent_child`` (4x4)."""
    t, q = se3.to_xyz_quat(T)
    return {"parent": parent, "child": child, "translation": t.tolist(), "quaternion_xyzw": q.tolist()}


def _closure(c: Closure, names: list[str]) -> dict[str, Any]:
    return {"streams": [names[i] for i in c.nodes], "rotation_deg": c.rotation_deg, "translation_m": c.translation_m}


@dataclass(frozen=True, eq=False)
class RigResult:
    """Everything a rig calibration produced.

    names, reference: the sensors and the reference's index; streams: as used (after inversion);
    inverted: per stream; offsets: each clock's offset to the reference's; edges: the calibrated
    pairs (pairwise-only results); corrections: per pair, the test of its streams' relative drift
    and the bias removed; problem: the joint cost; synchronised: ``T_ref_k`` (n, 4, 4)
    of the graph synchronisation; matrices: the joint ``T_ref_k`` (n, 4, 4); closures: the
    pairwise-only loop closures; joint_closures: those of the joint result; consistency: the χ²
    test of the pairwise estimates and the bad stream it names; noise: every stream's estimated
    pose noise; covariances: (n, 6, 6) the noise model's covariance of each joint ``T_ref_k``
    (rotation [rad], translation [m]);
    uncertainty: bootstrap spread (or None); warnings, inputs, settings.
    """

    names: list[str]
    reference: int
    streams: list[PoseStream]
    inverted: list[bool]
    offsets: list[ClockOffset]
    edges: list[Edge]
    corrections: list[Correction]
    problem: JointProblem
    synchronised: Array
    matrices: Array
    closures: list[Closure]
    joint_closures: list[Closure]
    consistency: Consistency
    noise: StreamNoise
    covariances: Array
    uncertainty: RigUncertainty | None = None
    warnings: list[str] = field(default_factory=list)
    inputs: dict[str, Any] = field(default_factory=dict)
    settings: dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        """One line: the sensors (the reference first), the consistency test and the warnings."""
        return (f"RigResult({len(self.names)} sensors, reference {self.names[self.reference]}: "
                f"{', '.join(self._sensor_lines())}; {len(self.warnings)} warning(s))")

    def _sensor_lines(self) -> list[str]:
        ref = self.names[self.reference]
        return [f"T_{ref}_{name} t=[{', '.join(f'{v:.4f}' for v in T[:3, 3])}] m "
                f"{np.rad2deg(float(se3.rotation_angle(T))):.3f}°"
                for name, T in zip(self.names, self.matrices, strict=True) if name != ref]

    def _repr_html_(self) -> str:
        """A table for notebooks: each sensor's ``T_ref_k`` and the warnings."""
        import html

        rows = [("sensor", html.escape(line)) for line in self._sensor_lines()]
        rows += [("warning", html.escape(w)) for w in self.warnings]
        body = "".join(f"<tr><th style='text-align:left'>{k}</th><td>{v}</td></tr>" for k, v in rows)
        return f"<table>{body}</table>"

    def stated(self) -> list[Frame]:
        """Every joint ``T_ref_k`` (4x4, metres) as the document states it — its translation and x-y-z-w quaternion
        (:func:`transform_entry`), what a user reads — the reference's first: what the verdicts and the report
        judge."""
        ref = self.names[self.reference]
        entries = [transform_entry(ref, name, T) for name, T in zip(self.names, self.matrices, strict=True)
                   if name != ref]
        return [Frame(e["parent"], e["child"], se3.from_xyz_quat(np.asarray(e["translation"], dtype=float),
                                                                 np.asarray(e["quaternion_xyzw"], dtype=float)))
                for e in entries]

    def T(self, parent: str, child: str) -> Array:
        """``T_parent_child`` (4x4) of the joint result."""
        i, j = self.names.index(parent), self.names.index(child)
        return np.asarray(se3.inverse(self.matrices[i]) @ self.matrices[j], dtype=np.float64)

    def _pair(self, edge: Edge, correction: Correction, std: Array) -> dict[str, Any]:
        names, A, B = self.names, edge.calibration.pairs.A, edge.calibration.pairs.B
        joint = self.T(names[edge.j], names[edge.k])
        mask = None if edge.calibration.weights is None else edge.calibration.weights > 0
        rot, trans = extrinsic_error(joint, edge.matrix)
        return {**transform_entry(names[edge.j], names[edge.k], joint),
                "pairwise_only": transform_entry(names[edge.j], names[edge.k], edge.matrix),
                "difference": {"rotation_deg": rot, "translation_m": trans},
                "pairs_used": len(A), "alpha": edge.calibration.solution.alpha,
                "drift": correction.as_dict(),
                "pairwise_only_error": {"rotation_deg": float(np.rad2deg(std[0])), "translation_m": float(std[1])},
                "residuals": {"joint": pair_residuals(A, B, joint).summary(mask).as_dict(),
                              "pairwise_only": pair_residuals(A, B, edge.matrix).summary(mask).as_dict()}}

    def _streams(self) -> list[dict[str, Any]]:
        return [{"name": name, "source": s.source, "frame_id": s.frame_id, "child_frame_id": s.child_frame_id,
                 "samples": len(s), "inverted": inv, "time_offset": off.as_dict(),
                 "noise": dict(zip(("rotation_deg", "translation_m"),
                                   np.multiply(self.noise.std(k), (np.rad2deg(1.0), 1.0)).tolist(), strict=True))}
                for k, (name, s, inv, off) in enumerate(zip(self.names, self.streams, self.inverted, self.offsets,
                                                            strict=True))]

    def _noise_model(self) -> dict[str, Any]:
        """The joint estimate's noise model: its cost (a χ² of ``dof`` degrees of freedom when the
        model holds) and each sensor's predicted error (root of the covariance's trace)."""
        dof = 6 * (len(self.edges) - len(self.names) + 1)
        cov = self.covariances
        return {"method": "every pose sample's noise propagated to every pairwise estimate; joint covariance; "
                          "generalised least squares",
                "cost": self.problem.cost(self.matrices), "dof": dof,
                "excluded": None if self.problem.excluded is None else self.names[self.problem.excluded],
                "predicted_error": {name: {"rotation_deg": float(np.rad2deg(np.sqrt(np.trace(cov[k, :3, :3])))),
                                           "translation_m": float(np.sqrt(np.trace(cov[k, 3:, 3:])))}
                                    for k, name in enumerate(self.names) if k != self.reference}}

    def _uncertainty(self) -> dict[str, Any] | None:
        u = self.uncertainty
        if u is None:
            return None
        return {"method": "block bootstrap over the shared samples, joint re-solve", "replicates": u.replicates,
                "block_seconds": u.block_s, "seed": u.seed,
                "sensors": {name: {"rotation_std_deg": u.rotation_std_deg[i].tolist(),
                                   "translation_std_m": u.translation_std_m[i].tolist(),
                                   "rotation_interval_deg": u.rotation_interval_deg[i].tolist(),
                                   "translation_interval_m": u.translation_interval_m[i].tolist()}
                            for i, name in enumerate(self.names) if i != self.reference}}

    def _consistency(self) -> dict[str, Any]:
        """The χ² test; a value that cannot be tested (no degrees of freedom) is None."""
        c = self.consistency

        def value(x: float) -> float | None:
            return None if np.isnan(x) else x

        return {"test": "χ² of the pairwise estimates against the joint fit under their joint covariance; per "
                        "stream, how much removing its pairs lowers it",
                "statistic": c.statistic, "dof": c.dof, "p_value": value(c.p_value), "threshold": CONSISTENCY_P_VALUE,
                "streams": {name: {"reduction": value(c.reductions[k]), "dof": c.reduction_dof[k],
                                   "p_value": value(c.reduction_p[k])} for k, name in enumerate(self.names)},
                "suspect": None if c.suspect is None else self.names[c.suspect]}

    def document(self) -> dict[str, Any]:
        """The rig result as a plain dict (see the module docstring)."""
        names, ref = self.names, self.names[self.reference]
        doc = {
            "reference": ref,
            "transforms": [transform_entry(ref, name, T) for name, T in zip(names, self.matrices, strict=True)
                           if name != ref],
            "method": "pairwise dqopt, graph synchronisation, generalised least squares of the pairwise estimates "
                      "under their joint noise model",
            "noise_model": self._noise_model(),
            "pairwise": [self._pair(e, c, s) for e, c, s in
                         zip(self.edges, self.corrections, self.problem.edge_std(), strict=True)],
            "loop_closures": {
                "pairwise_only": [_closure(cl, names) for cl in self.closures],
                "joint_max": {"rotation_deg": max((cl.rotation_deg for cl in self.joint_closures), default=0.0),
                              "translation_m": max((cl.translation_m for cl in self.joint_closures), default=0.0)}},
            "consistency": self._consistency(),
            "streams": self._streams(),
            "uncertainty": self._uncertainty(),
            "inputs": self.inputs, "settings": self.settings, "version": __version__,
            "warnings": list(self.warnings),
        }
        out: dict[str, Any] = plain({k: v for k, v in doc.items() if v is not None})
        return out
