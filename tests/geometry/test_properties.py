"""Properties that must hold for every input, checked on generated ones (hypothesis)."""
from __future__ import annotations

import numpy as np
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from handeye_cli import solve
from handeye_cli.config import load_options
from handeye_cli.geometry import se3
from handeye_cli.options import Options
from handeye_cli.simulation import motion_pairs, random_transform

seeds = st.integers(min_value=0, max_value=2**32 - 1)


@given(seeds)
def test_pose_round_trip_through_position_and_quaternion(seed):
    T = random_transform(np.random.default_rng(seed), 5.0)
    xyz, q = se3.to_xyz_quat(T)
    np.testing.assert_allclose(se3.from_xyz_quat(xyz, q), T, atol=1e-12)
    np.testing.assert_allclose(se3.inverse(se3.inverse(T)), T, atol=1e-12)
    np.testing.assert_allclose(T @ se3.inverse(T), np.eye(4), atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(seeds, st.floats(0.0, 0.01))
def test_swapping_the_streams_gives_the_inverse(seed, noise):
    """Exactly on noise-free motions; on noisy ones within the noise (the cost weighs translation
    residuals in frame a, so the swapped problem is not the same least-squares problem)."""
    rng = np.random.default_rng(seed)
    X = random_transform(rng, 0.5)
    A, B = motion_pairs(40, X, rng, "random", sigma_r=noise, sigma_t=noise)
    loop = solve(A, B).matrix @ solve(B, A).matrix
    bound = 1e-8 + 20 * noise
    assert se3.rotation_angle(loop) < bound and np.linalg.norm(loop[:3, 3]) < bound


option_values = st.fixed_dictionaries({"gate": st.just("paper")}, optional={     # the jump limits are its
    "sync": st.sampled_from(["interpolate", "nearest"]),
    "max_dt": st.floats(1e-3, 10.0),
    "time_offset": st.one_of(st.just("auto"), st.floats(-1e4, 1e4)),
    "max_jump": st.one_of(st.none(), st.floats(1e-3, 5.0)),
    "max_jump_deg": st.one_of(st.none(), st.floats(0.1, 180.0)),
    "pairs": st.sampled_from(["keyframes", "all", "consecutive", "stride:7", "random:100"]),
    "max_pairs": st.integers(1, 10**6),
    "alpha": st.one_of(st.just("auto"), st.floats(1e-3, 1e3)),
    "prior_weights": st.tuples(st.floats(0, 10), st.floats(0, 10)),
    "robust": st.booleans(),
    "bootstrap": st.integers(0, 5000),
    "name_a": st.one_of(st.none(), st.from_regex(r"[a-z][a-z0-9_]{0,12}", fullmatch=True)),
})


@settings(max_examples=60, deadline=None)
@given(option_values)
def test_any_valid_config_round_trips_through_a_file(tmp_path_factory, values):
    opts = Options.from_flat(**values)
    path = tmp_path_factory.mktemp("cfg") / "c.yaml"
    path.write_text(yaml.safe_dump(opts.flat()))
    assert load_options(path) == opts
    assert load_options(path, **{k: None for k in values}) == opts          # None = "not given"
