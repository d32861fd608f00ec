"""The command line end to end on text pose files: results, options, config precedence, errors."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from _util import ROOT, pose_error, run, write_tum

from handeye_cli.geometry import se3
from handeye_cli.io.pairfile import read_extrinsic
from handeye_cli.simulation import Rig, motion_pairs, random_transform, simulate_rig


def test_version_and_help(capsys):
    code, out, _ = run(capsys, "--version")
    assert code == 0 and "0.1.0" in out
    for cmd in ("solve", "calibrate", "inspect", "batch", "check", "report", "rig", "compare"):
        code, out, _ = run(capsys, cmd, "--help")
        assert code == 0 and "Example" in out and f"handeye {cmd}" in out


def test_solve_sample_pairs_recovers_the_truth(capsys):
    code, out, _ = run(capsys, "solve", ROOT / "sample_data" / "pairs.csv")
    assert code == 0
    doc = yaml.safe_load(out)
    rot, trans = pose_error(np.array(doc["matrix"]), read_extrinsic(ROOT / "sample_data" / "pairs_truth.yaml"))
    assert rot < 0.5 and trans < 0.02          # 100 pairs with σr = 0.57°, σt = 1 cm
    for key in ("matrix", "translation", "quaternion_xyzw", "frames", "method", "alpha", "cost", "pairs_used",
                "samples", "inputs", "version", "warnings"):
        assert key in doc


def test_solve_npz_with_weights_and_prior(capsys, tmp_path):
    rng = np.random.default_rng(1)
    X = random_transform(rng)
    A, B = motion_pairs(30, X, rng, sigma_r=0.01, sigma_t=0.01)
    np.savez(tmp_path / "p.npz", A=A, B=B, weights=np.full(30, 2.0))
    code, out, _ = run(capsys, "solve", tmp_path / "p.npz", "--method", "dq2ndord", "--format", "json")
    assert code == 0
    doc = json.loads(out)
    assert doc["method"] == "dq2ndord" and pose_error(np.array(doc["matrix"]), X)[0] < 2
    (tmp_path / "prior.yaml").write_text(out)
    code, out2, _ = run(capsys, "solve", tmp_path / "p.npz", "--prior", tmp_path / "prior.yaml",
                        "--prior-weights", "1e6,1e6")
    assert code == 0 and np.allclose(yaml.safe_load(out2)["matrix"], doc["matrix"], atol=1e-5)


def test_calibrate_two_tum_files(capsys, rig, tmp_path):
    code, out, err = run(capsys, "calibrate", rig["a"], rig["b"])
    assert code == 0, err
    doc = yaml.safe_load(out)
    rot, trans = pose_error(np.array(doc["matrix"]), rig["X"])
    assert rot < 0.1 and trans < 0.005
    s = doc["samples"]
    assert s["read_a"] == 1800 and s["read_b"] == 1200 and s["dropped_pose_jump"] >= 3
    assert doc["pairs_used"] == s["pairs"] > 100
    assert "T_a_b" in err                                   # the one-line summary on stderr


def test_yaml_and_json_carry_the_same_content(capsys, rig, tmp_path):
    assert run(capsys, "calibrate", rig["a"], rig["b"], "-q", "-o", tmp_path / "r.json")[0] == 0
    assert run(capsys, "calibrate", rig["a"], rig["b"], "-q", "-o", tmp_path / "r.yaml")[0] == 0
    as_json = json.loads((tmp_path / "r.json").read_text())
    as_yaml = yaml.safe_load((tmp_path / "r.yaml").read_text())
    assert as_json == as_yaml
    assert not list(tmp_path.glob(".*tmp"))                 # no temporary file left behind


def test_swapping_the_streams_gives_the_inverse(capsys, rig):
    X_ab = np.array(yaml.safe_load(run(capsys, "calibrate", rig["a"], rig["b"], "-q")[1])["matrix"])
    X_ba = np.array(yaml.safe_load(run(capsys, "calibrate", rig["b"], rig["a"], "-q")[1])["matrix"])
    rot, trans = pose_error(X_ba, se3.inverse(X_ab))
    assert rot < 0.05 and trans < 0.003
    for estimate in (X_ab, se3.inverse(X_ba)):              # each against the truth, not only each other
        rot, trans = pose_error(estimate, rig["X"])
        assert rot < 0.1 and trans < 0.005


def test_invert_b_undoes_an_inverted_stream(capsys, rig, tmp_path):
    _, b = rig["streams"]
    inv = write_tum(tmp_path / "b_inv.tum", b.inverted())
    code, out, _ = run(capsys, "calibrate", rig["a"], inv, "--invert-b", "-q")
    assert code == 0
    assert pose_error(np.array(yaml.safe_load(out)["matrix"]), rig["X"])[1] < 0.005


def test_time_offset_auto(capsys, tmp_path):
    X = random_transform(np.random.default_rng(5), 0.3)
    a, b = simulate_rig(Rig(X, 100_250_000_000), duration_s=60, rate_a=100, rate_b=30,
                        sigma_r=np.deg2rad(0.1), sigma_t=0.002, seed=5)
    fa, fb = write_tum(tmp_path / "a.tum", a), write_tum(tmp_path / "b.tum", b)
    code, _, err = run(capsys, "calibrate", fa, fb, "--time-offset", "0")
    assert code == 2 and "--time-offset" in err             # forced 0: the raw spans do not overlap, the error says so
    code, _, err = run(capsys, "calibrate", fa, fb)          # beyond the default range (the 60-s span): refused
    assert code == 2 and "do not overlap" in err and "--max-time-offset" in err, err
    for flags in (["--max-time-offset", "200"], ["--time-offset", "auto", "--max-time-offset", "off"]):
        code, out, err = run(capsys, "calibrate", fa, fb, *flags, "-q")   # estimated, applied (significant), warned
        assert code == 0, err
        doc = yaml.safe_load(out)
        assert doc["time_offset"]["seconds"] == pytest.approx(100.25, abs=1e-3) and doc["time_offset"]["applied"]
        assert any("clock offset of 100.25" in w and "did not overlap" in w for w in doc["warnings"]), doc["warnings"]
        assert pose_error(np.array(doc["matrix"]), X)[1] < 0.005


def test_default_time_offset_applies_only_a_significant_estimate(capsys, tmp_path):
    """No clock offset: the default's estimate is reported and, within its σ of 0, not applied; a 30 ms one is."""
    X = random_transform(np.random.default_rng(6), 0.3)
    for true_ns, applied in ((0, False), (30_000_000, True)):
        a, b = simulate_rig(Rig(X, true_ns), duration_s=30, rate_a=100, rate_b=30, sigma_r=np.deg2rad(0.1),
                            sigma_t=0.002, seed=6)
        fa, fb = write_tum(tmp_path / "a.tum", a), write_tum(tmp_path / "b.tum", b)
        code, out, err = run(capsys, "calibrate", fa, fb, "-q")
        assert code == 0, err
        report = yaml.safe_load(out)["time_offset"]
        assert report["applied"] is applied
        assert report["estimated_seconds"] == pytest.approx(true_ns / 1e9, abs=3 * report["std_seconds"] + 1e-4)
        assert report["seconds"] == (report["estimated_seconds"] if applied else 0.0)


