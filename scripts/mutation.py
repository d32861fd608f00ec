#!/usr/bin/env python3
"""Mutation spot-check: apply one-line bugs to the core modules one at a time, run a fast test subset,
and print the mutants no test kills (the survivors).

Each mutant replaces one exact snippet (it must occur exactly once in its file) and is reverted
afterwards, also on Ctrl-C. A mutant is *killed* when the tests fail (or time out), *survives* when
they pass. Run from the repository root, in a checkout whose ``handeye_cli`` is what Python imports
(``pip install -e .``); it edits the working tree, so do not run two at once::

    python scripts/mutation.py                 # every mutant, the default test subset
    python scripts/mutation.py --list          # the mutants only
    python scripts/mutation.py -k gates -k document --tests tests/calibration/test_mutations.py

mutmut and cosmic-ray mutate every operator of a module and run the suite for each: thousands of
runs, hours on a shared 2-core machine. This fixed list of realistic bugs (wrong order, unit,
sign, bound, off-by-one, dropped correction) runs in minutes, and the list grows with every bug
that reaches a user.
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# The fast tests of the mutated modules (the 10 dqopt-vs-brute-force cases take ~2 min: left out).
TESTS = ("tests/solvers/test_solvers.py", "tests/stages/test_sync.py", "tests/stages/test_gates.py",
         "tests/stages/test_pairs.py",
         "tests/cli/test_cli.py", "tests/calibration/test_mutations.py",
         "--deselect=tests/solvers/test_solvers.py::test_dqopt_is_the_global_optimum")


@dataclass(frozen=True)
class Mutant:
    """One bug: in ``path`` (relative to the repository root) ``old`` becomes ``new``."""

    name: str
    path: str
    old: str
    new: str


MUTANTS = (
    # The four the issue found alive (issue 12 item 6).
    Mutant("result quaternion in w-x-y-z order", "handeye_cli/output/document.py",
           "t, q = solution.translation, solution.quaternion_xyzw",
           "t, q = solution.translation, solution.quaternion_xyzw[[3, 0, 1, 2]]"),
    Mutant("Solution.quaternion_xyzw in w-x-y-z order", "handeye_cli/solvers/__init__.py",
           "q, _ = dualquat.from_transforms(self.matrix)\n        return q",
           "q, _ = dualquat.from_transforms(self.matrix)\n        return q[[3, 0, 1, 2]]"),
    Mutant("paper gate: degrees passed as radians", "handeye_cli/options.py",
           "else math.radians(self.max_jump_deg)", "else self.max_jump_deg"),
    Mutant("paper gate: both limits doubled", "handeye_cli/stages/gates.py",
           "max_t = np.inf if max_translation_m is None else float(max_translation_m)\n"
           "    cos_half = -1.0 if max_rotation_rad is None else float(np.cos(min(max_rotation_rad, np.pi) / 2))",
           "max_t = np.inf if max_translation_m is None else 2 * float(max_translation_m)\n"
           "    cos_half = -1.0 if max_rotation_rad is None else float(np.cos(min(2 * max_rotation_rad, np.pi) / 2))"),
    Mutant("bootstrap: HC1 correction dropped", "handeye_cli/analysis/bootstrap.py",
           "return float(np.sqrt(n / (n - 6))) if n > 12 else float(np.sqrt(2.0))", "return 1.0"),
    # output/document.py
    Mutant("ROS snippet: frames swapped", "handeye_cli/output/document.py",
           "--frame-id {frames.get('a', 'a')} --child-frame-id {frames.get('b', 'b')}",
           "--frame-id {frames.get('b', 'b')} --child-frame-id {frames.get('a', 'a')}"),
    Mutant("ROS snippet: numbers rounded to 3 digits", "handeye_cli/output/document.py",
           "f\"--{k} {float(v)!r}\"", "f\"--{k} {float(v):.3f}\""),
    Mutant("result translation negated", "handeye_cli/output/document.py",
           '"translation": t,', '"translation": -t,'),
    # solvers
    Mutant("dual part: sign of t x v flipped", "handeye_cli/solvers/dualquat.py",
           "D[j, 4 * b + a] -= 0.5", "D[j, 4 * b + a] += 0.5"),
    Mutant("quaternion sign: w <= 0 kept", "handeye_cli/solvers/dualquat.py",
           "q *= np.where(q[3] < 0, -1.0, 1.0)", "q *= np.where(q[3] > 0, -1.0, 1.0)"),
    Mutant("to_transform: translation halved", "handeye_cli/solvers/dualquat.py",
           "s2 = 2.0 * s", "s2 = 1.0 * s"),
    Mutant("DQOpt: mu doubled in f", "handeye_cli/solvers/optimal.py",
           "tm = 2.0 * mu", "tm = 4.0 * mu"),
    Mutant("DQOpt: polish when well-conditioned too", "handeye_cli/solvers/optimal.py",
           "if _EPS * max(abs(l0), abs(l3)) > 1e-10 * (l1 - l0):", "if True:"),
    Mutant("KKT polish: cost may rise", "handeye_cli/solvers/optimal.py",
           "if not cost <= best:", "if cost > 2 * best + 1:"),
    # stages/sync.py
    Mutant("sync: the faster stream sets the times", "handeye_cli/stages/sync.py",
           'reference = "b" if method == "auto" and steps[1] > steps[0] else "a"',
           'reference = "b" if method == "auto" and steps[1] < steps[0] else "a"'),
    Mutant("sync: timestamp gate strict <", "handeye_cli/stages/sync.py",
           "keep = gap <= gate_ns", "keep = gap < gate_ns"),
    Mutant("sync: interpolation fraction from the upper sample", "handeye_cli/stages/sync.py",
           "frac = np.where(exact, 0.0, d_lo / np.maximum(stamps[hi] - stamps[lo], 1))",
           "frac = np.where(exact, 0.0, d_hi / np.maximum(stamps[hi] - stamps[lo], 1))"),
    Mutant("sync: nearest picks the farther sample", "handeye_cli/stages/sync.py",
           "pick = np.where(d_hi < d_lo, hi, lo)", "pick = np.where(d_hi > d_lo, hi, lo)"),
    Mutant("sync: time offset applied with the wrong sign", "handeye_cli/stages/sync.py",
           "b = b.shifted(-int(time_offset_ns))", "b = b.shifted(int(time_offset_ns))"),
    Mutant("sync: default max_dt of 1 step", "handeye_cli/stages/sync.py",
           "int(_MAX_DT_STEPS * step_ns)", "int(1 * step_ns)"),
    # stages/gates.py
    Mutant("auto gate: threshold halved", "handeye_cli/stages/gates.py",
           "score = (residual / limit).max(axis=0)", "score = 2 * (residual / limit).max(axis=0)"),
    Mutant("gates: glitch runs kept (accept_after ignored)", "handeye_cli/stages/gates.py",
           "keep = np.bincount(run)[run] >= accept_after", "keep = np.bincount(run)[run] >= 1"),
    Mutant("paper gate: translation limit ignored", "handeye_cli/stages/gates.py",
           "(np.linalg.norm(xyz[j] - xyz[i], axis=1) > max_t)", "(np.linalg.norm(xyz[j] - xyz[i], axis=1) > np.inf)"),
    Mutant("paper gate: quaternion sign not folded", "handeye_cli/stages/gates.py",
           'np.abs(np.einsum("ij,ij->i", quat[i], quat[j])) < cos_half)',
           'np.einsum("ij,ij->i", quat[i], quat[j]) < cos_half)'),
    Mutant("gates: every re-localisation bridged", "handeye_cli/stages/gates.py",
           "new[across] = bridge_breaks(last[across], first[across])", "new[across] = False"),
    # stages/pairs.py
    Mutant("pairs: keyframe rotation test uses the full angle", "handeye_cli/stages/pairs.py",
           "cos_half, t2 = np.cos(rotation_rad / 2), translation_m ** 2",
           "cos_half, t2 = np.cos(rotation_rad), translation_m ** 2"),
    Mutant("pairs: valid pairs need < min rotation", "handeye_cli/stages/pairs.py",
           "mask = np.abs(qa[r0:r1] @ qa[c0:c1].T) <= cos_half", "mask = np.abs(qa[r0:r1] @ qa[c0:c1].T) >= cos_half"),
    Mutant("pairs: motions may span a segment break", "handeye_cli/stages/pairs.py",
           "mask &= np.arange(c0, c1)[None, :] < seg_end[r0:r1, None]",
           "mask &= np.arange(c0, c1)[None, :] <= seg_end[r0:r1, None]"),
)


def run_tests(tests: list[str], timeout: float) -> tuple[str, float, str]:
    """Run pytest on ``tests`` up to the first failure: ('killed' | 'survived' | 'timeout', seconds, the
    failing test's id or '')."""
    t0 = time.perf_counter()
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-rf", "-p", "no:cacheprovider", "--no-header", *tests]
    try:
        done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return "timeout", time.perf_counter() - t0, ""
    failed = re.search(r"^(?:FAILED|ERROR) (\S+)", done.stdout, re.MULTILINE)
    outcome = "survived" if done.returncode == 0 else "killed"
    return outcome, time.perf_counter() - t0, failed.group(1) if failed else ""


def apply(m: Mutant) -> str:
    """Write the mutant into its file; returns the original text (raises if ``old`` is not unique)."""
    path = ROOT / m.path
    text = path.read_text()
    if text.count(m.old) != 1:
        raise SystemExit(f"mutant {m.name!r}: its snippet occurs {text.count(m.old)} times in {m.path}; update it")
    path.write_text(text.replace(m.old, m.new))
    return text


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tests", nargs="+", default=list(TESTS),
                    help="test files (and pytest options) run against each mutant")
    ap.add_argument("-k", dest="select", action="append", default=[], help="only mutants whose name or file "
                    "contains this (repeatable)")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds per mutant (a timeout counts as killed)")
    ap.add_argument("--list", action="store_true", help="list the mutants and exit")
    args = ap.parse_args()
    chosen = [m for m in MUTANTS if not args.select or any(s in m.name or s in m.path for s in args.select)]
    if args.list:
        for m in chosen:
            print(f"{m.path}: {m.name}")
        return 0
    base, secs, _ = run_tests(args.tests, args.timeout)
    if base != "survived":
        print(f"the tests fail without any mutant ({base}, {secs:.0f} s): fix them first")
        return 2
    survivors = []
    for k, m in enumerate(chosen, 1):
        original = apply(m)
        try:
            outcome, secs, by = run_tests(args.tests, args.timeout)
        finally:
            (ROOT / m.path).write_text(original)
        print(f"[{k:2d}/{len(chosen)}] {outcome:8s} {secs:5.0f} s  {m.path}: {m.name}" + (f"  (by {by})" if by else ""),
              flush=True)
        if outcome == "survived":
            survivors.append(m)
    print(f"\n{len(chosen) - len(survivors)} of {len(chosen)} mutants killed; {len(survivors)} survived:")
    for m in survivors:
        print(f"  {m.path}: {m.name}\n      - {m.old!r}\n      + {m.new!r}")
    return 1 if survivors else 0


if __name__ == "__main__":
    sys.exit(main())
