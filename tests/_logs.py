"""Write small logs with known poses: MCAP (ROS 2 CDR, ROS 1, Foxglove JSON), ROS 1 bags, ROS 2
bags (sqlite3 / MCAP storage) and TUM / EuRoC / CSV text — with the ``mcap`` and ``rosbags``
writers only, never with handeye's own code, so that reading them back tests the readers.

A *record* is ``(stamp_ns, frame_id, child_frame_id, x, y, z, qx, qy, qz, qw)``: the pose
``T_frame_child``, metres, Hamilton quaternion x-y-z-w. A :class:`Channel` holds
``(log_time_ns, payload)`` messages; the payload is a list of records (one for single-pose
types, any number for ``tf2_msgs/msg/TFMessage`` / ``foxglove.FrameTransforms``), ready
``bytes`` or a message object/dict serialised as is.

Also used by ``sample_data/make_samples.py`` and ``benchmarks/readers.py``.
"""
from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag1 import Writer as Bag1Writer
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Bag2Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from handeye_cli.streams import PoseStream

Record = tuple  # (stamp_ns, frame, child, x, y, z, qx, qy, qz, qw)

ROS2_STORE = get_typestore(Stores.ROS2_HUMBLE)
ROS1_STORE = get_typestore(Stores.ROS1_NOETIC)
ROS1_STORE.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))

POSE = "geometry_msgs/msg/PoseStamped"
POSE_COV = "geometry_msgs/msg/PoseWithCovarianceStamped"
TRANSFORM = "geometry_msgs/msg/TransformStamped"
ODOM = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"
FOX_POSE = "foxglove.PoseInFrame"
FOX_POSES = "foxglove.PosesInFrame"
FOX_TF = "foxglove.FrameTransform"
FOX_TFS = "foxglove.FrameTransforms"
ROS_POSE_TYPES = (POSE, POSE_COV, TRANSFORM, ODOM, TF)
JSON_POSE_TYPES = (FOX_POSE, FOX_POSES, FOX_TF, FOX_TFS)
_LATCHED = Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
               QosTime(0, 0), QosTime(0, 0), QosLiveliness.AUTOMATIC, QosTime(0, 0), False)


@dataclass
class Channel:
    """One topic: its type and ``(log_time_ns, payload)`` messages. ``static`` = latched TF."""

    topic: str
    msgtype: str
    messages: Iterable[tuple[int, Any]]
    static: bool = False


def records(stream: PoseStream, frame: str | None = None, child: str | None = None) -> list[Record]:
    """The samples of ``stream`` as records (frames default to the stream's)."""
    f = stream.frame_id if frame is None else frame
    c = stream.child_frame_id if child is None else child
    return [(int(t), f, c, *map(float, p), *map(float, q))
            for t, p, q in zip(stream.stamps_ns, stream.xyz, stream.quat_xyzw, strict=True)]


def pose_channel(topic: str, msgtype: str, recs: Sequence[Record], log_offset_ns: int = 0) -> Channel:
    """One message per record, logged ``log_offset_ns`` after its stamp."""
    return Channel(topic, msgtype, [(r[0] + log_offset_ns, [r]) for r in recs])


def image_channel(topic: str, start_ns: int, end_ns: int, rate_hz: float, n_bytes: int, *,
                  distinct: bool = False) -> Channel:
    """``sensor_msgs/msg/Image`` (mono8, 1000 bytes a row) of ``n_bytes`` [B] of random pixels
    every 1/``rate_hz`` [s] in [start_ns, end_ns) [ns]: one image repeated, or ``distinct`` ones."""
    T, rng, width = ROS2_STORE.types, np.random.default_rng(0), 1000
    rows = max(n_bytes // width, 1)

    def image() -> bytes:
        msg = T["sensor_msgs/msg/Image"](
            header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="cam"),
            height=rows, width=width, encoding="mono8", is_bigendian=0, step=width,
            data=rng.integers(0, 255, rows * width, dtype=np.uint8))
        return bytes(ROS2_STORE.serialize_cdr(msg, "sensor_msgs/msg/Image"))

    stamps = np.arange(start_ns, end_ns, int(1e9 / rate_hz), dtype=np.int64)
    same = None if distinct else image()
    return Channel(topic, "sensor_msgs/msg/Image", [(int(t), same or image()) for t in stamps])


