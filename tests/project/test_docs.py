"""The documentation cannot rot: its examples run, its tables match the code, the site builds.

* every fenced ``python`` block of README.md and docs/**/*.md, and every ``bash`` block of
  docs/**/*.md, runs — the blocks of one page in order, sharing one namespace, in a fresh folder
  where ``sample_data/`` is the repository's (so tutorials read the shipped samples and write
  nowhere else). A block is skipped only when the line before its fence is
  ``<!-- skip-test: REASON -->`` (or, in the README, its info string says ``skip-test``);
* the doctests of every module of ``handeye_cli``;
* the option table of docs/reference/options.md against :mod:`handeye_cli.options`, and the result
  schema page against the keys of a real result;
* ``mkdocs build --strict`` (skipped with its reason when the docs extra is not installed, but
  failing when the ``CI`` environment variable is set, as ``.ci/run`` sets it).
"""
from __future__ import annotations

import doctest
import importlib
import importlib.util
import os
import pkgutil
import re
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest

import handeye_cli
from handeye_cli.cli.params import _default_text
from handeye_cli.options import FIELDS, SECTIONS

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]
FENCE = re.compile(r"^(?P<indent>[ ]*)```(?P<info>[^`\n]*)\n(?P<body>.*?)^(?P=indent)```[ ]*$", re.M | re.S)
SKIP = re.compile(r"<!--\s*skip-test:\s*(?P<reason>.*?)\s*-->\s*$")
RUN_LANGS = {"python": "all", "bash": "docs"}     # which fenced blocks run, and on which pages


@dataclass(frozen=True)
class Block:
    """One fenced code block: its page, line, language, code and the reason it is skipped (if any)."""

    page: Path
    line: int
    lang: str
    code: str
    skip: str | None

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def blocks(page: Path) -> list[Block]:
    """The fenced code blocks of a Markdown page, in order (indented fences in list items too)."""
    text = page.read_text(encoding="utf-8")
    out = []
    for m in FENCE.finditer(text):
        info = m["info"].split()
        before = text[:m.start()].rstrip("\n").rsplit("\n", 1)[-1]
        marked = SKIP.search(before)
        skip = marked["reason"] if marked else ("skip-test in the info string" if "skip-test" in info[1:] else None)
        out.append(Block(page, text.count("\n", 0, m.start()) + 1, info[0] if info else "",
                         textwrap.dedent(m["body"]), skip))
    return out


def runnable(block: Block) -> bool:
    scope = RUN_LANGS.get(block.lang)
    return scope == "all" or (scope == "docs" and block.page.is_relative_to(DOCS))


def _workdir(tmp_path: Path) -> Path:
    """A fresh folder holding ``sample_data`` (the repository's) and a ``bin/handeye`` that runs this
    checkout's CLI with this interpreter, whatever is on PATH."""
    (tmp_path / "sample_data").symlink_to(ROOT / "sample_data", target_is_directory=True)
    shim = tmp_path / ".bin" / "handeye"
    shim.parent.mkdir()
    shim.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m handeye_cli "$@"\n', encoding="utf-8")
    shim.chmod(0o755)
    return tmp_path


