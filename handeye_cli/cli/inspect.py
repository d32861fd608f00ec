"""``handeye inspect``: what a log holds — topics, pose streams, rates, TF tree."""
from __future__ import annotations

from typing import Any

import click

from ..output.document import plain, render
from ..output.formats import SUMMARY_FORMATS
from ..output.writers import write_stdout
from .common import CONTEXT
from .params import command_options, options_from_cli, quiet_option


def _inspect_text(info: dict[str, Any]) -> str:
    lines = [f"{info['path']}: {info['format']}"]
    if "duration_ns" in info:
        lines.append(f"  span {info['duration_ns'] / 1e9:.3f} s"
                     + (f", {info['rows']} rows at {info['rate_hz']} Hz" if "rows" in info else ""))
    topics = info.get("topics", [])
    if topics:
        width = max(len(t["topic"]) for t in topics)
        lines.append("  topics (* = a pose stream calibrate can use with --topic-a/--topic-b):")
        for t in topics:
            lines.append(f"  {'*' if t['pose'] else ' '} {t['topic']:<{width}}  {t['type']}  {t['count']} msgs"
                         f"  {t['rate_hz']} Hz")
    frames = info.get("tf_frames", [])
    if frames:
        lines.append("  TF edges (use with --frames-a/--frames-b PARENT CHILD):")
        for f in frames:
            lines.append(f"    {f['parent']} -> {f['child']}  {'static' if f['static'] else str(f['count']) + ' msgs'}")
    return "\n".join(lines) + "\n"


@click.command("inspect", context_settings=CONTEXT)
@click.argument("input_file", type=click.Path())
@click.option("--format", "fmt", type=click.Choice(SUMMARY_FORMATS), default="text", show_default=True,
              help="Human-readable text, or machine-readable YAML/JSON.")
@click.option("--all-tf", is_flag=True, help="Read every TF message for the TF edges [default: the first 2000].")
@quiet_option
@command_options("inspect")
def inspect(input_file: str, fmt: str, all_tf: bool, quiet: bool, **remote: Any) -> None:
    """List the topics, message types, counts, rates and time span of a log, which topics carry
    poses, and its TF frame tree.

    \b
    Examples:
      handeye inspect sample_data/rig.mcap
      handeye inspect sample_data/rig_ros2 --format json
      handeye inspect s3://fleet-logs/robot42/2026-11-30.mcap
    """
    from ..io import inspect_log
    from ..io.remote import session_of

    with session_of(options_from_cli(remote).read):
        info = plain(inspect_log(input_file, quiet=quiet, all_tf=all_tf))
    write_stdout(_inspect_text(info) if fmt == "text" else render(info, fmt))
