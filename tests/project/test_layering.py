"""Every import in the package follows the floors of docs/design.md's "Layers" table: no module
imports from a floor above its own, and no import cycle exists between modules."""
from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "handeye_cli"


def _floors() -> dict[str, int]:
    """``{module prefix: floor}`` from the Layers table of docs/design.md."""
    text = (ROOT / "docs" / "design.md").read_text(encoding="utf-8")
    table = text.split("## Layers", 1)[1].split("\n## ", 1)[0]
    floors = {}
    for floor, modules in re.findall(r"^\| (\d+) \| ([^|]+) \|", table, flags=re.M):
        for name in re.findall(r"`([\w.]+)`", modules):
            floors[name] = int(floor)
    return floors


def _module(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts) or "__init__"


def _exists(module: str) -> bool:
    base = PACKAGE.joinpath(*module.split(".")) if module else PACKAGE
    return base.with_suffix(".py").is_file() or (base / "__init__.py").is_file()


def _imports(path: Path, source: str | None = None) -> set[str]:
    """The package modules ``path`` imports (relative to the package, ``""`` for its ``__init__``);
    ``source``: the module's text, if not the file's."""
    here = _module(path)
    package = here.split(".") if path.name == "__init__.py" and here != "__init__" else here.split(".")[:-1]
    if here == "__init__":
        package = []
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8") if source is None else source)):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - node.level + 1] if node.level > 1 else package
                target = ".".join(base + ([node.module] if node.module else []))
            elif node.module and node.module.split(".")[0] == "handeye_cli":
                target = node.module.partition(".")[2]
            else:
                continue
            for alias in node.names:
                sub = f"{target}.{alias.name}" if target else alias.name
                found.add(sub if _exists(sub) else target)
        elif isinstance(node, ast.Import):
            found |= {a.name.partition(".")[2] for a in node.names if a.name.split(".")[0] == "handeye_cli"}
    return found - {here}


def _floor(module: str, floors: dict[str, int]) -> int:
    name = module or "__init__"
    matches = [p for p in floors if name == p or name.startswith(p + ".")]
    assert matches, f"handeye_cli.{name} is in no floor of docs/design.md's Layers table: add it there"
    return floors[max(matches, key=len)]


GRAPH = {_module(p): _imports(p) for p in sorted(PACKAGE.rglob("*.py"))}


def test_the_table_names_every_top_level_module_once() -> None:
    """Every top-level module or package has a floor; a package's own modules may be given floors below it
    (``calibration.pairing`` under ``verify``, ``calibration`` above it), and every name in the table exists."""
    floors = _floors()
    tops = {m.split(".")[0] for m in GRAPH}
    assert tops <= set(floors), f"modules in no floor: {sorted(tops - set(floors))}"
    assert set(floors) <= set(GRAPH), f"the table names modules that do not exist: {sorted(set(floors) - set(GRAPH))}"
    parts = {name for name in floors if "." in name}
    assert all(floors[name] < floors[name.split(".")[0]] for name in parts), "a part sits at or above its package"


def test_no_import_goes_up_a_floor() -> None:
    floors = _floors()
    up = sorted(f"handeye_cli.{m} (floor {_floor(m, floors)}) imports handeye_cli.{t or '__init__'} "
                f"(floor {_floor(t, floors)})"
                for m, targets in GRAPH.items() for t in targets if _floor(t, floors) > _floor(m, floors))
    assert not up, "\n".join(up)


def test_no_import_cycle() -> None:
    """Tarjan's strongly connected components over the module graph: each must be one module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in GRAPH.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in GRAPH:
        if v not in index:
            visit(v)
    assert not cycles, f"import cycles: {cycles}"


def test_the_checker_sees_upward_imports_however_written() -> None:
    """The checker itself: io/tf.py (floor 2) importing the calibration run (floor 9) or a stage (floor 5),
    relatively, absolutely or inside a function, is seen as that import."""
    floors = _floors()
    tf = PACKAGE / "io" / "tf.py"
    for text, target in (("from ..calibration import calibrate\n", "calibration"),
                         ("def f():\n    from ..stages.sync import associate\n", "stages.sync"),
                         ("import handeye_cli.stages.gates\n", "stages.gates"),
                         ("from handeye_cli.stages import sync\n", "stages.sync")):
        assert target in _imports(tf, text)
        assert _floor(target, floors) > _floor(_module(tf), floors)
