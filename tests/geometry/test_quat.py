"""The batched quaternion functions of ``geometry/dualquat.py`` (x-y-z-w) against scipy's ``Rotation``,
the reference: products, relative rotations, rotation vectors both ways and SLERP agree within 1e-12
on random rotations and at the edges — angles near 0 and near π, exact half-turns, ``q`` against
``-q``, interpolation fractions 0 and 1."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from handeye_cli.geometry import dualquat as dq

TOL = 1e-12
EDGE_ANGLES = np.array([0.0, 1e-300, 1e-15, 1e-9, 1e-6, 9.999e-4, 1e-3, 1.0001e-3, 0.1, 1.0, 3.0, np.pi - 1e-3,
                        np.pi - 1e-6, np.pi - 1e-9, np.pi - 1e-12, np.pi])


def axes(n: int, seed: int) -> np.ndarray:
    """(n, 3) random unit vectors."""
    u = np.random.default_rng(seed).normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def edge_quats(seed: int) -> np.ndarray:
    """Unit quaternions of every edge angle about random axes, composed with random rotations,
    each with both signs, and the exact half-turns ``w = 0`` of every sign pattern of x, y, z."""
    angles = np.tile(EDGE_ANGLES, 8)
    local = Rotation.from_rotvec(axes(len(angles), seed) * angles[:, None]).as_quat()
    base = Rotation.random(len(angles), random_state=seed).as_quat()
    half_turns = np.array([[x, y, z, 0.0] for x in (-1.0, 0.0, 1.0) for y in (-1.0, 0.0, 1.0) for z in (-1.0, 0.5)])
    half_turns /= np.linalg.norm(half_turns, axis=1, keepdims=True)
    q = np.concatenate([local, dq.multiply(base, local), half_turns])
    return np.concatenate([q, -q])                              # -q: the half-turns with w = -0.0


def test_products_and_relative_rotations_equal_scipys() -> None:
    p, q = edge_quats(1), edge_quats(2)
    rp, rq = Rotation.from_quat(p), Rotation.from_quat(q)
    np.testing.assert_allclose(dq.multiply(p, q), (rp * rq).as_quat(), rtol=0, atol=TOL)
    np.testing.assert_allclose(dq.relative(p, q), (rp.inv() * rq).as_quat(), rtol=0, atol=TOL)
    np.testing.assert_allclose(dq.multiply(p[3], q), (rp[3] * rq).as_quat(), rtol=0, atol=TOL)    # broadcast
    np.testing.assert_allclose(dq.relative(p, q[5]), (rp.inv() * rq[5]).as_quat(), rtol=0, atol=TOL)


def test_rotation_vectors_equal_scipys_near_zero_near_pi_and_for_both_signs() -> None:
    q = edge_quats(3)
    np.testing.assert_allclose(dq.to_rotvec(q), Rotation.from_quat(q).as_rotvec(), rtol=0, atol=TOL)
    n = len(q) // 2                     # q[n:] = -q[:n]: the same vector (the shorter arc), but at the
    # exact half-turns (w = ±0), where scipy's rule picks the sign of the first non-zero of x, y, z
    same = np.abs(q[:n, 3]) > 0
    np.testing.assert_allclose(dq.to_rotvec(q[:n][same]), dq.to_rotvec(q[n:][same]), rtol=0, atol=TOL)
    r = np.concatenate([axes(len(EDGE_ANGLES), 4) * EDGE_ANGLES[:, None], np.zeros((1, 3)),
                        axes(5, 5) * np.linspace(np.pi, 3 * np.pi, 5)[:, None]])      # past π too
    np.testing.assert_allclose(dq.from_rotvec(r), Rotation.from_rotvec(r).as_quat(), rtol=0, atol=TOL)


def test_the_maps_are_exact_to_the_last_digits_at_tiny_and_half_turn_angles() -> None:
    angles = np.array([1e-300, 1e-200, 1e-15, 1e-9, 1e-6, 9.999e-4, 1.0001e-3, np.pi - 1e-9, np.pi - 1e-12])
    r = axes(len(angles), 6) * angles[:, None]
    np.testing.assert_allclose(dq.to_rotvec(dq.from_rotvec(r)), r, rtol=1e-14, atol=0)
    np.testing.assert_allclose(np.linalg.norm(dq.from_rotvec(r), axis=1), 1.0, rtol=0, atol=1e-15)


def test_shapes_follow_the_inputs() -> None:
    q = Rotation.random(24, random_state=7).as_quat().reshape(2, 3, 4, 4)
    assert dq.to_rotvec(q).shape == (2, 3, 4, 3) and dq.from_rotvec(dq.to_rotvec(q)).shape == q.shape
    assert dq.relative(q[:, 0], q[:, 1]).shape == (2, 4, 4) and dq.to_rotvec(q[0, 0, 0]).shape == (3,)
    np.testing.assert_allclose(dq.to_rotvec(q[0, 0, 0]), Rotation.from_quat(q[0, 0, 0]).as_rotvec(), rtol=0, atol=TOL)
    assert dq.slerp(q[0], q[1], np.full((3, 4), 0.5)).shape == (3, 4, 4)


def scipy_slerp(q_lo: np.ndarray, q_hi: np.ndarray, frac: np.ndarray) -> np.ndarray:
    """What ``stages/sync.py`` did before the fast path: SLERP by scipy's Rotation."""
    r_lo = Rotation.from_quat(q_lo)
    step = (r_lo.inv() * Rotation.from_quat(q_hi)).as_rotvec()
    return (r_lo * Rotation.from_rotvec(step * frac[:, None])).as_quat()


