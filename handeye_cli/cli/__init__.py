"""The ``handeye`` command line: click commands that parse options, call the library and print.

Exit codes: 0 success; 2 bad input or an unsolvable problem (one line on stderr, no output
file); 3 warnings under ``--strict``.
"""
from __future__ import annotations

import sys
import traceback

import click

from .. import __version__
from ..config import load_config
from ..errors import HandEyeError
from ..io.pairfile import read_extrinsic, read_pairs
from ..output.document import FORMATS, format_for_path, plain, render, result_document, write_atomic
from ..solvers import METHODS, Prior, solve

_CONTEXT = {"help_option_names": ["-h", "--help"], "max_content_width": 100}


class StrictFailure(Exception):
    """Warnings were raised under ``--strict`` (exit code 3)."""


def emit(doc: dict, output: str | None, fmt: str | None) -> None:
    """Print the result to stdout, or write it atomically to ``output``."""
    text = render(doc, format_for_path(output, fmt))
    if output:
        write_atomic(output, text)
    else:
        click.echo(text, nl=False)


def _prior_weights(text: str) -> list[float]:
    """``--prior-weights a,b`` → [a, b]."""
    try:
        a, b = (float(v) for v in text.split(","))
    except ValueError:
        raise HandEyeError(f"bad --prior-weights {text!r}", "--prior-weights",
                           "give two non-negative numbers a,b, e.g. 1,1") from None
    return [a, b]


def parse_prior(path: str | None, weights: str) -> Prior | None:
    """``--prior FILE --prior-weights a,b`` → :class:`Prior` (eq 26), or None."""
    return None if path is None else Prior(read_extrinsic(path), *_prior_weights(weights))


output_options = [
    click.option("-o", "--output", type=click.Path(dir_okay=False), help="Write the result here "
                 "(atomically) instead of stdout; a .json suffix selects JSON."),
    click.option("--format", "fmt", type=click.Choice(FORMATS), help="Output format [default: yaml, "
                 "or json for a .json output file]."),
]
solver_options = [
    click.option("--method", type=click.Choice(METHODS), default="dqopt", show_default=True,
                 help="Solver: dqopt is the global optimum; the others are the paper's approximations "
                 "and Daniilidis' method."),
    click.option("--prior", "prior_file", type=click.Path(), help="Prior extrinsic T_a_b (a handeye result "
                 "or YAML with translation and quaternion_xyzw); fixes directions the motion cannot observe."),
    click.option("--prior-weights", default="1,1", show_default=True,
                 help="Weights a,b of the prior's rotation and translation terms (eq 26)."),
]


def _apply(options: list):
    def decorate(f):
        for option in reversed(options):
            f = option(f)
        return f
    return decorate


@click.group(context_settings=_CONTEXT)
@click.version_option(__version__, "-V", "--version", prog_name="handeye")
@click.option("--debug", is_flag=True, help="Show the full traceback on errors.")
def cli(debug: bool) -> None:
    """Optimal hand-eye / extrinsic calibration between two rigidly attached pose sources.

    The result is T_a_b: the pose of frame b (second stream) in frame a (first stream); it
    maps points from b to a. Quaternions are x-y-z-w.

    \b
    Examples:
      handeye calibrate sample_data/rig.mcap --topic-a /cam0/pose --topic-b /cam1/pose
      handeye inspect sample_data/rig.mcap
      handeye solve sample_data/pairs.csv --method dqopt
    """


@cli.command(context_settings=_CONTEXT)
@click.argument("pairs_file", type=click.Path())
@_apply(solver_options)
@click.option("--alpha", type=float, default=1.0, show_default=True,
              help="Weight of translational residuals [1/m] (eq 8).")
@_apply(output_options)
def solve_cmd(pairs_file: str, method: str, prior_file: str | None, prior_weights: str, alpha: float,
              output: str | None, fmt: str | None) -> None:
    """Solve A_i X = X B_i for X = T_a_b from a file of relative motion pairs.

    PAIRS_FILE is a CSV with the header
    ax,ay,az,aqx,aqy,aqz,aqw,bx,by,bz,bqx,bqy,bqz,bqw[,weight] (one motion pair per row:
    translations in metres, quaternions x-y-z-w), or a .npz with arrays A and B of shape
    (N, 4, 4) and optionally weights (N,).

    \b
    Example:
      handeye solve sample_data/pairs.csv --method dqopt --alpha 1
    """
    A, B, weights = read_pairs(pairs_file)
    sol = solve(A, B, method=method, alpha=alpha, prior=parse_prior(prior_file, prior_weights), weights=weights)
    emit(result_document(sol, inputs={"pairs_file": pairs_file}, samples={"pairs": len(A)}), output, fmt)


solve_cmd.name = "solve"


def _number_or(word: str, value: str | None, option: str) -> float | str | None:
    """A number, or the keyword ``word`` ('auto', 'off') kept as a string so that it overrides the
    config; None when the option was not given."""
    if value is None or value.strip().lower() == word:
        return value and word
    try:
        return float(value)
    except ValueError:
        raise HandEyeError(f"bad value {value!r}", option, f"give a number or '{word}'") from None


