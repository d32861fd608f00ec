"""The HTML report: self-contained structure, the alignment it plots, and rendering in a real
headless browser (Debian's chromium). .ci/run installs it and sets CI=1, where a missing browser fails;
elsewhere (a fresh machine running the README's test command) the browser test is skipped, saying why."""
from __future__ import annotations

import base64
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from _html import _images, _run_chromium
from scipy.spatial.transform import Rotation

from handeye_cli import document
from handeye_cli.calibration import calibrate
from handeye_cli.errors import HandEyeError
from handeye_cli.output.report import render_report, world_alignment, write_report
from handeye_cli.simulation import Rig, random_transform, simulate_rig

WARNING = "translation along z of frame a is unobservable: spread < 0.4° & more"
SVG_URI = "data:image/svg+xml;base64,"


@pytest.fixture(scope="module")
def rig():
    rng = np.random.default_rng(7)
    X, G = random_transform(rng, 0.3), random_transform(rng, 5.0)
    a, b = simulate_rig(Rig(X), duration_s=20.0, sigma_r=0.002, sigma_t=0.002, jumps=1, seed=11, T_wb_wa=G)
    return X, G, calibrate(a, b)


@pytest.fixture(scope="module")
def full(rig):
    """The calibration with two warnings, pairs rejected by --robust and more diagnostic sections (a bootstrap):
    the report reads the typed calibration, so that is what is given."""
    from dataclasses import replace

    _, _, cal = rig
    robust = calibrate(cal.stream_a, cal.stream_b, robust=True, bootstrap=20)
    return replace(robust, warnings=[WARNING, "second warning"])


@pytest.fixture(scope="module")
def full_doc(full):
    return document(full)


@pytest.fixture(scope="module")
def deviations():
    rng = np.random.default_rng(3)
    return np.c_[rng.normal(0, 0.02, (300, 3)), rng.normal(0, 1e-3, (300, 3))]


