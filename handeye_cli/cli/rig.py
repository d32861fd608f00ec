"""``handeye rig``: every sensor of a rig from one log, jointly consistent.

A separate command rather than ``calibrate`` with more streams: its inputs are a set of *named*
streams (any number, one of them the reference) with per-stream clock offsets and inversion,
where calibrate's are exactly a and b (``--topic-a``, ``--invert-b``, ``--name-a``…); and its
result is a different document — a list of transforms, the pairwise table, loop closures and the
consistency diagnostic — not the single ``T_a_b`` of the result schema (docs/design.md) that scripts read.
"""
from __future__ import annotations

from typing import Any

import click
import numpy as np

from ..analysis.verdict import Verdict
from ..config import presets
from ..errors import ConfigError
from ..geometry import dualquat as dq
from ..io.nominal import read_nominal
from ..output.writers import check_writable, output_format
from .check import verdict_options
from .common import CONTEXT, emit, finish
from .params import apply, flags, options_from_cli, output_options

__all__ = ["rig"]

# The calibrate options that apply to every pair of a rig (the a/b-specific ones do not).
RIG_OPTIONS = ("time_source", "time_unit", "csv_columns", "sync", "max_dt", "max_time_offset", "gate", "max_jump",
               "max_jump_deg", "stations",
               "pairs", "min_rotation", "keyframe_rotation", "keyframe_translation", "max_pairs", "seed",
               "method", "alpha", "min_pairs", "robust", "bootstrap", "strict", "accept_poor_fit",
               "storage_option", "remote_timeout", "remote_retries")


def _named(values: tuple[str, ...], flag: str) -> dict[str, str]:
    out = {}
    for text in values:
        name, sep, value = text.partition("=")
        if not sep or not name.strip() or not value.strip():
            raise ConfigError(f"bad value {text!r}", flag, "write NAME=SECONDS or NAME=auto")
        out[name.strip()] = value.strip()
    return out


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


def _drift_message(verdicts: dict[str, Verdict]) -> str:
    """One line naming every drifted sensor and its verdict."""
    return "; ".join(f"sensor {name} {v.summary()}" for name, v in verdicts.items() if v.drift)


@click.command("rig", context_settings=CONTEXT)
@click.argument("log", required=False)
@click.option("--stream", "streams", multiple=True, required=True, metavar="NAME=SOURCE",
              help="A sensor: NAME=/topic or NAME=tf:PARENT,CHILD of LOG, or NAME=FILE (TUM, EuRoC, CSV). "
              "Repeat for every sensor (at least two).")
@click.option("--reference", metavar="NAME", help="The sensor every T_ref_k is expressed in [default: the first].")
@click.option("--time-offset", "offsets", multiple=True, metavar="NAME=SECONDS|auto",
              help="How far NAME's clock is ahead of the reference's [default: auto for every stream].")
@click.option("--invert", multiple=True, metavar="NAME", help="Invert stream NAME first (it records "
              "T_sensor_world). Repeatable.")
@click.option("--block", "block_s", type=float, default=2.0, show_default=True, metavar="SECONDS",
              help="Block length of the bootstrap over the shared samples.")
@apply(flags(*RIG_OPTIONS),
       click.option("--config", "config_file", type=click.Path(), help="YAML file of options applied to every pair."),
       click.option("--preset", type=click.Choice(presets()), help="Preset of options applied to every pair."))
@verdict_options
@output_options
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary on stderr.")
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
      handeye rig log.mcap --stream cam0=/cam0/pose --stream cam1=/cam1/pose --format urdf -o rig.urdf
      handeye rig log.mcap --stream cam0=/cam0/pose --stream cam1=/cam1/pose --against robot.urdf  # exit 1: moved

    With --against NOMINAL (a URDF, launch file, static_transform_publisher lines, a handeye result)
    every sensor gets a verdict: T_ref_k against the nominal's transform between the frames named as
    the reference and sensor k; the document lists them under 'verdicts' and the exit code is 1 when
    any sensor drifted.
    """
    from ..rig import RigOptions, calibrate_rig_files, parse_stream
    from ..rig.verdicts import check_sensor_names, rig_verdicts

    options = options_from_cli(p)
    specs = [parse_stream(s) for s in p["streams"]]
    check_writable(p["output"], "-o")
    fmt = output_format(p["output"], p["fmt"])
    nominal = read_nominal(p["against"]) if p["against"] else None      # a bad nominal fails before the work
    if nominal is not None:
        check_sensor_names([str(s.name) for s in specs], nominal)
    opts = RigOptions(reference=p["reference"], time_offsets=_named(p["offsets"], "--time-offset"),
                      invert=tuple(p["invert"]), block_s=p["block_s"], options=options)
    result = calibrate_rig_files(log, specs, opts, quiet=p["quiet"])
    doc = result.document()
    verdicts = {} if nominal is None else rig_verdicts(doc, nominal, p["max_rotation_deg"], p["max_translation_m"])
    if verdicts:
        doc["verdicts"] = {name: v.as_dict() for name, v in verdicts.items()}
    emit(doc, p["output"], fmt)
    if not p["quiet"]:
        click.echo(_summary(doc), err=True, nl=False)
    finish(doc, strict=options.analysis.strict, quiet=p["quiet"],
           drift=_drift_message(verdicts) if any(v.drift for v in verdicts.values()) else None,
           within=f"every sensor within tolerance of the nominal {p['against']}" if verdicts else None)
