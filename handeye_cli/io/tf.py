"""A TF tree from ``/tf`` + ``/tf_static`` transforms, and frame-pair lookups through it.

Every edge is ``T_parent_child`` (TransformStamped semantics: the pose of the child in the
parent). Static edges hold at all times; dynamic edges are interpolated at the query stamps
(linear translation, SLERP rotation) and never extrapolated. Leading ``/`` (ROS 1) is stripped
from frame ids.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from ..errors import ConfigError, DataError
from ..geometry import se3
from ..streams import PoseStream
from .common import LOG_STAMPS_FIX, PoseBuffer, make_stream
from .messages import PoseRecord

__all__ = ["TfTree"]


class TfTree:
    """Collects transforms, then resolves ``T_parent_child(t)`` for any connected frame pair.

    ``name`` (the log file) appears in error messages.
    """

    def __init__(self, name: str) -> None:
        self.name = name
        self._dynamic: dict[tuple[str, str], PoseBuffer] = {}
        self._static: dict[tuple[str, str], PoseBuffer] = {}

    def add(self, records: Sequence[PoseRecord], *, static: bool) -> None:
        """Add pose records ``(stamp_ns, parent, child, x, y, z, qx, qy, qz, qw)`` of one message
        (positions [m], quaternion x-y-z-w); ``static`` = from ``/tf_static``."""
        edges = self._static if static else self._dynamic
        for rec in records:
            key = (rec[1].lstrip("/"), rec[2].lstrip("/"))
            edges.setdefault(key, PoseBuffer()).add([(rec[0], *key, *rec[3:])])

    def add_arrays(self, parent: str, child: str, stamps: np.ndarray, values: np.ndarray, *, static: bool) -> None:
        """Add the transforms ``T_parent_child`` of one edge: int64 stamps [ns], values (N, 7) =
        x, y, z [m], qx, qy, qz, qw."""
        edges = self._static if static else self._dynamic
        key = (parent.lstrip("/"), child.lstrip("/"))
        edges.setdefault(key, PoseBuffer()).add_arrays(key, stamps, values)

    def edges(self) -> list[dict[str, Any]]:
        """Tree edges ``[{parent, child, static, count}]``, sorted by parent then child."""
        rows = {k: {"parent": k[0], "child": k[1], "static": True, "count": len(b)}
                for k, b in self._static.items()}
        rows.update({k: {"parent": k[0], "child": k[1], "static": False, "count": len(b)}
                     for k, b in self._dynamic.items()})
        return [rows[k] for k in sorted(rows)]

    def _parents(self) -> dict[str, str]:
        parent_of: dict[str, str] = {}
        for parent, child in [*self._static, *self._dynamic]:
            if parent_of.setdefault(child, parent) != parent:
                raise DataError(f"TF frame {child!r} has two parents ({parent_of[child]!r} and "
                                   f"{parent!r})", self.name, "the TF tree is inconsistent; use a topic instead")
        return parent_of

    def _edge_stream(self, key: tuple[str, str]) -> PoseStream:
        """The validated samples of an edge (dynamic if it has any, else static), sorted by stamp."""
        dynamic = self._dynamic.get(key)
        stamps, xyz, quat = (dynamic or self._static[key]).arrays()
        return make_stream(stamps, xyz, quat, source=f"{self.name}: TF {key[0]}->{key[1]}",
                           frame_id=key[0], child_frame_id=key[1], time_source="",
                           where=lambda i: f"transform {i}", zero_stamps_fix=LOG_STAMPS_FIX if dynamic else None)

    @staticmethod
    def _edge_at(edge: PoseStream, static: bool, t: np.ndarray) -> np.ndarray:
        """(N, 4, 4) ``T_parent_child`` at stamps ``t`` (within the edge's span if dynamic).

        A static edge is its latest broadcast at every stamp; a dynamic one is interpolated as
        ``--sync interpolate`` does (linear translation, SLERP rotation).
        """
        if static or len(edge) == 1:
            return np.broadcast_to(edge.matrices()[-1], (len(t), 4, 4))
        at = edge.sample(t)                         # every stamp is inside the span: none left out
        return se3.from_xyz_quat(at.xyz, at.quat_xyzw)

    def _chain(self, parent: str, child: str) -> tuple[list[tuple[str, str]], list[tuple[str, str]]]:
        """Edges ``(parent_of[f], f)`` from ``parent`` and from ``child`` up to their common ancestor."""
        parent_of = self._parents()
        known = sorted(set(parent_of) | set(parent_of.values()))
        for frame in (parent, child):
            if frame not in known:
                raise ConfigError(f"unknown TF frame {frame!r}", self.name,
                                   f"known frames: {', '.join(known) or '(none: no /tf or /tf_static data)'}")

        def up(frame: str) -> list[str]:
            chain = [frame]
            while chain[-1] in parent_of:
                chain.append(parent_of[chain[-1]])
            return chain

        up_p, up_c = up(parent), up(child)
        common = next((f for f in up_c if f in up_p), None)
        if common is None:
            raise DataError(f"TF frames {parent!r} and {child!r} are not connected "
                               f"(roots {up_p[-1]!r} and {up_c[-1]!r})", self.name,
                               "pick two frames of the same TF tree (handeye inspect FILE)")
        return ([(parent_of[f], f) for f in up_p[:up_p.index(common)]],
                [(parent_of[f], f) for f in up_c[:up_c.index(common)]])

    def lookup(self, parent: str, child: str, *, time_source: str = "header") -> PoseStream:
        """The stream ``T_parent_child(t)`` (pose of ``child`` in ``parent``; metres, x-y-z-w).

        Sampled at the stamps of the most frequent dynamic edge on the chain, restricted to the
        span every dynamic edge covers (never extrapolated); the other dynamic edges are
        interpolated there and static edges are constant. ``duplicates_dropped`` counts the
        duplicate stamps of that reference edge. HandEyeError if a frame is unknown, the frames
        are not connected, the chain has no moving edge, or a transform is invalid.
        """
        parent, child = parent.lstrip("/"), child.lstrip("/")
        keys_p, keys_c = self._chain(parent, child)
        edges = {k: self._edge_stream(k) for k in keys_p + keys_c}
        dynamic = [e for k, e in edges.items() if k in self._dynamic]
        source = f"{self.name}:{parent}->{child}"
        if not dynamic:
            raise DataError("empty stream: the frames are linked by static transforms only, "
                               "so they never move", source, "pick a frame pair with a moving (/tf) edge")
        ref = max(dynamic, key=len)     # first of the most frequent: ties keep chain order
        lo = max(e.stamps_ns[0] for e in dynamic)
        hi = min(e.stamps_ns[-1] for e in dynamic)
        t = ref.stamps_ns[(ref.stamps_ns >= lo) & (ref.stamps_ns <= hi)]
        if len(t) == 0:
            raise DataError("empty stream: the moving TF edges on the chain do not overlap in time",
                               source, "check the recording of /tf")

        notes = tuple(w for e in edges.values() for w in e.warnings)
        if len(edges) == 1:         # one moving edge, sampled at its own stamps: no interpolation, no products
            edge = ref if keys_c else ref.inverted()
            return replace(edge, frame_id=parent, child_frame_id=child, source=source, time_source=time_source,
                           warnings=notes)

        def compose(keys: list[tuple[str, str]]) -> np.ndarray:   # T_common_frame
            T = np.broadcast_to(np.eye(4), (len(t), 4, 4))
            for key in keys:
                T = self._edge_at(edges[key], key not in self._dynamic, t) @ T
            return T

        T = se3.inverse(compose(keys_p)) @ compose(keys_c)
        xyz, quat = se3.to_xyz_quat(T)
        return PoseStream(t, xyz, quat, frame_id=parent, child_frame_id=child, source=source,
                          time_source=time_source, duplicates_dropped=ref.duplicates_dropped, warnings=notes)
