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
from ..options import FIELDS, Options, optional_flag
from ..output.formats import ALL_FORMATS

__all__ = ["apply", "flags", "calibrate_options", "options_from_cli", "OPTION_NAMES", "stream_options",
           "output_options"]

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


def flags(*names: str) -> Callable[[F], F]:
    """The flags of the named options only (e.g. for ``handeye solve``)."""
    return apply(*(_flag(name) for name in names))


calibrate_options = apply(
    flags(*OPTION_NAMES),
    click.option("--config", "config_file", type=click.Path(), help="YAML file of options (see "
                 "configs/default.yaml); flags given here override it."),
    click.option("--preset", type=click.Choice(presets()), help="Options for a kind of capture, shipped with "
                 "handeye (robot-arm: stations, gate off, all pairs); --config and flags override it."),
)


def options_from_cli(params: dict[str, Any]) -> Options:
    """The options a command line gives: defaults < --preset < --config < flags.
    Removes the option keys from ``params``, leaving the command's own."""
    given = {name: params.pop(name) for name in OPTION_NAMES if name in params}
    given = {name: value for name, value in given.items() if value != ()}     # a repeatable flag not given
    return load_options(params.pop("config_file", None), params.pop("preset", None), **given)


def _frame_pair(ctx: click.Context, param: click.Parameter, value: tuple[str, str] | None
                ) -> tuple[str, str] | None:
    """``--frames-a PARENT CHILD``: two frame names; a flag taken as a frame (``--frames-a base_link --topic-b
    …``: click gives ``--topic-b`` as CHILD) is refused naming the flag and what it takes."""
    flag = param.opts[0]
    for role, name in zip(("PARENT", "CHILD"), value or (), strict=False):
        if name.startswith("-"):
            raise ConfigError(f"{flag} takes two frame names, PARENT CHILD; got {name!r} as {role}", flag,
                              f"give both frames, the parent first, e.g. {flag} odom base_link")
    return value


stream_options = apply(
    click.option("--topic-a", help="Topic of stream a (PoseStamped, PoseWithCovarianceStamped, TransformStamped, "
                 "Odometry, TFMessage, Foxglove pose types)."),
    click.option("--topic-b", help="Topic of stream b."),
    click.option("--frames-a", nargs=2, metavar="PARENT CHILD", callback=_frame_pair, help="Stream a as the TF "
                 "chain PARENT→CHILD resolved through /tf and /tf_static (the parent first, e.g. odom base_link)."),
    click.option("--frames-b", nargs=2, metavar="PARENT CHILD", callback=_frame_pair,
                 help="Stream b as a TF chain PARENT CHILD."),
)

output_options = apply(
    click.option("-o", "--output", metavar="FILE", help="Write the result here instead of stdout ('-': stdout); "
                 "a regular file is replaced atomically; .json selects JSON, .yaml/.yml YAML."),
    click.option("--format", "fmt", type=click.Choice(ALL_FORMATS), help="Output format: the result as YAML/JSON, "
                 "or the extrinsic as a URDF joint, a ROS 1/2 launch file, a static_transform_publisher line or "
                 "Kalibr YAML [default: from the -o name (.yaml .json .urdf .launch .launch.py .sh), else yaml]."),
)
