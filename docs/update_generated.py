"""Regenerate the files generated from handeye_cli/options.py: configs/default.yaml and the option
table of docs/reference/options.md (tests check both).   python docs/update_generated.py"""
from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def main() -> None:
    from test_docs import option_rows

    from handeye_cli.config import default_yaml

    (ROOT / "configs" / "default.yaml").write_text(default_yaml(), encoding="utf-8")
    page = ROOT / "docs" / "reference" / "options.md"
    lines = page.read_text(encoding="utf-8").splitlines()
    rows = [i for i, line in enumerate(lines) if re.match(r"\| `[a-z_]+` \| `--", line)]
    lines[rows[0]:rows[-1] + 1] = option_rows()
    page.write_text("\n".join(lines) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
