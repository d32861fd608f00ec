"""``handeye batch INPUTS…`` (many logs, one JSON Lines record each) and ``handeye report``
(the fleet-trend HTML report of those records).

Exit codes of ``batch``: 1 when any input drifted from the nominal, else 2 when any input
failed, else 3 with ``--strict`` and warnings, else 0; 4 when the batch itself crashed (a bug; a
crash while calibrating one input is that input's error record); 128 + N when it was ended by
signal N (SIGINT, SIGTERM, SIGHUP), its workers killed, the records written so far whole lines.
"""
from __future__ import annotations

import sys
from typing import Any

import click

from ..errors import ConfigError
from ..fleet import BatchSettings, Job, Streams, discover, run_batch
from ..fleet.engine import DEFAULT_TIMEOUT_S
from ..fleet.journal import Journal
from ..fleet.overrides import read_overrides, settings_for, unmatched
from ..io.spec import stream_source
from ..options import number
from ..output.formats import ALL_FORMATS
from ..output.records import BatchRecord
from ..output.writers import check_writable, write_stdout
from .check import verdict_options
from .common import CONTEXT, warn
from .params import (
    command_options,
    options_from_cli,
    quiet_option,
    refused_report,
    report_option,
    stream_options,
    stream_values,
)

__all__ = ["batch", "report"]

_parse_seconds = number(unit="seconds", word="off")


def _timeout(ctx: click.Context, param: click.Parameter, value: str) -> float | None:
    limit = _parse_seconds(value, "--timeout")
    return None if limit is None else float(limit)


@click.command(context_settings=CONTEXT)
@click.argument("inputs", nargs=-1, required=True)
@stream_options
@command_options("batch")
@verdict_options
@click.option("--per-input", "per_input", type=click.Path(dir_okay=False), help="YAML mapping glob patterns of "
              "input paths (or, without '/', of a path component: robot07*) to the options and streams that differ "
              "for them (flat names as in --config; stream_a/stream_b: /topic, tf:PARENT,CHILD or FILE), applied over "
              "the shared options in file order.")
@click.option("--timeout", default=f"{DEFAULT_TIMEOUT_S:g}", callback=_timeout, metavar="SECONDS|off",
              show_default=True, help="Time limit of each input [s]: an input still running then (a FIFO no one "
              "writes, a hung file system) is an error record; off: no limit.")
@click.option("-j", "--jobs", type=click.IntRange(min=1), help="Local worker processes [default: one per core].")
@click.option("--scheduler", metavar="ADDRESS", help="Run on this Dask distributed scheduler (e.g. tcp://host:8786) "
              "instead of local processes; needs pip install 'handeye-cli[dask]' (in a checkout: "
              "pip install '.[dask]').")
@click.option("-o", "--output", "records_file", type=click.Path(dir_okay=False), help="Append the JSON Lines "
              "records to this file instead of stdout, each made durable (fsync) as it is written; with --skip-done "
              "a resumed batch keeps the records there and runs only the inputs they lack.")
@click.option("--output-dir", type=click.Path(file_okay=False), help="Write each input's full result file here, "
              "named after the input.")
@click.option("--format", "fmt", type=click.Choice(ALL_FORMATS), default="yaml", show_default=True,
              help="Format of the result files in --output-dir (the records are always JSON Lines).")
@click.option("--skip-done", is_flag=True, help="Resume: with -o, keep the records already in that file; with "
              "--output-dir, reuse results computed from the same file content, options and handeye version.")
