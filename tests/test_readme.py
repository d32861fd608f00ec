"""The README's Quickstart: exactly two commands, the second one is what CI runs."""
from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _quickstart() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("## Quickstart", 1)[1]
    block = re.search(r"```bash\n(.*?)```", section, re.S).group(1)
    return [line for line in block.splitlines() if line.strip()]


def test_quickstart_has_two_commands_and_ci_runs_the_second():
    lines = _quickstart()
    assert len(lines) == 2
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").strip().splitlines()
    assert lines[1] in ci                       # verbatim, as one line of its own (lint, types, docs follow)


def test_quickstart_first_command_runs_on_the_sample(tmp_path):
    install, run = _quickstart()[0].split(" && ")
    assert install == "pip install ."
    argv = shlex.split(run)
    assert argv[0] == "handeye"
    out = subprocess.run([sys.executable, "-m", "handeye_cli", *argv[1:]], cwd=ROOT, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "matrix:" in out.stdout and "quaternion_xyzw:" in out.stdout
    # the name the README gives the result is the one printed (it said T_cam0_cam1; it is T_cam0_pose_cam1_pose)
    named = re.search(r"the result, `(T_\w+)` as YAML", (ROOT / "README.md").read_text(encoding="utf-8"))
    assert named is not None and out.stderr.startswith(f"{named.group(1)}: translation")
