"""Pose-carrying message types: where the numbers live in each, and how to get them out.

One table (:data:`SPECS`) names the field paths of every supported type; the same table drives
reading (decoded ROS messages or JSON dicts → numbers), the fast CDR path and the fixture
writers. A *pose record* is the tuple
``(stamp_ns, frame_id, child_frame_id, x, y, z, qx, qy, qz, qw)``: the pose ``T_frame_child``,
translation in metres, Hamilton quaternion in x-y-z-w order, stamp in int64 nanoseconds.
"""
from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

__all__ = ["Spec", "SPECS", "LISTS", "POSE_TYPES", "TF_TYPES", "normalize_type", "get_field",
           "extract", "pose_decoder", "PoseRecord", "UnsupportedContent", "BadField"]

PoseRecord = tuple[Any, ...]  # (stamp_ns, frame_id, child_frame_id, x, y, z, qx, qy, qz, qw)


class UnsupportedContent(ValueError):
    """A well-formed message whose content handeye cannot use (e.g. PosesInFrame with 3 poses)."""


class BadField(ValueError):
    """A decoded message (a JSON dict most often) without a field of its type, or with a field
    that is not a number where one is expected: the message is not of its declared type."""


@dataclass(frozen=True)
class Spec:
    """Dotted field paths of one message type ("a|b" = try a, then b; digits index lists).

    ``cdr_child`` describes the CDR layout for the fast decoder: after the header comes a
    child_frame_id string (True) or directly the 7 doubles of the pose (False); None = no
    fast path.
    """

    stamp: str
    frame: str
    child: str | None
    position: str
    orientation: str
    single: str | None = None      # a list that must hold exactly one element (PosesInFrame)
    cdr_child: bool | None = None


SPECS: dict[str, Spec] = {
    "geometry_msgs/msg/PoseStamped": Spec(
        "header.stamp", "header.frame_id", None, "pose.position", "pose.orientation", cdr_child=False),
    "geometry_msgs/msg/PoseWithCovarianceStamped": Spec(
        "header.stamp", "header.frame_id", None, "pose.pose.position", "pose.pose.orientation",
        cdr_child=False),
    "geometry_msgs/msg/TransformStamped": Spec(
        "header.stamp", "header.frame_id", "child_frame_id", "transform.translation",
        "transform.rotation", cdr_child=True),
    "nav_msgs/msg/Odometry": Spec(
        "header.stamp", "header.frame_id", "child_frame_id", "pose.pose.position",
        "pose.pose.orientation", cdr_child=True),
    "foxglove.PoseInFrame": Spec("timestamp", "frame_id", None, "pose.position", "pose.orientation"),
    "foxglove.PosesInFrame": Spec("timestamp", "frame_id", None, "poses.0.position",
                                  "poses.0.orientation", single="poses"),
    "foxglove.FrameTransform": Spec(
        "timestamp", "parent_frame_id", "child_frame_id", "translation|transform.translation",
        "rotation|transform.rotation"),
}
"""Single-pose types → field paths."""

LISTS: dict[str, tuple[str, str]] = {
    "tf2_msgs/msg/TFMessage": ("transforms", "geometry_msgs/msg/TransformStamped"),
    "foxglove.FrameTransforms": ("transforms", "foxglove.FrameTransform"),
}
"""Types holding a list of transforms → (list field, element type)."""

POSE_TYPES = frozenset(SPECS) | frozenset(LISTS)
TF_TYPES = frozenset(LISTS) | {"foxglove.FrameTransform"}


def normalize_type(name: str) -> str:
    """``geometry_msgs/PoseStamped`` (ROS 1 style) → ``geometry_msgs/msg/PoseStamped``."""
    parts = name.split("/")
    return f"{parts[0]}/msg/{parts[1]}" if len(parts) == 2 else name


def get_field(obj: Any, path: str) -> Any:
    """The value at a dotted ``path`` of a message object or JSON dict; BadField if absent."""
    for alternative in path.split("|"):
        cur = obj
        try:
            for key in alternative.split("."):
                if key.isdigit():
                    cur = cur[int(key)]
                elif isinstance(cur, dict):
                    cur = cur[key]
                else:
                    cur = getattr(cur, key)
            return cur
        except (KeyError, AttributeError, IndexError, TypeError):
            continue
    raise BadField(f"field {path!r} missing")


