"""Readings chosen by the fit: a text file's quaternion order (analysis/readings.py).

The format's order is kept unless the other fits decisively better; then it is used, said in a warning
and in ``interpretation``; an explicit ``--wxyz-*`` / ``--no-wxyz-*`` is taken as given.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import yaml
from _util import pose_error, run, write_tum

from handeye_cli import calibrate, document
from handeye_cli.analysis.readings import choose_quaternion_order
from handeye_cli.errors import DataError, as_flags
from handeye_cli.simulation import Rig, random_transform, simulate_rig
from handeye_cli.simulation.ground import simulate_ground


def _rig(seed: int, tmp_path, *, wxyz_b: bool, invert_b: bool = False):
    X = random_transform(np.random.default_rng(seed), 0.3)
    a, b = simulate_rig(Rig(X), duration_s=20, rate_a=100, rate_b=30, sigma_r=np.deg2rad(0.1), sigma_t=0.002,
                        seed=seed)
    if invert_b:
        b = b.inverted()
    fa, fb = write_tum(tmp_path / "a.tum", a), write_tum(tmp_path / "b.tum", b)
    if wxyz_b:                                    # an exporter that wrote w first under a TUM name
        rows = np.loadtxt(fb)
        np.savetxt(fb, np.c_[rows[:, :4], rows[:, 7], rows[:, 4:7]], fmt="%.9f")
    return X, fa, fb


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_w_first_tum_file_is_read_in_the_order_that_fits(capsys, tmp_path, seed):
    X, fa, fb = _rig(seed, tmp_path, wxyz_b=True)
    code, out, err = run(capsys, "calibrate", fa, fb, "-q")
    assert code == 0, err
    doc = yaml.safe_load(out)
    rot_deg, trans_m = pose_error(np.array(doc["matrix"]), X)
    assert rot_deg < 0.2 and trans_m < 0.005
    interp = doc["interpretation"]
    assert interp["chosen_by"] == "fit" and interp["quaternion_order"] == {"a": "xyzw", "b": "wxyz"}
    assert interp["runner_up"]["rotation_deg"] > 3 * interp["fit_median"]["rotation_deg"]
    assert "--no-wxyz-b" in doc["warnings"][0] and str(fb) in doc["warnings"][0]
    # the explicit flags are taken as given: the right one gives the same result, the wrong one no choice
    code, out, _ = run(capsys, "calibrate", fa, fb, "-q", "--wxyz-b")
    right = yaml.safe_load(out)
    assert right["interpretation"]["quaternion_order"] == {"a": "xyzw", "b": None}        # b's is not open
    assert right["interpretation"]["chosen_by"] == "format" and not any("wxyz" in w for w in right["warnings"])
    np.testing.assert_allclose(right["matrix"], doc["matrix"], atol=1e-9)
    code, out, _ = run(capsys, "calibrate", fa, fb, "-q", "--no-wxyz-b", "--wxyz-a")   # as told: no choice
    assert code == 2 or "interpretation" not in yaml.safe_load(out)


def test_the_format_order_is_kept_when_it_fits(capsys, tmp_path):
    X, fa, fb = _rig(3, tmp_path, wxyz_b=False)
    code, out, err = run(capsys, "calibrate", fa, fb, "-q")
    assert code == 0, err
    doc = yaml.safe_load(out)
    assert doc["interpretation"]["chosen_by"] == "format"
    assert doc["interpretation"]["quaternion_order"] == {"a": "xyzw", "b": "xyzw"}
    assert pose_error(np.array(doc["matrix"]), X)[0] < 0.2
    assert not any("quaternion" in w for w in doc["warnings"])


def test_the_order_is_found_when_the_stream_also_needs_inverting(capsys, tmp_path):
    """A camera's target detections written w first: the order is fixed by the fit whatever the inversion,
    and the inversion check then refuses, naming its flag; with it the result is right."""
    X, fa, fb = _rig(4, tmp_path, wxyz_b=True, invert_b=True)
    code, _, err = run(capsys, "calibrate", fa, fb, "-q")
    assert code == 2 and "--invert-b" in err and err.count("\n") == 1
    code, out, err = run(capsys, "calibrate", fa, fb, "-q", "--invert-b")
    assert code == 0, err
    doc = yaml.safe_load(out)
    assert doc["interpretation"]["quaternion_order"]["b"] == "wxyz"
    assert pose_error(np.array(doc["matrix"]), X)[0] < 0.2


def test_streams_whose_order_is_not_open_are_left_alone():
    """In memory (or a log's named fields, or a user's flag): no order to choose, and nothing is solved."""
    X = random_transform(np.random.default_rng(5), 0.3)
    a, b = simulate_rig(Rig(X), duration_s=10, rate_a=50, rate_b=30, seed=5)
    a2, b2, choice = choose_quaternion_order(a, b)
    assert choice is None and a2 is a and b2 is b
    assert "interpretation" not in document(calibrate(a, b))


def test_orders_that_fit_alike_with_other_extrinsics_are_refused(monkeypatch, tmp_path):
    """When the other order fits as well but gives another extrinsic, the data cannot decide: one line
    names the flags that do. (Real data that fit alike in both orders are contrived; the fits are stubbed.)"""
    from handeye_cli.analysis import readings
    from handeye_cli.io import read_stream

    _, fa, fb = _rig(7, tmp_path, wxyz_b=False)
    a, b = read_stream(fa), read_stream(fb)
    for other, refused in ((random_transform(np.random.default_rng(1), 0.1), True), (np.eye(4), False)):
        calls: list[int] = []

        def stub(*args, other=other, calls=calls):       # the format's reading first, then the others
            calls.append(1)
            return readings.MedianFit(np.eye(4), 0.1, 0.002) if len(calls) == 1 else readings.MedianFit(
                other, 0.11, 0.0021)

        monkeypatch.setattr(readings, "_best_over_inversions", stub)
        if refused:
            with pytest.raises(DataError, match=r"cannot be told.*wxyz_[ab]=False or wxyz_[ab]=True"):
                choose_quaternion_order(a, b)
        else:                                             # alike and the same extrinsic: the format's is kept
            assert choose_quaternion_order(a, b)[2].chosen_by == "format"


@pytest.mark.parametrize("units", [0.5, 2.0])
def test_monocular_units_are_found_by_the_fit(units):
    """b's translations in other units (monocular odometry): they fit far better scaled, so the scale is
    estimated with T_a_b and said in a warning; metric streams get no scale reading."""
    X = random_transform(np.random.default_rng(8), 0.3)
    a, b = simulate_rig(Rig(X), duration_s=20, rate_a=100, rate_b=30, sigma_r=np.deg2rad(0.1), sigma_t=0.002,
                        seed=8)
    metric = calibrate(a, b)
    assert "scale" not in metric.diagnostics.get("interpretation", {})
    cal = calibrate(a, replace(b, xyz=b.xyz / units))             # b in units of `units` metres
    reading = cal.diagnostics["interpretation"]["scale"]
    assert reading["applied"] and reading["gain"] > 3
    assert cal.diagnostics["scale"]["value"] == pytest.approx(units, rel=0.01)
    assert "--scale" in as_flags(cal.warnings[0])
    assert pose_error(cal.matrix, X)[1] < 3 * pose_error(metric.matrix, X)[1] + 1e-3


@pytest.mark.parametrize("w_first_b", [False, True])
def test_planar_motion_keeps_the_format_order_and_still_finds_a_w_first_file(w_first_b):
    """On planar motion a stream read inverted fits the rotations as well as the right reading (the common axis only
    turns over), with translations metres off. Ranked by the rotation alone, that inversion stood for the format's
    order, and TUM files of a 60-s diff-drive base were read as w-x-y-z (fit 1.02° / 0.118 m against 1.00° / 2.16 m);
    ranked by both medians the format's order is kept (1.00° / 0.025 m), and a file stored w first is still found."""
    g = simulate_ground("diff-drive", seed=0, duration_s=60.0)
    a = replace(g.base, quaternion_order="xyzw")
    q = g.sensor.quat_xyzw[:, [3, 0, 1, 2]] if w_first_b else g.sensor.quat_xyzw     # w x y z columns read as x y z w
    b = replace(g.sensor, quat_xyzw=q, quaternion_order="xyzw")
    a2, b2, choice = choose_quaternion_order(a, b)
    assert choice is not None and choice.orders == ("xyzw", "wxyz" if w_first_b else "xyzw")
    assert choice.chosen_by == ("fit" if w_first_b else "format") and choice.used[1] < 0.1
    assert np.allclose(np.abs(np.sum(b2.quat_xyzw * g.sensor.quat_xyzw, axis=1)), 1.0) and a2 is a


