"""``--scale auto`` over seeds (issue 19): the scale's σ covers its error, and the translation costs
at most 2x what the true scale gives on the same streams (paired per seed)."""
from __future__ import annotations

import numpy as np
import pytest

from handeye_cli import calibrate
from handeye_cli.analysis import extrinsic_error
from handeye_cli.simulation import Rig, random_transform
from handeye_cli.simulation.arm import monocular
from handeye_cli.simulation.recordings import absolute, drifting, simulate_recording

SCALE = 0.5


@pytest.mark.statistical
def test_monocular_vio_scale_is_covered_by_its_sigma_and_costs_little_translation():
    z, auto, known = [], [], []
    for seed in range(2):
        X = random_transform(np.random.default_rng([seed, 1]), 0.3)
        rec = simulate_recording(Rig(X, 0), absolute(0.05, 0.0005), drifting(), duration_s=12, rate_a=100,
                                 rate_b=30, seed=seed, speed=0.5)
        cal = calibrate(rec.a, monocular(rec.b, SCALE), scale="auto", time_offset=0.0, max_pairs=400)
        z.append((cal.diagnostics["scale"]["value"] - SCALE) / cal.diagnostics["scale"]["std"])
        auto.append(extrinsic_error(cal.matrix, X)[1])
        known.append(extrinsic_error(calibrate(rec.a, rec.b, time_offset=0.0, max_pairs=400).matrix, X)[1])
    assert np.all(np.abs(z) < 2.5), z
    assert np.mean(auto) <= 2.0 * np.mean(known), (auto, known)
