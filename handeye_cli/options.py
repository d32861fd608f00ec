"""Every option of ``handeye calibrate``: its name, default, unit, check and help — in one place.

The options are frozen dataclasses, one per pipeline stage (:class:`ReadOptions`,
:class:`SyncOptions`, :class:`GateOptions`, :class:`PairOptions`, :class:`SolverOptions`,
:class:`AnalysisOptions`, :class:`OutputOptions`), gathered in :class:`Options`. A field has one
name everywhere: the command-line flag without its dashes (``--max-jump`` is ``max_jump``), the
key of a configuration file, and the keyword argument of :func:`handeye_cli.calibrate_files`.

Units: seconds, metres, degrees, as each field's help says. Gates that can be switched off take
``None``, which files and flags spell ``off`` (YAML's ``off``/``false``/``null`` all mean off).

Examples
--------
>>> opts = Options.from_flat(gate="paper", max_jump="off", alpha="auto", pairs="stride:30")
>>> opts.gates.max_jump is None, opts.solver.alpha, opts.pairs.pairs
(True, 'auto', 'stride:30')
>>> Options.from_flat(max_jump=0.3)          # a limit of the paper gate, under the default gate auto
Traceback (most recent call last):
...
handeye_cli.errors.ConfigError: a pose-jump limit is given, but ... gate auto ignores it (max_jump): ...
>>> Options.from_flat(max_dt="fast")
Traceback (most recent call last):
...
handeye_cli.errors.ConfigError: bad value 'fast' (max_dt): give a number of seconds > 0, or 'auto'
"""
from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any

from .errors import ConfigError
from .solvers import METHODS, OPTIMAL
from .untrusted import REMOTE_DEADLINE_S, REMOTE_RETRIES, REMOTE_TIMEOUT_S, frame_id_problem

__all__ = ["Options", "ReadOptions", "SyncOptions", "GateOptions", "PairOptions", "SolverOptions",
           "AnalysisOptions", "OutputOptions", "SECTIONS", "FIELDS", "OptionInfo"]

Parser = Callable[[Any, str], Any]
_OFF_WORDS = ("off", "none", "null", "no", "false")


def _words(value: Any) -> str | None:
    return value.strip().lower() if isinstance(value, str) else None


def number(*, unit: str, low: float = 0.0, strict: bool = True, word: str | tuple[str, ...] | None = None) -> Parser:
    """Parser of a real number ≥/> ``low``; ``word`` ('off' or 'auto', or both as a tuple) is also accepted.

    'off' (and YAML's false/null) becomes None; 'auto' stays the string 'auto'."""
    words = (word,) if isinstance(word, str) else word or ()

    def parse(value: Any, where: str) -> float | str | None:
        if "off" in words and (value is None or value is False or _words(value) in _OFF_WORDS):
            return None
        if "auto" in words and _words(value) == "auto":
            return "auto"
        if not isinstance(value, bool):
            try:
                x = float(value)
            except (TypeError, ValueError):
                x = math.nan
            if math.isfinite(x) and (x > low if strict else x >= low):
                return x
        rel = ">" if strict else "≥"
        alt = "".join(f", or '{w}'" for w in words)
        raise ConfigError(f"bad value {value!r}", where, f"give a number of {unit} {rel} {low:g}{alt}")
    return parse


def real(*, unit: str, word: str | None = None) -> Parser:
    """Parser of any finite real number (e.g. a signed time offset), or ``word``."""
    def parse(value: Any, where: str) -> float | str:
        if word and _words(value) == word:
            return word
        try:
            x = float(value)
        except (TypeError, ValueError):
            x = math.nan
        if isinstance(value, bool) or not math.isfinite(x):
            alt = f", or '{word}'" if word else ""
            raise ConfigError(f"bad value {value!r}", where, f"give a finite number of {unit}{alt}")
        return x
    return parse


def integer(*, low: int = 0) -> Parser:
    def parse(value: Any, where: str) -> int:
        if isinstance(value, bool):
            value = "bool"
        try:
            x = int(str(value).strip())
        except ValueError:
            x = low - 1
        if x < low:
            raise ConfigError(f"bad value {value!r}", where, f"give a whole number ≥ {low}")
        return x
    return parse


