"""The rig's χ² survival function against scipy.special.chdtrc, its reference."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.special import chdtrc

from handeye_cli.numeric.chi2 import chi2_log_sf, chi2_sf


@pytest.mark.parametrize("dof", [2, 6, 12, 18, 36, 120])
def test_equals_scipy(dof: int) -> None:
    for x in np.r_[0.0, np.geomspace(1e-3, 1400.0, 60)]:
        reference = float(chdtrc(dof, x))
        assert chi2_sf(dof, x) == pytest.approx(reference, rel=1e-11, abs=1e-300)
        if reference > 1e-290:
            assert chi2_log_sf(dof, x) == pytest.approx(np.log(reference), rel=1e-11, abs=1e-13)


def test_the_far_tail_stays_finite_and_ranks() -> None:
    """Where the probability underflows (scipy gives 0) the logarithm still orders the statistics."""
    assert chdtrc(6, 5000.0) == 0.0
    far = [chi2_log_sf(6, x) for x in (2000.0, 5000.0, 1e6)]
    assert all(np.isfinite(far)) and far[0] > far[1] > far[2]
    assert chi2_log_sf(12, 5000.0) > chi2_log_sf(6, 5000.0)        # more degrees of freedom: more probable


@pytest.mark.parametrize("dof", [0, 1, 5])
def test_odd_or_no_degrees_of_freedom_refused(dof: int) -> None:
    with pytest.raises(ValueError, match="even"):
        chi2_log_sf(dof, 1.0)