# --- message construction -------------------------------------------------------------------
def ros_message(store: Typestore, msgtype: str, recs: Sequence[Record]) -> Any:
    """A rosbags message object of ``msgtype`` (ROS_POSE_TYPES) holding ``recs``."""
    T = store.types
    ros1 = "seq" in T["std_msgs/msg/Header"].__dataclass_fields__

    def header(r: Record) -> Any:
        stamp = T["builtin_interfaces/msg/Time"](sec=r[0] // 10**9, nanosec=r[0] % 10**9)
        extra = {"seq": 0} if ros1 else {}
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id=r[1], **extra)

    def vec(cls: str, r: Record) -> Any:
        return T[cls](x=r[3], y=r[4], z=r[5])

    def quat(r: Record) -> Any:
        return T["geometry_msgs/msg/Quaternion"](x=r[6], y=r[7], z=r[8], w=r[9])

    def pose(r: Record) -> Any:
        return T["geometry_msgs/msg/Pose"](position=vec("geometry_msgs/msg/Point", r), orientation=quat(r))

    def pose_cov(r: Record) -> Any:
        return T["geometry_msgs/msg/PoseWithCovariance"](pose=pose(r), covariance=np.zeros(36))

    def transform(r: Record) -> Any:
        tf = T["geometry_msgs/msg/Transform"](translation=vec("geometry_msgs/msg/Vector3", r), rotation=quat(r))
        return T[TRANSFORM](header=header(r), child_frame_id=r[2], transform=tf)

    if msgtype == TF:
        return T[TF](transforms=[transform(r) for r in recs])
    (r,) = recs
    if msgtype == POSE:
        return T[POSE](header=header(r), pose=pose(r))
    if msgtype == POSE_COV:
        return T[POSE_COV](header=header(r), pose=pose_cov(r))
    if msgtype == TRANSFORM:
        return transform(r)
    if msgtype == ODOM:
        zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        twist = T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=np.zeros(36))
        return T[ODOM](header=header(r), child_frame_id=r[2], pose=pose_cov(r), twist=twist)
    raise ValueError(f"not a ROS pose type: {msgtype}")