def choice(*names: str) -> Parser:
    """Parser of one of ``names`` (case-insensitive); the names also become the flag's click.Choice."""
    def parse(value: Any, where: str) -> str:
        word = "off" if value is False and "off" in names else _words(value)     # YAML reads `off` as false
        if word not in names:
            raise ConfigError(f"bad value {value!r}", where, f"choose one of {', '.join(names)}")
        return word
    parse.names = names          # type: ignore[attr-defined]  # read by option() for the click.Choice
    return parse


def flag(value: Any, where: str) -> bool:
    """A yes/no option (YAML true/false)."""
    if isinstance(value, bool):
        return value
    word = _words(value)
    if word in ("true", "yes", "on", "1"):
        return True
    if word in ("false", "no", "off", "0"):
        return False
    raise ConfigError(f"bad value {value!r}", where, "give true or false")


def optional_flag(value: Any, where: str) -> bool | None:
    """A yes/no option that may be left unset (None: the user did not choose)."""
    return None if value is None else flag(value, where)


def frame_name(value: Any, where: str) -> str | None:
    """A frame id by the rule of :func:`handeye_cli.untrusted.frame_id_problem` (tf2's: no whitespace,
    control characters or quotes); a leading '/' of ROS 1 style is dropped (tf2 ids cannot start with one)."""
    if value is None:
        return None
    name = str(value).strip().lstrip("/")
    problem = frame_id_problem(name)
    if problem:
        raise ConfigError(f"bad frame name {value!r}: {problem}", where,
                          "use letters, digits, '_', '.', '/' or '-', e.g. camera_link")
    return name


def path(value: Any, where: str) -> str | None:
    if value is None:
        return None
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"bad path {value!r}", where, "give a file name")
    return value


def weight_pair(value: Any, where: str) -> tuple[float, float]:
    """Two non-negative numbers: a list ``[a, b]`` or the text ``a,b``."""
    items = value.split(",") if isinstance(value, str) else value
    try:
        a, b = (float(v) for v in items)
        ok = all(math.isfinite(v) and v >= 0 for v in (a, b)) and not any(isinstance(v, bool) for v in items)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ConfigError(f"bad weights {value!r}", where, "give two non-negative numbers a,b, e.g. 1,1")
    return a, b


_STRATEGY = re.compile(r"^(auto|keyframes|consecutive|all|stride:[1-9][0-9]*|random:[1-9][0-9]*)$")


def strategy(value: Any, where: str) -> str:
    word = _words(value) or ""
    if not _STRATEGY.match(word):
        raise ConfigError(f"bad pair strategy {value!r}", where,
                          "choose auto, keyframes, consecutive, all, stride:K or random:N (K, N whole numbers ≥ 1)")
    return word


_CSV_KEYS = ("t", "t_unit", "x", "y", "z", "qx", "qy", "qz", "qw")


def columns(value: Any, where: str) -> Mapping[str, str] | None:
    """Generic CSV column names: a mapping, or the text ``t=time,x=px,…`` (keys t, t_unit, x…qw)."""
    if value is None:
        return None
    if isinstance(value, str):
        try:
            value = dict(item.split("=", 1) for item in value.split(",") if item.strip())
        except ValueError:
            raise ConfigError(f"bad column mapping {value!r}", where, "write KEY=COLUMN,… e.g. t=time,x=px") from None
    if not isinstance(value, Mapping) or not value:
        raise ConfigError(f"bad column mapping {value!r}", where, f"map keys of {', '.join(_CSV_KEYS)} to columns")
    unknown = sorted(set(map(str, value)) - set(_CSV_KEYS))
    if unknown:
        raise ConfigError(f"unknown CSV key(s) {', '.join(unknown)}", where, f"use {', '.join(_CSV_KEYS)}")
    return {str(k).strip(): str(v).strip() for k, v in value.items()}


def storage_options(value: Any, where: str) -> tuple[tuple[str, str], ...]:
    """fsspec storage options: ``KEY=VALUE`` texts (one, or a list: the flag is repeatable) or a mapping,
    as (key, value) pairs. The values may be credentials: no message repeats them."""
    if value is None or value == ():
        return ()
    if isinstance(value, Mapping):
        items = [(str(k), str(v)) for k, v in value.items()]
    else:
        texts = [value] if isinstance(value, str) else list(value)
        items = []
        for text in texts:
            key, eq, val = str(text).partition("=")
            if not eq or not key.strip():
                raise ConfigError("bad storage option (its value is not shown: it may be a credential)", where,
                                  "write KEY=VALUE, e.g. ⟦storage_option='endpoint_url=http://127.0.0.1:9000'⟧")
            items.append((key.strip(), val))
    return tuple(items)