def _record(spec: Spec, msg: Any) -> PoseRecord:
    if spec.single is not None and (n := len(get_field(msg, spec.single))) != 1:
        raise UnsupportedContent(f"{spec.single!r} holds {n} poses; handeye reads messages with exactly one")
    t = get_field(msg, spec.stamp)
    p, q = get_field(msg, spec.position), get_field(msg, spec.orientation)
    try:
        return (int(get_field(t, "sec")) * 1_000_000_000 + int(get_field(t, "nanosec|nsec")),
                str(get_field(msg, spec.frame)), str(get_field(msg, spec.child)) if spec.child else "",
                float(get_field(p, "x")), float(get_field(p, "y")), float(get_field(p, "z")),
                float(get_field(q, "x")), float(get_field(q, "y")), float(get_field(q, "z")),
                float(get_field(q, "w")))
    except BadField:
        raise
    except (TypeError, ValueError, OverflowError) as exc:     # a JSON null, string or inf where a number belongs
        raise BadField(f"a stamp or pose field is not a number: {exc}") from exc


def extract(msgtype: str, msg: Any) -> list[PoseRecord]:
    """Pose records of one decoded message (ROS object or JSON dict) of a type in POSE_TYPES."""
    if msgtype in LISTS:
        field, element = LISTS[msgtype]
        return [_record(SPECS[element], item) for item in get_field(msg, field)]
    return [_record(SPECS[msgtype], msg)]


# --- fast path for little-endian CDR ----------------------------------------------------------
# Decoding PoseStamped & co with struct.unpack_from is ~5x faster than rosbags'
# Typestore.deserialize_cdr (notes/formats.md §4.3; benchmarks/readers.py measures the whole
# reader). It covers the fixed layouts of the ROS 2 types above, little-endian plain CDR
# (encapsulation header 00 01); anything else (big-endian, ROS 1, custom types) goes through the
# typestore.
_HEAD = struct.Struct("<iII")
_LEN = struct.Struct("<I")
_POSE = struct.Struct("<7d")


def _cdr_transform(buf: bytes, o: int, child: bool) -> tuple[PoseRecord, int]:
    """One header[+child]+7-double block starting at absolute offset ``o`` (4-aligned)."""
    sec, nsec, n = _HEAD.unpack_from(buf, o)
    frame = buf[o + 12:o + 11 + n].decode()
    o += 12 + n
    child_id = ""
    if child:
        o += -(o - 4) % 4
        (n,) = _LEN.unpack_from(buf, o)
        child_id = buf[o + 4:o + 3 + n].decode()
        o += 4 + n
    o += -(o - 4) % 8
    return (sec * 1_000_000_000 + nsec, frame, child_id, *_POSE.unpack_from(buf, o)), o + 56


def _fast_cdr(msgtype: str) -> Callable[[bytes], list[PoseRecord]] | None:
    if msgtype in LISTS and LISTS[msgtype][1] in SPECS and SPECS[LISTS[msgtype][1]].cdr_child:
        def decode_list(buf: bytes) -> list[PoseRecord]:
            (count,) = _LEN.unpack_from(buf, 4)
            out, o = [], 8
            for _ in range(count):
                rec, o = _cdr_transform(buf, o + (-(o - 4) % 4), True)
                out.append(rec)
            return out
        return decode_list
    spec = SPECS.get(msgtype)
    if spec is None or spec.cdr_child is None:
        return None
    child = spec.cdr_child
    return lambda buf: [_cdr_transform(buf, 4, child)[0]]


def pose_decoder(msgtype: str, deserialize: Callable[[bytes], Any], *,
                 cdr: bool = False) -> Callable[[bytes], list[PoseRecord]]:
    """A function raw message bytes → pose records, for a type in :data:`POSE_TYPES`.

    ``deserialize`` turns bytes into a message object or dict (typestore, json.loads…). With
    ``cdr=True`` little-endian CDR payloads of fixed-layout types are parsed directly.
    """
    fast = _fast_cdr(msgtype) if cdr else None

    def slow(buf: bytes) -> list[PoseRecord]:
        return extract(msgtype, deserialize(buf))

    if fast is None:
        return slow
    return lambda buf: fast(buf) if buf[:2] == b"\x00\x01" else slow(buf)
