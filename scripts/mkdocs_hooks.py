"""MkDocs hooks (``hooks:`` in mkdocs.yml): the CLI reference shows each command's examples as code.

mkdocs-click copies a command's help into the page as Markdown, where the lines click prints
unwrapped (its ``\\b`` blocks: ``Examples:`` and the indented command lines under it) run together
into one paragraph, and a ``*`` of a glob (``logs/2026-11-*/``) turns into italics.
:class:`ClickExamples` runs right after mkdocs-click and writes each such block as a fenced code
block; its heading line stays text.
"""
from __future__ import annotations

import textwrap
from typing import Any

from markdown import Markdown
from markdown.extensions import Extension
from markdown.preprocessors import Preprocessor


def fence_examples(lines: list[str]) -> list[str]:
    """``lines`` with every run of indented lines that follows a heading line ending in ``:`` and starts with a
    ``handeye`` command written as a fenced code block (the run ends at a blank or unindented line)."""
    out: list[str] = []
    i = 0
    while i < len(lines):
        out.append(lines[i])
        j = i + 1
        while j < len(lines) and lines[j].startswith("  ") and lines[j].strip():
            j += 1
        block = textwrap.dedent("\n".join(lines[i + 1:j])).splitlines()
        if lines[i].rstrip().endswith(":") and not lines[i].startswith(" ") and block and \
                block[0].startswith("handeye "):
            out += ["", "```shell", *block, "```"]
            i = j
        else:
            i += 1
    return out


class _Processor(Preprocessor):
    def run(self, lines: list[str]) -> list[str]:
        return fence_examples(lines)


class ClickExamples(Extension):
    """The preprocessor, registered just after mkdocs-click's (priority 141)."""

    def extendMarkdown(self, md: Markdown) -> None:
        md.preprocessors.register(_Processor(md), "click_examples", 140)


def on_config(config: Any) -> Any:
    """Add :class:`ClickExamples` to the site's Markdown extensions."""
    config.markdown_extensions.append(ClickExamples())
    return config