# Which commands take an option (its scope): the commands' flags are generated from it (handeye_cli/cli/params.py).
PAIR = ("calibrate", "batch", "compare")        # the options of one pair of streams a, b
EVERY_PAIR = (*PAIR, "rig")                      # ... that also apply to every pair of a rig
REMOTE = (*EVERY_PAIR, "inspect")                # reading URLs
SOLVER = (*EVERY_PAIR, "solve")                  # the solver on pairs (also handeye solve's file of pairs)


@dataclass(frozen=True)
class OptionInfo:
    """How an option is parsed and shown: its parser, help text and command-line metavar; a
    ``secret`` option's values are shown as ``***`` in settings (:meth:`Options.flat`), and its flag repeats.

    ``commands``: the commands that take it as a flag of its own name (its scope). ``per_stream``: the
    flag by which ``handeye rig`` takes an option of stream a or b for any named stream (``invert_a`` →
    ``--invert NAME``/``--no-invert NAME``, ``scale`` → ``--scale NAME=VALUE``), parsed by the same parser."""

    parse: Parser
    help: str
    metavar: str | None = None
    choices: tuple[str, ...] = ()
    secret: bool = False
    commands: tuple[str, ...] = EVERY_PAIR
    per_stream: str | None = None


def option(default: Any, parse: Parser, help: str, metavar: str | None = None, secret: bool = False, *,
           commands: tuple[str, ...] = EVERY_PAIR, per_stream: str | None = None) -> Any:
    """A dataclass field carrying its :class:`OptionInfo` (a :func:`choice` parser gives the choices)."""
    info = OptionInfo(parse, help, metavar, tuple(getattr(parse, "names", ())), secret, commands, per_stream)
    return field(default=default, metadata={"info": info})


@dataclass(frozen=True)
class ReadOptions:
    """How the streams are read: time stamps, and streams recorded as ``T_sensor_world``."""

    time_source: str = option("header", choice("header", "log"),
                              "Stamps: header (header.stamp) or log (the recorder's log time).")
    invert_a: bool | None = option(None, optional_flag, "Invert stream a first: it records T_sensor_world (e.g. "
                                   "a camera observing a fixed target). Unset: not inverted, and a stream that "
                                   "clearly fits only inverted refuses the result.", commands=PAIR, per_stream="invert")
    invert_b: bool | None = option(None, optional_flag, "Invert stream b first.", commands=PAIR, per_stream="invert")
    wxyz_a: bool | None = option(None, optional_flag, "Stream a's text file stores quaternions w first: w x y z "
                                 "(--no-wxyz-a: x y z w). Unset: the format's order (TUM and CSV x y z w, EuRoC "
                                 "w first), unless the other fits decisively better (the result's interpretation).",
                                 commands=PAIR, per_stream="wxyz")
    wxyz_b: bool | None = option(None, optional_flag, "Stream b's text file stores quaternions w first.",
                                 commands=PAIR, per_stream="wxyz")
    time_unit: str = option("auto", choice("auto", "s", "ms", "us", "ns"), "Unit of the stamps in TUM/CSV files: "
                            "auto picks epoch stamps by magnitude; time since start is seconds in TUM (as the "
                            "format defines) and read by the median step in a CSV, with a warning.")
    csv_columns: Mapping[str, str] | None = option(None, columns, "Generic CSV columns: t=COL,x=COL,…,qw=COL "
                                                   "(keys t, t_unit, x, y, z, qx, qy, qz, qw).", "KEY=COL,…")
    storage_option: tuple[tuple[str, str], ...] = option(
        (), storage_options, "For inputs given as URLs (s3://, gs://, https://): a keyword of the fsspec file "
        "system, KEY=VALUE, repeatable (e.g. endpoint_url=…, profile=…, anon=true). Credentials otherwise come "
        "from the environment (AWS_ENDPOINT_URL, AWS_ACCESS_KEY_ID, AWS_PROFILE …); none is ever printed.",
        "KEY=VALUE", secret=True, commands=REMOTE)
    remote_timeout: float = option(REMOTE_TIMEOUT_S, number(unit="seconds"), "For URL inputs: how long one "
                                   "request may take [s] before it is tried again.", "SECONDS", commands=REMOTE)
    remote_retries: int = option(REMOTE_RETRIES, integer(low=1), "For URL inputs: how many times a request is "
                                 "tried before the input fails.", "N", commands=REMOTE)
    remote_deadline: float = option(REMOTE_DEADLINE_S, number(unit="seconds"), "For URL inputs: how long one object "
                                    "may go without an answered request [s] (the clock starts with the first try "
                                    "after its last answer) before the input fails, whatever the timeout and "
                                    "retries allow.", "SECONDS", commands=REMOTE)