@pytest.mark.parametrize("frac", ["random", 0.0, 1.0])
def test_slerp_equals_scipys_for_steps_near_zero_near_pi_and_either_sign(frac: str | float) -> None:
    # Steps up to π - 1e-12, not π itself: at a half-turn both arcs are equally short, and which one is
    # taken hangs on the rounding of w ≈ 1e-17 (scipy normalises its inputs first; either answer is right).
    angles = np.tile(EDGE_ANGLES[:-1], 4)
    q_lo = Rotation.random(len(angles), random_state=8).as_quat()
    step = Rotation.from_rotvec(axes(len(q_lo), 9) * angles[:, None]).as_quat()
    q_hi = dq.multiply(q_lo, step)
    q_hi[1::2] *= -1.0                                           # q_hi ~ -q_hi: the same, shorter arc
    f = np.random.default_rng(10).uniform(size=len(q_lo)) if frac == "random" else np.full(len(q_lo), frac)
    got = dq.slerp(q_lo, q_hi, f)
    np.testing.assert_allclose(got, scipy_slerp(q_lo, q_hi, f), rtol=0, atol=TOL)
    if frac == 0.0:
        np.testing.assert_allclose(got, q_lo, rtol=0, atol=TOL)
    elif frac == 1.0:                                           # q_hi's rotation, with the sign of q_lo's arc
        np.testing.assert_allclose(got * np.sign(np.sum(got * q_hi, axis=1))[:, None], q_hi, rtol=0, atol=TOL)


def test_matrices_both_ways_equal_scipys_at_the_edges() -> None:
    """Quaternion → matrix (of non-unit quaternions too: both normalise) and matrix → quaternion in
    scipy's canonical sign, on the edge rotations, exact half-turns included (w = 0: the first
    non-zero of x, y, z positive)."""
    q = edge_quats(7)
    np.testing.assert_allclose(dq.to_matrix(3.0 * q), Rotation.from_quat(q).as_matrix(), rtol=0, atol=TOL)
    stacked = Rotation.from_quat(q).as_matrix().reshape(2, -1, 3, 3)
    np.testing.assert_allclose(dq.to_matrix(q.reshape(2, -1, 4)), stacked, rtol=0, atol=TOL)
    R = Rotation.from_quat(q).as_matrix()
    flips = np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])
    R = np.concatenate([R, np.array(flips), R[:1]])       # exact half-turns about the axes; one matrix alone
    np.testing.assert_allclose(dq.from_matrix(R), Rotation.from_matrix(R).as_quat(canonical=True), rtol=0, atol=TOL)
    assert dq.from_matrix(R[0]).shape == (4,)
    np.testing.assert_array_equal(dq.from_matrix(np.array(flips))[:, 3], 0.0)
    assert (dq.from_matrix(np.array(flips))[:, :3].sum(axis=1) == 1.0).all()


def test_means_equal_scipys() -> None:
    rng = np.random.default_rng(9)
    for spread in (1e-6, 0.1, 1.0, 3.0):      # a tight cluster to rotations all over
        center = Rotation.random(random_state=int(spread * 10))
        cloud = center * Rotation.from_rotvec(rng.normal(scale=spread, size=(50, 3)))
        signs = np.where(rng.random(50) < 0.5, -1.0, 1.0)[:, None]    # mixed signs count alike
        mean = dq.mean(cloud.as_quat() * signs)
        assert mean[3] >= 0
        np.testing.assert_allclose(mean, cloud.mean().as_quat(canonical=True), rtol=0, atol=1e-10)