def test_config_file_and_command_line_precedence(capsys, rig, tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("method: dq2steps\npairs: stride:5\nmax_pairs: 50\n")
    doc = yaml.safe_load(run(capsys, "calibrate", rig["a"], rig["b"], "--config", cfg, "-q")[1])
    assert doc["method"] == "dq2steps" and doc["pairs_used"] == 50
    doc = yaml.safe_load(run(capsys, "calibrate", rig["a"], rig["b"], "--config", cfg, "--method", "dqopt",
                             "--max-pairs", "40", "-q")[1])
    assert doc["method"] == "dqopt" and doc["pairs_used"] == 40


def test_default_config_file_documents_the_defaults():
    from handeye_cli.config import default_yaml, load_options

    text = (ROOT / "configs" / "default.yaml").read_text()
    assert text == default_yaml(), "configs/default.yaml is generated: python -c 'from handeye_cli.config import " \
        "default_yaml; print(default_yaml(), end=\"\")' > configs/default.yaml"
    assert load_options(ROOT / "configs" / "default.yaml") == load_options()


def test_gates_can_be_switched_off(capsys, rig):
    doc = yaml.safe_load(run(capsys, "calibrate", rig["a"], rig["b"], "--max-jump", "off", "--max-jump-deg", "off",
                             "-q")[1])
    assert doc["samples"]["dropped_pose_jump"] == 0


@pytest.mark.parametrize("args, message", [
    (["calibrate", "missing.tum", "missing2.tum"], "not found"),
    (["calibrate", "{a}"], "a topic or a TF chain for each stream"),
    (["calibrate", "{a}", "{b}", "--pairs", "bogus"], "bad pair strategy"),
    (["calibrate", "{a}", "{b}", "--pairs", "keyframes", "--min-rotation", "179"], "motion pair(s) left"),
    (["calibrate", "{a}", "{b}", "--max-dt", "1e-6"], "timestamp gate"),
    (["calibrate", "{a}", "{b}", "--time-offset", "soon"], "bad value"),
    (["calibrate", "{a}", "{b}", "--alpha", "big"], "bad value"),
    (["calibrate", "{a}", "{b}", "--config", "{dir}/bad.yaml"], "grouped key 'pairs'"),
    (["calibrate", "{a}", "{b}", "--method", "kabsch"], "Invalid value"),
    (["solve", "{dir}/bad_pairs.csv"], "unexpected CSV header"),
])
def test_errors_are_one_line_exit_2_and_leave_no_output(capsys, rig, args, message):
    d = rig["dir"]
    (d / "bad.yaml").write_text("pairs:\n  stratgy: all\n")
    (d / "bad_pairs.csv").write_text("a,b\n1,2\n")
    out_file = d / "result.yaml"
    argv = [a.format(a=rig["a"], b=rig["b"], dir=d) for a in args] + ["-o", str(out_file)]
    code, out, err = run(capsys, *argv)
    assert code == 2
    assert err.startswith("error: ") and message in err and err.count("\n") == 1, err
    assert out == "" and not out_file.exists()


def test_output_to_a_missing_folder_is_anpose_error(capsys, rig):
    code, _, err = run(capsys, "calibrate", rig["a"], rig["b"], "-o", "/nonexistent/dir/r.yaml")
    assert code == 2 and "output folder" in err


def test_generic_csv_with_columns_from_the_config(capsys, rig, tmp_path):
    """A CSV with its own column names, mapped by ``csv_columns`` in a config file."""
    names = ["time_ms", "px", "py", "pz", "rx", "ry", "rz", "rw"]
    paths = []
    for name, stream in zip("ab", rig["streams"], strict=True):
        p = tmp_path / f"{name}.csv"
        data = np.c_[stream.stamps_ns / 1e6, stream.xyz, stream.quat_xyzw]
        np.savetxt(p, data, delimiter=",", header=",".join(names), comments="", fmt="%.9f")
        paths.append(p)
    cfg = tmp_path / "columns.yaml"
    cfg.write_text(yaml.safe_dump({"csv_columns": {"t": "time_ms", "t_unit": "ms", "x": "px", "y": "py", "z": "pz",
                                                   "qx": "rx", "qy": "ry", "qz": "rz", "qw": "rw"}}))
    code, out, err = run(capsys, "calibrate", *paths, "--config", cfg, "-q")
    assert code == 0, err
    rot, trans = pose_error(np.array(yaml.safe_load(out)["matrix"]), rig["X"])
    assert rot < 0.1 and trans < 0.005


def _truncated_mcap(d: Path) -> Path:
    """Cut before the first complete chunk: nothing to recover (a longer intact part is read, with a warning)."""
    data = (ROOT / "sample_data" / "rig.mcap").read_bytes()
    p = d / "truncated.mcap"
    p.write_bytes(data[:100])
    return p


def _nan_tum(d: Path) -> Path:
    """Every pose NaN (a few invalid poses are dropped with a warning; none valid is an error)."""
    lines = (ROOT / "sample_data" / "rig_a.tum").read_text().splitlines()
    for i, ln in enumerate(lines):
        if ln.strip() and not ln.startswith("#"):
            lines[i] = " ".join(ln.split()[:4] + ["nan", "0", "0", "1"])
    p = d / "nan.tum"
    p.write_text("\n".join(lines) + "\n")
    return p


@pytest.mark.parametrize("make, extra, message", [
    (_truncated_mcap, ["--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose"], "truncated.mcap"),
    (_nan_tum, [str(ROOT / "sample_data" / "rig_b.tum")], "nan.tum"),
    (lambda d: ROOT / "sample_data" / "rig.mcap", ["--topic-a", "/tf_static", "--topic-b", "/cam1/pose"], "/tf_static"),
    (lambda d: ROOT / "sample_data" / "rig.mcap", ["--frames-a", "world", "nowhere", "--topic-b", "/cam1/pose"],
     "nowhere"),
    (lambda d: (d / "empty.tum").write_text("# nothing\n") and d / "empty.tum",
     [str(ROOT / "sample_data" / "rig_b.tum")], "empty.tum"),
])
def test_bad_logs_give_one_line_exit_2_and_no_output(capsys, tmp_path, make, extra, message):
    src = make(tmp_path)
    out_file = tmp_path / "r.yaml"
    code, out, err = run(capsys, "calibrate", src, *extra, "-o", out_file)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1 and message in err, err
    assert out == "" and not out_file.exists()


def test_a_cap_that_keeps_too_few_pairs_says_so(capsys, rig):
    code, _, err = run(capsys, "calibrate", rig["a"], rig["b"], "--max-pairs", "2")
    assert code == 2 and "raise --max-pairs" in err and err.count("\n") == 1


def test_an_estimated_offset_the_fit_contradicts_is_not_applied(capsys, tmp_path, monkeypatch):
    """A significant estimate that is an alias (periodic motion, a short recording) fits worse than no offset
    and synchronises a fraction of the samples: it is reported, not applied; the true one (0 here) is used."""
    from handeye_cli.stages import timeoffset

    X = random_transform(np.random.default_rng(7), 0.3)
    a, b = simulate_rig(Rig(X, 0), duration_s=20, rate_a=100, rate_b=30, sigma_r=np.deg2rad(0.1), sigma_t=0.002,
                        seed=7)
    alias = timeoffset.TimeOffset(offset_ns=-9_000_000_000, std_ns=1e5, coarse_ns=-9_000_000_000, correlation=0.9,
                                  method="stub")
    monkeypatch.setattr(timeoffset, "estimate_time_offset", lambda *args, **kw: alias)
    fa, fb = write_tum(tmp_path / "a.tum", a), write_tum(tmp_path / "b.tum", b)
    code, out, err = run(capsys, "calibrate", fa, fb, "-q")
    assert code == 0, err
    doc = yaml.safe_load(out)
    report = doc["time_offset"]
    assert report["estimated_seconds"] == -9.0 and report["applied"] is False and report["seconds"] == 0.0
    assert report["confirmed_by"] is None
    assert report["fit_median"]["applied"]["samples"] < 0.8 * report["fit_median"]["none"]["samples"]
    assert pose_error(np.array(doc["matrix"]), X)[1] < 0.005


def _stub_offset(monkeypatch, seconds: float) -> None:
    from handeye_cli.stages import timeoffset

    est = timeoffset.TimeOffset(offset_ns=int(seconds * 1e9), std_ns=1e5, coarse_ns=int(seconds * 1e9),
                                correlation=0.9, method="stub")
    monkeypatch.setattr(timeoffset, "estimate_time_offset", lambda *args, **kw: est)


def test_an_offset_that_drops_samples_needs_a_misfit_without_it(capsys, tmp_path, monkeypatch):
    """An estimate that keeps fewer than 80 % of the samples and whose pairs fit better (here made to fit far
    better, as the 50 samples of a periodic arm capture's alias fit by chance) is not applied when every sample without
    it fits as the streams' noise predicts: it has nothing to explain (kinhec noise-000001: 154° wrong applied)."""
    from handeye_cli.analysis.readings import MedianFit
    from handeye_cli.verify import reading

    X = random_transform(np.random.default_rng(7), 0.3)
    a, b = simulate_rig(Rig(X, 0), duration_s=20, rate_a=100, rate_b=30, sigma_r=np.deg2rad(0.1), sigma_t=0.002,
                        seed=7)
    _stub_offset(monkeypatch, -9.0)
    real = reading.median_fit
    calls = []

    def flattering(A, B, **kw):                   # the estimate's pairs are solved first: they fit far better
        fit = real(A, B, **kw)
        calls.append(len(A))
        return MedianFit(fit.matrix, 1e-3, 1e-5) if len(calls) == 1 else fit
    monkeypatch.setattr(reading, "median_fit", flattering)
    fa, fb = write_tum(tmp_path / "a.tum", a), write_tum(tmp_path / "b.tum", b)
    code, out, err = run(capsys, "calibrate", fa, fb, "-q")
    assert code == 0, err
    report = yaml.safe_load(out)["time_offset"]
    assert len(calls) == 2 and report["applied"] is False and report["confirmed_by"] is None
    assert report["fit_median"]["applied"]["samples"] < 0.8 * report["fit_median"]["none"]["samples"]


def test_an_offset_that_drops_samples_is_applied_where_they_misfit_without_it(capsys, tmp_path, monkeypatch):
    """b's clock 6 s ahead, both logs cut to the same 20 s of stamps: the true offset pairs 70 % of the samples
    that the stamps pair as they are. Without it nothing fits, with it every pair does, so it is applied."""
    X = random_transform(np.random.default_rng(7), 0.3)
    a, b = simulate_rig(Rig(X, 6_000_000_000), duration_s=26, rate_a=100, rate_b=30, sigma_r=np.deg2rad(0.1),
                        sigma_t=0.002, seed=7)
    t0 = a.stamps_ns[0] + 6_000_000_000
    a, b = (s.select((s.stamps_ns >= t0) & (s.stamps_ns <= t0 + 20_000_000_000)) for s in (a, b))
    _stub_offset(monkeypatch, 6.0)
    fa, fb = write_tum(tmp_path / "a.tum", a), write_tum(tmp_path / "b.tum", b)
    code, out, err = run(capsys, "calibrate", fa, fb, "-q", "--max-time-offset", "off", "--no-wxyz-a", "--no-wxyz-b")
    assert code == 0, err
    doc = yaml.safe_load(out)
    report = doc["time_offset"]
    assert report["applied"] is True and report["confirmed_by"] == "fit" and report["seconds"] == 6.0
    assert report["fit_median"]["applied"]["samples"] < 0.8 * report["fit_median"]["none"]["samples"]
    assert pose_error(np.array(doc["matrix"]), X)[1] < 0.005


def test_solve_takes_robust_bootstrap_and_against_as_calibrate_does(capsys, tmp_path):
    """Issue 21: 'solve lacks --robust/--bootstrap/--against' (click's bare 'No such option'). On a file of pairs
    with 6 gross outliers, --robust rejects exactly those and recovers X where the plain solve does not;
    --bootstrap N gives the uncertainty section; --against the truth exits 0 and against a nominal 2 cm off
    exits 1 with the verdict in the result. handeye_cli.solve_pairs gives the same result."""
    import handeye_cli

    rng = np.random.default_rng(4)
    X = random_transform(rng)
    A, B = motion_pairs(60, X, rng, sigma_r=0.002, sigma_t=0.002)
    bad = np.array([3, 11, 20, 31, 45, 58])
    B[bad] = np.stack([random_transform(rng) for _ in bad])
    np.savez(tmp_path / "p.npz", A=A, B=B)
    code, out, err = run(capsys, "solve", tmp_path / "p.npz", "--format", "json", "-q")
    assert code == 0 and pose_error(np.array(json.loads(out)["matrix"]), X)[1] > 0.01, err      # spoilt
    code, out, err = run(capsys, "solve", tmp_path / "p.npz", "--robust", "--bootstrap", "40", "--format", "json",
                         "-q")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["robust"]["rejected"] == bad.tolist() and doc["robust"]["inliers"] == 54
    rot, trans = pose_error(np.array(doc["matrix"]), X)
    assert rot < 0.2 and trans < 0.002
    u = doc["uncertainty"]
    assert u["replicates"] == 40 and 0 < max(u["translation_std_m"]) < 0.002
    from inspect import signature

    from handeye_cli.options import FIELDS

    params = signature(handeye_cli.solve_pairs).parameters            # the flags' keywords, with their defaults
    assert all(params[k].default == FIELDS[k][2] for k in ("method", "alpha", "robust", "bootstrap", "seed"))
    py = handeye_cli.solve_pairs(A, B, robust=True, bootstrap=40)
    assert np.allclose(py.solution.matrix, doc["matrix"], atol=1e-12) and py.robust is not None
    assert py.sections()["uncertainty"]["translation_std_m"] == pytest.approx(u["translation_std_m"])

    def line(T: np.ndarray) -> str:
        t, q = se3.to_xyz_quat(T)
        return "static_transform_publisher " + " ".join(repr(float(v)) for v in (*t, *q)) + " a b"

    moved = X.copy()
    moved[0, 3] += 0.02
    for nominal, want in ((X, 0), (moved, 1)):
        code, out, err = run(capsys, "solve", tmp_path / "p.npz", "--robust", "--against", line(nominal),
                             "--format", "json", "-q")
        assert code == want and json.loads(out)["verdict"]["drift"] == bool(want), err