@dataclass(frozen=True)
class SyncOptions:
    """Association of the two streams in time (paper §5: timestamp gate)."""

    sync: str = option("auto", choice("auto", "interpolate", "nearest"),
                       "Association: auto (the faster stream interpolated at the slower one's stamps), interpolate "
                       "(b at a's stamps, linear + SLERP) or nearest (b's closest sample to a's stamps).")
    max_dt: float | str = option("auto", number(unit="seconds", word="auto"),
                                 "Timestamp gate [s]: a sample is kept only if the interpolated stream's samples it "
                                 "uses are this close; auto: max(0.1 s, 2.5 median steps of that stream).",
                                 "SECONDS|auto")
    time_offset: float | str = option("auto", real(unit="seconds", word="auto"),
                                      "How far b's clock is ahead of a's [s]; auto: estimated from the angular "
                                      "velocities and applied when it is significant against its own uncertainty "
                                      "(else 0; both reported in the result's time_offset); 0 forces none.",
                                      "SECONDS|auto", commands=PAIR, per_stream="time_offset")
    max_time_offset: float | str | None = option(
        "auto", number(unit="seconds", word=("auto", "off")),
        "With --time-offset auto (the default), search only clock offsets within ±this [s]; auto: within the "
        "shorter stream's span (a larger offset only when given here); off: any lag.", "SECONDS|auto|off")

    @property
    def max_dt_ns(self) -> int | None:
        """The timestamp gate [ns], or None for the default that follows the interpolated stream's rate."""
        return None if self.max_dt == "auto" else int(round(float(self.max_dt) * 1e9))


@dataclass(frozen=True)
class GateOptions:
    """The pose-jump gate: drops the samples of tracking failures (see handeye_cli/stages/gates.py)."""

    gate: str = option("auto", choice("auto", "paper", "off"),
                       "Pose-jump gate: auto (a and b must move alike, at any rate), paper (the paper's per-step "
                       "limits --max-jump/--max-jump-deg, meant for ~5 Hz streams) or off.")
    max_jump: float | None = option(0.10, number(unit="metres", word="off"), "Limit of --gate paper: translation [m] "
                                    "between consecutive samples, or off (with --max-jump-deg off: no gate).",
                                    "METRES|off")
    max_jump_deg: float | None = option(11.5, number(unit="degrees", word="off"),
                                        "Limit of --gate paper: rotation [deg], or off.", "DEGREES|off")

    @property
    def max_jump_rad(self) -> float | None:
        """The paper gate's rotation limit [rad], or None."""
        return None if self.max_jump_deg is None else math.radians(self.max_jump_deg)


@dataclass(frozen=True)
class PairOptions:
    """Which relative motions (pairs of samples) are solved."""

    pairs: str = option("auto", strategy, "Pair strategy: auto (spans and weights from a noise model fitted to "
                        "the recording) | keyframes | consecutive | stride:K | all | random:N.", "STRATEGY")
    min_rotation: float = option(10.0, number(unit="degrees", strict=False),
                                 "Least rotation of a pair [deg] (keyframes, all, random).", "DEGREES")
    keyframe_rotation: float = option(5.0, number(unit="degrees"),
                                      "A new keyframe once either sensor rotated this much [deg].", "DEGREES")
    keyframe_translation: float = option(0.02, number(unit="metres"),
                                         "... or moved this far [m].", "METRES")
    max_pairs: int = option(2000, integer(low=1), "Cap on the number of pairs, spread over the recording.", "N")
    stations: str = option("auto", choice("auto", "off"), "Station captures (sparse poses, or dwells of both "
                           "sensors): auto detects them and pairs the averaged stations all with all, without the "
                           "pose-jump gate; off treats every capture as continuous tracking.")
    seed: int = option(0, integer(), "Seed of random:N, of --robust's sampling and of the bootstrap.", "N",
                       commands=SOLVER)


