"""Every message the library writes names its options by key (issue 37): a literal outside the command line's
own layers (``cli/``, ``fleet/``) says ``⟦max_dt⟧``, never ``--max-dt``; each key it marks is an option the Python
API takes; each install hint names this distribution's extras. The CLI and the API then word the marks once
(``errors.as_flags`` / ``errors.as_keywords``)."""
from __future__ import annotations

import ast
import re
from dataclasses import fields
from pathlib import Path

import pytest

from handeye_cli.errors import KEYWORD_FLAGS, ConfigError, as_flags, as_keywords, option
from handeye_cli.options import FIELDS
from handeye_cli.rig import RigOptions

PACKAGE = Path(__file__).resolve().parents[2] / "handeye_cli"
CLI_LAYERS = ("cli", "fleet")          # the command line's own words: they name flags
FLAG = re.compile(r"(?<![\w-])--(?:no-)?[a-z][a-z0-9*{}_-]*")
MARK = re.compile(r"⟦([A-Za-z_*{}][A-Za-z0-9_*{}]*)(?:=[^⟦⟧]*)?⟧")
#: literals that are another program's flags or a flag as data, not a message naming an option of ours:
#: static_transform_publisher's arguments (read from a nominal, written for a launch line), the flags of
#: RigOptions' fields (the CLI's table), the commented configuration file ``handeye`` writes for ``--config``,
#: and the HTML report's labels (``--report`` is the command line's: its messages are worded as flags)
DATA = {*{("io/nominal.py", f"--{name}") for name in ("x", "y", "z", "qx", "qy", "qz", "qw", "roll", "pitch",
                                                      "yaw", "frame-id", "child-frame-id", "ros-args")},
        *{(m, f) for m in ("output/document.py", "output/formats.py") for f in ("--frame-id", "--child-frame-id")},
        *{("rig/__init__.py", f"--{name}") for name in ("reference", "time-offset", "invert", "no-invert", "wxyz",
                                                        "scale", "block")},
        ("config.py", "--config"), ("output/report.py", "--robust"), ("rig/report.py", "--bootstrap")}
RENDERER = "errors.py"                 # as_flags and its table: where keys become flags


def _docstrings(tree: ast.AST) -> set[int]:
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            found.add(id(node.value))
    return found


def _literals() -> list[tuple[str, int, str]]:
    """(module, line, text) of every string literal of the library's layers but the docstrings and help texts."""
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        module = path.relative_to(PACKAGE).as_posix()
        if module.split("/")[0] in CLI_LAYERS or module == RENDERER:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        skip = _docstrings(tree)
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "option" and module == "options.py":
                skip |= {id(a) for a in ast.walk(node) if isinstance(a, ast.Constant)}    # the flags' --help texts
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in skip:
                out.append((module, node.lineno, node.value))
    return out


LITERALS = _literals()
KEYS = ({*FIELDS, *KEYWORD_FLAGS, *(f.name for f in fields(RigOptions))}
        | {f"{kind}_{side}" for kind in ("stream", "topic", "frames", "name") for side in "ab"}
        | {"accept_poor_fit", "robust", "strict", "bootstrap", "prior", "against", "report", "topic", "frames",
           "max_rotation_deg", "max_translation_m", "time_offset", "scale", "invert", "wxyz"})


def test_no_library_message_names_a_flag() -> None:
    said = [(m, line, FLAG.findall(text)) for m, line, text in LITERALS
            if any((m, f) not in DATA for f in FLAG.findall(text))]
    assert not said, "\n".join(f"handeye_cli/{m}:{line}: {flags}: name the option as ⟦key⟧ (errors.option)"
                               for m, line, flags in said)


def test_every_marked_option_is_a_keyword_of_the_api() -> None:
    unknown = [(m, line, key) for m, line, text in LITERALS for key in MARK.findall(text)
               if re.sub(r"\{[^{}]*\}", "a", key) not in KEYS and "*" not in key]
    assert not unknown, unknown


def test_every_install_hint_names_this_distribution() -> None:
    hints = [(m, line, text) for m, line, text in LITERALS if "pip install" in text]
    for path in (PACKAGE / "cli").glob("*.py"):
        hints += [(path.name, 0, t) for t in re.findall(r"pip install[^\"]*", path.read_text(encoding="utf-8"))]
    assert hints
    for m, line, text in hints:
        for target in re.findall(r"pip install '([^']+)'", text):
            assert target.startswith(("handeye-cli[", ".[")), (m, line, text)
        assert "dask[" not in text, (m, line, text)


@pytest.mark.parametrize(("value", "keyword", "flag"), [
    (None, "max_dt", "--max-dt"), (True, "robust=True", "--robust"), (False, "invert_b=False", "--no-invert-b"),
    ("off", "gate='off'", "--gate off"), ("N", "max_pairs=N", "--max-pairs N"),
    (0.25, "time_offset=0.25", "--time-offset 0.25"),
    (("PARENT", "CHILD"), "frames_a=(PARENT, CHILD)", "--frames-a PARENT CHILD"),
    ("json", "fmt='json'", "--format json"),
])
def test_an_option_is_worded_once_by_each_front_end(value, keyword, flag) -> None:
    key = keyword.split("=")[0]
    text = f"try {option(key, value)} next"
    assert as_keywords(text) == f"try {keyword} next" and as_flags(text) == f"try {flag} next"


def test_an_error_says_keywords_in_python_and_flags_on_the_command_line() -> None:
    e = ConfigError("too few pairs", "max_pairs", f"raise {option('max_pairs', 'N')} or try {option('pairs', 'all')}")
    assert str(e) == "too few pairs (max_pairs): raise max_pairs=N or try pairs='all'"
    assert e.line(as_flags) == "too few pairs (max_pairs): raise --max-pairs N or try --pairs all"
    assert "⟦" in e.fix and "⟦" in e.line()                  # the parts keep the marks, for a message that quotes it
