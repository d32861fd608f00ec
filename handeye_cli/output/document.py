"""The result document (schema in docs/design.md) and its YAML/JSON text.

Keys, in order: ``matrix`` (4x4 ``T_a_b`` row-major: pose of frame b in frame a, maps points
from b to a), ``translation`` [m], ``quaternion_xyzw`` (Hamilton, x-y-z-w, w ≥ 0), ``frames``
``{a, b}``, ``method``, ``alpha`` [1/m], ``cost`` (cost 8, + prior terms), ``pairs_used``,
``samples`` (what each stage read, kept and dropped), ``inputs``, ``version``, ``warnings``,
then diagnostics (e.g. ``solver``, ``residuals``, ``time_offset``, ``uncertainty``) and
``ros2_static_transform`` (a ready command line publishing the extrinsic on /tf_static).
YAML and JSON carry the same content; a non-finite number is null in both (JSON has no NaN).
"""
from __future__ import annotations

import json
import math
import shlex
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np
import yaml

from .._typing import FloatArray
from ..errors import ConfigError
from ..solvers import Solution

if TYPE_CHECKING:
    from ..calibration import Calibration
from ..version import __version__

__all__ = ["FORMATS", "ResultDocument", "calibration_document", "result_document", "render", "plain", "finite",
           "solver_section", "static_transform_command"]

FORMATS = ("yaml", "json")


def plain(value: Any) -> Any:
    """Numpy scalars/arrays and tuples → built-in Python types, recursively (for YAML/JSON)."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


def static_transform_command(t: FloatArray, q: FloatArray, frames: dict[str, str]) -> str:
    """The command line, every word shell-quoted (frame names may come from a log)."""
    names = ("x", "y", "z", "qx", "qy", "qz", "qw")
    nums = " ".join(f"--{k} {float(v)!r}" for k, v in zip(names, [*t, *q], strict=True))   # repr: round-trips
    return (f"ros2 run tf2_ros static_transform_publisher {nums} "
            f"--frame-id {shlex.quote(str(frames.get('a', 'a')))} "
            f"--child-frame-id {shlex.quote(str(frames.get('b', 'b')))}")


def solver_section(solution: Solution, refinement: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The result's ``solver`` block: the multipliers, iterations and convergence the solver reports, its own
    details, and the optimality certificate. For an estimate that minimises no cost (8) (the reduced in-plane
    solve of planar motion, the maximum-likelihood refinement) these are of the optimum it was made from, the
    certificate marked ``of: optimum`` — the global optimum that is certified is that solve's, not the ``matrix``
    written — and ``optimum`` holds that solve's pose and cost (8); ``refined``: the refinement's account
    (:meth:`~handeye_cli.analysis.refinement.Refinement.as_dict`)."""
    source = solution.optimum or solution
    solver: dict[str, Any] = {k: v for k, v in (("lambda", source.lam), ("mu", source.mu),
                                ("iterations", source.iterations), ("converged", source.converged))
                              if v is not None}
    solver.update(source.details)
    if source.certificate is not None:
        solver["certificate"] = {**source.certificate.as_dict(), **({"of": "optimum"} if solution.optimum else {})}
    if solution.optimum is not None:
        solver["optimum"] = {"quaternion_xyzw": plain(source.quaternion_xyzw), "translation": plain(source.translation),
                             "cost": float(source.cost)}
    if refinement is not None:
        solver["refined"] = dict(refinement)
    return solver


class ResultDocument(TypedDict):
    """The keys every result document holds, in schema order, with their plain types (the schema's "Always
    present" table, docs/reference/result-schema.md): ``matrix`` is ``T_a_b`` (4x4, row-major, metres),
    ``quaternion_xyzw`` Hamilton x-y-z-w with w ≥ 0. The diagnostic sections follow ``solver``, before
    ``ros2_static_transform``."""

    matrix: list[list[float]]
    translation: list[float]
    quaternion_xyzw: list[float]
    frames: dict[str, str]
    method: str
    alpha: float
    cost: float
    pairs_used: int
    samples: dict[str, Any]
    inputs: dict[str, Any]
    version: str
    warnings: list[str]
    solver: dict[str, Any]
    ros2_static_transform: str


