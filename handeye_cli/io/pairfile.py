"""Files of relative motion pairs (input of ``handeye solve``) and extrinsic files (priors).

Motion-pair files hold ``A_i`` (motion of sensor a) and ``B_i`` (motion of sensor b) over the
same interval, ``A_i X = X B_i`` with ``X = T_a_b``:

* ``.npz`` with arrays ``A`` and ``B`` of shape (N, 4, 4) and optionally ``weights`` (N,).
* CSV with a header and 14 columns ``ax, ay, az, aqx, aqy, aqz, aqw, bx, by, bz, bqx, bqy, bqz,
  bqw`` (translations [m], quaternions x-y-z-w), optionally a 15th column ``weight``.

Extrinsic files (``--prior``) are any handeye result (YAML/JSON with ``matrix``) or a YAML/JSON
mapping with ``translation`` [m] and ``quaternion_xyzw``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..errors import HandEyeError, ReadError
from ..geometry import se3
from ..untrusted import load_yaml, numbers_problem, yaml_problem

__all__ = ["CSV_COLUMNS", "read_pairs", "write_pairs_csv", "read_extrinsic", "extrinsic_of"]

CSV_COLUMNS = ("ax", "ay", "az", "aqx", "aqy", "aqz", "aqw", "bx", "by", "bz", "bqx", "bqy", "bqz", "bqw")


def _file(path: str | Path) -> Path:
    p = Path(path)
    if not p.is_file():
        raise ReadError("file not found", str(p), "check the path")
    return p


def _read_npz(p: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    try:
        with np.load(p) as z:
            missing = {"A", "B"} - set(z.files)
            if missing:
                raise ReadError(f"missing array(s) {', '.join(sorted(missing))}; found {', '.join(z.files)}",
                                   str(p), "save the motions as A and B, each of shape (N, 4, 4)")
            return z["A"], z["B"], (z["weights"] if "weights" in z.files else None)
    except (OSError, ValueError) as e:
        if isinstance(e, HandEyeError):
            raise
        raise ReadError("not a readable .npz file", str(p), "write it with numpy.savez(path, A=..., B=...)") from e


def _read_csv(p: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    with p.open(encoding="utf-8") as f:
        header = [h.strip() for h in f.readline().split(",")]
    expected = list(CSV_COLUMNS)
    if header[:14] != expected or header[14:] not in ([], ["weight"]):
        raise ReadError(f"unexpected CSV header {','.join(header)!r}", f"{p}:1",
                           f"the header must be {','.join(CSV_COLUMNS)}[,weight]")
    try:
        data = np.loadtxt(p, delimiter=",", skiprows=1, ndmin=2)
    except ValueError as e:
        raise ReadError(f"unreadable row: {e}", str(p), f"every row needs {len(header)} numbers") from e
    if data.shape[1] != len(header):
        raise ReadError(f"rows have {data.shape[1]} columns, the header {len(header)}", str(p),
                           "give one number per header column")
    norms = np.linalg.norm(data[:, [3, 4, 5, 6, 10, 11, 12, 13]].reshape(-1, 2, 4), axis=2)
    bad = np.flatnonzero(~(np.isfinite(norms).all(axis=1) & (norms > 1e-9).all(axis=1)))
    if len(bad):
        raise ReadError("NaN or zero-norm quaternion", f"{p}:{bad[0] + 2}", "repair or remove that row")
    A = se3.from_xyz_quat(data[:, 0:3], data[:, 3:7])
    B = se3.from_xyz_quat(data[:, 7:10], data[:, 10:14])
    return A, B, (data[:, 14] if data.shape[1] == 15 else None)


def read_pairs(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Motions ``(A, B, weights or None)`` from a ``.npz`` or CSV file (see the module docstring)."""
    p = _file(path)
    return _read_npz(p) if p.suffix.lower() == ".npz" else _read_csv(p)


def write_pairs_csv(path: str | Path, A: np.ndarray, B: np.ndarray, weights: np.ndarray | None = None) -> None:
    """Write motions in the CSV layout :func:`read_pairs` reads (17 significant digits)."""
    ta, qa = se3.to_xyz_quat(A)
    tb, qb = se3.to_xyz_quat(B)
    cols = [ta, qa, tb, qb] + ([np.asarray(weights)[:, None]] if weights is not None else [])
    header = ",".join(CSV_COLUMNS) + (",weight" if weights is not None else "")
    np.savetxt(path, np.hstack(cols), delimiter=",", header=header, comments="", fmt="%.17g")


def extrinsic_of(doc: Any, where: str) -> np.ndarray:
    """The 4x4 ``T_a_b`` a parsed handeye result or ``{translation, quaternion_xyzw}`` mapping states.
    ReadError naming ``where`` and the field when it holds none, a non-finite number (NaN, inf) or
    no rigid transform."""
    if isinstance(doc, dict) and "matrix" in doc:
        T = _numbers(doc["matrix"], (4, 4), "matrix", where)
        for key, shape in (("translation", (3,)), ("quaternion_xyzw", (4,))):     # stated beside it: finite too
            if key in doc:
                _numbers(doc[key], shape, key, where)
        if not se3.is_rotation(T[:3, :3], 1e-6) or np.abs(T[3] - [0, 0, 0, 1]).max() > 1e-9:
            raise ReadError("'matrix' is not a rigid transform (rotation block not orthonormal, or last row "
                            "not 0 0 0 1)", where, "pass a handeye result file")
        return T
    if isinstance(doc, dict) and {"translation", "quaternion_xyzw"} <= set(doc):
        t = _numbers(doc["translation"], (3,), "translation", where)
        q = _numbers(doc["quaternion_xyzw"], (4,), "quaternion_xyzw", where)
        if np.linalg.norm(q) < 1e-9:
            raise ReadError("'quaternion_xyzw' is zero", where, "give a unit quaternion [x, y, z, w]")
        return se3.from_xyz_quat(t, q)
    raise ReadError("no extrinsic found", where, "pass a handeye result (with 'matrix') or a mapping with "
                    "'translation: [x, y, z]' and 'quaternion_xyzw: [x, y, z, w]'")


def _numbers(value: Any, shape: tuple[int, ...], key: str, where: str) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.shape != shape:
        raise ReadError(f"'{key}' is not {' x '.join(map(str, shape))} numbers", where, "pass a handeye result file")
    problem = numbers_problem(a)
    if problem:
        raise ReadError(f"'{key}': {problem}", where, "pass a result of a successful calibration")
    return a


def read_extrinsic(path: str | Path) -> np.ndarray:
    """A 4x4 ``T_a_b`` from a handeye result or a ``{translation, quaternion_xyzw}`` YAML/JSON file
    (read with :func:`handeye_cli.untrusted.load_yaml`: no aliases, bounded nesting)."""
    p = _file(path)
    try:
        doc = load_yaml(p.read_text(encoding="utf-8"))   # YAML ⊃ JSON
    except (OSError, UnicodeDecodeError) as e:
        raise ReadError(f"cannot read ({e.__class__.__name__})", str(p), "pass a handeye result file") from None
    except yaml.YAMLError as e:
        what, where = yaml_problem(e, str(p))
        raise ReadError(f"not a YAML or JSON file: {what}", where, "pass a handeye result file") from None
    return extrinsic_of(doc, str(p))
