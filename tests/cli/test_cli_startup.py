"""What starting a command costs: each command imports only what it runs; BLAS runs one thread."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

SAMPLES = Path(__file__).resolve().parents[2] / "sample_data"

PROBE = """
import json, os, sys
from handeye_cli.cli import cli
cli.get_command(None, {command!r})
print(json.dumps({{"modules": sorted(sys.modules), "blas": os.environ.get("OPENBLAS_NUM_THREADS")}}))
"""


def _started(command: str, **env: str) -> dict:
    clean = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                                                               "MKL_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", PROBE.format(command=command)], env={**clean, **env},
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out)


@pytest.mark.parametrize("command", ["calibrate", "solve", "inspect", "check"])
def test_a_command_imports_only_what_it_runs(command: str) -> None:
    modules = set(_started(command)["modules"])
    for heavy in ("scipy.optimize", "scipy.signal", "matplotlib", "xml.sax.saxutils", "handeye_cli.rig",
                  "handeye_cli.fleet", "handeye_cli.output.report", "rosbags"):
        assert heavy not in modules, f"handeye {command} imports {heavy}"


RUN = """
import json, sys
from handeye_cli.cli import main
sys.argv = ["handeye", *{args!r}]
try:
    main()
except SystemExit as end:
    code = end.code
print(json.dumps({{"code": code, "scipy": sorted(m for m in sys.modules if m.startswith("scipy"))}}))
"""


@pytest.mark.parametrize("args", [
    ["calibrate", str(SAMPLES / "rig.mcap"), "--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose"],   # + summary line
    ["calibrate", str(SAMPLES / "rig.mcap"), "--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose", "--format",
     "ros2-launch", "--against", str(SAMPLES / "truth.yaml"), "-q"],
    ["calibrate", str(SAMPLES / "rig.mcap"), "--frames-a", "world", "cam0", "--frames-b", "world", "cam1",
     "--format", "json", "-q"],
    ["calibrate", str(SAMPLES / "rig_a.tum"), str(SAMPLES / "rig_b.tum"), "--format", "tf-static", "-q"],
    ["calibrate", str(SAMPLES / "rig_ros1.bag"), "--topic-a", "/cam0/odom", "--topic-b", "/cam1/pose", "-q"],
    ["calibrate", str(SAMPLES / "rig_ros2"), "--topic-a", "/cam0/transform", "--topic-b", "/cam1/odom", "-q"],
    ["solve", str(SAMPLES / "pairs.csv")],
])
def test_a_default_run_imports_no_scipy(args: list[str]) -> None:
    """A default run (every stage, the analysis, the writers) does not import scipy, whose start-up
    (0.3 s with scipy.linalg) would be most of a short run's time: numpy does its linear algebra."""
    run = subprocess.run([sys.executable, "-c", RUN.format(args=[*args, "-o", "-"])],
                         capture_output=True, text=True, check=True)
    done = json.loads(run.stdout.splitlines()[-1])
    assert done["code"] in (0, None) and done["scipy"] == []


def test_a_rig_run_imports_no_scipy() -> None:
    """``handeye rig`` (clock offsets, pairs, noise model, joint, its χ² test, the summary) runs on numpy
    alone: scipy's start-up would be a quarter of a short rig's time."""
    args = ["rig", str(SAMPLES / "rig4.mcap"), "--stream", "cam0=/cam0/pose", "--stream", "cam1=/cam1/pose",
            "--stream", "lidar=/lidar/odom", "--stream", "imu=tf:odom,imu_link", "-o", "-"]
    run = subprocess.run([sys.executable, "-c", RUN.format(args=args)], capture_output=True, text=True, check=True)
    done = json.loads(run.stdout.splitlines()[-1])
    assert done["code"] in (0, None) and done["scipy"] == []
    assert "child: imu" in run.stdout and "T_cam0_imu: translation" in run.stderr      # the summary too


def test_every_command_is_listed_and_loads() -> None:
    import click

    from handeye_cli.cli import COMMANDS, cli

    ctx = click.Context(cli)
    assert cli.list_commands(ctx) == sorted(COMMANDS)
    for name in COMMANDS:
        command = cli.get_command(ctx, name)
        assert isinstance(command, click.Command) and command.name == name
    assert cli.get_command(ctx, "calibrat") is None


def test_blas_runs_one_thread_unless_the_environment_says() -> None:
    assert _started("calibrate")["blas"] == "1"
    assert _started("calibrate", OPENBLAS_NUM_THREADS="2")["blas"] == "2"
    assert _started("calibrate", OMP_NUM_THREADS="4")["blas"] is None      # the user's setting stands


def test_the_public_api_resolves_lazily() -> None:
    import handeye_cli

    for name in handeye_cli.__all__:
        assert getattr(handeye_cli, name) is not None
    assert set(handeye_cli.__all__) <= set(dir(handeye_cli))
    with pytest.raises(AttributeError):
        handeye_cli.no_such_name  # noqa: B018


@pytest.mark.parametrize("module", ["handeye_cli.stages.timeoffset", "handeye_cli.rig"])
def test_the_time_offset_and_the_rig_leave_out_the_slowest_scipy_modules(module: str) -> None:
    code = f"import sys, {module}; print(' '.join(sorted(sys.modules)))"
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    loaded = set(run.stdout.split())
    assert module in loaded
    assert not {"scipy.signal", "scipy.stats"} & loaded          # 1 s of imports each


def test_a_time_offset_estimate_imports_no_scipy() -> None:
    """``--time-offset auto`` estimates the clock offset with numpy alone (FFT, smoothing, Brent's
    minimiser), so the estimate can run on every calibrate without scipy's start-up."""
    args = ["calibrate", str(SAMPLES / "rig_a.tum"), str(SAMPLES / "rig_b.tum"), "--time-offset", "auto",
            "--format", "json", "-q", "-o", "-"]
    lines = subprocess.run([sys.executable, "-c", RUN.format(args=args)], capture_output=True, text=True,
                           check=True).stdout.splitlines()
    done = json.loads(lines[-1])
    assert done["code"] in (0, None) and done["scipy"] == []
    offset = json.loads("\n".join(lines[:-1]))["time_offset"]
    assert "cross-correlation" in offset["method"] and offset["correlation"] > 0.9
