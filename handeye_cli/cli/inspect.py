"""``handeye inspect``: what a log holds — topics, pose streams, rates, TF tree."""
from __future__ import annotations

from typing import Any

import click

from ..errors import as_flags, worded
from ..output.document import plain, render
from ..output.formats import SUMMARY_FORMATS
from ..output.writers import write_stdout
from .common import CONTEXT
from .params import command_options, options_from_cli, quiet_option


def _rate(t: dict[str, Any]) -> str:
    """A topic's rate as the text shows it (see :func:`handeye_cli.io.logs._rate`)."""
    if t["rate_over"] == "latched":
        return "latched (static)"
    if t["rate_hz"] is None:
        return "one stamp" if t["count"] > 1 else "one message"
    return f"{t['rate_hz']} Hz" + (" (over the log's span)" if t["rate_over"] == "log" else "")


def _tf_tree(frames: list[dict[str, Any]]) -> list[str]:
    """The TF tree, each child indented under its parent (roots: frames that are nobody's child),
    each line ``child  static`` or ``child  N msgs``; edges on a loop, unreachable from a root,
    are listed after it as ``parent -> child``."""
    children: dict[str, list[dict[str, Any]]] = {}
    for f in frames:
        children.setdefault(f["parent"], []).append(f)
    child_frames = {f["child"] for f in frames}
    lines: list[str] = []
    shown: set[tuple[str, str]] = set()

    def walk(frame: str, depth: int, path: tuple[str, ...]) -> None:
        for f in children.get(frame, []):
            edge = (f["parent"], f["child"])
            if edge in shown or f["child"] in path:
                continue
            shown.add(edge)
            what = "static" if f["static"] else f"{f['count']} msgs"
            lines.append(f"    {'  ' * depth}{f['child']}  {what}")
            walk(f["child"], depth + 1, (*path, f["child"]))

    for root in sorted(children.keys() - child_frames):
        lines.append(f"    {root}")
        walk(root, 1, (root,))
    lines += [f"    {f['parent']} -> {f['child']}  (on a loop)" for f in frames
              if (f["parent"], f["child"]) not in shown]
    return lines


def _inspect_text(info: dict[str, Any]) -> str:
    lines = [f"{info['path']}: {info['format']}"]
    lines += [f"  warning: {w}" for w in info.get("warnings", [])]
    if "duration_ns" in info:
        lines.append(f"  span {info['duration_ns'] / 1e9:.3f} s"
                     + (f", {info['rows']} rows at {info['rate_hz']} Hz" if "rows" in info else ""))
    topics = info.get("topics", [])
    if topics:
        width = max(len(t["topic"]) for t in topics)
        lines.append("  topics (* = a pose stream calibrate can use with --stream-a/--stream-b /topic; rates over each "
                     "topic's own span):")
        for t in topics:
            lines.append(f"  {'*' if t['pose'] else ' '} {t['topic']:<{width}}  {t['type']}  {t['count']} msgs"
                         f"  {_rate(t)}")
    frames = info.get("tf_frames", [])
    if frames:
        lines.append(f"  TF tree, from all {info['tf_messages']} TF messages "
                     "(use with --stream-a/--stream-b tf:PARENT,CHILD, the parent first):")
        lines += _tf_tree(frames)
    return "\n".join(lines) + "\n"


@click.command("inspect", context_settings=CONTEXT)
@click.argument("input_file", type=click.Path())
@click.option("--format", "fmt", type=click.Choice(SUMMARY_FORMATS), default="text", show_default=True,
              help="Human-readable text, or machine-readable YAML/JSON.")
@quiet_option
@command_options("inspect")
def inspect(input_file: str, fmt: str, quiet: bool, **remote: Any) -> None:
    """List the topics, message types, counts, rates (each over the topic's own span) and time
    span of a log, which topics carry poses, its TF frame tree (from every TF message), and what
    a cut-off or damaged file lost.

    \b
    Examples:
      handeye inspect sample_data/rig.mcap
      handeye inspect sample_data/rig_ros2 --format json
      handeye inspect s3://fleet-logs/robot42/2026-11-30.mcap
    """
    from ..io import inspect_log
    from ..io.remote import session_of

    with session_of(options_from_cli(remote).read):
        info = worded(plain(inspect_log(input_file, quiet=quiet)), as_flags)
    write_stdout(_inspect_text(info) if fmt == "text" else render(info, fmt))
