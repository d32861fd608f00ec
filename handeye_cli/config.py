"""Where option values come from: defaults < ``--preset`` < ``--config FILE`` < flags/keywords.

The options themselves (names, defaults, checks) live in :mod:`handeye_cli.options`; this module
reads configuration files — flat YAML mappings whose keys are the option names — and presets,
which are such files shipped inside the package (``handeye_cli/presets/*.yaml``).
``configs/default.yaml`` is generated from the options by :func:`default_yaml`.
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from .errors import ConfigError
from .options import FIELDS, SECTIONS, Options
from .untrusted import load_yaml, yaml_problem

__all__ = ["load_options", "read_config", "presets", "default_yaml"]

_MAX_CONFIG_BYTES = 1 << 20


def presets() -> list[str]:
    """Names of the presets shipped with the package (``--preset NAME``)."""
    folder = resources.files("handeye_cli") / "presets"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def _parse_yaml(text: str, where: str) -> dict[str, Any]:
    try:
        doc = load_yaml(text) or {}
    except yaml.YAMLError as e:
        raise ConfigError(*yaml_problem(e, where), "fix the file (see configs/default.yaml)") from None
    if not isinstance(doc, dict):
        raise ConfigError("a configuration file must hold a mapping of option: value", where,
                          "see configs/default.yaml")
    for key, value in doc.items():
        if key in SECTIONS and isinstance(value, dict):
            raise ConfigError(f"grouped key {key!r}: options are flat now", where,
                              f"write the options of {key!r} at the top level, e.g. gate: off "
                              "(see configs/default.yaml)")
    return doc


def read_config(path: str | Path) -> dict[str, Any]:
    """The option values of a configuration file, by flat name (not yet checked)."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError("configuration file not found", str(p), "check the ⟦config_file⟧ path")
    if p.stat().st_size > _MAX_CONFIG_BYTES:
        raise ConfigError("configuration file larger than 1 MiB", str(p), "pass a configuration, not data")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"cannot read the configuration ({e.__class__.__name__})", str(p), "check the file") from None
    return _parse_yaml(text, str(p))


def _preset(name: str) -> dict[str, Any]:
    if name not in presets():
        raise ConfigError(f"unknown preset {name!r}", "preset", f"choose one of {', '.join(presets())}")
    text = (resources.files("handeye_cli") / "presets" / f"{name}.yaml").read_text(encoding="utf-8")
    return _parse_yaml(text, f"preset {name}")


def load_options(config_file: str | Path | None = None, preset: str | None = None, *,
                 base: Options | None = None, **overrides: Any) -> Options:
    """The options: defaults (or ``base``) < ``preset`` < ``config_file`` < ``overrides``.

    ``overrides`` are flat option names with values as a user writes them (``gate="off"``,
    ``alpha="auto"``, ``time_offset=0.02``); ``None`` means "not given". Every value is checked:
    a bad one raises :class:`~handeye_cli.errors.ConfigError` naming where it came from."""
    opts = base or Options()
    if preset is not None:
        opts = Options.from_flat(opts, f"preset {preset}", **_preset(preset))
    if config_file is not None:
        opts = Options.from_flat(opts, str(config_file), **read_config(config_file))
    given = {k: v for k, v in overrides.items() if v is not None}
    return Options.from_flat(opts, "", **given)


def _yaml_value(value: Any) -> str:
    if value is None:
        return "null"
    return yaml.safe_dump(value, default_flow_style=True).strip().removesuffix("\n...").strip()


def default_yaml() -> str:
    """The text of ``configs/default.yaml``: every option with its default and help, by stage."""
    lines = ["# handeye calibrate: every option with its default (generated from handeye_cli/options.py).",
             "# Pass a file with any subset of these keys as --config FILE; each key is the command-line",
             "# flag without its dashes, and flags given on the command line override the file.",
             "# Gates that can be switched off take 'off'. Units: seconds, metres, degrees."]
    for section, cls in SECTIONS.items():
        lines += ["", f"# {section}: {(cls.__doc__ or '').splitlines()[0]}"]
        for name, (sec, info, default) in FIELDS.items():
            if sec == section:
                lines.append(f"{name}: {_yaml_value(default)}".ljust(30) + f"# {info.help}")
    return "\n".join(lines) + "\n"
