"""verify.reading.confirm_offset: an estimate made elsewhere (a rig's) is applied as calibrate applies one —
significant, unambiguous, and confirmed by the fit of the pairs it gives (issue 37: the rig applied every
significant estimate unconfirmed)."""
from __future__ import annotations

import numpy as np

from handeye_cli.options import Options
from handeye_cli.simulation import Rig, random_transform, simulate_rig
from handeye_cli.stages.timeoffset import TimeOffset, estimate_time_offset
from handeye_cli.verify.reading import confirm_offset

OFFSET_NS = 40_000_000


def _streams(offset_ns: int):
    rig = Rig(random_transform(np.random.default_rng(4), 0.3), time_offset_ns=offset_ns)
    return simulate_rig(rig, duration_s=40.0, sigma_r=np.deg2rad(0.1), sigma_t=0.002, seed=4)


def test_a_true_estimate_is_confirmed_by_the_fit() -> None:
    a, b = _streams(OFFSET_NS)
    est = estimate_time_offset(a, b)
    reading = confirm_offset(a, b, Options(), est)
    assert reading.applied and reading.confirmed_by == "fit" and reading.offset_ns == est.offset_ns
    assert abs(reading.offset_ns - OFFSET_NS) < 2_000_000
    assert reading.as_dict()["fit_median"]["applied"]["rotation_deg"] < reading.as_dict()["fit_median"]["none"][
        "rotation_deg"]


def test_a_wrong_significant_estimate_is_not_applied() -> None:
    """Clocks that agree, and an estimate of 60 ms ± 1 ms (significant, no warning): the pairs it gives fit worse
    than those without an offset, so it is not applied and the reading says the fit did not confirm it."""
    a, b = _streams(0)
    wrong = TimeOffset(60_000_000, 1e6, 60_000_000, 0.99, "given by the test")
    assert wrong.applicable
    reading = confirm_offset(a, b, Options(), wrong)
    assert not reading.applied and reading.offset_ns == 0 and reading.confirmed_by is None
    fits = reading.as_dict()["fit_median"]
    assert fits["applied"]["rotation_deg"] > fits["none"]["rotation_deg"]


def test_an_insignificant_estimate_is_not_applied_and_the_fit_is_not_asked() -> None:
    a, b = _streams(0)
    noise = TimeOffset(300_000, 1e6, 300_000, 0.99, "given by the test")
    reading = confirm_offset(a, b, Options(), noise)
    assert not reading.applied and reading.offset_ns == 0 and "confirmed_by" not in reading.as_dict()