def _overrides(o: dict) -> dict:
    """Command-line options → the nested config keys they override (None = not given)."""
    gates = {"max_translation": _number_or("off", o["max_jump"], "--max-jump"),
             "max_rotation_deg": _number_or("off", o["max_jump_deg"], "--max-jump-deg")}
    weights = None if o["prior_weights"] is None else _prior_weights(o["prior_weights"])
    return {
        "time_source": o["time_source"], "invert_a": o["invert_a"], "invert_b": o["invert_b"],
        "name_a": o["name_a"], "name_b": o["name_b"],
        "sync": {"method": o["sync"], "max_dt": o["max_dt"],
                 "time_offset": _number_or("auto", o["time_offset"], "--time-offset")},
        "gates": gates,
        "pairs": {"strategy": o["pairs"], "min_rotation_deg": o["min_rotation"], "max_pairs": o["max_pairs"],
                  "seed": o["seed"]},
        "solver": {"method": o["method"], "alpha": _number_or("auto", o["alpha"], "--alpha"), "prior": o["prior_file"],
                   "prior_weights": weights},
        "analysis": {"robust": o["robust"], "bootstrap": o["bootstrap"], "strict": o["strict"]},
    }


def _gates_off(cfg: dict) -> dict:
    for key in ("max_translation", "max_rotation_deg"):
        if cfg["gates"][key] == "off":
            cfg["gates"][key] = None
    return cfg


def _summary(doc: dict) -> str:
    from scipy.spatial.transform import Rotation

    rotvec = Rotation.from_quat(doc["quaternion_xyzw"]).as_rotvec(degrees=True)
    t = doc["translation"]
    angle = float((rotvec @ rotvec) ** 0.5)
    return (f"T_{doc['frames']['a']}_{doc['frames']['b']}: translation [{t[0]:.4f}, {t[1]:.4f}, {t[2]:.4f}] m, "
            f"rotation {angle:.3f}° (rotvec [{rotvec[0]:.3f}, {rotvec[1]:.3f}, {rotvec[2]:.3f}]°); "
            f"{doc['method']} on {doc['pairs_used']} pairs")


@cli.command(context_settings=_CONTEXT)
@click.argument("inputs", nargs=-1, required=True, type=click.Path())
@click.option("--topic-a", help="Topic of stream a (PoseStamped, PoseWithCovarianceStamped, TransformStamped, "
              "Odometry, TFMessage, Foxglove pose types).")
@click.option("--topic-b", help="Topic of stream b.")
@click.option("--frames-a", nargs=2, metavar="PARENT CHILD", help="Stream a as the TF chain PARENT→CHILD "
              "resolved through /tf and /tf_static.")
@click.option("--frames-b", nargs=2, metavar="PARENT CHILD", help="Stream b as a TF chain.")
@click.option("--invert-a/--no-invert-a", default=None, help="Invert stream a first (it records T_sensor_world, "
              "e.g. a camera observing a target).")
@click.option("--invert-b/--no-invert-b", default=None, help="Invert stream b first.")
@click.option("--name-a", metavar="FRAME", help="Name of frame a in the result and the ROS snippet [default: the "
              "stream's child frame, else its topic].")
@click.option("--name-b", metavar="FRAME", help="Name of frame b in the result.")
@click.option("--time-source", type=click.Choice(["header", "log"]), help="Stamps: header.stamp or log time "
              "[default: header].")
@click.option("--time-offset", metavar="SECONDS|auto", help="How far b's clock is ahead of a's, or 'auto' to "
              "estimate it [default: 0].")
@click.option("--sync", type=click.Choice(["interpolate", "nearest"]), help="Association of b to a's stamps "
              "[default: interpolate].")
@click.option("--max-dt", type=float, help="Timestamp gate [s] [default: 0.1].")
@click.option("--max-jump", metavar="METRES|off", help="Pose-jump gate, translation [default: 0.10].")
@click.option("--max-jump-deg", metavar="DEGREES|off", help="Pose-jump gate, rotation [default: 11.5].")
@click.option("--pairs", metavar="STRATEGY", help="keyframes | consecutive | stride:K | all | random:N "
              "[default: keyframes].")
@click.option("--min-rotation", type=float, help="Least rotation of a pair [deg] [default: 10].")
@click.option("--max-pairs", type=int, help="Cap on the number of pairs [default: 2000].")
@click.option("--seed", type=int, help="Seed for random:N and the bootstrap [default: 0].")
@click.option("--method", type=click.Choice(METHODS), help="Solver [default: dqopt, the global optimum].")
@click.option("--alpha", metavar="NUMBER|auto", help="Weight of translational residuals [1/m] [default: 1].")
@click.option("--prior", "prior_file", type=click.Path(), help="Prior extrinsic file (a handeye result, or YAML "
              "with translation and quaternion_xyzw).")
