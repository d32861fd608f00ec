"""An inverted stream is named first, with the numbers; overwhelming evidence refuses the result."""
from __future__ import annotations

import numpy as np
import pytest
import yaml
from _util import pose_error, run, write_tum

from handeye_cli.analysis.inversion import Candidate, InversionVerdict, check_inversion
from handeye_cli.errors import DataError, as_flags
from handeye_cli.simulation.arm import simulate_arm
from handeye_cli.stages.stations import detect_stations


def _stations(invert_b: bool):
    c = simulate_arm(12, sparse=True, seed=1)
    st = detect_stations(c.robot, c.camera.inverted() if invert_b else c.camera)
    i, j = np.triu_indices(len(st), 1)
    return st.synced.T_a, st.synced.T_b, i, j


def test_correct_streams_give_no_verdict():
    assert check_inversion(*_stations(invert_b=True)) is None


def test_an_inverted_station_stream_is_named_with_the_numbers():
    verdict = check_inversion(*_stations(invert_b=False))
    assert verdict is not None and verdict.overwhelming
    # Inverting a instead also satisfies T_a X = Y T_b (X and Y swapped): both are candidates.
    assert set(verdict.streams) == {"a", "b"}
    assert verdict.given[0] > 5 and all(c.inverted[0] < 0.3 and c.ratio > 50 for c in verdict.candidates)
    text = as_flags(verdict.message())                    # the options as the CLI names them
    assert "--invert-b" in text and "--invert-a" in text and f"{verdict.given[0]:.3g}°" in text


def test_refusal_with_or_without_an_explicit_invert_flag():
    """Overwhelming evidence refuses the result; an explicit flag the data contradict is named as such."""
    verdict = check_inversion(*_stations(invert_b=False))
    for explicit in (False, True):
        with pytest.raises(DataError) as info:
            raise verdict.refusal(explicit)
        text = info.value.line(as_flags)
        assert "no result was written" in text and "--invert-b or --invert-a" in text
        assert "invert_b=True or invert_a=True" in str(info.value)                # the API's
        assert ("contradict the data" in text) is explicit


def test_an_explicit_flag_decisively_contradicted_is_refused_below_overwhelming():
    """Issue 19: the real arm read with --invert-a fitted 6.2× better the other way (given fit 1.0° / 15 mm):
    below the 10× that refuses a default reading, it was a warning with exit 0 and a result 0.6 m wrong. An
    explicit flag the data decisively contradict, with an implausible given fit, is refused; the same evidence
    without a flag stays a warning, and a plausible given fit is never refused for a flag."""
    candidate = Candidate("b", (0.5, 0.0024), 6.2, "⟦invert_b=True⟧")
    contradicted = InversionVerdict((1.02, 0.0147), (candidate,), overwhelming=False, implausible=True)
    refusal = contradicted.refusal(explicit=True)
    assert refusal is not None and "contradict the data" in str(refusal)
    assert "accept_poor_fit=True (exit code 3)" in str(refusal) and "--" not in str(refusal)     # the API's words
    assert "--accept-poor-fit (exit code 3)" in refusal.line(as_flags)                          # the CLI's
    assert contradicted.refusal(explicit=False) is None
    plausible = InversionVerdict((0.2, 0.004), (candidate,), overwhelming=False, implausible=False)
    assert plausible.refusal(explicit=True) is None
    verdict = check_inversion(*_stations(invert_b=False))
    assert verdict is not None and verdict.implausible          # the simulated inverted capture: 5° and more


def test_flag_names_the_undo_when_the_user_inverted_the_wrong_stream():
    c = simulate_arm(12, sparse=True, seed=1)
    st = detect_stations(c.robot.inverted(), c.camera.inverted())     # --invert-a --invert-b, a wrongly
    i, j = np.triu_indices(len(st), 1)
    verdict = check_inversion(st.synced.T_a, st.synced.T_b, i, j, inverted_now=(True, True))
    assert {as_flags(c.flag) for c in verdict.candidates} == {"--no-invert-a", "--no-invert-b"}


@pytest.fixture()
def station_files(tmp_path):
    c = simulate_arm(12, sparse=True, seed=2)
    return c, write_tum(tmp_path / "robot.tum", c.robot), write_tum(tmp_path / "camera.tum", c.camera)