def test_readings_that_fit_alike_because_the_motion_is_degenerate_name_the_motion():
    """When the two quaternion orders fit alike with other extrinsics because the motion leaves a direction open
    (one oblique rotation axis), the refusal names the motion, not --wxyz (kinhec's motion-000004: 'cannot be told
    from the data ... say which with --wxyz-a'); a ground robot's z axis and general motion are not refused."""
    from test_observability import _arm_about_one_joint

    from handeye_cli.analysis.readings import _refuse_degenerate
    from handeye_cli.errors import UnderdeterminedError

    a, b, _, _ = _arm_about_one_joint()
    k = np.arange(0, len(a) - 10, 3)
    with pytest.raises(UnderdeterminedError, match="is not determined by the motion"):
        _refuse_degenerate(a.matrices(), b.matrices(), k, k + 10)
    g = simulate_ground("diff-drive", seed=2, duration_s=60.0)
    rig = simulate_rig(Rig(random_transform(np.random.default_rng(3), 0.3)), duration_s=20.0, seed=3)
    for stream in (g.base, rig[0]):                     # rotation about z of base_link; general 3-D motion
        T = stream.matrices()
        k = np.arange(0, len(T) - 10, 3)
        _refuse_degenerate(T, T, k, k + 10)             # no refusal
