"""Issue 21 item 8: the precise error subclass is raised everywhere; the base class is never raised directly.

Callers that fall back on one kind of failure catch the subclass (:mod:`handeye_cli.errors`), so a bare
``raise HandEyeError(...)`` is a failure nobody can catch precisely."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

import handeye_cli
from handeye_cli import errors

PACKAGE = Path(handeye_cli.__file__).parent


def _bare_raises(tree: ast.AST) -> list[int]:
    """Lines of ``raise HandEyeError(...)`` / ``raise errors.HandEyeError(...)`` / ``raise HandEyeError``."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Raise) and node.exc is not None:
            exc = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
            name = exc.attr if isinstance(exc, ast.Attribute) else getattr(exc, "id", None)
            if name == "HandEyeError":
                out.append(node.lineno)
    return out


def test_the_checker_sees_every_spelling() -> None:
    code = "raise HandEyeError('x')\nraise errors.HandEyeError('y', 'w')\nraise HandEyeError\nraise ReadError('z')\n"
    assert _bare_raises(ast.parse(code)) == [1, 2, 3]


def test_no_bare_base_class_is_raised() -> None:
    found = [f"{p.relative_to(PACKAGE.parent)}:{line}" for p in sorted(PACKAGE.rglob("*.py"))
             for line in _bare_raises(ast.parse(p.read_text(encoding="utf-8")))]
    assert found == []


@pytest.mark.parametrize(("text", "kind"), [
    ("ax,ay\n1,2\n", errors.ReadError),                 # a pairs file with a wrong header
    (None, errors.ReadError),                           # a missing pairs file
])
def test_pair_file_errors_are_read_errors(tmp_path: Path, text: str | None, kind: type) -> None:
    from handeye_cli.io.pairfile import read_pairs

    p = tmp_path / "pairs.csv"
    if text is not None:
        p.write_text(text)
    with pytest.raises(kind):
        read_pairs(str(p))


def test_short_streams_for_a_time_offset_are_a_data_error() -> None:
    import numpy as np

    from handeye_cli.stages.timeoffset import estimate_time_offset
    from handeye_cli.streams import PoseStream

    t = np.arange(5, dtype=np.int64) * 10_000_000
    s = PoseStream(t, np.zeros((5, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (5, 1)), source="a")
    with pytest.raises(errors.DataError):
        estimate_time_offset(s, s)


def test_rosbags_internals_are_pinned() -> None:
    """rosbag1_scan imports names outside rosbags' public API (rosbags 0.10.0 lacks ``decompressors``): the
    dependency is bounded above to the minor series tested, and the installed version lies within it."""
    import re
    from importlib.metadata import version

    from packaging.requirements import Requirement

    text = (PACKAGE.parent / "pyproject.toml").read_text(encoding="utf-8")
    req = Requirement(re.search(r'^\s*"(rosbags[^"]*)"', text, re.M).group(1))
    assert any(s.operator == "<" for s in req.specifier) and any(s.operator == ">=" for s in req.specifier)
    assert req.specifier.contains(version("rosbags"))
    from rosbags.rosbag1.reader import Header, RecordType, decompressors, read_uint32  # what rosbag1_scan uses

    assert callable(read_uint32) and Header and RecordType and {"bz2", "lz4"} <= set(decompressors)


def test_a_too_few_pairs_error_names_keywords_in_the_api_and_flags_on_the_command_line(capsys):
    """Issue 37: ``calibrate_files(pairs='consecutive', max_pairs=2)`` said 'with --pairs consecutive' (in the part
    the old flag-to-keyword rewrite missed) and 'raise max_pairs=True' (a value flag named without its value): the API's
    message names no flag and a keyword with a value; the CLI's names the flag."""
    from _util import ROOT, run

    from handeye_cli.errors import TooFewPairsError

    log, topics = ROOT / "sample_data" / "rig.mcap", {"topic_a": "/cam0/pose", "topic_b": "/cam1/pose"}
    with pytest.raises(TooFewPairsError) as info:
        handeye_cli.calibrate_files(log, **topics, pairs="consecutive", max_pairs=2)
    text = str(info.value)
    assert "--" not in text and "max_pairs=N (now 2)" in text and "=True" not in text, text
    code, _, err = run(capsys, "calibrate", log, "--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose",
                       "--pairs", "consecutive", "--max-pairs", "2")
    assert code == 2 and err.count("\n") == 1 and "raise --max-pairs N (now 2)" in err, err