@report_option
@quiet_option
@click.pass_context
def batch(ctx: click.Context, /, inputs: tuple[str, ...], **o: Any) -> None:
    """Calibrate many logs with one set of options (every calibrate option applies to every input):
    one JSON Lines record per input on stdout.

    INPUTS are files, directories (searched recursively for logs by content: MCAP, ROS 1 bags,
    ROS 2 bags, and folders holding two TUM/EuRoC files a and b), glob patterns, @LIST files
    (one log, or two pose files 'A B', per line) or - (such a list on stdin). A bad log is an
    error record, never an abort. With --against each record carries a drift verdict.

    \b
    Exit codes: 0 all within tolerance, 1 a sensor drifted, 2 some input failed,
    3 --strict and some result has warnings, 4 internal error (a bug).
    \b
    Examples:
      handeye batch logs/2026-11-*/ --topic-a /cam0/pose --topic-b /cam1/pose \\
          --against nominal/robot42.urdf --max-rotation-deg 0.5 --max-translation-m 0.005 \\
          --jobs 8 --output-dir results/ > verdicts.jsonl
      find logs -name '*.mcap' | handeye batch - --topic-a /cam0/pose --topic-b /cam1/pose
      handeye batch logs/ --topic-a /cam0/pose --topic-b /cam1/pose -o records.jsonl --skip-done
    """
    if o["skip_done"] and not (o["output_dir"] or o["records_file"]):
        raise ConfigError("--skip-done needs --output-dir or -o", "--skip-done",
                          "add -o records.jsonl (resume from its records) or --output-dir DIR")
    nominal = None
    if o["against"]:
        from ..io.nominal import read_nominal

        nominal = read_nominal(o["against"])
    given = stream_values(o)
    streams = Streams(*(stream_source(f"stream_{side}", given[f"stream_{side}"], topic=given[f"topic_{side}"],
                                      frames=given[f"frames_{side}"]) for side in "ab"))
    options = options_from_cli(o)
    overrides = read_overrides(o["per_input"]) if o["per_input"] else ()
    from ..io.remote import session_of

    with session_of(options.read):         # URLs are listed with the options' credentials and time limits
        found = discover(inputs, sys.stdin, warn)
    unmatched(overrides, found, warn)
    jobs = [Job(i, *settings_for(i, streams, options, overrides), timeout=o["timeout"]) for i in found]
    settings = BatchSettings(nominal, o["max_rotation_deg"], o["max_translation_m"], o["output_dir"], o["fmt"],
                             o["skip_done"], options.analysis.strict, o["jobs"], o["scheduler"],
                             progress=not o["quiet"])
    shown: list[BatchRecord] = []             # the typed records, for the fleet report
    if o["report_file"]:
        check_writable(o["report_file"], "--report")
    journal = Journal(o["records_file"], o["skip_done"], warn, "-o") if o["records_file"] else None
    try:
        summary = run_batch(jobs, settings, journal.append if journal else lambda line: write_stdout(line + "\n"),
                            done=journal.done if journal else None, observe=shown.append if o["report_file"] else None)
    finally:
        if journal:
            journal.close()
    if o["report_file"]:
        from ..output.fleet_report import write_fleet_report

        write_fleet_report(o["report_file"], shown, "--report")
    if summary.full:                      # a full disk: one line, even with -q (each record says what was written)
        click.echo(f"error: {summary.full}", err=True)
    if not o["quiet"]:
        click.echo(summary.text(), err=True)
    ctx.exit(summary.exit_code)


@click.command(context_settings=CONTEXT)
@click.argument("records_file", type=click.Path())
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="The HTML file to write.")
@refused_report("handeye report writes the report itself: give its file with -o")
@quiet_option
def report(records_file: str, output: str, quiet: bool) -> None:
    """Write the fleet-trend report of batch records (JSON Lines): per sensor pair, the extrinsic's
    rotation and translation over log time against the nominal and its tolerance band, and the
    table of drifted and failed logs. One self-contained HTML file.

    \b
    Example:
      handeye report verdicts.jsonl -o fleet.html -q
    """
    from ..output.fleet_report import read_records, write_fleet_report

    records = read_records(records_file, warn)
    write_fleet_report(output, records)
    if not quiet:
        counts = {s: sum(r.status == s for r in records) for s in ("ok", "drift", "error")}
        click.echo(f"{output}: {len(records)} records ({', '.join(f'{n} {s}' for s, n in counts.items())})", err=True)