@dataclass(frozen=True)
class SolverOptions:
    """The solver and its cost (paper eqs 8, 26)."""

    method: str = option("dqopt", choice(*METHODS), "Solver: dqopt is the global optimum (paper §3.2.1); dq2steps, "
                         "dqconvrlx, dq2ndord and dqitr the paper's approximations; daniilidis the dual-quaternion "
                         "SVD; tsai, park, horaud and andreff the classical methods (rotation, then translation).",
                         commands=SOLVER)
    alpha: float | str = option("auto", number(unit="1/m", word="auto"),
                                "Weight of translational residuals [1/m] (eq 8), or auto (maximum likelihood "
                                "under the recording's noise model).", "NUMBER|auto", commands=SOLVER)
    scale: float | str = option(1.0, number(unit="metres per unit of stream b", word="auto"),
                                "Scale of stream b's translations [m per unit] (monocular odometry), or auto to "
                                "estimate it with T_a_b.", "NUMBER|auto", commands=PAIR, per_stream="scale")
    prior: str | None = option(None, path, "Nominal T_a_b (a URDF, launch file, static_transform_publisher "
                               "line, Kalibr YAML or handeye result; frames a, b as the result names them): fixes "
                               "what the motion cannot observe. In handeye rig the nominal of every sensor, its "
                               "frames named as the streams (as --against reads it): each pair j, k takes "
                               "T_j_k from it.", "FILE", commands=SOLVER)
    prior_weights: tuple[float, float] = option((1.0, 1.0), weight_pair,
                                                "Weights a,b of the prior's rotation and translation terms.", "A,B",
                                                commands=SOLVER)
    min_pairs: int = option(3, integer(low=2), "Fewer motion pairs than this is an error.", "N")
    refine: bool = option(False, flag, "Refine dqopt's (or dqitr's) certified optimum of cost (8) to the maximum "
                          "likelihood of the samples, under a noise model fitted to them (solver.refined; "
                          "solver.optimum keeps the optimum and its certificate).", commands=EVERY_PAIR)


@dataclass(frozen=True)
class AnalysisOptions:
    """What is checked after the solve."""

    robust: bool = option(False, flag, "Reject outlier pairs before the final solve.", commands=SOLVER)
    bootstrap: int = option(0, integer(), "Uncertainty from N bootstrap resamples (0: off).", "N", commands=SOLVER)
    strict: bool = option(False, flag, "Exit with code 3 when there are warnings (degenerate motion, suspect "
                          "residuals, doubtful time offset).")
    accept_poor_fit: bool = option(False, flag, "Keep a result that fails the fit test (residuals far beyond "
                                   "what the streams' own noise predicts for a rigid rig): it is written with a "
                                   "warning and the command exits with code 3, instead of refusing it (exit 2).")


@dataclass(frozen=True)
class OutputOptions:
    """How the result names the frames."""

    name_a: str | None = option(None, frame_name, "Name of frame a in the result and the ROS snippet [default: "
                                "the stream's child frame, else its topic].", "FRAME", commands=PAIR, per_stream="name")
    name_b: str | None = option(None, frame_name, "Name of frame b in the result.", "FRAME",
                                commands=PAIR, per_stream="name")


SECTIONS: dict[str, type] = {"read": ReadOptions, "sync": SyncOptions, "gates": GateOptions,
                             "pairs": PairOptions, "solver": SolverOptions, "analysis": AnalysisOptions,
                             "output": OutputOptions}
FIELDS: dict[str, tuple[str, OptionInfo, Any]] = {
    f.name: (section, f.metadata["info"], f.default) for section, cls in SECTIONS.items() for f in fields(cls)}