def test_inverted_station_capture_is_refused_without_an_explicit_flag(capsys, tmp_path, station_files):
    _, fa, fb = station_files
    out_file = tmp_path / "result.yaml"
    code, out, err = run(capsys, "calibrate", fa, fb, "-o", out_file)
    assert code == 2 and not out_file.exists()
    assert err.count("\n") == 1 and "almost certainly inverted" in err and "--invert-b" in err


def test_an_explicit_flag_the_data_contradict_is_refused(capsys, tmp_path, station_files):
    """--no-invert-b on a capture whose camera stream fits only inverted: exit 2, one line naming the
    evidence and the flag, nothing written — never a wrong extrinsic with exit 0."""
    _, fa, fb = station_files
    out_file = tmp_path / "result.yaml"
    code, out, err = run(capsys, "calibrate", fa, fb, "--no-invert-b", "--no-invert-a", "-o", out_file)
    assert code == 2 and not out_file.exists() and out == ""
    assert err.count("\n") == 1 and "contradict the data" in err and "--invert-b" in err
    code, out, err = run(capsys, "calibrate", fa, fb, "--no-invert-b", "--no-invert-a", "--accept-poor-fit", "-q")
    assert code == 3, err                                                   # kept on request: exit 3
    doc = yaml.safe_load(out)
    assert doc["warnings"][0].startswith("poor fit accepted") and doc["inversion"]["overwhelming"]
    assert "looks inverted" in doc["warnings"][1]
    c = station_files[0]
    assert pose_error(np.array(doc["matrix"]), c.truth)[0] > 1          # the streams as given: a wrong result


def test_the_right_flag_calibrates_without_an_inversion_warning(capsys, station_files):
    c, fa, fb = station_files
    code, out, err = run(capsys, "calibrate", fa, fb, "--invert-b", "-q")
    assert code == 0, err
    doc = yaml.safe_load(out)
    assert not any("inverted" in w for w in doc["warnings"]) and "inversion" not in doc
    assert pose_error(np.array(doc["matrix"]), c.truth)[1] < 0.005


def test_tf_frames_given_child_first_are_refused_naming_parent_child(capsys, tmp_path):
    """--frames-a cam0 world reads T_cam0_world: refused, and the fix names the frames PARENT CHILD in the spelling
    every command shares (tf:PARENT,CHILD); so is the same chain named in it (--stream-a tf:cam0,world)."""
    from _util import ROOT

    out_file = tmp_path / "r.yaml"
    code, out, err = run(capsys, "calibrate", ROOT / "sample_data" / "rig.mcap", "--frames-a", "cam0", "world",
                         "--frames-b", "world", "cam1", "-o", out_file)
    assert code == 2 and not out_file.exists() and err.count("\n") == 1
    assert "--stream-a tf:world,cam0 (tf:PARENT,CHILD, the parent first)" in err
    code, _, again = run(capsys, "calibrate", ROOT / "sample_data" / "rig.mcap", "--stream-a", "tf:cam0,world",
                         "--stream-b", "tf:world,cam1", "-o", out_file)
    assert code == 2 and again == err
    code, _, err = run(capsys, "calibrate", ROOT / "sample_data" / "rig.mcap", "--frames-a", "world", "cam0",
                       "--frames-b", "world", "cam1", "-o", out_file)
    assert code == 0, err


def test_an_overridden_inversion_refusal_alone_is_reported_as_accepted(capsys, monkeypatch, station_files):
    """Issue 37: ``poor_fit_accepted`` ORed the fit test's, the moved mount's and the order's refusals, not the
    inversion check's. With the fit test made to pass, only the inversion refusal is left to override: kept by
    ``accept_poor_fit``, it is an accepted poor fit (the API's flag), and the CLI exits 3, never 0."""
    from handeye_cli import calibrate
    from handeye_cli.analysis.fit_test import FitTest

    monkeypatch.setattr(FitTest, "refusal", lambda self, *args, **kwargs: None)
    c, fa, fb = station_files
    result = calibrate(c.robot, c.camera, accept_poor_fit=True)
    assert result.diagnostics.poor_fit_accepted
    assert "looks inverted" in result.warnings[0]
    assert not calibrate(c.robot, c.camera.inverted()).diagnostics.poor_fit_accepted      # nothing overridden
    code, out, err = run(capsys, "calibrate", fa, fb, "--accept-poor-fit", "-q")
    assert code == 3, err
    assert yaml.safe_load(out)["inversion"]["overwhelming"]
