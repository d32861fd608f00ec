"""The result in the formats ROS users paste in: YAML/JSON, a URDF fixed joint, ROS 1 and ROS 2
static transform publisher launch files, a ``static_transform_publisher`` command line, Kalibr YAML.

Every writer states ``T_a_b`` — the pose of frame b (``frames.b``) in frame a (``frames.a``),
mapping points from b to a — with numbers at full precision (``repr``), so reading the output
back with :func:`handeye_cli.io.nominal.read_nominal` gives the same transform to 1e-9:

* ``urdf``: ``<joint type="fixed">`` with parent a, child b, ``<origin xyz rpy>`` (rpy: fixed-axis
  roll x, pitch y, yaw z, ``R = Rz·Ry·Rx`` — accurate to ~1e-9 except within ~1e-4 rad of pitch ±90°);
* ``ros1-launch``: ``tf2_ros static_transform_publisher`` node, ``args="x y z qx qy qz qw a b"``;
* ``ros2-launch``: a Python launch file with the node's ``--x … --frame-id a --child-frame-id b``;
* ``tf-static``: the ``ros2 run tf2_ros static_transform_publisher …`` command line;
* ``kalibr``: ``cam0.T_cam_imu`` = ``T_a_b`` (a is Kalibr's camera, b its IMU) and
  ``cam0.T_imu_cam``, the inverse (as OpenVINS names it).

Quaternions are x-y-z-w, translations metres.
"""
from __future__ import annotations

import json
import re
import shlex
from collections.abc import Callable
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from .. import __version__, se3
from ..errors import ConfigError
from .document import render

__all__ = ["ALL_FORMATS", "render_format"]



def _parts(doc: dict[str, Any]) -> tuple[NDArray[np.float64], str, str]:
    """``T_a_b`` and the names of frames a and b."""
    frames = doc.get("frames") or {}
    return np.asarray(doc["matrix"], dtype=float), str(frames.get("a", "a")), str(frames.get("b", "b"))


def _num(values: NDArray[np.float64]) -> list[str]:
    return [repr(float(v)) for v in values]


def _comment(doc: dict[str, Any], a: str, b: str) -> str:
    return (f"T_{a}_{b}: the pose of frame '{b}' in frame '{a}' (maps points from {b} to {a}); handeye "
            f"{doc.get('version', __version__)}, method {doc.get('method', '?')}, {doc.get('pairs_used', '?')} pairs")


def _node_name(a: str, b: str) -> str:
    return re.sub(r"\W", "_", f"handeye_{a}_to_{b}")


def _xyz_quat(T: NDArray[np.float64]) -> list[str]:
    t, q = se3.to_xyz_quat(T)
    return _num(np.r_[t, q])


def _flag_args(T: NDArray[np.float64], a: str, b: str) -> list[str]:
    args = []
    for flag, value in zip(("x", "y", "z", "qx", "qy", "qz", "qw"), _xyz_quat(T), strict=True):
        args += [f"--{flag}", value]
    return [*args, "--frame-id", a, "--child-frame-id", b]


def _urdf(doc: dict[str, Any]) -> str:
    T, a, b = _parts(doc)
    rpy = Rotation.from_matrix(T[:3, :3]).as_euler("xyz")
    return (f'<?xml version="1.0"?>\n<!-- {_comment(doc, a, b).replace("--", "- -")} -->\n'
            f'<robot name="handeye_extrinsic">\n  <link name={quoteattr(a)}/>\n  <link name={quoteattr(b)}/>\n'
            f'  <joint name={quoteattr(f"{a}_to_{b}")} type="fixed">\n'
            f"    <parent link={quoteattr(a)}/>\n    <child link={quoteattr(b)}/>\n"
            f'    <origin xyz="{" ".join(_num(T[:3, 3]))}" rpy="{" ".join(_num(rpy))}"/>\n'
            "  </joint>\n</robot>\n")


def _ros1_launch(doc: dict[str, Any]) -> str:
    T, a, b = _parts(doc)
    args = " ".join([*_xyz_quat(T), a, b])
    return (f"<launch>\n  <!-- {_comment(doc, a, b).replace('--', '- -')} -->\n"
            f'  <node pkg="tf2_ros" type="static_transform_publisher" name="{_node_name(a, b)}"\n'
            f"        args={quoteattr(args)}/>\n</launch>\n")


def _ros2_launch(doc: dict[str, Any]) -> str:
    T, a, b = _parts(doc)
    args = ", ".join(json.dumps(v) for v in _flag_args(T, a, b))
    return (f'"""{_comment(doc, a, b)}."""\nfrom launch import LaunchDescription\n'
            "from launch_ros.actions import Node\n\n\ndef generate_launch_description():\n"
            "    return LaunchDescription([\n        Node(\n            package=\"tf2_ros\",\n"
            "            executable=\"static_transform_publisher\",\n"
            f"            name=\"{_node_name(a, b)}\",\n            arguments=[{args}],\n        ),\n    ])\n")


def _tf_static(doc: dict[str, Any]) -> str:
    T, a, b = _parts(doc)
    words = ["ros2", "run", "tf2_ros", "static_transform_publisher", *_flag_args(T, a, b)]
    return f"# {_comment(doc, a, b)}\n{' '.join(shlex.quote(w) for w in words)}\n"


def _kalibr(doc: dict[str, Any]) -> str:
    T, a, b = _parts(doc)
    body = {"cam0": {"T_cam_imu": T.tolist(), "T_imu_cam": se3.inverse(T).tolist()}}
    head = (f"# {_comment(doc, a, b)}\n# Kalibr names: frame '{a}' is cam0, frame '{b}' is imu0; "
            "T_cam_imu maps points from imu0 to cam0, T_imu_cam is its inverse.\n")
    return head + yaml.safe_dump(body, sort_keys=False, default_flow_style=None, width=200)


_WRITERS: dict[str, Callable[[dict[str, Any]], str]] = {"urdf": _urdf, "ros1-launch": _ros1_launch,
                                              "ros2-launch": _ros2_launch, "tf-static": _tf_static,
                                              "kalibr": _kalibr}
ALL_FORMATS = ("yaml", "json", *_WRITERS)


def render_format(doc: dict[str, Any], fmt: str) -> str:
    """The result document ``doc`` (needs ``matrix`` = ``T_a_b`` and ``frames``) as text in ``fmt``,
    one of :data:`ALL_FORMATS`. Raises ConfigError for an unknown format."""
    if fmt in ("yaml", "json"):
        return render(doc, fmt)
    if fmt not in _WRITERS:
        raise ConfigError(f"unknown output format {fmt!r}", "--format", f"use one of {', '.join(ALL_FORMATS)}")
    return _WRITERS[fmt](doc)
