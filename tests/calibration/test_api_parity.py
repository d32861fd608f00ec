"""Python API parity: every option acts alike on files (calibrate_files) and on the same poses in memory
(calibrate), or calibrate refuses it with a ConfigError naming the keyword; none is silently ignored.
And a PoseStream refuses float stamps."""
from __future__ import annotations

from dataclasses import fields
from fractions import Fraction

import numpy as np
import pytest
from _util import write_tum

from handeye_cli import document
from handeye_cli.calibration import StreamSpec, calibrate, calibrate_files, read_streams
from handeye_cli.errors import ConfigError, DataError, HandEyeError
from handeye_cli.geometry import se3
from handeye_cli.options import FIELDS, SECTIONS, flag, optional_flag
from handeye_cli.simulation import Rig, simulate_rig
from handeye_cli.streams import PoseStream

# A value away from the default for the options whose parser does not say one (choices and flags do)
VALUES = {
    "csv_columns": "t=t,x=x,y=y,z=z,qx=qx,qy=qy,qz=qz,qw=qw", "max_dt": 0.5, "time_offset": 0.02,
    "max_time_offset": 1.0, "max_jump": 0.5, "max_jump_deg": 30.0, "pairs": "stride:3", "min_rotation": 5.0,
    "keyframe_rotation": 3.0, "keyframe_translation": 0.05, "max_pairs": 60, "seed": 3, "alpha": 2.0,
    "scale": 1.5, "prior": "PRIOR", "prior_weights": "0.5,2", "min_pairs": 5, "bootstrap": 3,
    "name_a": "cam_a", "name_b": "cam_b", "storage_option": ["anon=true"], "remote_timeout": 5.0, "remote_retries": 2,
    "remote_deadline": 20.0,
}
# calibrate refuses these for in-memory streams: only a file reader applies them
REFUSED = {"wxyz_a", "wxyz_b", "time_unit", "csv_columns", "time_source", "storage_option", "remote_timeout",
           "remote_retries", "remote_deadline"}
# under every run (unless it is the option tested): consecutive pairs take 0.05 s where the default noise
# model's 2000 pairs take 0.7 s; both surfaces get the same options either way
FAST = {"pairs": "consecutive"}
# the pose-jump limits are --gate paper's (refused under another gate): tested with it
WITH = {"max_jump": {"gate": "paper"}, "max_jump_deg": {"gate": "paper"}}


def _value(name: str):
    section, info, default = FIELDS[name]
    if name in VALUES:
        return VALUES[name]
    if info.choices:
        return next(c for c in info.choices if c != default)
    if info.parse in (flag, optional_flag):
        return not default
    raise AssertionError(f"option {name!r} is new: give it a test value in VALUES "
                         "(tests/calibration/test_api_parity.py)")


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """Two small TUM files (20 s at 10 / 8 Hz), a prior file, and the same poses as in-memory streams."""
    d = tmp_path_factory.mktemp("parity")
    X = se3.from_xyz_quat(np.array([0.1, -0.05, 0.2]), np.array([0.1, 0.3, -0.2, 0.9]))
    a, b = simulate_rig(Rig(X, 0), duration_s=20, rate_a=10, rate_b=8, sigma_r=np.deg2rad(0.1), sigma_t=0.001,
                        seed=7)
    fa, fb = write_tum(d / "a.tum", a), write_tum(d / "b.tum", b)
    prior = d / "prior.yaml"
    prior.write_text(f"translation: {X[:3, 3].tolist()}\nquaternion_xyzw: "
                     f"{se3.to_xyz_quat(X[None])[1][0].tolist()}\n", encoding="utf-8")
    streams = read_streams([StreamSpec(str(fa)), StreamSpec(str(fb))])    # what the files hold, as read
    return {"files": (fa, fb), "streams": streams, "prior": str(prior)}


def _outcome(run):
    """The result's document without ``inputs`` (files vs memory), plus what it records as inverted; or the
    error raised."""
    try:
        cal = run()
    except HandEyeError as e:
        return type(e), str(e)
    doc = document(cal)
    inputs = doc.pop("inputs")
    return doc, {k: v for k, v in inputs.items() if k.startswith("invert")}


def test_every_option_is_covered():
    names = [f.name for cls in SECTIONS.values() for f in fields(cls)]
    assert sorted(names) == sorted(FIELDS) and set(FIELDS) >= REFUSED
    for name in names:
        assert _value(name) != FIELDS[name][2] or name == "prior"