def json_message(msgtype: str, recs: Sequence[Record]) -> dict:
    """A Foxglove JSON message (JSON_POSE_TYPES) holding ``recs``."""
    def stamp(r: Record) -> dict:
        return {"sec": r[0] // 10**9, "nsec": r[0] % 10**9}

    def xyz(r: Record) -> dict:
        return {"x": r[3], "y": r[4], "z": r[5]}

    def q(r: Record) -> dict:
        return {"x": r[6], "y": r[7], "z": r[8], "w": r[9]}

    def frame_transform(r: Record) -> dict:
        return {"timestamp": stamp(r), "parent_frame_id": r[1], "child_frame_id": r[2],
                "translation": xyz(r), "rotation": q(r)}

    if msgtype == FOX_TFS:
        return {"transforms": [frame_transform(r) for r in recs]}
    (r,) = recs
    if msgtype == FOX_TF:
        return frame_transform(r)
    pose = {"position": xyz(r), "orientation": q(r)}
    if msgtype == FOX_POSE:
        return {"timestamp": stamp(r), "frame_id": r[1], "pose": pose}
    if msgtype == FOX_POSES:
        return {"timestamp": stamp(r), "frame_id": r[1], "poses": [pose]}
    raise ValueError(f"not a Foxglove pose type: {msgtype}")


def _payload(store: Typestore | None, msgtype: str, payload: Any) -> Any:
    """A message object/dict for a record list; anything else unchanged."""
    if isinstance(payload, list) and all(isinstance(r, tuple) for r in payload):
        return json_message(msgtype, payload) if store is None else ros_message(store, msgtype, payload)
    return payload


def _serialize(store: Typestore | None, msgtype: str, payload: Any, ros1: bool = False) -> bytes:
    if isinstance(payload, (bytes, bytearray, memoryview)):
        return bytes(payload)
    msg = _payload(store, msgtype, payload)
    if store is None:
        return json.dumps(msg).encode()
    return bytes(store.serialize_ros1(msg, msgtype) if ros1 else store.serialize_cdr(msg, msgtype))


def _merged(channels: Sequence[Channel]) -> list[tuple[int, int, Any]]:
    """(log_ns, channel index, payload) of all channels in log-time order (stable)."""
    rows = [(t, i, p) for i, ch in enumerate(channels) for t, p in ch.messages]
    rows.sort(key=lambda r: (r[0], r[1]))
    return rows


# --- containers -----------------------------------------------------------------------------
def _idl_struct(msgtype: str, fields: Sequence[tuple[str, str]]) -> str:
    pkg, _, name = msgtype.split("/")
    body = "".join(f"      {typ} {field};\n" for typ, field in fields)
    return f"module {pkg} {{\n  module msg {{\n    struct {name} {{\n{body}    }};\n  }};\n}};\n"


_IDL_SEP = "=" * 80 + "\n"
POSE_STAMPED_IDL = "".join(f"{_IDL_SEP}IDL: {t}\n{_idl_struct(t, f)}" for t, f in {
    POSE: [("std_msgs::msg::Header", "header"), ("geometry_msgs::msg::Pose", "pose")],
    "std_msgs/msg/Header": [("builtin_interfaces::msg::Time", "stamp"), ("string", "frame_id")],
    "builtin_interfaces/msg/Time": [("int32", "sec"), ("uint32", "nanosec")],
    "geometry_msgs/msg/Pose": [("geometry_msgs::msg::Point", "position"),
                               ("geometry_msgs::msg::Quaternion", "orientation")],
    "geometry_msgs/msg/Point": [("double", "x"), ("double", "y"), ("double", "z")],
    "geometry_msgs/msg/Quaternion": [("double", "x"), ("double", "y"), ("double", "z"), ("double", "w")],
}.items())
"""PoseStamped as a ``ros2idl`` MCAP schema (rosbag2's layout: one IDL block per type)."""


def write_mcap(path: str | Path, channels: Sequence[Channel], *, ros1: bool = False,
               compression: str = "zstd", chunk_size: int = 1024 * 1024, idl: bool = False) -> Path:
    """An MCAP (profile ros2, or ros1 with ``ros1=True``); ``foxglove.*`` channels are JSON;
    ``idl=True`` stores PoseStamped schemas as ``ros2idl`` instead of ``ros2msg``."""
    path = Path(path)
    store = ROS1_STORE if ros1 else ROS2_STORE
    with open(path, "wb") as f:
        w = McapWriter(f, compression=CompressionType[compression.upper()], chunk_size=chunk_size)
        w.start(profile="ros1" if ros1 else "ros2", library="handeye tests/_logs.py")
        ids = []
        for ch in channels:
            if ch.msgtype.startswith("foxglove."):
                schema = json.dumps({"title": ch.msgtype, "type": "object"}).encode()
                sid = w.register_schema(ch.msgtype, "jsonschema", schema)
                ids.append(w.register_channel(ch.topic, "json", sid))
            elif idl and ch.msgtype == POSE and not ros1:
                sid = w.register_schema(POSE, "ros2idl", POSE_STAMPED_IDL.encode())
                ids.append(w.register_channel(ch.topic, "cdr", sid))
            else:
                text, _ = store.generate_msgdef(ch.msgtype, ros_version=1 if ros1 else 2)
                name = ch.msgtype.replace("/msg/", "/") if ros1 else ch.msgtype
                sid = w.register_schema(name, "ros1msg" if ros1 else "ros2msg", text.encode())
                ids.append(w.register_channel(ch.topic, "ros1" if ros1 else "cdr", sid))
        stores = [None if ch.msgtype.startswith("foxglove.") else store for ch in channels]
        for seq, (t, i, payload) in enumerate(_merged(channels)):
            data = _serialize(stores[i], channels[i].msgtype, payload, ros1)
            w.add_message(ids[i], log_time=t, data=data, publish_time=t, sequence=seq)
        w.finish()
    return path


def write_bag1(path: str | Path, channels: Sequence[Channel], compression: str | None = None) -> Path:
    """A ROS 1 bag (Noetic types + TFMessage); static channels are latched; ``compression``
    ``"lz4"`` or ``"bz2"`` compresses its chunks."""
    path = Path(path)
    writer = Bag1Writer(path)
    if compression:
        writer.set_compression(Bag1Writer.CompressionFormat[compression.upper()])
    with writer as w:
        conns = [w.add_connection(ch.topic, ch.msgtype, typestore=ROS1_STORE,
                                  latching=1 if ch.static else None) for ch in channels]
        for t, i, payload in _merged(channels):
            w.write(conns[i], t, _serialize(ROS1_STORE, channels[i].msgtype, payload, ros1=True))
    return path


def write_bag2(path: str | Path, channels: Sequence[Channel], storage: str = "sqlite3") -> Path:
    """A ROS 2 bag directory (format 9, ``sqlite3`` or ``mcap`` storage); static channels are
    TRANSIENT_LOCAL like a recorded ``/tf_static``."""
    path = Path(path)
    plugin = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage]
    with Bag2Writer(path, version=9, storage_plugin=plugin) as w:
        conns = [w.add_connection(ch.topic, ch.msgtype, typestore=ROS2_STORE,
                                  offered_qos_profiles=[_LATCHED] if ch.static else [])
                 for ch in channels]
        for t, i, payload in _merged(channels):
            w.write(conns[i], t, _serialize(ROS2_STORE, channels[i].msgtype, payload))
    return path


