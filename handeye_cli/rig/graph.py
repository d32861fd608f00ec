"""Graph synchronisation of pairwise extrinsics, and their loop closures.

Nodes are the rig's sensors 0…n-1; an edge (j, k) carries ``T_j_k`` (pose of k in j; maps points
from k to j) and a weight. Unknowns are the poses ``T_ref_k`` of every sensor in the reference's
frame (``T_ref_ref = I``), consistent by construction: ``T_j_k = T_ref_j⁻¹ T_ref_k``.

* Rotation averaging, chordal L2 (spectral): with ``V_k = R_kᵀ`` stacked (3n x 3), consistent
  data give the block matrix ``H_jk = R_j_k = V_j V_kᵀ``, so ``H V = D V`` (D: the weighted
  degrees); the top three generalised eigenvectors of ``(H, D)`` span V, each block is
  projected onto SO(3) and the gauge fixed by the reference.
* Translations: linear least squares of ``t_k - t_j = R_j t_j_k`` with ``t_ref = 0``.
* Loop closures: for every triangle j < k < l the error of ``T_j_k T_k_l T_j_l⁻¹`` (identity when
  consistent): rotation [deg], translation [m].
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations, pairwise, permutations

import numpy as np
from numpy.typing import NDArray

from ..errors import DataError
from ..geometry import se3
from ..geometry.lie import nearest_rotation

__all__ = ["Closure", "synchronise", "loop_closures", "connected"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Closure:
    """Loop-closure error of the triangle of sensors ``(j, k, l)``: rotation [deg], translation [m]."""

    nodes: tuple[int, int, int]
    rotation_deg: float
    translation_m: float


def connected(n: int, pairs: list[tuple[int, int]], start: int = 0) -> NDArray[np.bool_]:
    """Which of the n nodes the edge list connects to node ``start`` (breadth-first)."""
    seen = np.zeros(n, dtype=bool)
    seen[start], frontier = True, [start]
    while frontier:
        node = frontier.pop()
        for j, k in pairs:
            for a, b in ((j, k), (k, j)):
                if a == node and not seen[b]:
                    seen[b] = True
                    frontier.append(b)
    return seen


def _rotations(n: int, pairs: list[tuple[int, int]], X: Array, w: Array, reference: int) -> Array:
    """Chordal L2 rotation averaging: ``R_ref_k`` (n, 3, 3) from the relative ``R_j_k``."""
    H = np.zeros((3 * n, 3 * n))
    for (j, k), Xe, we in zip(pairs, X, w, strict=True):
        H[3 * j:3 * j + 3, 3 * k:3 * k + 3] = we * Xe[:3, :3]
        H[3 * k:3 * k + 3, 3 * j:3 * j + 3] = we * Xe[:3, :3].T
    scale = 1.0 / np.sqrt(np.repeat(np.bincount(np.ravel(pairs), weights=np.repeat(w, 2), minlength=n), 3))
    _, vecs = np.linalg.eigh(scale[:, None] * H * scale)  # H V = D V (consistent data: the top eigenvalue) as
    V = (scale[:, None] * vecs[:, -3:]).reshape(n, 3, 3)  # D^-½ H D^-½ U = U Λ, V = D^-½ U; V_k ≈ R_kᵀ Q, one Q
    if np.sum(np.linalg.det(V)) < 0:
        V = -V
    R = nearest_rotation(np.swapaxes(V, 1, 2), up_to_sign=True)
    return np.asarray(R[reference].T @ R, dtype=np.float64)


def _translations(n: int, pairs: list[tuple[int, int]], X: Array, w: Array, R: Array, reference: int) -> Array:
    """``t_ref_k`` (n, 3) from ``t_k - t_j = R_j t_j_k`` (least squares, ``t_ref = 0``)."""
    rows = np.zeros((3 * len(pairs), 3 * n))
    rhs = np.zeros(3 * len(pairs))
    for e, ((j, k), Xe, we) in enumerate(zip(pairs, X, np.sqrt(w), strict=True)):
        rows[3 * e:3 * e + 3, 3 * k:3 * k + 3] = we * np.eye(3)
        rows[3 * e:3 * e + 3, 3 * j:3 * j + 3] = -we * np.eye(3)
        rhs[3 * e:3 * e + 3] = we * (R[j] @ Xe[:3, 3])
    free = np.ones(3 * n, dtype=bool)
    free[3 * reference:3 * reference + 3] = False
    t = np.zeros(3 * n)
    t[free] = np.linalg.lstsq(rows[:, free], rhs, rcond=None)[0]
    return t.reshape(n, 3)


def synchronise(n: int, pairs: list[tuple[int, int]], X: Array, weights: Array, reference: int) -> Array:
    """Consistent ``T_ref_k`` (n, 4, 4) from pairwise ``T_j_k`` (E, 4, 4) on the edges ``pairs``
    with non-negative ``weights`` (E,). Raises DataError when a sensor is not connected."""
    reach = connected(n, [(min(j, k), max(j, k)) for j, k in pairs]) if n else np.zeros(0, bool)
    if not reach.all():
        raise DataError(f"sensor(s) {', '.join(map(str, np.flatnonzero(~reach)))} share no calibrated pair with the "
                        "others", "rig", "check those streams' topics, time overlap and motion")
    R = _rotations(n, pairs, X, weights, reference)
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = R
    T[:, :3, 3] = _translations(n, pairs, X, weights, R, reference)
    return T


def loop_closures(n: int, relative: dict[tuple[int, int], Array]) -> list[Closure]:
    """Closure errors of every triangle j < k < l whose three ``T_j_k`` are in ``relative``."""
    out = []
    for j, k, m in combinations(range(n), 3):
        if (j, k) in relative and (k, m) in relative and (j, m) in relative:
            C = relative[(j, k)] @ relative[(k, m)] @ se3.inverse(relative[(j, m)])
            out.append(Closure((j, k, m), float(np.rad2deg(se3.rotation_angle(C))), float(np.linalg.norm(C[:3, 3]))))
    return out


def chains(relative: dict[tuple[int, int], Array], n: int, k: int, reference: int = 0) -> dict[tuple[int, ...], Array]:
    """Every simple chain of pairwise results from ``reference`` to sensor ``k``: the path of
    sensors → the composed ``T_reference_k``. ``relative[(j, k)]`` is ``T_j_k`` (either direction
    suffices; the inverse is filled in)."""
    rel = dict(relative)
    rel.update({(b, a): se3.inverse(X) for (a, b), X in relative.items() if (b, a) not in relative})
    others = [i for i in range(n) if i not in (reference, k)]
    out: dict[tuple[int, ...], Array] = {}
    for r in range(len(others) + 1):
        for mid in permutations(others, r):
            path, X = (reference, *mid, k), np.eye(4)
            for a, b in pairwise(path):
                X = X @ rel[(a, b)]
            out[path] = X
    return out
