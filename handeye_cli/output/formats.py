"""The result in the formats ROS users paste in: YAML/JSON, a URDF, ROS 1 and ROS 2 static transform
publisher launch files, ``static_transform_publisher`` command lines, Kalibr YAML.

A document states one or more transforms ``T_parent_child`` — the pose of the child frame in the parent
frame, mapping points from child to parent: a calibrate result its ``T_a_b`` (``matrix``, ``frames``), a
rig result every ``T_ref_k`` (``transforms``). Every writer takes that list (one entry for a calibrate
result) and writes the numbers at full precision (``repr``), so reading the output back with
:func:`handeye_cli.io.nominal.read_nominal` gives the same transforms to 1e-9:

* ``urdf``: a ``<robot>`` with the links and one ``<joint type="fixed">`` per transform (``urdf-joint``: the
  joints alone, to paste into an existing robot's URDF), ``<origin xyz rpy>`` (rpy: fixed-axis roll x,
  pitch y, yaw z, ``R = Rz·Ry·Rx`` — accurate to ~1e-9 except within ~1e-4 rad of pitch ±90°);
* ``ros1-launch``: one ``tf2_ros static_transform_publisher`` node per transform, ``args="x y z qx qy qz qw
  parent child"``;
* ``ros2-launch``: a Python launch file, one node per transform, ``--x … --frame-id P --child-frame-id C``;
* ``tf-static``: one ``ros2 run tf2_ros static_transform_publisher …`` command line per transform;
* ``kalibr``: ``camN.T_cam_imu`` and ``camN.T_imu_cam``, its inverse (as OpenVINS names it); for a
  calibrate result frame a is cam0 and b imu0, for a rig the reference is imu0 and the sensors cam0, cam1…

Quaternions are x-y-z-w, translations metres.

Frame names may come from a log, so every writer escapes them for its language whatever checked
them before (docs/design.md, "Generated files and nominals"): Python literals by ``repr`` (the
launch file's docstring too), shell words by ``shlex.quote``, XML attributes by ``quoteattr``,
YAML by the emitter; a comment holding names is made one line (unprintable characters written as
escapes) and, in XML, free of ``--``. A name a format cannot carry — a character XML 1.0 forbids,
NUL in a shell word, ``$(`` or ``${`` in the ROS XML files (roslaunch and xacro evaluate them),
in a ROS 1 launch file's whitespace-split ``args`` anything the frame-id rule refuses — is a
ConfigError naming the frame and the format.
"""
from __future__ import annotations

import re
import shlex
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from ..errors import ConfigError, one_line
from ..geometry import se3
from ..untrusted import frame_id_problem
from ..version import __version__
from .document import render

__all__ = ["ALL_FORMATS", "SUMMARY_FORMATS", "Frame", "render_format", "transforms_of"]

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Frame:
    """One transform a writer states: ``matrix`` = ``T_parent_child`` (4x4, metres)."""

    parent: str
    child: str
    matrix: Array


def transforms_of(doc: dict[str, Any]) -> list[Frame]:
    """The transforms a document states: a rig document's ``transforms`` (every ``T_ref_k``, from
    ``translation`` + ``quaternion_xyzw``), else the single ``T_a_b`` of ``matrix`` and ``frames``."""
    if "transforms" in doc:
        return [Frame(str(t["parent"]), str(t["child"]),
                      se3.from_xyz_quat(np.asarray(t["translation"], dtype=float),
                                        np.asarray(t["quaternion_xyzw"], dtype=float)))
                for t in doc["transforms"]]
    frames = doc.get("frames") or {}
    return [Frame(str(frames.get("a", "a")), str(frames.get("b", "b")), np.asarray(doc["matrix"], dtype=float))]


def _num(values: Array) -> list[str]:
    return [repr(float(v)) for v in values]


def _comment(doc: dict[str, Any], frames: list[Frame]) -> str:
    """What the file states, one line (every unprintable character of a name written as its escape)."""
    head = (f"handeye {doc.get('version', __version__)}, method {doc.get('method', '?')}, "
            f"{doc.get('pairs_used', '?')} pairs" if "transforms" not in doc else
            f"handeye {doc.get('version', __version__)} rig, reference {doc.get('reference', frames[0].parent)}")
    names = ", ".join(f"T_{f.parent}_{f.child}" for f in frames)
    return one_line(f"{names}: the pose of each child frame in its parent frame (maps points from child to parent); "
                    f"{head}")


