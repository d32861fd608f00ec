"""The result objects a notebook user holds (issue 21): a one-line repr instead of 65 kB of arrays, an HTML
table, and the extrinsic's parts and spread as attributes."""
from __future__ import annotations

import numpy as np
import pytest
from _util import ROOT

import handeye_cli
from handeye_cli import RigOptions, calibrate_rig_files
from handeye_cli.geometry import se3

RIG = ROOT / "sample_data" / "rig.mcap"


@pytest.fixture(scope="module")
def cal() -> handeye_cli.Calibration:
    return handeye_cli.calibrate_files(str(RIG), topic_a="/cam0/pose", topic_b="/cam1/pose")


def test_calibration_repr_is_one_short_line(cal) -> None:
    text = repr(cal)
    assert "\n" not in text and len(text) < 300
    assert text.startswith("Calibration(T_cam0_pose_cam1_pose: t=[") and "certified" in text
    html = cal._repr_html_()
    assert html.startswith("<table>") and "σ (covariance)" in html and len(html) < 2000


def test_calibration_exposes_translation_rotation_and_uncertainty(cal) -> None:
    np.testing.assert_array_equal(cal.translation, cal.matrix[:3, 3])
    np.testing.assert_allclose(se3.from_xyz_quat(cal.translation, cal.quaternion_xyzw), cal.matrix, atol=1e-12)
    unc = cal.uncertainty
    assert unc is not None and unc.method == "covariance"
    doc = handeye_cli.document(cal)["observability"]
    np.testing.assert_allclose(unc.rotation_std_deg, doc["predicted_rotation_std_deg"])
    np.testing.assert_allclose(unc.translation_std_m, doc["predicted_translation_std_m"])
    boot = handeye_cli.calibrate_files(str(RIG), topic_a="/cam0/pose", topic_b="/cam1/pose", bootstrap=20)
    assert boot.uncertainty is not None and boot.uncertainty.method == "bootstrap"
    np.testing.assert_allclose(boot.uncertainty.translation_std_m,
                               handeye_cli.document(boot)["uncertainty"]["translation_std_m"])


def test_rig_result_repr_is_one_short_line() -> None:
    result = calibrate_rig_files(str(ROOT / "sample_data" / "rig4.mcap"), ["cam0=/cam0/pose", "cam1=/cam1/pose"],
                                 RigOptions())
    text = repr(result)
    assert "\n" not in text and len(text) < 400 and text.startswith("RigResult(2 sensors, reference cam0: T_cam0_cam1")
    assert result._repr_html_().count("<tr>") == 1 + len(result.warnings)
    assert handeye_cli.document(result)["reference"] == "cam0"


def test_compare_methods_is_library_code_with_typed_rows(cal) -> None:
    """Issue 21: compare_methods lived in the CLI; it is handeye_cli.compare_methods, with typed rows the CLI
    only formats. dqopt's row is the calibration itself, and no method reaches a lower cost (8)."""
    rows = handeye_cli.compare_methods(cal)
    assert rows[0].method == "dqopt" and rows[0].vs_dqopt_deg == 0.0
    np.testing.assert_allclose(rows[0].matrix, cal.matrix, atol=1e-12)
    assert {r.method for r in rows} >= {"tsai", "park", "daniilidis", "shah (robot-world)"}
    pair_rows = [r for r in rows if "robot-world" not in r.method]
    assert min(r.cost for r in pair_rows) >= rows[0].cost * (1 - 1e-9)
    d = rows[1].as_dict()
    assert d["milliseconds"] == 1e3 * rows[1].seconds and len(d["rotation_vector_deg"]) == 3


def test_diagnostics_are_typed_and_read_only(cal) -> None:
    """The analyses leave as typed objects and a read-only mapping of the document's sections (issue 21: dicts
    filled in place): nothing can change a result's fit test after the fact, and what code reads is typed."""
    from handeye_cli.analysis.fit_test import FitTest
    from handeye_cli.analysis.observability import Observability
    from handeye_cli.analysis.subspace import Subspace

    d = cal.diagnostics
    assert isinstance(d.fit, FitTest) and isinstance(d.observability, Observability)
    assert isinstance(d.subspace, Subspace) and d.selection is not None
    assert d["fit_test"]["ratio"] == d.fit.ratio and list(d)[0] == "time_offset"
    with pytest.raises(TypeError):
        d["fit_test"] = {}                                                   # type: ignore[index]
    with pytest.raises(AttributeError):
        d.fit = None                                                         # type: ignore[misc]
    assert handeye_cli.document(cal)["fit_test"] == d["fit_test"]