@pytest.mark.parametrize("name", sorted(FIELDS))
def test_option_acts_alike_in_memory_or_is_refused(recording, name):
    value = _value(name)
    value = recording["prior"] if value == "PRIOR" else value
    (fa, fb), (sa, sb) = recording["files"], recording["streams"]
    if name in REFUSED:
        with pytest.raises(ConfigError) as info:
            calibrate(sa, sb, **{name: value})
        assert info.value.where == name and f"{name}=" in str(info.value)
        return
    options = {**FAST, **WITH.get(name, {}), name: value}
    from_files = _outcome(lambda: calibrate_files(fa, fb, **options))
    in_memory = _outcome(lambda: calibrate(sa, sb, **options))
    assert from_files == in_memory, name
    if name not in ("invert_a", "invert_b"):                 # an inverted stream may not calibrate at all
        doc, _ = from_files
        assert isinstance(doc, dict), doc
        assert doc["settings"]["options"][name] != FIELDS[name][2]          # recorded as applied


def test_defaults_agree_and_invert_b_is_applied(recording):
    (fa, fb), (sa, sb) = recording["files"], recording["streams"]
    assert _outcome(lambda: calibrate_files(fa, fb, **FAST)) == _outcome(lambda: calibrate(sa, sb, **FAST))
    # b needs no inversion: the data refute the flag (refused), so the result is asked for anyway to compare
    plain, flipped = calibrate(sa, sb, **FAST), calibrate(sa, sb, **FAST, invert_b=True, accept_poor_fit=True)
    assert np.abs(plain.matrix - flipped.matrix).max() > 0.01             # the inversion changed the problem
    assert flipped.stream_b.child_frame_id == sb.child_frame_id and flipped.inputs.as_dict() == {"invert_b": True}
    # the sensor keeps its name (a text file's world is unnamed)
    with pytest.raises(DataError, match="contradict the data"):
        calibrate(sa, sb, **FAST, invert_b=True)
    by_hand = calibrate(sa, sb.inverted(), **FAST, invert_b=False, accept_poor_fit=True)
    np.testing.assert_array_equal(flipped.matrix, by_hand.matrix)


def test_calibrate_files_refuses_file_options_for_an_in_memory_stream(recording):
    (fa, _), (_, sb) = recording["files"], recording["streams"]
    with pytest.raises(ConfigError, match=r"\(wxyz_b\)"):
        calibrate_files(fa, sb, wxyz_b=True)
    as_is, w_first = calibrate_files(fa, sb, **FAST), calibrate_files(fa, sb, wxyz_a=True, accept_poor_fit=True,
                                                                      **FAST)   # the wrong order, kept on request
    assert np.abs(as_is.matrix - w_first.matrix).max() > 0.01             # a's file was read w first
    assert calibrate_files(fa, sb, time_unit="s", **FAST).options.read.time_unit == "s"   # a file reads it


def test_pose_stream_refuses_float_stamps():
    xyz, quat = np.zeros((2, 3)), np.tile([0.0, 0, 0, 1], (2, 1))
    with pytest.raises(DataError, match=r"stamps must be int64 nanoseconds; use PoseStream.from_seconds"):
        PoseStream(np.array([0.0, 0.1]), xyz, quat)
    with pytest.raises(DataError, match=r"\(cam0\)"):                     # names the stream's source
        PoseStream([0.5, 1.5], xyz, quat, source="cam0")
    seconds = [1_700_000_000.123456789, 1_700_000_000.2, -3.0000000015]
    s = PoseStream.from_seconds(seconds, np.zeros((3, 3)), np.tile([0.0, 0, 0, 1], (3, 1)), frame_id="w")
    assert s.stamps_ns.dtype == np.int64 and s.frame_id == "w"
    assert s.stamps_ns.tolist() == [round(Fraction(t) * 10**9) for t in seconds]   # each float's exact value
    assert PoseStream.from_seconds([0.5, 2.25], xyz, quat).stamps_ns.tolist() == [500_000_000, 2_250_000_000]
    assert len(PoseStream([], np.zeros((0, 3)), np.zeros((0, 4)))) == 0   # empty lists are no float stamps
    with pytest.raises(DataError, match="finite"):
        PoseStream.from_seconds([np.nan, 1.0], xyz, quat)