def _xml_comment(text: str) -> str:
    """``text`` (one line) as the body of ``<!-- … -->``: no ``--`` inside (XML forbids it)."""
    return re.sub(r"-(?=-)", "- ", text)


# Characters XML 1.0 cannot carry at all, not even as character references.
_NOT_XML = re.compile(r"[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def _refuse(frames: list[Frame], fmt: str, problem: Callable[[str], str | None]) -> None:
    """ConfigError for the first frame name ``fmt`` cannot carry (``problem`` says why)."""
    for name in (n for f in frames for n in (f.parent, f.child)):
        why = problem(name)
        if why:
            raise ConfigError(f"frame name {name!r} cannot be written as {fmt}: {why}", "fmt",
                              "name the frames with ⟦name_a⟧/⟦name_b⟧ (letters, digits, '_', '.', '/', '-')")


def _xml_problem(name: str) -> str | None:
    bad = _NOT_XML.search(name)
    if bad:
        return f"XML 1.0 has no character {bad.group()!r}"
    if "$(" in name or "${" in name:
        return "roslaunch and xacro evaluate '$(' and '${'"
    return None


def _node_name(f: Frame) -> str:
    return re.sub(r"\W", "_", f"handeye_{f.parent}_to_{f.child}", flags=re.ASCII)


def _xyz_quat(T: Array) -> list[str]:
    t, q = se3.to_xyz_quat(T)
    return _num(np.r_[t, q])


def _flag_args(f: Frame) -> list[str]:
    args = []
    for flag, value in zip(("x", "y", "z", "qx", "qy", "qz", "qw"), _xyz_quat(f.matrix), strict=True):
        args += [f"--{flag}", value]
    return [*args, "--frame-id", f.parent, "--child-frame-id", f.child]


def _joints(frames: list[Frame]) -> str:
    """One fixed ``<joint>`` per transform (parent, child, ``<origin xyz rpy>``), every name by ``quoteattr``."""
    from xml.sax.saxutils import quoteattr  # 50 ms of imports (urllib, http, ssl): only for the XML formats

    from scipy.spatial.transform import Rotation  # 0.3 s to import: only for URDF's roll, pitch, yaw

    _refuse(frames, "a URDF", _xml_problem)
    return "".join(
        f"  <joint name={quoteattr(f'{f.parent}_to_{f.child}')} type=\"fixed\">\n"
        f"    <parent link={quoteattr(f.parent)}/>\n    <child link={quoteattr(f.child)}/>\n"
        f'    <origin xyz="{" ".join(_num(f.matrix[:3, 3]))}" '
        f'rpy="{" ".join(_num(Rotation.from_matrix(f.matrix[:3, :3]).as_euler("xyz")))}"/>\n  </joint>\n'
        for f in frames)


def _urdf(doc: dict[str, Any], frames: list[Frame]) -> str:
    """A whole ``<robot>``: the links in order of appearance (a rig's reference is the root), one fixed joint per
    transform."""
    from xml.sax.saxutils import quoteattr

    joints = _joints(frames)
    links = "".join(f"  <link name={quoteattr(name)}/>\n"
                    for name in dict.fromkeys(name for f in frames for name in (f.parent, f.child)))
    return (f'<?xml version="1.0"?>\n<!-- {_xml_comment(_comment(doc, frames))} -->\n'
            f'<robot name="handeye_extrinsic">\n{links}{joints}</robot>\n')


def _urdf_joint(doc: dict[str, Any], frames: list[Frame]) -> str:
    """The joints alone, without ``<robot>`` or ``<link>``s: pasted into a robot's URDF that has the links
    already, it adds no duplicate link (a rig's several joints follow each other)."""
    return f"<!-- {_xml_comment(_comment(doc, frames))} -->\n{_joints(frames)}"


def _ros1_launch(doc: dict[str, Any], frames: list[Frame]) -> str:
    from xml.sax.saxutils import quoteattr

    _refuse(frames, "a ROS 1 launch file", lambda name: _xml_problem(name) or frame_id_problem(name))
    nodes = "".join(f'  <node pkg="tf2_ros" type="static_transform_publisher" name={quoteattr(_node_name(f))}\n'
                    f"        args={quoteattr(' '.join([*_xyz_quat(f.matrix), f.parent, f.child]))}/>\n"
                    for f in frames)
    return f"<launch>\n  <!-- {_xml_comment(_comment(doc, frames))} -->\n{nodes}</launch>\n"


def _ros2_launch(doc: dict[str, Any], frames: list[Frame]) -> str:
    """Every string a Python literal by ``repr``, the module docstring included."""
    nodes = "".join("        Node(\n            package='tf2_ros',\n"
                    "            executable='static_transform_publisher',\n"
                    f"            name={_node_name(f)!r},\n"
                    f"            arguments=[{', '.join(repr(v) for v in _flag_args(f))}],\n        ),\n"
                    for f in frames)
    return (f"{_comment(doc, frames) + '.'!r}\nfrom launch import LaunchDescription\n"
            "from launch_ros.actions import Node\n\n\ndef generate_launch_description():\n"
            f"    return LaunchDescription([\n{nodes}    ])\n")


def _tf_static(doc: dict[str, Any], frames: list[Frame]) -> str:
    """Every word shell-quoted; the comment one line."""
    _refuse(frames, "a shell command", lambda name: "a shell word cannot hold NUL" if "\0" in name else None)
    lines = "".join(" ".join(shlex.quote(w) for w in ["ros2", "run", "tf2_ros", "static_transform_publisher",
                                                       *_flag_args(f)]) + "\n" for f in frames)
    return f"# {_comment(doc, frames)}\n{lines}"


def _kalibr(doc: dict[str, Any], frames: list[Frame]) -> str:
    """Kalibr has one IMU and cameras ``camN`` with ``T_cam_imu`` (and ``T_imu_cam``, its inverse).
    A single result ``T_a_b``: a is cam0, b is imu0. A rig: the reference is imu0, sensor k is camN
    (``T_cam_imu`` = ``T_k_ref``)."""
    rig = "transforms" in doc
    imu = frames[0].parent if rig else frames[0].child
    cams = [(f.child, se3.inverse(f.matrix)) if rig else (f.parent, f.matrix) for f in frames]
    body = {f"cam{i}": {"T_cam_imu": T.tolist(), "T_imu_cam": se3.inverse(T).tolist()} for i, (_, T) in enumerate(cams)}
    names = ", ".join(f"frame '{name}' is cam{i}" for i, (name, _) in enumerate(cams))
    head = (f"# {_comment(doc, frames)}\n# " + one_line(f"Kalibr names: {names}, frame '{imu}' is imu0; ")
            + "T_cam_imu maps points from imu0 to camN, T_imu_cam is its inverse.\n")
    text: str = yaml.safe_dump(body, sort_keys=False, default_flow_style=None, width=200)
    return head + text


_WRITERS: dict[str, Callable[[dict[str, Any], list[Frame]], str]] = {
    "urdf": _urdf, "urdf-joint": _urdf_joint,
    "ros1-launch": _ros1_launch, "ros2-launch": _ros2_launch, "tf-static": _tf_static, "kalibr": _kalibr}
ALL_FORMATS = ("yaml", "json", *_WRITERS)
# the formats of a command's summary (check, compare, inspect): a text table or line, or its data as YAML/JSON
SUMMARY_FORMATS = ("text", "yaml", "json")


def render_format(doc: dict[str, Any], fmt: str) -> str:
    """The result document as text in ``fmt``, one of :data:`ALL_FORMATS`: a calibrate result (``matrix`` =
    ``T_a_b`` and ``frames``) or a rig result (``transforms``: every ``T_ref_k``), see :func:`transforms_of`.
    Raises ConfigError for an unknown format."""
    if fmt in ("yaml", "json"):
        return render(doc, fmt)
    if fmt not in _WRITERS:
        raise ConfigError(f"unknown output format {fmt!r}", "fmt", f"use one of {', '.join(ALL_FORMATS)}")
    return _WRITERS[fmt](doc, transforms_of(doc))
