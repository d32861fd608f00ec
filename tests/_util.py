"""Helpers shared by the tests: run the CLI in-process, write TUM files, measure errors."""
from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from handeye_cli.cli import main
from handeye_cli.errors import HandEyeError, as_flags
from handeye_cli.geometry import se3

ROOT = Path(__file__).resolve().parents[1]


def run(capsys, *args) -> tuple[int, str, str]:
    """Run ``handeye ARGS`` in-process: (exit code, stdout, stderr)."""
    with pytest.raises(SystemExit) as info:
        main([str(a) for a in args])
    out, err = capsys.readouterr()
    return info.value.code, out, err


def write_tum(path: Path, stream, header: bool = True) -> Path:
    """Write a PoseStream as a TUM file (``t x y z qx qy qz qw``, seconds)."""
    np.savetxt(path, np.c_[stream.stamps_ns / 1e9, stream.xyz, stream.quat_xyzw], fmt="%.9f",
               header="timestamp tx ty tz qx qy qz qw" if header else "")
    return path


def pose_error(X: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """(rotation error [deg], translation error [m]) of ``X`` against ``truth`` (4x4 each)."""
    X, truth = np.asarray(X, dtype=float), np.asarray(truth, dtype=float)
    return (float(np.rad2deg(se3.rotation_angle(X[:3, :3].T @ truth[:3, :3]))),
            float(np.linalg.norm(X[:3, 3] - truth[:3, 3])))


def fails(call: Callable[[], object], *patterns: str) -> HandEyeError:
    """``call()`` raises a one-line HandEyeError whose text in the command line's words (its options as flags,
    as ``handeye`` prints it) matches every regex in ``patterns``."""
    with pytest.raises(HandEyeError) as info:
        call()
    text = info.value.line(as_flags)
    assert "\n" not in text and info.value.what
    for p in patterns:
        assert re.search(p, text), f"{p!r} not in {text!r}"
    return info.value


def signed_rank_p(d: np.ndarray) -> float:
    """One-sided exact Wilcoxon signed-rank test of paired differences ``d``: ``P(W⁺ ≥ w⁺)`` under
    "symmetric about 0" (small: the differences lean positive). Ties of |d| do not occur in continuous errors."""
    ranks = np.argsort(np.argsort(np.abs(d))) + 1
    w = int(ranks[d > 0].sum())
    n = len(d)
    counts = np.zeros(n * (n + 1) // 2 + 1)
    counts[0] = 1.0
    for r in range(1, n + 1):                      # subsets of the ranks 1..r by their sum
        counts[r:] = counts[r:] + counts[:-r].copy()
    return float(counts[w:].sum() / 2.0 ** n)
