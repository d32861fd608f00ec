"""``handeye calibrate``: one extrinsic from a log or two pose files."""
from __future__ import annotations

from typing import Any

import click
import numpy as np

from ..analysis.verdict import verdict_for
from ..calibration import Calibration, calibrate_specs, stream_specs
from ..errors import HandEyeError
from ..geometry import dualquat as dq
from ..io.nominal import read_nominal
from ..output.document import calibration_document
from ..output.writers import check_writable
from .check import verdict_options
from .common import CONTEXT, emit, finish, report_failure, result_format
from .params import (
    command_options,
    options_from_cli,
    output_options,
    quiet_option,
    report_option,
    stream_options,
    stream_values,
)


def summary_line(doc: dict[str, Any]) -> str:
    rotvec = np.rad2deg(dq.to_rotvec(np.asarray(doc["quaternion_xyzw"], dtype=np.float64)))
    t = doc["translation"]
    angle = float((rotvec @ rotvec) ** 0.5)
    return (f"T_{doc['frames']['a']}_{doc['frames']['b']}: translation [{t[0]:.4f}, {t[1]:.4f}, {t[2]:.4f}] m, "
            f"rotation {angle:.3f}° (rotvec [{rotvec[0]:.3f}, {rotvec[1]:.3f}, {rotvec[2]:.3f}]°); "
            f"{doc['method']} on {doc['pairs_used']} pairs")


def write_run_report(path: str, result: Calibration) -> HandEyeError | None:
    """Write the HTML report of ``result``; a failure is returned (:func:`.common.report_failure`), not raised, so
    the result is still written."""
    def write() -> None:
        from ..output.report import write_report  # the report's stack is imported only when one is asked for

        write_report(path, result)
    return report_failure(write)


@click.command("calibrate", context_settings=CONTEXT)
@click.argument("inputs", nargs=-1)
@stream_options
@command_options("calibrate")
@report_option
@verdict_options
@output_options
@quiet_option
def calibrate(inputs: tuple[str, ...], **p: Any) -> None:
    """Calibrate T_a_b from a log (MCAP, ROS 1 bag, ROS 2 bag) or two pose files (TUM, EuRoC, CSV).

    Stream a is the first topic/TF chain/file, stream b the second; T_a_b is the pose of b's
    frame in a's frame. A stream is named as every command names one (--stream-a SOURCE): /topic,
    tf:PARENT,CHILD (the parent first) or FILE. The result goes to stdout (YAML) unless -o is
    given. A text stream may come from stdin as '-'.

    \b
    Examples:
      handeye calibrate sample_data/rig.mcap --topic-a /cam0/pose --topic-b /cam1/pose
      handeye calibrate log.bag --stream-a tf:world,cam0 --stream-b tf:odom,imu --time-offset auto
      handeye calibrate log.bag --stream-a /cam0/pose --stream-b wheels.tum   # a topic against a file
      handeye calibrate a.tum b.tum --method dqopt -o extrinsic.json
      cat a.tum | handeye calibrate - b.tum --robust --alpha auto --bootstrap 1000 --report report.html
      handeye calibrate log.mcap --topic-a /cam0/pose --topic-b /cam1/pose --against robot.urdf  # exit 1: moved
      handeye calibrate log.mcap --topic-a /cam0/pose --topic-b /cam1/pose --format urdf -o cam1.urdf
      handeye calibrate log.mcap --topic-a /cam0/pose --topic-b /cam1/pose --format urdf-joint  # paste into a URDF
    """
    config_file, preset = p.get("config_file"), p.get("preset")
    options = options_from_cli(p)
    spec_a, spec_b = stream_specs(inputs, **stream_values(p))
    fmt = result_format(p["output"], p["fmt"])
    if p["report_file"]:
        check_writable(p["report_file"], "--report")
    nominal = read_nominal(p["against"]) if p["against"] else None      # a bad nominal fails before the work
    result = calibrate_specs(spec_a, spec_b, options, quiet=p["quiet"])
    result = result.with_origin(config_file, preset)
    doc = calibration_document(result)
    verdict = (None if nominal is None else
               verdict_for(result.judged(), nominal, p["max_rotation_deg"], p["max_translation_m"]))
    if verdict is not None:
        doc["verdict"] = verdict.as_dict()
    late = write_run_report(p["report_file"], result) if p["report_file"] else None
    emit(doc, p["output"], fmt)
    if not p["quiet"]:
        click.echo(summary_line(doc), err=True)
    finish(doc, strict=options.analysis.strict, quiet=p["quiet"],
           drift=verdict.summary() if verdict is not None and verdict.drift else None,
           within=verdict.summary() if verdict is not None else None,
           late=late, poor_fit_accepted=result.diagnostics.poor_fit_accepted)
