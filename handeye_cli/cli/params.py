"""Click options generated from :mod:`handeye_cli.options`: one flag per option, same name, same help.

Every generated flag defaults to ``None`` ("not given"), so a value from ``--config`` or
``--preset`` is overridden only by a flag the user actually typed; the value is checked by the
option's own parser when the options are loaded, so a file, a flag and a Python keyword are
checked alike.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

from ..config import load_options, presets
from ..errors import ConfigError
from ..options import EVERY_PAIR, FIELDS, Options, optional_flag
from ..output.formats import ALL_FORMATS, SUMMARY_FORMATS

__all__ = ["apply", "command_options", "options_from_cli", "OPTION_NAMES", "per_stream_options", "per_stream_values",
           "stream_options", "stream_values", "STREAM_KEYS", "output_options", "scoped", "quiet_option",
           "report_option", "refused", "refused_report", "refused_quiet", "summary_format"]

F = Callable[..., Any]


def _default_text(default: Any) -> str:
    if default is None:
        return "off"
    if isinstance(default, bool):
        return "on" if default else "off"
    if isinstance(default, tuple):
        return ",".join(f"{v:g}" for v in default)
    return f"{default:g}" if isinstance(default, float) else str(default)


def _flag(name: str) -> Callable[[F], F]:
    _, info, default = FIELDS[name]
    dashed = "--" + name.replace("_", "-")
    given = "[default:" in info.help         # the help says what the default is in words (--name-a)
    help_text = info.help if given else f"{info.help} [default: {_default_text(default)}]"
    if isinstance(default, bool) or info.parse is optional_flag:
        return click.option(f"{dashed}/--no-{dashed[2:]}", name, default=None, help=help_text)
    kind = click.Choice(info.choices, case_sensitive=False) if info.choices else click.STRING
    if info.secret:     # repeatable; never shown back (its default is "none")
        return click.option(dashed, name, type=kind, multiple=True, metavar=info.metavar, help=info.help)
    return click.option(dashed, name, type=kind, default=None, metavar=info.metavar, help=help_text)


OPTION_NAMES = tuple(FIELDS)


def apply(*decorators: Callable[[F], F]) -> Callable[[F], F]:
    """One decorator applying ``decorators`` so that the options show in the order given."""
    def decorate(f: F) -> F:
        for option in reversed(decorators):
            f = option(f)
        return f
    return decorate


def scoped(command: str) -> tuple[str, ...]:
    """The options ``command`` takes as flags of their own names: those whose scope names it (options.py)."""
    return tuple(name for name, (_, info, _) in FIELDS.items() if command in info.commands)


def command_options(command: str) -> Callable[[F], F]:
    """The flags of every option in ``command``'s scope, in the options' order; a command that calibrates
    pairs of streams also takes ``--config`` and ``--preset``."""
    extra = [] if command not in EVERY_PAIR else [
        click.option("--config", "config_file", type=click.Path(), help="YAML file of options (see "
                     "configs/default.yaml); flags given here override it."),
        click.option("--preset", type=click.Choice(presets()), help="Options for a kind of capture, shipped with "
                     "handeye (robot-arm: stations, gate off, all pairs); --config and flags override it.")]
    return apply(*(_flag(name) for name in scoped(command)), *extra)


def _per_stream(form: str, names: list[str]) -> list[Callable[[F], F]]:
    """``handeye rig``'s flags of the stream-a/b options whose per-stream form is ``form``: a yes/no option is
    ``--FORM NAME`` and ``--no-FORM NAME`` (the user says: not so), any other ``--FORM NAME=VALUE`` or, for every
    stream but the reference, ``--FORM VALUE``; each repeatable."""
    _, info, default = FIELDS[names[0]]
    dashed = "--" + form.replace("_", "-")
    what = info.help.split(" [")[0].split("; ")[0].split(" (")[0].rstrip(".")
    for a, b in (("Stream a's", "The stream's"), ("stream a", "the stream"), ("stream b's", "the stream's"),
                 ("b's clock is ahead of a's", "the stream's clock is ahead of the reference's")):
        what = what.replace(a, b)
    ab = "/".join("--" + n.replace("_", "-") for n in names)
    if info.parse is optional_flag:
        return [click.option(dashed, f"{form}_names", multiple=True, metavar="NAME",
                             help=f"calibrate's {ab} for stream NAME: {what}. Repeatable."),
                click.option(f"--no-{dashed[2:]}", f"no_{form}_names", multiple=True, metavar="NAME",
                             help=f"calibrate's --no-{dashed[2:]}-a/-b for stream NAME: the user says it is not "
                             "so. Repeatable.")]
    meta = (info.metavar or "VALUE")
    return [click.option(dashed, f"{form}_values", multiple=True, metavar=f"[NAME=]{meta}",
                         help=f"calibrate's {ab} for stream NAME, same values: {what}; without NAME=, every "
                         f"stream but the reference. Repeatable [default: {_default_text(default)}].")]


def per_stream_forms() -> dict[str, list[str]]:
    """Per-stream form → the options (of stream a, b) it stands for, e.g. ``invert`` → invert_a, invert_b;
    ``name`` is the NAME of ``--stream NAME=SOURCE`` and has no flag of its own."""
    forms: dict[str, list[str]] = {}
    for name, (_, info, _) in FIELDS.items():
        if info.per_stream:
            forms.setdefault(info.per_stream, []).append(name)
    return forms


per_stream_options = apply(*(option for form, names in per_stream_forms().items() if form != "name"
                             for option in _per_stream(form, names)))


def per_stream_values(params: dict[str, Any], form: str) -> dict[str, Any]:
    """``--FORM [NAME=]VALUE`` values as ``{NAME: VALUE}`` (``""`` for the bare form: every stream but the
    reference), or for a yes/no form ``{NAME: True/False}`` from ``--FORM NAME`` / ``--no-FORM NAME``; removed
    from ``params``. A value is checked by the option's parser where the rig's options are built."""
    if f"{form}_names" in params:
        out = {name: True for name in params.pop(f"{form}_names")}
        for name in params.pop(f"no_{form}_names"):
            if out.get(name):
                raise ConfigError(f"stream {name!r} is given both --{form} and --no-{form}", f"--no-{form} {name}",
                                  "keep one of the two")
            out[name] = False
        return out
    values: dict[str, Any] = {}
    for text in params.pop(f"{form}_values"):
        name, sep, value = text.rpartition("=")
        values[name.strip() if sep else ""] = value.strip()
    return values


def refused(decls: tuple[str, ...], what: str, why: str, *, is_flag: bool = False) -> Callable[[F], F]:
    """A flag a command does not take although others do, refused as one line: ``what`` the command does not
    do and ``why`` (what to run instead). Hidden from --help, so that a flag means one thing everywhere, or a
    clear no — never click's bare "No such option"."""
    def refuse(ctx: click.Context, param: click.Parameter, value: Any) -> None:
        if value:
            raise ConfigError(f"{ctx.command_path} {what}", decls[0], why)
    return click.option(*decls, is_flag=is_flag, expose_value=False, callback=refuse, hidden=True)


