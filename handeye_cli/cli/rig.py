"""``handeye rig``: every sensor of a rig from one log, jointly consistent.

A separate command rather than ``calibrate`` with more streams: its inputs are a set of *named*
streams (any number, one of them the reference), and calibrate's options of stream a or b take the
stream's name instead (``--invert-b`` → ``--invert NAME``, ``--no-invert-b`` → ``--no-invert NAME``,
``--scale auto`` → ``--scale NAME=auto``, ``--name-a`` → the NAME of ``--stream NAME=…``; generated from
the options' ``per_stream`` field, same values and parsers); and its
result is a different document — a list of transforms, the pairwise table, loop closures and the
consistency diagnostic — not the single ``T_a_b`` of the result schema (docs/design.md) that scripts read.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import click
import numpy as np

from ..analysis.verdict import Verdict
from ..geometry import dualquat as dq
from ..io.nominal import read_nominal
from ..output.writers import check_writable
from .check import verdict_options
from .common import CONTEXT, emit, finish, report_failure, result_format
from .params import (
    apply,
    command_options,
    options_from_cli,
    output_options,
    per_stream_options,
    per_stream_values,
    quiet_option,
    refused,
    report_option,
)

if TYPE_CHECKING:
    from ..rig import RigResult

__all__ = ["rig"]

def _summary(doc: dict[str, Any]) -> str:
    lines = [f"rig of {len(doc['transforms']) + 1} sensors, reference {doc['reference']}:"]
    for t in doc["transforms"]:
        angle = np.rad2deg(np.linalg.norm(dq.to_rotvec(np.asarray(t["quaternion_xyzw"], dtype=float))))
        x, y, z = t["translation"]
        lines.append(f"  T_{t['parent']}_{t['child']}: translation [{x:.4f}, {y:.4f}, {z:.4f}] m, "
                     f"rotation {angle:.3f}°")
    worst = max(doc["loop_closures"]["pairwise_only"], key=lambda c: c["rotation_deg"], default=None)
    if worst:
        lines.append(f"  worst pairwise loop closure {'-'.join(worst['streams'])}: {worst['rotation_deg']:.3f}° / "
                     f"{worst['translation_m'] * 1e3:.1f} mm (joint: identity)")
    return "\n".join(lines) + "\n"


def _write_report(path: str, result: RigResult) -> None:
    """The rig's HTML page (``--report``): its stack (scipy's Rotation) is imported only when one is asked for."""
    from ..rig.report import write_rig_report

    write_rig_report(path, result)


def _drift_message(verdicts: dict[str, Verdict]) -> str:
    """One line naming every drifted sensor and its verdict."""
    return "; ".join(f"sensor {name} {v.summary()}" for name, v in verdicts.items() if v.drift)


@click.command("rig", context_settings=CONTEXT)
@click.argument("log", required=False)
@click.option("--stream", "streams", multiple=True, required=True, metavar="NAME=SOURCE",
              help="A sensor: NAME=/topic or NAME=tf:PARENT,CHILD of LOG, or NAME=FILE (TUM, EuRoC, CSV). "
              "Repeat for every sensor (at least two).")
@click.option("--reference", metavar="NAME", help="The sensor every T_ref_k is expressed in [default: the first].")
@per_stream_options
@click.option("--block", "block_s", type=float, default=2.0, show_default=True, metavar="SECONDS",
              help="Block length of the bootstrap over the shared samples.")
@command_options("rig")
@verdict_options
@output_options
@report_option
@apply(*(refused((f"--name-{side}",), f"names no stream {side}", "a rig's sensor is named once, by --stream "
                 "NAME=SOURCE: NAME is its frame in every output (calibrate's --name-a/-b)") for side in "ab"))
@quiet_option
def rig(log: str | None, **p: Any) -> None:
    """Calibrate every sensor of a rig from one log: T_ref_k for each stream k, jointly.

    Every pair of streams is calibrated (dqopt), the pairwise results are synchronised (rotation
    averaging, translation least squares) and combined by generalised least squares under their
    joint noise model (each stream's pose noise propagated to every pair it is in), so that
    T_j_k = T_ref_j⁻¹ T_ref_k agrees with the data of every pair. The log is read once.
    The result lists every T_ref_k and T_j_k, per-pair residuals (joint vs pairwise-only),
    each stream's estimated noise and the predicted errors, the pairwise loop closures and the
    stream that spoils them, and with --bootstrap N the uncertainty of each extrinsic.

    \b
    Examples:
      handeye rig sample_data/rig4.mcap --stream cam0=/cam0/pose --stream cam1=/cam1/pose \\
          --stream lidar=/lidar/odom --stream imu=tf:odom,imu_link
      handeye rig log.mcap --stream cam0=/cam0/pose --stream wheels=wheels.tum --reference cam0 \\
          --time-offset wheels=0.05 --bootstrap 200 -o rig.yaml
      handeye rig log.mcap --stream cam0=/cam0/pose --stream mono=/orb/pose --scale mono=auto \\
          --stream board=board.tum --invert board --wxyz board --no-invert cam0
      handeye rig log.mcap --stream cam0=/cam0/pose --stream cam1=/cam1/pose --format urdf -o rig.urdf
      handeye rig log.mcap --stream cam0=/cam0/pose --stream cam1=/cam1/pose --against robot.urdf  # exit 1: moved
      handeye rig log.mcap --stream cam0=/cam0/pose --stream cam1=/cam1/pose --report rig.html
      handeye rig --stream base_link=base.tum --stream lidar=lidar.tum --prior robot.urdf  # planar: z from it

    With --against NOMINAL (a URDF, launch file, static_transform_publisher lines, a handeye result)
    every sensor gets a verdict: T_ref_k against the nominal's transform between the frames named as
    the reference and sensor k; the document lists them under 'verdicts' and the exit code is 1 when
    any sensor drifted.

    With --prior NOMINAL (read as --against reads it: frames named as the streams) each pair takes from the
    nominal what its motion leaves open, as calibrate --prior does (a planar rig's z), and the joint
    result keeps it.

    With --report FILE the rig's HTML page: the joint extrinsics, the clock offsets, and each pair's
    residuals (joint and pairwise only), fit test and drift test.
    """
    from ..rig import RigOptions, calibrate_rig_files, parse_stream
    from ..rig.verdicts import check_sensor_names, rig_verdicts

    options = options_from_cli(p)
    specs = [parse_stream(s) for s in p["streams"]]
    fmt = result_format(p["output"], p["fmt"])
    if p["report_file"]:
        check_writable(p["report_file"], "--report")
    nominal = read_nominal(p["against"]) if p["against"] else None      # a bad nominal fails before the work
    if nominal is not None:
        check_sensor_names([str(s.name) for s in specs], nominal)
    inverted = per_stream_values(p, "invert")
    opts = RigOptions(reference=p["reference"], time_offsets=per_stream_values(p, "time_offset"),
                      invert=tuple(n for n, v in inverted.items() if v),
                      not_inverted=tuple(n for n, v in inverted.items() if not v), wxyz=per_stream_values(p, "wxyz"),
                      scales=per_stream_values(p, "scale"), block_s=p["block_s"], options=options)
    result = calibrate_rig_files(log, specs, opts, quiet=p["quiet"])
    doc = result.document()
    verdicts = {} if nominal is None else rig_verdicts(result, nominal, p["max_rotation_deg"], p["max_translation_m"])
    if verdicts:
        doc["verdicts"] = {name: v.as_dict() for name, v in verdicts.items()}
    late = report_failure(lambda: _write_report(p["report_file"], result)) if p["report_file"] else None
    emit(doc, p["output"], fmt)
    if not p["quiet"]:
        click.echo(_summary(doc), err=True, nl=False)
    finish(doc, strict=options.analysis.strict, quiet=p["quiet"],
           drift=_drift_message(verdicts) if any(v.drift for v in verdicts.values()) else None,
           within=f"every sensor within tolerance of the nominal {p['against']}" if verdicts else None, late=late)
