"""A TF tree from ``/tf`` + ``/tf_static`` transforms, and frame-pair lookups through it.

Every edge is ``T_parent_child`` (TransformStamped semantics: the pose of the child in the
parent). Static edges hold at all times; dynamic edges are interpolated at the query stamps
(linear translation, SLERP rotation) and never extrapolated. Leading ``/`` (ROS 1) is stripped
from frame ids.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from .. import se3
from ..errors import HandEyeError
from ..streams import PoseStream
from .common import PoseBuffer, make_stream

__all__ = ["TfTree"]


class TfTree:
    """Collects transforms, then resolves ``T_parent_child(t)`` for any connected frame pair.

    ``name`` (the log file) appears in error messages.
    """

    def __init__(self, name: str) -> None:
        self.name = name
        self._dynamic: dict[tuple[str, str], PoseBuffer] = {}
        self._static: dict[tuple[str, str], tuple] = {}
        self._static_count: dict[tuple[str, str], int] = {}

    def add(self, records: Sequence[tuple], *, static: bool, stamp_ns: int | None = None) -> None:
        """Add pose records ``(stamp, parent, child, x, y, z, qx, qy, qz, qw)`` of one message.

        ``stamp_ns`` (the log time) replaces each transform's own stamp when given.
        """
        for rec in records:
            key = (rec[1].lstrip("/"), rec[2].lstrip("/"))
            rec = (rec[0] if stamp_ns is None else stamp_ns, *key, *rec[3:])
            if static:
                self._static[key] = rec                      # the latest broadcast wins
                self._static_count[key] = self._static_count.get(key, 0) + 1
            else:
                self._dynamic.setdefault(key, PoseBuffer()).add([rec])

    def edges(self) -> list[dict]:
        """Tree edges ``[{parent, child, static, count}]``, sorted by parent then child."""
        rows = {k: {"parent": k[0], "child": k[1], "static": True, "count": n}
                for k, n in self._static_count.items()}
        rows.update({k: {"parent": k[0], "child": k[1], "static": False, "count": len(b)}
                     for k, b in self._dynamic.items()})
        return [rows[k] for k in sorted(rows)]

    def _parents(self) -> dict[str, str]:
        parent_of: dict[str, str] = {}
        for parent, child in [*self._static, *self._dynamic]:
            if parent_of.setdefault(child, parent) != parent:
                raise HandEyeError(f"TF frame {child!r} has two parents ({parent_of[child]!r} and "
                                   f"{parent!r})", self.name, "the TF tree is inconsistent; use a topic instead")
        return parent_of

    def _edge_stream(self, key: tuple[str, str]) -> PoseStream:
        stamps, xyz, quat = self._dynamic[key].arrays()
        return make_stream(stamps, xyz, quat, source=f"{self.name}: TF {key[0]}->{key[1]}",
                           frame_id=key[0], child_frame_id=key[1], time_source="")

    def _edge_at(self, key: tuple[str, str], edge: PoseStream | None, t: np.ndarray) -> np.ndarray:
        """(N, 4, 4) ``T_parent_child`` at stamps ``t`` (within the edge's span)."""
        if edge is None:
            rec = self._static[key]
            return np.broadcast_to(se3.from_xyz_quat(np.array(rec[3:6]), np.array(rec[6:10])), (len(t), 4, 4))
        if len(edge) == 1:
            return np.broadcast_to(edge.matrices()[0], (len(t), 4, 4))
        rel = (edge.stamps_ns - edge.stamps_ns[0]).astype(np.float64)
        x = (t - edge.stamps_ns[0]).astype(np.float64)
        xyz = np.stack([np.interp(x, rel, edge.xyz[:, k]) for k in range(3)], axis=-1)
        rot = Slerp(rel, Rotation.from_quat(edge.quat_xyzw))(x)
        out = np.zeros((len(t), 4, 4))
        out[:, :3, :3], out[:, :3, 3], out[:, 3, 3] = rot.as_matrix(), xyz, 1.0
        return out

    def lookup(self, parent: str, child: str, *, time_source: str = "header") -> PoseStream:
        """The stream ``T_parent_child(t)``, sampled at the stamps of the dynamic edges on the chain.

        Stamps are the union of those edges' stamps within the span all of them cover.
        HandEyeError if a frame is unknown, the frames are not connected, or the chain is static.
        """
        parent, child = parent.lstrip("/"), child.lstrip("/")
        parent_of = self._parents()
        known = sorted(set(parent_of) | set(parent_of.values()))
        for frame in (parent, child):
            if frame not in known:
                raise HandEyeError(f"unknown TF frame {frame!r}", self.name,
                                   f"known frames: {', '.join(known) or '(none: no /tf or /tf_static data)'}")

        def up(frame: str) -> list[str]:
            chain = [frame]
            while chain[-1] in parent_of:
                chain.append(parent_of[chain[-1]])
            return chain

        up_p, up_c = up(parent), up(child)
        common = next((f for f in up_c if f in up_p), None)
        if common is None:
            raise HandEyeError(f"TF frames {parent!r} and {child!r} are not connected "
                               f"(roots {up_p[-1]!r} and {up_c[-1]!r})", self.name,
                               "pick two frames of the same TF tree (handeye inspect FILE)")
        keys_p = [(parent_of[f], f) for f in up_p[:up_p.index(common)]]
        keys_c = [(parent_of[f], f) for f in up_c[:up_c.index(common)]]
        edges = {k: self._edge_stream(k) if k in self._dynamic else None for k in keys_p + keys_c}
        dynamic = [e for e in edges.values() if e is not None]
        source = f"{self.name}:{parent}->{child}"
        if not dynamic:
            raise HandEyeError("empty stream: the frames are linked by static transforms only, "
                               "so they never move", source, "pick a frame pair with a moving (/tf) edge")
        lo = max(e.stamps_ns[0] for e in dynamic)
        hi = min(e.stamps_ns[-1] for e in dynamic)
        t = np.unique(np.concatenate([e.stamps_ns for e in dynamic]))
        t = t[(t >= lo) & (t <= hi)]
        if len(t) == 0:
            raise HandEyeError("empty stream: the moving TF edges on the chain do not overlap in time",
                               source, "check the recording of /tf")

        def compose(keys: list[tuple[str, str]]) -> np.ndarray:   # T_common_frame
            T = np.broadcast_to(np.eye(4), (len(t), 4, 4))
            for key in keys:
                T = self._edge_at(key, edges[key], t) @ T
            return T

        T = se3.inverse(compose(keys_p)) @ compose(keys_c)
        xyz, quat = se3.to_xyz_quat(T)
        return PoseStream(t, xyz, quat, frame_id=parent, child_frame_id=child, source=source,
                          time_source=time_source)