def test_solve_has_the_command_lines_defaults_and_values(tmp_path, capsys):
    """Issue 21: Python ``solve()`` defaulted to α = 1.0 where ``handeye solve`` defaults to auto, refused
    ``alpha="auto"`` with a TypeError, and refused ``method="Tsai"`` which the CLI took as ``--method Tsai``.
    Now both surfaces take the options' defaults and values, and give the same answer."""
    import inspect
    import json
    from pathlib import Path

    import handeye_cli
    from handeye_cli.cli import main
    from handeye_cli.io.pairfile import read_pairs

    pairs = Path(__file__).parents[2] / "sample_data" / "pairs.csv"
    params = inspect.signature(handeye_cli.solve).parameters
    assert params["alpha"].default == FIELDS["alpha"][2] == "auto"
    assert params["method"].default == FIELDS["method"][2]
    A, B, w = read_pairs(str(pairs))
    for method, alpha in (("DQopt", "auto"), ("Tsai", "2")):
        sol = handeye_cli.solve(A, B, method=method, alpha=alpha, weights=w)
        with pytest.raises(SystemExit) as exit_:
            main(["solve", str(pairs), "--method", method, "--alpha", alpha, "--format", "json"])
        doc = json.loads(capsys.readouterr().out)
        assert exit_.value.code == 0 and sol.method == method.lower()
        assert doc["alpha"] == pytest.approx(sol.alpha) and doc["method"] == sol.method and sol.alpha != 1.0
        assert np.allclose(doc["matrix"], sol.matrix, atol=1e-12)
    with pytest.raises(ConfigError, match=r"\(alpha\)"):
        handeye_cli.solve(A, B, alpha="fast")


def test_a_nan_in_an_in_memory_stream_is_named_as_the_user_indexes_it():
    """What a new user hit (issue 21): a NaN in stream b was reported as ``motions_b[401]``, an internal
    index into the motion pairs. It is stream b's sample as the user's arrays index it (0-based)."""
    from dataclasses import replace

    from handeye_cli.rig import calibrate_rig

    a, b = simulate_rig(Rig(np.eye(4)), duration_s=10.0, seed=1)
    xyz = b.xyz.copy()
    xyz[10, 1] = np.nan
    quat = b.quat_xyzw.copy()
    quat[12] = 0.0
    bad = replace(b, xyz=xyz, quat_xyzw=quat)
    with pytest.raises(DataError, match=r"^stream b, sample 10 \(0-based: xyz\[10\] \[[^]]*nan[^]]*\], quat_xyzw\[10\]"
                                        r".*; 2 such sample\(s\) in all") as e:
        calibrate_files(a, bad)
    assert "motions" not in str(e.value)
    with pytest.raises(DataError, match=r"^stream 'cam1', sample 10 \(0-based"):
        calibrate_rig({"cam0": a, "cam1": bad})


def test_python_errors_name_keywords_where_the_command_line_names_flags(capsys):
    """The same refusal in each surface's words: the CLI's fix names flags, the Python API's the keyword
    arguments (issue 21: the API's errors cited CLI flags)."""
    from _util import run

    import handeye_cli

    with pytest.raises(handeye_cli.HandEyeError) as info:
        handeye_cli.calibrate_files("sample_data/rig.mcap", topic_a="/cam0/pose", topic_b="/cam1/pose",
                                    max_jump=0.01)
    assert "(max_jump)" in str(info.value) and "gate='paper'" in info.value.fix and "--" not in str(info.value)
    code, _, err = run(capsys, "calibrate", "sample_data/rig.mcap", "--topic-a", "/cam0/pose", "--topic-b",
                       "/cam1/pose", "--max-jump", "0.01")
    assert code == 2 and "(--max-jump)" in err and "--gate paper" in err


def test_the_stream_keywords_are_the_command_lines_stream_flags():
    """One spelling of a stream on both surfaces (issue 21): calibrate_files takes a keyword for each of the flags
    calibrate, compare and batch name a stream by (--stream-a SOURCE and its synonyms --topic-a, --frames-a)."""
    import inspect

    from handeye_cli.cli.batch import batch
    from handeye_cli.cli.calibrate import calibrate as calibrate_command
    from handeye_cli.cli.compare import compare
    from handeye_cli.cli.params import STREAM_KEYS

    assert set(STREAM_KEYS) <= set(inspect.signature(calibrate_files).parameters)
    for command in (calibrate_command, compare, batch):
        names = {p.name for p in command.params}
        assert names & {k for k in names if k.split("_")[0] in ("stream", "topic", "frames")} == set(STREAM_KEYS)