def result_document(solution: Solution, *, frames: dict[str, str] | None = None,
                    inputs: dict[str, Any] | None = None, samples: dict[str, Any] | None = None,
                    warnings: list[str] | None = None, diagnostics: dict[str, Any] | None = None,
                    refinement: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The result as a plain dict in schema order (see the module docstring): the :class:`ResultDocument`
    keys, built here from the typed solution, with ``diagnostics`` after ``solver`` (``refinement``: its
    ``solver.refined``).

    ``frames`` names frames a and b (default ``{"a": "a", "b": "b"}``); ``samples`` holds the
    per-stage counts; ``diagnostics`` are appended after the required keys.
    """
    frames = dict(frames or {"a": "a", "b": "b"})
    t, q = solution.translation, solution.quaternion_xyzw
    core = ResultDocument(
        matrix=plain(solution.matrix), translation=plain(t), quaternion_xyzw=plain(q), frames=frames,
        method=solution.method, alpha=float(solution.alpha), cost=float(solution.cost), pairs_used=int(solution.pairs),
        samples=plain(samples or {"pairs": solution.pairs}), inputs=plain(inputs or {}), version=__version__,
        warnings=list(warnings or []), solver=plain(solver_section(solution, refinement)),
        ros2_static_transform=static_transform_command(t, q, frames))
    doc: dict[str, Any] = {k: v for k, v in core.items() if k != "ros2_static_transform"}
    doc.update(plain(diagnostics or {}))
    doc["ros2_static_transform"] = core["ros2_static_transform"]
    return doc


def calibration_document(calibration: Calibration) -> dict[str, Any]:
    """The result of a calibration as ``handeye calibrate`` prints it (schema in docs/design.md):
    the solution, frames, inputs, sample counts, warnings, diagnostics and the settings used."""
    return result_document(calibration.solution, frames=calibration.frames, inputs=calibration.inputs.as_dict(),
                           samples=calibration.samples.as_dict(), warnings=calibration.warnings,
                           diagnostics={**calibration.diagnostics, "settings": calibration.settings()},
                           refinement=None if calibration.refinement is None else calibration.refinement.as_dict())


class _Dumper(yaml.SafeDumper):
    """Lists of scalars in flow style (``[x, y, z]``), everything else in block style."""


def _represent_list(dumper: yaml.SafeDumper, data: list[Any]) -> yaml.Node:
    flow = all(not isinstance(v, (list, dict)) for v in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


def _represent_str(dumper: yaml.SafeDumper, data: str) -> yaml.Node:
    """A string with a line break or another unprintable character (names may come from a log) in
    double quotes, where the emitter escapes it: unquoted, U+0085 or U+2028 would read back as a
    line break."""
    return dumper.represent_scalar("tag:yaml.org,2002:str", data, style=None if data.isprintable() else '"')


_Dumper.add_representer(list, _represent_list)
_Dumper.add_representer(str, _represent_str)


def finite(value: Any) -> Any:
    """NaN and infinities → None (null), recursively through dicts and lists: JSON has no NaN
    (``json.loads`` of strict parsers, jq, browsers reject it), and YAML says the same."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite(v) for v in value]
    return value


def render(doc: dict[str, Any], fmt: str = "yaml") -> str:
    """The document as YAML or JSON text (floats at full precision, ``repr`` round-trip; a non-finite
    number — an undefined statistic — is null in both, see :func:`finite`)."""
    if fmt == "json":
        return json.dumps(finite(doc), indent=2, allow_nan=False) + "\n"
    if fmt == "yaml":
        return yaml.dump(finite(doc), Dumper=_Dumper, sort_keys=False, allow_unicode=True, width=10_000)
    raise ConfigError(f"unknown output format {fmt!r}", "fmt", f"use one of {', '.join(FORMATS)}")