@pytest.fixture(scope="module")
def report(full, deviations, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("report") / "out.html"
    path.write_text(render_report(full, deviations), encoding="utf-8")
    return path


def test_report_is_self_contained_and_states_the_result(report, full_doc, rig):
    text = report.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    for v in [*full_doc["translation"], *full_doc["quaternion_xyzw"], *np.ravel(full_doc["matrix"])]:
        assert f"{v:.6f}" in text
    # The stated numbers against the simulation's truth (scipy's quaternion, w ≥ 0), not only the document.
    X = rig[0]
    q = Rotation.from_matrix(X[:3, :3]).as_quat()
    shown = np.array([float(v) for v in re.findall(r"-?\d+\.\d{6}\b", text)])
    for v in [*X[:3, 3], *(q if q[3] >= 0 else -q)]:
        assert np.abs(shown - v).min() < 2e-3, v
    assert "dqopt" in text and str(full_doc["pairs_used"]) in text
    assert "2 warning(s)" in text and "second warning" in text
    assert "spread &lt; 0.4° &amp; more" in text                      # escaped, not raw HTML
    for section in ("Time offset", "Uncertainty", "Residual summary", "Outlier rejection", "Observability"):
        assert section in text
    images = _images(text)
    assert len(images) == 4 == text.count("<img")                     # trajectories, residuals, samples, bootstrap
    for src in images:
        assert src.startswith(SVG_URI)
        svg = ET.fromstring(base64.b64decode(src[len(SVG_URI):]))       # well-formed XML
        assert svg.tag == "{http://www.w3.org/2000/svg}svg" and float(svg.get("width", 0)) > 500
    assert not re.search(r"https?:", text, flags=re.I)
    assert not re.search(r"\b(?:src|href)\s*=\s*['\"](?!data:|#)", text)    # nothing fetched from anywhere
    assert "<link" not in text and "@import" not in text and "url(" not in text
    assert report.stat().st_size < 2_000_000
    assert [p.name for p in report.parent.iterdir()] == ["out.html"]        # no temp file left behind


def test_optional_parts_may_be_missing(rig, tmp_path):
    _, _, cal = rig                                                   # no warnings, no robust step, no bootstrap
    (tmp_path / "bare.html").write_text(render_report(cal, np.full((4, 6), np.nan)), encoding="utf-8")
    text = (tmp_path / "bare.html").read_text(encoding="utf-8")
    for v in cal.matrix[:3, 3]:
        assert f"{v:.6f}" in text
    assert "No warnings." in text and "no finite replicates" in text
    assert len(_images(text)) == 3                                    # no bootstrap figure without finite replicates


def test_bad_arguments_fail_without_a_file(rig, tmp_path):
    _, _, cal = rig
    with pytest.raises(ValueError, match=r"\(K, 6\)"):
        render_report(cal, np.zeros((5, 3)))
    with pytest.raises(HandEyeError):
        write_report(tmp_path / "missing" / "r.html", cal)
    assert list(tmp_path.iterdir()) == []


def test_world_alignment_recovers_the_world_to_world_transform(rig):
    X, G, cal = rig                                                   # T_wb_b = G · T_wa_a · X
    W = world_alignment(cal.synced, cal.matrix)                       # T_wa_wb = G⁻¹
    err = W @ G
    assert np.rad2deg(np.arccos(np.clip((np.trace(err[:3, :3]) - 1) / 2, -1, 1))) < 0.1
    assert np.linalg.norm(err[:3, 3]) < 0.01


# ---------------------------------------------------------------------------------------------
def test_report_renders_in_headless_chromium(report, tmp_path):
    url = report.resolve().as_uri()
    dom = _run_chromium(tmp_path, "--dump-dom", url).stdout
    body = re.search(r"<body\b[^>]*>", dom)
    assert body, f"no <body> in chromium's DOM dump: {dom[:500]!r}"
    images = re.search(r"data-images=\"(\d+)\"", body.group(0))
    loaded = re.search(r"data-loaded=\"(\d+)\"", body.group(0))
    assert images and loaded, f"the page's load script did not run: {body.group(0)!r}"
    assert int(images.group(1)) == 4
    assert int(loaded.group(1)) == 4, "not every embedded image decoded in the browser"

    import matplotlib.image as mpimg

    shot = tmp_path / "shot.png"
    _run_chromium(tmp_path, "--window-size=1200,2400", f"--screenshot={shot}", url)
    assert shot.exists(), "chromium wrote no screenshot"
    pixels = mpimg.imread(shot)[..., :3]
    assert pixels.shape[:2] == (2400, 1200)
    assert pixels.std() > 0.05                                         # not a blank page
    # the figures' plot colours (trajectory blue, b's orange, the drop bars' red) were painted
    flat = pixels.reshape(-1, 3)
    for rgb in ((0x1f, 0x77, 0xb4), (0xff, 0x7f, 0x0e)):
        close = np.abs(flat - np.array(rgb) / 255.0).max(axis=1) < 0.06
        assert close.sum() > 200, f"colour {rgb} barely appears in the screenshot"


def _svgs(text: str) -> dict[str, str]:
    return {alt: base64.b64decode(data).decode() for alt, data in
            re.findall(r"<img alt='([^']*)' src='data:image/svg\+xml;base64,([^']*)'", text)}


def _bar_widths(svg: str, color: str) -> list[float]:
    return [float(w) for w in re.findall(rf"<rect x='[^']*' y='[^']*' width='([^']*)' height='[^']*' fill='{color}'/>",
                                         svg)]


def test_sample_bars_show_zero_as_nothing_and_one_drop_as_small(rig):
    """What a new user hit (issue 21): on the log scale a count of 0 drew a visible bar, and one dropped
    sample filled most of the linear drop panel in red. Both panels now share one log scale, 0 has no bar,
    and the drop panel is exactly SampleCounts.losses()."""
    from dataclasses import replace

    from handeye_cli.output.report import COLOR_A, COLOR_BAD
    from handeye_cli.stages.counts import SampleCounts

    counts = SampleCounts(read_a=3000, read_b=3000, synced=2999, dropped_outside_span=1, synced_kept=2999,
                          keyframes=2999, candidate_pairs=2998, pairs=1000)
    cal = replace(rig[2], samples=counts)
    svg = _svgs(render_report(cal))["samples per stage"]
    kept, drops = _bar_widths(svg, COLOR_A), _bar_widths(svg, COLOR_BAD)
    losses = counts.losses()
    assert len(drops) == len(losses) and len(kept) == len(counts.as_dict()) - len(losses)
    assert sorted(drops)[:-1] == [0.0] * (len(losses) - 1)                   # every zero: no bar
    assert kept.count(0.0) == sum(v == 0 for k, v in counts.as_dict().items() if k not in losses)
    assert 0 < max(drops) < 0.15 * max(kept)                                # 1 of 3000: a short bar


def test_the_diagnostics_are_titled_tables_without_empty_values(capsys, tmp_path):
    """The report ended in a raw-key dump ("Other diagnostics": every option, ``rms_deg None``). Each block
    of the result has a title, values not computed are left out, and the settings are the changed options."""
    from _util import ROOT, run

    code, _, err = run(capsys, "calibrate", ROOT / "sample_data" / "rig_a.tum", ROOT / "sample_data" / "rig_b.tum",
                       "--pairs", "consecutive", "--report", tmp_path / "r.html", "-q", "-o", tmp_path / "r.json")
    assert code == 0, err
    text = (tmp_path / "r.html").read_text()
    tables = text.split("<h2>Diagnostics</h2>", 1)[1]
    cells = re.findall(r"<td class='num'>([^<]*)</td>", tables)
    assert cells and "None" not in cells and "[]" not in cells and "{}" not in cells
    assert "Other diagnostics" not in text
    for title in ("Fit test", "Solver", "Synchronisation", "Settings"):
        assert f"<h2>{title}</h2>" in tables
    settings = tables.split("<h2>Settings</h2>", 1)[1].split("</div>", 1)[0]
    assert "the defaults, except:" in settings and re.findall(r"<th>([^<]*)</th>", settings) == ["pairs"]