def _run_bash(block: Block, cwd: Path) -> None:
    env = {**os.environ, "PATH": f"{cwd / '.bin'}{os.pathsep}{os.environ.get('PATH', '')}",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    out = subprocess.run(["bash", "-euo", "pipefail", "-c", block.code], cwd=cwd, env=env, capture_output=True,
                         text=True, timeout=600)
    assert out.returncode == 0, f"{block.where}: exit {out.returncode}\n{out.stdout[-2000:]}\n{out.stderr[-3000:]}"


def _run_page(page: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> int:
    cwd = _workdir(tmp_path)
    monkeypatch.chdir(cwd)
    namespace: dict[str, object] = {"__name__": "__docs__"}
    ran = 0
    for block in blocks(page):
        if not runnable(block) or block.skip:
            continue
        if block.lang == "python":
            exec(compile(block.code, block.where, "exec"), namespace)      # the docs' own examples
        else:
            _run_bash(block, cwd)
        ran += 1
    return ran


PAGES_WITH_CODE = [p for p in PAGES if any(runnable(b) for b in blocks(p))]


@pytest.mark.parametrize("page", PAGES_WITH_CODE, ids=[str(p.relative_to(ROOT)) for p in PAGES_WITH_CODE])
def test_code_blocks_run(page: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert _run_page(page, tmp_path, monkeypatch) >= 1, f"{page}: every code block is skipped"


def test_skipped_blocks_are_few_and_say_why() -> None:
    found = [b for p in PAGES for b in blocks(p) if runnable(b)]
    skipped = [b for b in found if b.skip]
    assert all(b.skip.strip() for b in skipped)
    assert len(found) >= 15, "the docs lost their examples"
    assert len(skipped) <= len(found) // 3, [b.where for b in skipped]


def test_block_parser_sees_indented_fences_and_skip_marks(tmp_path: Path) -> None:
    page = tmp_path / "p.md"
    page.write_text("- item\n\n  ```bash\n  handeye --version\n  ```\n\n<!-- skip-test: needs a robot -->\n"
                    "```python\nimport robot\n```\n\n```python skip-test\nx\n```\n", encoding="utf-8")
    got = blocks(page)
    assert [(b.lang, b.code, b.skip) for b in got] == [
        ("bash", "handeye --version\n", None), ("python", "import robot\n", "needs a robot"),
        ("python", "x\n", "skip-test in the info string")]


def _modules() -> list[str]:
    found = pkgutil.walk_packages(handeye_cli.__path__, "handeye_cli.")
    return sorted(m.name for m in found if m.name != "handeye_cli.__main__")     # __main__ runs the CLI


def test_doctests_of_every_module(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``python -m pytest --doctest-modules handeye_cli``, run from here (testpaths is tests/)."""
    monkeypatch.chdir(_workdir(tmp_path))
    finder, runner = doctest.DocTestFinder(), doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    examples = 0
    for name in ["handeye_cli", *_modules()]:
        module = importlib.import_module(name)
        for test in finder.find(module, name):
            runner.run(test)
            examples += len(test.examples)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} doctest examples failed (output above)"
    assert examples >= 20, "the docstrings lost their examples"


def option_rows() -> list[str]:
    """The rows of docs/reference/options.md's table, as :mod:`handeye_cli.options` defines them."""
    rows = []
    for section in SECTIONS:
        for name, (sec, info, default) in FIELDS.items():
            if sec == section:
                help_text = info.help.replace("|", "\\|")
                rig = f", rig `--{info.per_stream.replace('_', '-')} NAME`" if info.per_stream not in (None, "name") \
                    else ", rig: the stream's NAME" if info.per_stream else ""
                rows.append(f"| `{name}` | `--{name.replace('_', '-')}` | {sec} | {' '.join(info.commands)}{rig} "
                            f"| `{_default_text(default)}` | {help_text} |")
    return rows


def test_option_table_is_the_options_module() -> None:
    text = (DOCS / "reference" / "options.md").read_text(encoding="utf-8")
    table = [line for line in text.splitlines() if re.match(r"\| `[a-z_]+` \| `--", line)]
    assert table == option_rows(), "the table differs from handeye_cli/options.py: paste option_rows() into it"


def _documented_keys(page: str) -> set[str]:
    return set(re.findall(r"`([a-z_0-9]+)`", (DOCS / page).read_text(encoding="utf-8")))


def test_result_schema_page_names_every_key() -> None:
    cal = handeye_cli.calibrate_files(ROOT / "sample_data" / "rig_a.tum", ROOT / "sample_data" / "rig_b.tum",
                                      robust=True, alpha="auto", bootstrap=20, max_pairs=150)
    doc = handeye_cli.document(cal)
    keys = set(doc) | set(doc["samples"]) | set(doc["settings"]) | set(doc["solver"])
    for block in ("time_offset", "robust", "alpha_auto", "observability", "residuals", "uncertainty"):
        keys |= set(doc[block])
    missing = sorted(keys - _documented_keys("reference/result-schema.md"))
    assert not missing, f"docs/reference/result-schema.md does not describe {missing}"


def test_the_documents_required_keys_are_a_typed_schema_built_at_the_edge(tmp_path, capsys) -> None:
    """Issue 21: 'the result document (a TypedDict schema) is built at the output edge'. ResultDocument names the
    schema page's "Always present" keys in its order, and every document (calibrate's, solve's) holds them in that
    order, the diagnostic sections after solver and ros2_static_transform last."""
    from typing import get_type_hints

    import yaml
    from _util import run

    from handeye_cli.output.document import ResultDocument

    page = (DOCS / "reference" / "result-schema.md").read_text(encoding="utf-8")
    table = page.split("## Always present", 1)[1].split("###", 1)[0]
    required = re.findall(r"^\| `([a-z_0-9]+)` \|", table, flags=re.M)
    assert list(get_type_hints(ResultDocument)) == required and len(required) == 14
    code, out, err = run(capsys, "solve", ROOT / "sample_data" / "pairs.csv", "--bootstrap", "10", "-q")
    assert code == 0, err
    for doc in (handeye_cli.document(handeye_cli.calibrate_files(ROOT / "sample_data" / "rig_a.tum",
                                                                 ROOT / "sample_data" / "rig_b.tum", max_pairs=150)),
                yaml.safe_load(out)):
        keys = [k for k in doc if k in required]
        assert keys == required and list(doc)[-1] == "ros2_static_transform"
        assert list(doc).index("solver") == len(required) - 2 and len(doc) > len(required)     # diagnostics


def test_the_version_has_one_home() -> None:
    """Issue 21 item 8: the version lives in handeye_cli/version.py alone; the package metadata reads it from there
    (pyproject's dynamic version), --version prints it, and no other module or packaging file writes it out."""
    from importlib.metadata import version

    from handeye_cli.version import __version__

    pyproject = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    assert 'dynamic = ["version"]' in pyproject and 'version = {attr = "handeye_cli.version.__version__"}' in pyproject
    assert version("handeye-cli") == __version__
    literal = re.compile(rf"""["']{re.escape(__version__)}["']""")
    spelled = [p for p in [*(ROOT / "handeye_cli").rglob("*.py"), ROOT / "pyproject.toml"]
               if p.name != "version.py" and literal.search(p.read_text(encoding="utf-8"))]
    assert spelled == []


def test_nothing_cites_notes_outside_the_repository() -> None:
    cited = [f"{p.relative_to(ROOT)}:{n}" for folder in ("handeye_cli", "tests", "benchmarks")
             for p in (ROOT / folder).rglob("*.py") if p.name != "test_docs.py"
             for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
             if "DESIGN.md" in line or "shared/" in line]
    assert not cited, f"cite docs/design.md instead: {cited}"


def test_site_builds_strict(tmp_path: Path) -> None:
    if importlib.util.find_spec("mkdocs") is None or importlib.util.find_spec("mkdocs_click") is None:
        if os.environ.get("CI"):
            pytest.fail("mkdocs is not installed, but CI must build the docs: '.[test]' includes the docs extra")
        pytest.skip("mkdocs is not installed (pip install -e '.[docs]'); CI builds the site")
    site = tmp_path / "site"
    out = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(site)], cwd=ROOT,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-5000:]
    cli_page = (site / "reference" / "cli" / "index.html").read_text(encoding="utf-8")
    assert "--max-jump" in cli_page and "handeye calibrate" in cli_page      # generated from the click commands
    # issue 21: examples ran together as paragraphs and a glob's * became italics; every command's are code
    assert "logs/2026-11-*/" in re.sub(r"<[^>]+>", "", cli_page) and "2026-11-<em>" not in cli_page
    assert cli_page.count('<div class="highlight"><pre><span></span><code>handeye') >= 8
    assert "not part of this version" not in cli_page and "| 1 |" not in cli_page and ">1</td>" in cli_page
    api_page = (site / "reference" / "api" / "index.html").read_text(encoding="utf-8")
    assert "calibrate_files" in api_page and "ConfigError" in api_page      # generated from the docstrings


def test_cli_examples_become_code_blocks() -> None:
    """The hook of the CLI reference (scripts/mkdocs_hooks.py) fences a help text's examples, and only them."""
    spec = importlib.util.spec_from_file_location("mkdocs_hooks", ROOT / "scripts" / "mkdocs_hooks.py")
    assert spec is not None and spec.loader is not None
    hooks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hooks)
    lines = ["Intro text:", "  - a list item", "", "Examples:", "  handeye batch logs/*/ \\\\", "      --jobs 8",
             "  handeye check r.yaml", "Exit codes: 0 ok,", "  1 drift"]
    assert hooks.fence_examples(lines) == [
        "Intro text:", "  - a list item", "", "Examples:", "", "```shell", "handeye batch logs/*/ \\\\",
        "    --jobs 8", "handeye check r.yaml", "```", "Exit codes: 0 ok,", "  1 drift"]


def test_no_page_claims_a_version_the_package_is_not() -> None:
    """The tutorials said "since 0.2 (unreleased)" while ``handeye --version`` says 0.1.0: a page may name no
    version newer than the package's, nor date a feature "(unreleased)" (citing the changelog's *Unreleased*
    section is fine)."""
    from handeye_cli.version import __version__

    mine = tuple(int(p) for p in __version__.split(".")[:2])
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        assert "(unreleased)" not in text.lower(), page
        for major, minor in re.findall(r"\b(?:since|version|v)\s*(\d+)\.(\d+)\b", text, flags=re.I):
            assert (int(major), int(minor)) <= mine, (page, f"{major}.{minor}")