def refused_report(why: str) -> Callable[[F], F]:
    """``--report`` where a command has no page to write (a report of this run everywhere else)."""
    return refused(("--report",), "writes no report", why)


def refused_quiet(why: str) -> Callable[[F], F]:
    """``-q/--quiet`` where a command prints nothing to quiet."""
    return refused(("-q", "--quiet"), "has nothing to quiet", why, is_flag=True)


def summary_format(what: str) -> Callable[[F], F]:
    """``--format text|yaml|json`` of a command printing a summary (``what``), not a result file."""
    return click.option("--format", "fmt", type=click.Choice(SUMMARY_FORMATS), help=f"{what} [default: text, "
                        "or from the -o name (.yaml .yml .json)].")


quiet_option = click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary on stderr "
                            "(the result and errors are still written).")
report_option = click.option("--report", "report_file", metavar="FILE", help="Also write a self-contained HTML "
                             "report of this run: calibrate and compare the log's trajectories, residuals, gates, "
                             "uncertainty and warnings; rig the joint extrinsics, clock offsets and each pair's "
                             "residuals and fit; batch the fleet trend of its records.")


def options_from_cli(params: dict[str, Any]) -> Options:
    """The options a command line gives: defaults < --preset < --config < flags.
    Removes the option keys from ``params``, leaving the command's own."""
    given = {name: params.pop(name) for name in OPTION_NAMES if name in params}
    given = {name: value for name, value in given.items() if value != ()}     # a repeatable flag not given
    return load_options(params.pop("config_file", None), params.pop("preset", None), **given)


#: the flags naming streams a and b (the shared spelling and its two synonyms), as ``io.spec.stream_source`` takes them
STREAM_KEYS = ("stream_a", "stream_b", "topic_a", "topic_b", "frames_a", "frames_b")


def stream_values(params: dict[str, Any]) -> dict[str, Any]:
    """The stream flags of ``params`` (removed from it) as keywords of ``calibration.stream_specs`` (None: unset)."""
    return {key: params.pop(key) or None for key in STREAM_KEYS}


stream_options = apply(
    click.option("--stream-a", metavar="SOURCE", help="Stream a, as every command names a stream: /topic (a pose "
                 "topic of the log), tf:PARENT,CHILD (the TF chain PARENT→CHILD through /tf and /tf_static, the parent "
                 "first, e.g. tf:odom,base_link) or FILE (a pose file of its own: TUM, EuRoC, CSV)."),
    click.option("--stream-b", metavar="SOURCE", help="Stream b: /topic, tf:PARENT,CHILD or FILE."),
    click.option("--topic-a", help="Stream a's topic (PoseStamped, PoseWithCovarianceStamped, TransformStamped, "
                 "Odometry, TFMessage, Foxglove pose types): --stream-a /topic, for a topic of any name."),
    click.option("--topic-b", help="Stream b's topic."),
    click.option("--frames-a", nargs=2, metavar="PARENT CHILD", help="Stream a as the TF chain PARENT→CHILD: "
                 "--stream-a tf:PARENT,CHILD (the parent first, e.g. odom base_link)."),
    click.option("--frames-b", nargs=2, metavar="PARENT CHILD", help="Stream b as the TF chain PARENT→CHILD."),
)

output_options = apply(
    click.option("-o", "--output", metavar="FILE", help="Write the result here instead of stdout ('-': stdout); "
                 "a regular file is replaced atomically; .json selects JSON, .yaml/.yml YAML."),
    click.option("--format", "fmt", type=click.Choice(ALL_FORMATS), help="Output format: the result as YAML/JSON, "
                 "or the extrinsic as a URDF (urdf: a whole <robot>; urdf-joint: the <joint> alone, to paste into "
                 "a robot's URDF), a ROS 1/2 launch file, a static_transform_publisher line or Kalibr YAML "
                 "[default: from the -o name (.yaml .json .urdf .launch .launch.py .sh), else yaml]."),
)
