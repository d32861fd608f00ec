"""Drift verdicts for a whole rig: every ``T_ref_k`` against the nominal's transform between the same frames.

The sensors' names are the nominal's frame names: sensor k's verdict compares the joint ``T_ref_k``
(pose of frame k in the reference's frame, maps points from k to ref; metres) with the nominal's
chain of fixed transforms from frame ref to frame k (:meth:`handeye_cli.io.nominal.Nominal.transform`),
by :func:`handeye_cli.analysis.verdict.compare` (rotation angle [deg], translation distance [m]).
With ``--bootstrap N`` the rig result holds each sensor's 95 % intervals (the document's ``uncertainty.sensors.K``),
and the verdict judges significance from them as ``calibrate --against`` does. The verdicts read the typed
:class:`~handeye_cli.rig.result.RigResult`, not its document.
"""
from __future__ import annotations

from ..analysis.verdict import Verdict, compare
from ..errors import ReadError
from ..io.nominal import Nominal
from .result import RigResult

__all__ = ["check_sensor_names", "rig_verdicts"]


def check_sensor_names(names: list[str], nominal: Nominal) -> None:
    """Refuse (ReadError) a rig of more than two sensors whose names are not all frames of the nominal.

    A rig of two sensors may use a nominal holding a single transform under other frame names
    (:meth:`~handeye_cli.io.nominal.Nominal.transform` then uses that one transform)."""
    missing = [name for name in names if name not in set(nominal.frames)]
    if len(names) > 2 and missing:
        raise ReadError(f"sensor(s) {', '.join(missing)} not in the nominal (it names {', '.join(nominal.frames)})",
                        nominal.source, "name the streams as the nominal's frames: ⟦streams=FRAME=SOURCE⟧")


def rig_verdicts(result: RigResult, nominal: Nominal, max_rotation_deg: float,
                 max_translation_m: float) -> dict[str, Verdict]:
    """The verdict of every sensor of the rig ``result`` (its typed ``T_ref_k`` as the document states them, and
    each sensor's bootstrap intervals), keyed by sensor name. Raises ReadError as :func:`check_sensor_names`
    does."""
    frames = result.stated()
    check_sensor_names([result.names[result.reference], *(f.child for f in frames)], nominal)
    where = {"source": nominal.source, "kind": nominal.kind}
    u = result.uncertainty
    spread = {} if u is None else {name: (u.rotation_interval_deg[i], u.translation_interval_m[i])
                                   for i, name in enumerate(result.names)}
    return {f.child: compare(f.matrix, nominal.transform(f.parent, f.child), max_rotation_deg, max_translation_m,
                             intervals=spread.get(f.child), nominal=where)
            for f in frames}
