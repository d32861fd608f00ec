"""Configuration of ``handeye calibrate``: defaults, YAML files and command-line overrides.

``DEFAULTS`` is the single source of the defaults; ``configs/default.yaml`` documents every key
(a test keeps the two identical). Precedence: defaults < ``--config FILE`` < command-line options.
"""
from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import yaml

from .errors import HandEyeError

__all__ = ["DEFAULTS", "load_config", "merge"]

DEFAULTS: dict[str, Any] = {
    "time_source": "header",
    "invert_a": False,
    "invert_b": False,
    "name_a": None,
    "name_b": None,
    "csv_columns": None,
    "sync": {"method": "interpolate", "max_dt": 0.1, "time_offset": 0.0, "max_time_offset": None},
    "gates": {"max_translation": 0.10, "max_rotation_deg": 11.5},
    "pairs": {"strategy": "keyframes", "keyframe_rotation_deg": 5.0, "keyframe_translation": 0.02,
              "min_rotation_deg": 10.0, "max_pairs": 2000, "seed": 0},
    "solver": {"method": "dqopt", "alpha": 1.0, "prior": None, "prior_weights": [1.0, 1.0], "min_pairs": 3},
    "analysis": {"robust": False, "bootstrap": 0, "strict": False},
}


def merge(base: dict, override: dict, where: str) -> dict:
    """``base`` updated by ``override`` (nested); unknown keys raise a HandEyeError naming them."""
    out = copy.deepcopy(base)
    for key, value in override.items():
        if key not in base:
            raise HandEyeError(f"unknown configuration key {key!r}", where,
                               f"valid keys here: {', '.join(base)} (see configs/default.yaml)")
        if isinstance(base[key], dict) and base[key] and key != "csv_columns":
            if not isinstance(value, dict):
                raise HandEyeError(f"configuration key {key!r} must be a mapping", where,
                                   "see configs/default.yaml")
            out[key] = merge(base[key], value, f"{where}: {key}")
        else:
            out[key] = value
    return out


def load_config(path: str | Path | None = None, overrides: dict | None = None) -> dict:
    """Defaults, updated by the YAML file ``path`` (optional), then by ``overrides`` (nested dict
    of the values given on the command line; ``None`` values are ignored)."""
    cfg = copy.deepcopy(DEFAULTS)
    if path is not None:
        p = Path(path)
        if not p.is_file():
            raise HandEyeError("configuration file not found", str(p), "check the --config path")
        try:
            doc = yaml.safe_load(p.read_text(encoding="utf-8")) or {}
        except yaml.YAMLError as e:
            mark = getattr(e, "problem_mark", None)
            where = f"{p}:{mark.line + 1}" if mark else str(p)
            raise HandEyeError("invalid YAML", where, "fix the syntax (see configs/default.yaml)") from None
        if not isinstance(doc, dict):
            raise HandEyeError("a configuration file must hold a mapping", str(p), "see configs/default.yaml")
        cfg = merge(cfg, doc, str(p))
    if overrides:
        cfg = merge(cfg, _drop_none(overrides), "command line")
    return cfg


def _drop_none(d: dict) -> dict:
    return {k: (_drop_none(v) if isinstance(v, dict) else v) for k, v in d.items()
            if v is not None and not (isinstance(v, dict) and not _drop_none(v))}
