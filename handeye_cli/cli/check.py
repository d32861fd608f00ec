"""``handeye check RESULT --against NOMINAL``: the drift verdict on a result already computed.

Exit codes: 0 within tolerance, 1 drifted, 2 bad input.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

from ..analysis.verdict import DEFAULT_MAX_ROTATION_DEG, DEFAULT_MAX_TRANSLATION_M, Judged, verdict_for
from ..errors import as_flags, worded
from ..io.nominal import read_nominal, read_result
from ..output.document import render
from ..output.formats import SUMMARY_FORMATS
from ..output.writers import write_stdout
from .common import CONTEXT
from .params import refused_quiet, refused_report

__all__ = ["check", "verdict_options"]

_VERDICT_OPTIONS = [
    click.option("--against", "against", metavar="NOMINAL", help="Nominal extrinsic to compare with: a handeye "
                 "result, a URDF, a ROS launch file, a static_transform_publisher command line or a Kalibr YAML."),
    click.option("--max-rotation-deg", type=click.FloatRange(min=0), default=DEFAULT_MAX_ROTATION_DEG,
                 show_default=True, help="Rotation tolerance against the nominal [deg]."),
    click.option("--max-translation-m", type=click.FloatRange(min=0), default=DEFAULT_MAX_TRANSLATION_M,
                 show_default=True, help="Translation tolerance against the nominal [m]."),
]


def verdict_options(f: Callable[..., Any]) -> Callable[..., Any]:
    """Add ``--against``, ``--max-rotation-deg`` and ``--max-translation-m`` to a command."""
    for option in reversed(_VERDICT_OPTIONS):
        f = option(f)
    return f


@click.command(context_settings=CONTEXT)
@click.argument("result_file", type=click.Path())
@verdict_options
@click.option("--format", "fmt", type=click.Choice(SUMMARY_FORMATS), default="text", show_default=True,
              help="A one-line verdict, or the verdict as YAML/JSON.")
@refused_report("check reads a result, not the streams: run 'handeye calibrate --report FILE' on the log")
@refused_quiet("check prints only its verdict, on stdout: redirect it (> /dev/null) and read the exit code")
@click.pass_context
def check(ctx: click.Context, result_file: str, against: str | None, max_rotation_deg: float,
          max_translation_m: float, fmt: str) -> None:
    """Compare a calibration result with the nominal extrinsic; exit 1 when the sensor drifted.

    Drift: the rotation angle or the translation distance between RESULT's T_a_b and the
    nominal's exceeds its tolerance and, when RESULT has a bootstrap interval (calibrate
    --bootstrap N), the nominal lies outside it. The nominal's transform is looked up between
    RESULT's frames a and b (a file with a single transform is used as it is).

    \b
    Examples:
      handeye check result.yaml --against robot42.urdf --max-rotation-deg 0.5 --max-translation-m 0.005
      handeye check result.yaml --against "ros2 run tf2_ros static_transform_publisher --x 0.1 ..."
    """
    if against is None:
        raise click.UsageError("--against NOMINAL is required", ctx)
    result = Judged.from_document(read_result(result_file))         # the file read back, parsed once here
    verdict = verdict_for(result, read_nominal(against), max_rotation_deg, max_translation_m)
    write_stdout(as_flags(verdict.summary()) + "\n" if fmt == "text"
                 else render(worded(verdict.as_dict(), as_flags), fmt))
    ctx.exit(1 if verdict.drift else 0)
