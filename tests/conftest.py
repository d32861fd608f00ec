"""Fixtures shared by the tests (helper functions are in ``_util.py``)."""
from __future__ import annotations

import os

# One BLAS thread, as the command line runs (handeye_cli/cli/__init__.py): on a busy 2-core machine
# OpenBLAS's threads contend with each other and with the test's own work (the rig tests ran 3-6x slower).
# Set before numpy is first imported, here, where pytest loads the tests' first module.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import numpy as np
import pytest
from _util import write_tum

from handeye_cli.geometry import se3
from handeye_cli.simulation import Rig, simulate_rig


@pytest.fixture(scope="session")
def rig(tmp_path_factory):
    """Two TUM files of a noisy rig (30 Hz / 20 Hz, 0.2°, 2 mm, tracking jumps) and the truth."""
    d = tmp_path_factory.mktemp("rig")
    X = se3.from_xyz_quat(np.array([0.21, -0.18, 0.05]), np.array([0.2, 0.4, -0.1, 0.85]))
    a, b = simulate_rig(Rig(X, 0), duration_s=60, rate_a=30, rate_b=20, sigma_r=np.deg2rad(0.2),
                        sigma_t=0.002, jumps=3, seed=3)
    return {"X": X, "a": write_tum(d / "a.tum", a), "b": write_tum(d / "b.tum", b), "streams": (a, b), "dir": d}
