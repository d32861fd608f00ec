"""`handeye calibrate` with the trust features: robust, auto-α, degeneracy warnings and --strict,
bootstrap, the inverted-stream hint, and the HTML report — from the CLI and from Python."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import yaml
from _util import pose_error, run, write_tum

from handeye_cli import document
from handeye_cli.calibration import calibrate
from handeye_cli.geometry import se3
from handeye_cli.simulation import Rig, simulate_rig

X = se3.from_xyz_quat(np.array([0.2, -0.1, 0.15]), np.array([0.1, -0.3, 0.2, 0.9]))


def _files(tmp_path: Path, motion: str = "3d", **kw) -> tuple[Path, Path, tuple]:
    a, b = simulate_rig(Rig(X, 0), duration_s=40, rate_a=30, rate_b=20, motion=motion,
                        sigma_r=np.deg2rad(0.2), sigma_t=0.002, seed=11, **kw)
    return write_tum(tmp_path / "a.tum", a), write_tum(tmp_path / "b.tum", b), (a, b)


def _error(doc: dict) -> tuple[float, float]:
    return pose_error(doc["matrix"], X)


def test_well_posed_log_has_no_warnings_and_reports_residuals(capsys, tmp_path):
    fa, fb, _ = _files(tmp_path)
    code, out, err = run(capsys, "calibrate", fa, fb, "--strict", "-q")
    assert code == 0, err
    doc = yaml.safe_load(out)
    assert doc["warnings"] == [] and err == ""
    r = doc["residuals"]
    assert 0 < r["rotation_median_deg"] < r["rotation_p95_deg"] < 2
    assert 0 < r["translation_median_m"] < r["translation_p95_m"] < 0.05


def test_planar_motion_is_named_and_strict_exits_3(capsys, tmp_path):
    fa, fb, _ = _files(tmp_path, motion="planar")
    out_file = tmp_path / "r.json"
    code, _, err = run(capsys, "calibrate", fa, fb, "--strict", "-q", "-o", out_file)
    assert code == 3
    doc = json.loads(out_file.read_text())
    assert any("unobservable" in w and "z of frame a" in w for w in doc["warnings"])
    assert "warning: " in err and "--strict" in err
    assert "planar" in doc["observability"]["warnings"][0]["code"] or any(
        w["code"] in ("planar", "single_axis") for w in doc["observability"]["warnings"])


def test_prior_fixes_the_planar_log(capsys, tmp_path):
    fa, fb, _ = _files(tmp_path, motion="planar")
    prior = tmp_path / "prior.yaml"
    prior.write_text(yaml.safe_dump({"translation": X[:3, 3].tolist(),
                                     "quaternion_xyzw": se3.to_xyz_quat(X)[1].tolist()}))
    code, out, _ = run(capsys, "calibrate", fa, fb, "--prior", prior, "--prior-weights", "1,100", "-q")
    assert code == 0
    assert _error(yaml.safe_load(out))[1] < 0.01


def test_forgotten_inversion_is_diagnosed(capsys, tmp_path):
    _, _, (a, b) = _files(tmp_path)
    fb_inv = write_tum(tmp_path / "b_inv.tum", b.inverted())
    # Inverted, b fits 15x better: without an explicit choice the result is refused (exit 2) …
    code, out, err = run(capsys, "calibrate", tmp_path / "a.tum", fb_inv, "-q", "--pairs", "random:300")
    assert code == 2 and not out and "almost certainly inverted" in err and "--invert-b" in err
    # … and so is one whose explicit flag (--no-invert-b: "b is right as it is") the data contradict.
    code, out, err = run(capsys, "calibrate", tmp_path / "a.tum", fb_inv, "-q", "--pairs", "random:300",
                         "--no-invert-b")
    assert code == 2 and not out and "contradict the data" in err and "--invert-b" in err
    # … and kept with --accept-poor-fit (exit 3), the inversion the first warning after the override's.
    code, out, err = run(capsys, "calibrate", tmp_path / "a.tum", fb_inv, "-q", "--pairs", "random:300",
                         "--no-invert-b", "--accept-poor-fit")
    assert code == 3, err
    warnings = yaml.safe_load(out)["warnings"]
    assert warnings[0].startswith("poor fit accepted"), warnings
    assert "looks inverted" in warnings[1] and "--invert-b" in warnings[1], warnings


def test_robust_rejects_outlier_pairs(tmp_path):
    a, b = simulate_rig(Rig(X, 0), duration_s=40, rate_a=30, rate_b=20, sigma_r=np.deg2rad(0.2),
                        sigma_t=0.002, seed=11)
    # Corrupt 10 % of the samples of b after the gates would let them through: swap in poses of
    # another time (mis-associated samples) — small steps, so the pose-jump gate cannot see them.
    rng = np.random.default_rng(0)
    xyz, _quat = b.xyz.copy(), b.quat_xyzw.copy()
    bad = rng.choice(np.arange(5, len(b) - 5), size=len(b) // 10, replace=False)
    xyz[bad] += rng.normal(0, 0.03, (len(bad), 3))
    from dataclasses import replace
    b_bad = replace(b, xyz=xyz)
    plain = calibrate(a, b_bad, max_jump="off", max_jump_deg="off")
    robust = calibrate(a, b_bad, max_jump="off", max_jump_deg="off", robust=True)
    clean = calibrate(a, b, max_jump="off", max_jump_deg="off", robust=True)
    err = lambda c: float(np.linalg.norm(c.matrix[:3, 3] - X[:3, 3]))   # noqa: E731
    assert robust.robust is not None and len(robust.robust.rejected) > 0
    assert err(robust) < err(plain)
    assert err(robust) < 1.5 * err(clean) + 1e-4
    doc = document(robust)
    spans = doc["robust"]["rejected_spans_since_start_s"]
    assert len(spans) == len(robust.robust.rejected)
    assert all(0 <= t0 <= t1 <= 40 for t0, t1 in spans)              # readable: seconds since the start


def test_alpha_auto_and_bootstrap_from_the_cli(capsys, tmp_path):
    fa, fb, _ = _files(tmp_path)
    code, out, err = run(capsys, "calibrate", fa, fb, "--alpha", "auto", "--bootstrap", "200", "--seed", "3", "-q")
    assert code == 0, err
    doc = yaml.safe_load(out)
    assert doc["alpha"] == doc["alpha_auto"]["alpha"] > 0
    u = doc["uncertainty"]
    assert u["replicates"] == 200 and len(u["rotation_std_deg"]) == 3 and len(u["translation_std_m"]) == 3
    lo, hi = np.array(u["translation_interval_m"])
    assert np.all(lo < hi) and np.all(np.array(u["translation_std_m"]) < 0.01)
    rot, trans = _error(doc)
    assert trans < 5 * max(u["translation_std_m"]) + 0.002


def test_report_from_the_cli(capsys, tmp_path):
    fa, fb, _ = _files(tmp_path)
    report = tmp_path / "report.html"
    code, _, err = run(capsys, "calibrate", fa, fb, "--bootstrap", "50", "--report", report, "-q")
    assert code == 0, err
    html = report.read_text()
    assert html.count("data:image/svg+xml;base64,") == 4 and "Bootstrap" in html
