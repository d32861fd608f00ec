"""Every import a benchmark makes resolves, the ones inside its functions too: a benchmark whose helper module
moved (benchmarks/rig.py imported ``test_rig`` from tests/ after the tests moved into packages) fails here, not
on the day someone runs it. The modules are found as the benchmarks find them: this checkout first, then its
tests/ and benchmarks/ folders."""
from __future__ import annotations

import ast
import importlib.util
import sys

import pytest
from _util import ROOT

BENCHMARKS = sorted((ROOT / "benchmarks").glob("*.py"))


def _imported(path) -> set[str]:
    """The absolute module names ``path`` imports anywhere (module level, functions, type-checking blocks)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module)
    return names


@pytest.mark.parametrize("path", BENCHMARKS, ids=lambda p: p.name)
def test_every_import_of_a_benchmark_resolves(path, monkeypatch) -> None:
    monkeypatch.setattr(sys, "path", [str(ROOT), str(ROOT / "tests"), str(ROOT / "benchmarks"), *sys.path])
    optional = {"boto3", "moto", "moto.server", "cv2", "kinhec"}        # extras a benchmark says it needs
    missing = [name for name in sorted(_imported(path))
               if name not in optional and name.split(".")[0] not in optional
               and importlib.util.find_spec(name.split(".")[0]) is None]
    assert not missing, f"{path.name} imports what cannot be found: {missing}"
    for name in sorted(_imported(path)):
        top = name.split(".")[0]
        if (ROOT / "tests" / f"{top}.py").exists() or (ROOT / "benchmarks" / f"{top}.py").exists() \
                or top == "handeye_cli":
            assert importlib.util.find_spec(name) is not None, f"{path.name}: {name} is not found"
