"""A generated fleet of short logs in mixed formats, for the batch tests and benchmarks/batch.py.

Every rig has the nominal extrinsic ``NOMINAL`` (``T_cam0_cam1``, the pose of cam1 in cam0),
except the ones moved on purpose: beyond the tolerance (0.5°, 5 mm) or well below it. Logs carry
``/cam0/pose`` and ``/cam1/pose`` (PoseStamped); TUM inputs are folders with ``cam0.tum`` and
``cam1.tum``. Unreadable inputs are damaged files named like logs. Crashed recordings (issue 9
item 4) are an MCAP and a ROS 1 bag cut at 60 % of their size and a ROS 2 bag whose
metadata.yaml is missing.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from _logs import POSE, pose_channel, records, write_log, write_mcap, write_tum
from scipy.spatial.transform import Rotation

from handeye_cli.geometry import se3
from handeye_cli.simulation import Rig, simulate_rig

NOMINAL = se3.from_xyz_quat(np.array([0.12, -0.03, 0.02]),
                            Rotation.from_euler("xyz", [2, -88, 5], degrees=True).as_quat())
TOPICS = ("/cam0/pose", "/cam1/pose")
KINDS = ("mcap", "bag1", "bag2_sqlite", "bag2_mcap", "tum")
DAY_NS = 86_400 * 10**9


@dataclass(frozen=True)
class Expected:
    """What a fleet input should give: ``status`` and, when calibrated, its true extrinsic."""

    status: str
    truth: np.ndarray | None = None
    warning: str | None = None


def moved(rotation_deg: float, translation_m: float, seed: int) -> np.ndarray:
    """The nominal moved by a rotation of ``rotation_deg`` and a translation of ``translation_m``."""
    rng = np.random.default_rng(seed)
    axis, shift = rng.normal(size=3), rng.normal(size=3)
    D = se3.from_xyz_quat(shift / np.linalg.norm(shift) * translation_m,
                          Rotation.from_rotvec(np.deg2rad(rotation_deg) * axis / np.linalg.norm(axis)).as_quat())
    return NOMINAL @ D


def write_rig(folder: Path, kind: str, X: np.ndarray, seed: int, duration_s: float = 12.0) -> Path:
    """A short log (or a TUM pair folder) of a rig with extrinsic ``X``; returns the input path."""
    folder.mkdir(parents=True, exist_ok=True)
    if kind == "tum":
        a, b = _rig_streams(X, seed, duration_s)
        write_tum(folder / "cam0.tum", a)
        write_tum(folder / "cam1.tum", b)
        return folder
    return write_log(kind, folder, _rig_channels(X, seed, duration_s), name=f"rig{seed}")


def _rig_streams(X: np.ndarray, seed: int, duration_s: float = 12.0) -> tuple:
    return simulate_rig(Rig(X), duration_s=duration_s, rate_a=30, rate_b=20, sigma_r=5e-4, sigma_t=2e-4,
                        seed=seed, start_ns=1_790_000_000 * 10**9 + seed * DAY_NS)


def _rig_channels(X: np.ndarray, seed: int, duration_s: float = 12.0) -> list:
    a, b = _rig_streams(X, seed, duration_s)
    return [pose_channel(TOPICS[0], POSE, records(a, "world", "cam0")),
            pose_channel(TOPICS[1], POSE, records(b, "world", "cam1"))]


def crashed(root: Path) -> dict[str, Expected]:
    """Three crashed recordings of nominal rigs under ``root``, each salvaged by the readers and
    calibrated (cut logs with a 'truncated' warning)."""
    out: dict[str, Expected] = {}
    for i, kind in enumerate(("mcap", "bag1", "bag2_sqlite")):
        path = write_rig(root / f"crashed{i}", kind, NOMINAL, seed=100 + i)
        if kind == "mcap":        # recorders flush small chunks as they fill; this 12-s log fits one 1-MB chunk
            write_mcap(path, _rig_channels(NOMINAL, seed=100 + i), chunk_size=4096)
        if kind == "bag2_sqlite":
            (path / "metadata.yaml").unlink()               # the recorder died before writing it
            path = path / f"{path.name}.db3"
        else:
            with open(path, "r+b") as f:                     # power loss: the tail (chunk, index, footer) is gone
                f.truncate(int(path.stat().st_size * 0.6))
        missing_metadata = kind == "bag2_sqlite"           # a bare .db3 was readable before crash recovery
        out[str(path)] = Expected("ok", NOMINAL, None if missing_metadata else "truncated")
    return out


def make_fleet(root: Path, n_good: int = 22, n_beyond: int = 4, n_below: int = 3,
               broken: bool = True) -> dict[str, Expected]:
    """Write the fleet under ``root`` (one folder per log, and ``broken/`` with damaged files unless
    ``broken`` is false); expected status by input path."""
    plan = ([("ok", NOMINAL)] * n_good + [("drift", moved(2.0, 0.0, s)) for s in range(n_beyond // 2)]
            + [("drift", moved(0.0, 0.02, s)) for s in range(n_beyond - n_beyond // 2)]
            + [("ok", moved(0.2, 0.002, s)) for s in range(n_below)])
    expected: dict[str, Expected] = {}
    for i, (status, X) in enumerate(plan):
        kind = KINDS[i % len(KINDS)]
        path = write_rig(root / f"robot{i:02d}", kind, X, seed=i)
        label = " ".join(str(path / f) for f in ("cam0.tum", "cam1.tum")) if kind == "tum" else str(path)
        expected[label] = Expected(status, X)
    if not broken:
        return expected
    bad = root / "broken"
    bad.mkdir()
    (bad / "empty.bag").write_bytes(b"")
    (bad / "garbage.mcap").write_bytes(np.random.default_rng(0).bytes(4096))
    (bad / "header_only.mcap").write_bytes(b"\x89MCAP0\r\n")
    (bad / "notes.txt").write_text("not a log: skipped by the directory search\n")
    for name in ("empty.bag", "garbage.mcap", "header_only.mcap"):
        expected[str(bad / name)] = Expected("error")
    return expected