@dataclass(frozen=True)
class Options:
    """All options of a calibration, one frozen dataclass per stage.

    Build them with :meth:`from_flat` (keyword names as on the command line) or
    :func:`handeye_cli.config.load_options` (defaults < preset < file < overrides)."""

    read: ReadOptions = field(default_factory=ReadOptions)
    sync: SyncOptions = field(default_factory=SyncOptions)
    gates: GateOptions = field(default_factory=GateOptions)
    pairs: PairOptions = field(default_factory=PairOptions)
    solver: SolverOptions = field(default_factory=SolverOptions)
    analysis: AnalysisOptions = field(default_factory=AnalysisOptions)
    output: OutputOptions = field(default_factory=OutputOptions)

    @classmethod
    def from_flat(cls, base: Options | None = None, where: str = "", **values: Any) -> Options:
        """``base`` (default: the defaults) with the options given by flat name, each parsed and
        checked; ``where`` prefixes the name in errors (e.g. a file name)."""
        out = base or cls()
        grouped: dict[str, dict[str, Any]] = {}
        for name, value in values.items():
            if name not in FIELDS:
                raise ConfigError(f"unknown option {name!r}", where or "options", _suggest(name))
            section, info, _ = FIELDS[name]
            grouped.setdefault(section, {})[name] = info.parse(value, f"{where}: {name}" if where else name)
        out = replace(out, **{s: replace(getattr(out, s), **v) for s, v in grouped.items()})
        out = replace(out, gates=_gate_limits(out.gates, grouped.get("gates", {}), where))
        _check_refine(out.solver, where)
        return out

    def flat(self) -> dict[str, Any]:
        """Every option by its flat name (tuples as lists, mappings as dicts: ready for YAML/JSON)."""
        out: dict[str, Any] = {}
        for section in SECTIONS:
            for f in fields(getattr(self, section)):
                value = getattr(getattr(self, section), f.name)
                if f.metadata["info"].secret:
                    value = {k: "***" for k, _ in value}
                out[f.name] = list(value) if isinstance(value, tuple) else (
                    dict(value) if isinstance(value, Mapping) else value)
        return out

    def changed(self) -> dict[str, Any]:
        """The options that differ from their defaults, by flat name."""
        default = Options().flat()
        return {k: v for k, v in self.flat().items() if v != default[k]}


def _gate_limits(gates: GateOptions, given: Mapping[str, Any], where: str) -> GateOptions:
    """One meaning for the pose-jump limits: they are ``--gate paper``'s. Both off is no gate at all, and the
    settings say so (``gate: off``, as before ``--gate`` existed); a limit other than its default given while
    another gate runs would do nothing, so it is refused naming the option."""
    if gates.max_jump is None and gates.max_jump_deg is None:
        return replace(gates, gate="off")
    limits = [k for k in ("max_jump", "max_jump_deg") if k in given and given[k] != FIELDS[k][2]]
    if limits and gates.gate != "paper":
        raise ConfigError(f"a pose-jump limit is given, but it belongs to the paper gate and gate {gates.gate} "
                          "ignores it",
                          f"{where}: {limits[0]}" if where else limits[0],
                          "add ⟦gate='paper'⟧ to use the per-step limits, or ⟦gate='off'⟧ for no gate")
    return gates


def _check_refine(solver: SolverOptions, where: str) -> None:
    """The refinement starts at a certified optimum of cost (8) and its likelihood has no prior term: with another
    method or with a prior it would not do what it says, so it is refused naming the option."""
    if not solver.refine:
        return
    name = f"{where}: refine" if where else "refine"
    if solver.method not in OPTIMAL:
        raise ConfigError(f"the refinement starts at the certified optimum of cost (8), which {solver.method} does "
                          "not claim", name, "pass ⟦method='dqopt'⟧ with ⟦refine=True⟧, or leave the refinement off")
    if solver.prior is not None:
        raise ConfigError("the refinement's likelihood has no prior term, and a prior fixes what the motion leaves "
                          "open", name, "leave the refinement off with ⟦prior=FILE⟧")


# Names of the grouped configuration layout before 0.2, with the one name each has now.
RENAMED = {"max_translation": "max_jump", "max_rotation_deg": "max_jump_deg",
           "strategy": "pairs", "min_rotation_deg": "min_rotation", "keyframe_rotation_deg": "keyframe_rotation",
           "max_translation_m": "max_jump", "gates": "max_jump, max_jump_deg", "solver": "method, alpha, …",
           "analysis": "robust, bootstrap, strict"}


def _suggest(name: str) -> str:
    if name in RENAMED:
        return f"it is now {RENAMED[name]} (options are flat: one name per option, as the flag without '--')"
    import difflib

    close = difflib.get_close_matches(name, FIELDS, n=1)
    return f"did you mean {close[0]}?" if close else "see configs/default.yaml for every option"
