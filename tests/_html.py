"""What the HTML report tests share: the images a page embeds, and a real headless browser (Debian's
chromium: .ci/run installs it and sets CI=1, where a missing browser fails; elsewhere the test is skipped)."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest


def _images(text: str) -> list[str]:
    return re.findall(r"<img\b[^>]*\bsrc=['\"]([^'\"]*)['\"]", text)


def _chromium() -> str:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        message = ("chromium is not installed: the report test opens the report in a real headless browser; "
                   "install it with `apt-get install -y chromium` (.ci/run does)")
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    return exe


def _run_chromium(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    cmd = [_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
           "--no-first-run", "--hide-scrollbars", f"--user-data-dir={tmp_path / 'profile'}",
           "--virtual-time-budget=5000", *args]
    try:
        return subprocess.run(cmd, capture_output=True, text=True, timeout=60, check=True)
    except subprocess.TimeoutExpired:
        pytest.fail(f"chromium did not finish within 60 s: {' '.join(cmd)}")
    except subprocess.CalledProcessError as e:
        pytest.fail(f"chromium failed with exit code {e.returncode}: {e.stderr[-2000:]}")