# --- text -----------------------------------------------------------------------------------
def _seconds(ns: int) -> str:
    """Exact decimal seconds of an int ns stamp (no float round trip)."""
    sign = "-" if ns < 0 else ""
    return f"{sign}{abs(ns) // 10**9}.{abs(ns) % 10**9:09d}"


def write_tum(path: str | Path, stream: PoseStream, sep: str = " ") -> Path:
    """``t tx ty tz qx qy qz qw`` (seconds, w last), exact to the nanosecond and the last bit."""
    path = Path(path)
    rows = [sep.join([_seconds(r[0]), *(repr(v) for v in r[3:])]) for r in records(stream)]
    path.write_text("# timestamp tx ty tz qx qy qz qw\n" + "\n".join(rows) + "\n")
    return path


EUROC_HEADER = ("#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], "
                "q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], "
                "b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], "
                "b_a_RS_S_z [m s^-2]")


def write_euroc(path: str | Path, stream: PoseStream, *, header: bool = True, columns: int = 17) -> Path:
    """EuRoC ground truth: ``ns, px, py, pz, qw, qx, qy, qz`` (+ zero velocity/bias columns up to
    ``columns``), with or without the 17-column header."""
    path = Path(path)
    pad = ["0"] * (columns - 8)
    rows = [",".join([str(r[0]), *(repr(v) for v in (*r[3:6], r[9], *r[6:9])), *pad])
            for r in records(stream)]
    head = [EUROC_HEADER] if header else []
    path.write_text("\n".join(head + rows) + "\n")
    return path


def write_csv(path: str | Path, stream: PoseStream, names: Sequence[str], *, t_scale: int = 1) -> Path:
    """Generic CSV with header ``names`` for (t, x, y, z, qx, qy, qz, qw); t = ns // t_scale."""
    path = Path(path)
    rows = [",".join([str(r[0] // t_scale), *(repr(v) for v in r[3:])]) for r in records(stream)]
    path.write_text(",".join(names) + "\n" + "\n".join(rows) + "\n")
    return path


# --- one entry point for every container --------------------------------------------------
LOG_KINDS = ("mcap", "mcap_ros1", "bag1", "bag2_sqlite", "bag2_mcap", "db3")
"""Containers :func:`write_log` writes: ROS 2 MCAP, ROS 1-profile MCAP, ROS 1 bag, ROS 2 bag
directories (sqlite3 / MCAP storage) and the bare ``.db3`` of a sqlite3 bag."""


def write_log(kind: str, directory: str | Path, channels: Sequence[Channel], name: str = "log") -> Path:
    """Write ``channels`` as a log of ``kind`` (one of :data:`LOG_KINDS`) in ``directory``."""
    base = Path(directory) / name
    if kind == "mcap":
        return write_mcap(base.with_suffix(".mcap"), channels)
    if kind == "mcap_ros1":
        return write_mcap(base.with_suffix(".mcap"), channels, ros1=True)
    if kind == "bag1":
        return write_bag1(base.with_suffix(".bag"), channels)
    if kind in ("bag2_sqlite", "bag2_mcap"):
        return write_bag2(base, channels, storage="sqlite3" if kind == "bag2_sqlite" else "mcap")
    if kind == "db3":
        return write_bag2(base, channels) / f"{name}.db3"
    raise ValueError(f"unknown log kind {kind!r}; expected one of {LOG_KINDS}")
