"""sample_data/: up to date with its generator, every file carries the same rig, and the rig's
relative motions satisfy ``A X = X B`` with ``X = T_a_b`` from truth.yaml."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation, Slerp

from handeye_cli.geometry import se3
from handeye_cli.io import read_stream

SAMPLES = Path(__file__).resolve().parents[2] / "sample_data"
sys.path.insert(0, str(SAMPLES))
import make_samples  # noqa: E402

TRUTH = yaml.safe_load((SAMPLES / "truth.yaml").read_text())
X = np.array(TRUTH["matrix"])
GENERATED = [*make_samples.FILES, *(p for pair in make_samples.TEXT_FILES.values() for p in pair), "truth.yaml"]


@pytest.fixture(scope="module")
def rig():
    return make_samples.simulate()


def test_samples_are_what_the_generator_writes(tmp_path):
    make_samples.main(tmp_path)
    for name in GENERATED:
        for new in sorted((tmp_path / name).rglob("*")) if (tmp_path / name).is_dir() else [tmp_path / name]:
            committed = SAMPLES / new.relative_to(tmp_path)
            assert committed.read_bytes() == new.read_bytes(), f"{committed} is stale: run make_samples.py"


def test_folder_under_5_mb():
    assert sum(p.stat().st_size for p in SAMPLES.rglob("*") if p.is_file()) < 5e6


def test_truth_yaml():
    assert np.linalg.norm(X[:3, 3]) == pytest.approx(0.28, abs=1e-12)
    assert np.rad2deg(se3.rotation_angle(X)) == pytest.approx(50.0, abs=1e-9)
    np.testing.assert_allclose(se3.from_xyz_quat(np.array(TRUTH["translation"]), np.array(TRUTH["quaternion_xyzw"])),
                               X, atol=1e-14)
    assert set(TRUTH["files"]) == {*make_samples.FILES, *(a for a, _ in make_samples.TEXT_FILES.values())}


def _selections():
    for name, spec in TRUTH["files"].items():
        if "topic" in spec["a"]:
            yield name, "topic", (spec["a"]["topic"], spec["b"]["topic"])
        if "frames" in spec["a"]:
            yield name, "frames", (tuple(spec["a"]["frames"]), tuple(spec["b"]["frames"]))
        if "file" in spec["a"]:
            yield name, "file", (spec["a"]["file"], spec["b"]["file"])


@pytest.mark.parametrize("name, how, sel", list(_selections()), ids=lambda v: str(v))
def test_every_sample_reads_back_the_rig(rig, name, how, sel):
    for stream, truth in zip(sel, rig, strict=True):
        s = read_stream(SAMPLES / stream) if how == "file" else read_stream(SAMPLES / name, **{how: stream})
        np.testing.assert_array_equal(s.stamps_ns, truth.stamps_ns)
        np.testing.assert_allclose(s.matrices(), truth.matrices(), rtol=0, atol=1e-12)


def _relative_residuals(a, b, X: np.ndarray, gap_s: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Rotation [deg] and translation [m] residuals of ``A X = X B`` for motions ``gap_s`` apart,
    with b interpolated (linear + SLERP) at a's stamps inside b's span."""
    t0 = a.stamps_ns[0]
    ta, tb = (a.stamps_ns - t0) / 1e9, (b.stamps_ns - t0) / 1e9
    inside = (ta >= tb[0]) & (ta <= tb[-1])
    ta, Ta = ta[inside], a.matrices()[inside]
    Tb = np.tile(np.eye(4), (len(ta), 1, 1))
    Tb[:, :3, :3] = Slerp(tb, Rotation.from_quat(b.quat_xyzw))(ta).as_matrix()
    Tb[:, :3, 3] = np.stack([np.interp(ta, tb, b.xyz[:, k]) for k in range(3)], axis=-1)
    i = np.arange(len(ta))
    j = np.searchsorted(ta, ta + gap_s).clip(max=len(ta) - 1)
    A, B = se3.relative(Ta[i], Ta[j]), se3.relative(Tb[i], Tb[j])
    E = se3.inverse(A @ X) @ (X @ B)
    return np.rad2deg(se3.rotation_angle(E)), np.linalg.norm(E[:, :3, 3], axis=1)


def test_relative_motions_satisfy_ax_xb(rig):
    """Median residuals are at the noise level with X = T_a_b, and large with T_b_a instead."""
    rot, trans = _relative_residuals(*rig, X)
    assert np.median(rot) < 0.5 and np.median(trans) < 0.01      # 0.2° / 2 mm pose noise
    rot_wrong, trans_wrong = _relative_residuals(*rig, se3.inverse(X))
    assert np.median(rot_wrong) > 10 * np.median(rot) and np.median(trans_wrong) > 10 * np.median(trans)
