"""What a new user hit on the command line (issue 21, item 1), each as the user typed it."""
from __future__ import annotations

from _util import ROOT, run

SAMPLE = ROOT / "sample_data"


def test_frames_a_given_one_frame_names_the_flag_not_a_frame(capsys) -> None:
    """``--frames-a base_link --topic-b …`` said "unknown TF frame '--topic-b'" (then "file not found"): click
    took the next flag as CHILD. Now one line naming --frames-a and the PARENT CHILD it takes."""
    code, out, err = run(capsys, "calibrate", SAMPLE / "rig.mcap", "--frames-a", "base_link", "--topic-b",
                         "/cam1/pose")
    assert code == 2 and out == ""
    assert err.startswith("error: bad TF chain 'base_link --topic-b': it takes two frame names, PARENT CHILD; "
                          "got '--topic-b' as CHILD (--frames-a)")
    assert "--frames-a odom base_link" in err and len(err.splitlines()) == 1


def test_a_ros2_bags_metadata_yaml_points_at_the_bag_folder(capsys) -> None:
    """Passing a ROS 2 bag's metadata.yaml suggested --config (a configuration file); it is the bag's index."""
    code, out, err = run(capsys, "calibrate", SAMPLE / "rig_ros2" / "metadata.yaml", "--topic-a", "/cam0/pose",
                         "--topic-b", "/cam1/pose")
    assert code == 2 and out == "" and "--config" not in err
    assert "a ROS 2 bag's metadata.yaml" in err
    assert err.rstrip().endswith(f"pass the bag's folder: {SAMPLE / 'rig_ros2'}")


def test_inverted_tum_streams_keep_their_names_in_the_launch_line(capsys) -> None:
    """TUM inputs with --invert-b named sensor b 'world' (``--frame-id rig_a --child-frame-id world``), both
    inverted 'world → world': pasted into ROS, that breaks TF. Each sensor keeps its file's name."""
    for inverted in (["--invert-b"], ["--invert-a", "--invert-b"]):
        code, out, _ = run(capsys, "calibrate", SAMPLE / "rig_a.tum", SAMPLE / "rig_b.tum", *inverted,
                           "--accept-poor-fit", "--pairs", "consecutive", "--format", "tf-static", "-q")
        line = next(s for s in out.splitlines() if s.startswith("ros2 run"))
        assert code in (0, 3) and "world" not in out         # 3: a poor fit written on request
        assert line.endswith("--frame-id rig_a --child-frame-id rig_b")


def test_pose_jump_limits_mean_something_or_are_refused(capsys) -> None:
    """``--max-jump 0.01`` and ``--max-jump off`` did nothing under the default ``--gate auto``, and the settings
    said ``gate: auto`` when both limits off had switched the gate off. Now a limit under another gate is one
    line naming the flag and the fix; with --gate paper it applies; both off reads gate off."""
    import json

    files = (SAMPLE / "rig_a.tum", SAMPLE / "rig_b.tum", "--pairs", "consecutive", "--format", "json", "-q")
    for limit in (["--max-jump", "0.01"], ["--max-jump", "off"], ["--max-jump-deg", "3"]):
        code, out, err = run(capsys, "calibrate", *files, *limit)
        assert code == 2 and out == "" and len(err.splitlines()) == 1
        assert f"({limit[0]})" in err and "--gate paper" in err and "gate auto ignores it" in err
    code, out, _ = run(capsys, "calibrate", *files, "--gate", "paper", "--max-jump", "0.3")
    tight = run(capsys, "calibrate", *files, "--gate", "paper", "--max-jump", "0.001")
    assert code == 0 and json.loads(out)["settings"]["options"]["max_jump"] == 0.3
    assert tight[0] == 2 and "pose-jump gate" in tight[2]                    # the limit is applied
    code, out, _ = run(capsys, "calibrate", *files, "--max-jump", "off", "--max-jump-deg", "off")
    assert code == 0 and json.loads(out)["settings"]["options"]["gate"] == "off"


def test_gate_off_in_a_configuration_file(capsys, tmp_path) -> None:
    """YAML reads ``gate: off`` as false, which the gate's choices refused ("bad value False"); it is off."""
    import json

    cfg = tmp_path / "c.yaml"
    cfg.write_text("gate: off\nstations: off\n")
    code, out, err = run(capsys, "calibrate", SAMPLE / "rig_a.tum", SAMPLE / "rig_b.tum", "--config", cfg,
                         "--pairs", "consecutive", "--format", "json", "-q")
    options = json.loads(out)["settings"]["options"]
    assert code == 0, err
    assert (options["gate"], options["stations"]) == ("off", "off")


def test_a_mistyped_command_gets_did_you_mean(capsys) -> None:
    """``handeye calibrat`` got no "did you mean", though a mistyped option does."""
    code, out, err = run(capsys, "calibrat", SAMPLE / "rig_a.tum", SAMPLE / "rig_b.tum")
    assert code == 2 and out == "" and len(err.splitlines()) == 1
    assert "No such command 'calibrat'. (Did you mean 'calibrate'?)" in err
    code, _, err = run(capsys, "xyzzy")
    assert code == 2 and "No such command 'xyzzy'" in err and "Did you mean" not in err


def test_help_names_one_default_and_every_method(capsys) -> None:
    """``--name-a`` help showed two defaults ("[default: the stream's child frame, else its topic]. [default:
    off]"); ``--method`` help omitted tsai/park/horaud/andreff."""
    import re

    from handeye_cli.solvers import METHODS

    code, out, _ = run(capsys, "calibrate", "--help")
    text = " ".join(out.split())
    name_a = text.split("--name-a FRAME", 1)[1].split("--name-b", 1)[0]
    assert code == 0 and name_a.count("[default:") == 1 and "child frame" in name_a
    method = text.split("Solver:", 1)[1].split(" --", 1)[0]
    assert all(re.search(rf"\b{m}\b", method) for m in METHODS), method


def test_a_missing_optional_package_is_named_as_the_registry_knows_it(capsys, monkeypatch) -> None:
    """The hint ``pip install 'handeye-cli[report]'`` named an extra that does not exist. The hints for URLs and
    Dask name this distribution's extras (issue 37), and the spelling that installs them from a checkout."""
    import sys

    monkeypatch.setitem(sys.modules, "fsspec", None)          # import fsspec → ImportError
    monkeypatch.setitem(sys.modules, "distributed", None)
    code, out, err = run(capsys, "inspect", "s3://bucket/log.mcap")
    assert code == 2 and out == ""
    assert err.rstrip().endswith("pip install 'handeye-cli[remote]' (in a checkout: pip install '.[remote]')")
    code, _, err = run(capsys, "batch", SAMPLE / "rig.mcap", "--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose",
                       "--scheduler", "tcp://127.0.0.1:1")
    assert code == 2 and "pip install 'handeye-cli[dask]'" in err and "dask[distributed]" not in err
