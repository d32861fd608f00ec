"""The report's SVG charts (handeye_cli.output.svgplot): ticks as matplotlib places them, labels,
the data-to-pixel mapping, and well-formed documents."""
from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from handeye_cli.output.svgplot import Chart, linear_ticks, tick_labels

SVG = "{http://www.w3.org/2000/svg}"


@pytest.mark.parametrize(("lo", "hi", "nbins"), [(0.0, 1.0, 9), (-0.0123, 0.0089, 5), (-0.00043, 0.00041, 5),
                                                  (-90.0, 3779.0, 9), (0.0, 0.0166, 6), (1e-9, 3e-9, 4),
                                                  (-1.26, 1.31, 5), (0.0, 120.0, 9), (-0.11, 0.023, 5)])
def test_ticks_are_matplotlibs(lo, hi, nbins):
    from matplotlib.ticker import MaxNLocator

    want = MaxNLocator(nbins=nbins, steps=[1, 2, 2.5, 5, 10]).tick_values(lo, hi)
    want = want[(want >= lo - 1e-12 * (hi - lo)) & (want <= hi + 1e-12 * (hi - lo))]
    np.testing.assert_allclose(linear_ticks(lo, hi, nbins), want, rtol=0, atol=1e-9 * (hi - lo))


def test_labels_have_the_decimals_the_step_needs_and_a_true_minus():
    assert tick_labels(np.array([-0.0004, -0.0002, 0.0, 0.0002])) == ["−0.0004", "−0.0002", "0.0000", "0.0002"]
    assert tick_labels(np.array([0.0, 0.025, 0.05])) == ["0.000", "0.025", "0.050"]
    assert tick_labels(np.array([0.0, 500.0, 1000.0])) == ["0", "500", "1000"]


def _paths(svg: str) -> list[ET.Element]:
    return ET.fromstring(svg).findall(f".//{SVG}path")


def test_data_land_where_the_limits_say():
    chart = Chart(4.0, 3.0)                                            # 360 x 270 px
    (ax,) = chart.grid(1, 1, margins=(1.0, 0.0, 1.0, 0.0))              # the box: x 90…360, y 0…180 px
    ax.line([0.0, 1.0], [0.0, 1.0], "#123456")
    ax.xlim = (0.0, 1.0)
    svg = chart.svg()
    line = next(p for p in _paths(svg) if p.get("stroke") == "#123456")
    # y auto-scales with 5 % margins: 0 → 180 - 180/22 px; coordinates in tenths of a pixel, relative
    x0, y0 = 900, round(10 * (180 - 180 / 22))
    assert line.get("d") == f"M{x0} {y0}l2700 {-(y0 - round(10 * 180 / 22))}"
    assert "scale(0.1)" in svg


def test_a_nan_breaks_a_line_and_points_skip_it():
    chart = Chart(4.0, 3.0)
    (ax,) = chart.grid(1, 1, margins=(0.5, 0.1, 0.5, 0.1))
    ax.line([0, 1, np.nan, 3, 4], [0, 1, 2, 3, 4], "#111111")
    ax.points([0, np.nan, 2], [0, 1, 2], "#222222")
    ax.hline(np.nan, "#333333")
    paths = {p.get("stroke"): p.get("d") for p in _paths(chart.svg())}
    assert paths["#111111"].count("M") == 2
    assert paths["#222222"].count("h0") == 2
    assert "#333333" not in paths


def test_equal_aspect_widens_the_shorter_range():
    chart = Chart(6.0, 3.0)
    (ax,) = chart.grid(1, 1, margins=(0.0, 0.0, 0.0, 0.0))
    ax.line([0.0, 1.0], [0.0, 1.0], "#000000")
    ax.equal = True
    (x0, x1), (y0, y1) = ax._limits()
    assert (x1 - x0) / ax.box[2] == pytest.approx((y1 - y0) / ax.box[3])
    assert (x0 + x1) / 2 == pytest.approx(0.5) and y1 - y0 == pytest.approx(1.1)


def test_every_kind_of_item_makes_a_well_formed_document():
    chart = Chart(8.0, 3.0)
    a, b = chart.grid(1, 2, margins=(1.2, 0.1, 0.4, 0.3), gaps=(1.2, 0.0), width_ratios=[1, 2])
    a.barh([0.8, 1e5, 2e6], "#1f77b4", texts=["0", "100000", "2e+06"])
    a.yticks, a.xlog, a.grid, a.title = ["x < y", "b", "c"], True, "x", "counts & <drops>"
    a.xlim = (0.4, 8e6)
    b.stairs([1, 3, 2], [0.0, 1.0, 2.0, 3.0], "#ff7f0e", opacity=0.85)
    b.vline(1.5, "black", dash=":")
    b.hline(2.0, "black", label="median 2")
    b.points([0.5, 2.5], [1.0, 2.0], "#d62728", marker="x", label="rejected")
    b.legend = "upper left"
    root = ET.fromstring(chart.svg())
    texts = [t.text for t in root.iter(f"{SVG}text")]
    assert "counts & <drops>" in texts and "x < y" in texts and "10⁶" in texts and "2e+06" in texts
    assert float(root.get("width")) == 720 and len(root.findall(f".//{SVG}rect")) > 5