@click.option("--prior-weights", metavar="A,B", help="Weights of the prior's rotation and translation terms "
              "[default: 1,1].")
@click.option("--robust", is_flag=True, default=None, help="Reject outlier pairs before the final solve.")
@click.option("--bootstrap", type=int, metavar="N", help="Uncertainty from N bootstrap resamples.")
@click.option("--strict", is_flag=True, default=None, help="Exit with code 3 when there are warnings "
              "(degenerate motion, suspect residuals, doubtful time offset).")
@click.option("--report", "report_file", type=click.Path(dir_okay=False), help="Write a self-contained HTML "
              "report (trajectories, residuals, gates, uncertainty, warnings).")
@click.option("--config", "config_file", type=click.Path(), help="YAML configuration (see configs/default.yaml); "
              "options given here override it.")
@_apply(output_options)
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary on stderr.")
def calibrate(inputs: tuple[str, ...], **o) -> None:
    """Calibrate T_a_b from a log (MCAP, ROS 1 bag, ROS 2 bag) or two pose files (TUM, EuRoC, CSV).

    Stream a is the first topic/frame pair/file, stream b the second; T_a_b is the pose of b's
    frame in a's frame. The result goes to stdout (YAML) unless -o is given.

    \b
    Examples:
      handeye calibrate sample_data/rig.mcap --topic-a /cam0/pose --topic-b /cam1/pose
      handeye calibrate log.bag --frames-a world cam0 --frames-b odom imu --time-offset auto
      handeye calibrate a.tum b.tum --method dqopt -o extrinsic.json
      handeye calibrate a.tum b.tum --robust --alpha auto --bootstrap 1000 --report report.html
    """
    from ..pipeline import StreamSpec, calibrate_files

    if len(inputs) > 2:
        raise HandEyeError(f"{len(inputs)} inputs given", " ".join(inputs),
                           "pass one log, or one file per stream (a then b)")
    spec_a = StreamSpec(inputs[0], o["topic_a"], o["frames_a"] or None)
    spec_b = StreamSpec(inputs[-1], o["topic_b"], o["frames_b"] or None)
    if len(inputs) == 1 and not ((o["topic_a"] or o["frames_a"]) and (o["topic_b"] or o["frames_b"])):
        raise HandEyeError("one input needs a topic or a frame pair for each stream", inputs[0],
                           "add --topic-a/--topic-b or --frames-a/--frames-b (see 'handeye inspect "
                           f"{inputs[0]}'), or pass two pose files")
    cfg = _gates_off(load_config(o["config_file"], _overrides(o)))
    result = calibrate_files(spec_a, spec_b, cfg, quiet=o["quiet"])
    doc = result.document()
    if o["report_file"]:
        from ..output.report import write_report

        write_report(o["report_file"], result, doc, result.bootstrap_deviations())
    emit(doc, o["output"], o["fmt"])
    if not o["quiet"]:
        click.echo(_summary(doc), err=True)
    for w in doc["warnings"]:
        click.echo(f"warning: {w}", err=True)
    if doc["warnings"] and cfg["analysis"]["strict"]:
        raise StrictFailure(f"{len(doc['warnings'])} warning(s) under --strict (the result was still written)")


def _inspect_text(info: dict) -> str:
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


@cli.command(context_settings=_CONTEXT)
@click.argument("input_file", type=click.Path())
@click.option("--format", "fmt", type=click.Choice(["text", *FORMATS]), default="text", show_default=True,
              help="Human-readable text, or machine-readable YAML/JSON.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
def inspect(input_file: str, fmt: str, quiet: bool) -> None:
    """List the topics, message types, counts, rates and time span of a log, which topics carry
    poses, and its TF frame tree.

    \b
    Examples:
      handeye inspect sample_data/rig.mcap
      handeye inspect sample_data/rig_ros2 --format json
    """
    from ..io import inspect_log

    info = plain(inspect_log(input_file, quiet=quiet))
    click.echo(_inspect_text(info) if fmt == "text" else render(info, fmt), nl=False)


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``handeye`` script: run the command, map errors to exit codes."""
    args = sys.argv[1:] if argv is None else list(argv)
    debug = "--debug" in args
    try:
        code = cli.main(args=args, prog_name="handeye", standalone_mode=False)
    except HandEyeError as e:
        if debug:
            traceback.print_exc()
        click.echo(f"error: {e}", err=True)
        sys.exit(2)
    except click.ClickException as e:
        if debug:
            traceback.print_exc()
        hint = f" (run '{e.ctx.command_path} --help')" if getattr(e, "ctx", None) else ""
        click.echo(f"error: {e.format_message()}{hint}", err=True)
        sys.exit(e.exit_code)
    except StrictFailure as e:
        click.echo(f"error: {e}", err=True)
        sys.exit(3)
    except click.Abort:
        click.echo("aborted", err=True)
        sys.exit(130)
    sys.exit(code if isinstance(code, int) else 0)


from .batch import batch, report  # noqa: E402
from .check import check  # noqa: E402

for _command in (batch, check, report):
    cli.add_command(_command)
