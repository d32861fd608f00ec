"""Nominal extrinsics: every output format reads back as the same T_a_b (1e-9), and the files ROS
users keep (URDF chains, ROS 1/2 launch files, static_transform_publisher lines, Kalibr YAML)
give the transform their conventions define."""
from __future__ import annotations

import numpy as np
import pytest
from _util import run
from scipy.spatial.transform import Rotation

from handeye_cli.errors import HandEyeError
from handeye_cli.geometry import se3
from handeye_cli.io.nominal import read_nominal, static_publisher_transform
from handeye_cli.output.formats import ALL_FORMATS, render_format
from handeye_cli.output.writers import output_format as format_for_output
from handeye_cli.simulation import random_transform


def _doc(T: np.ndarray, a: str = "cam0_link", b: str = "imu") -> dict:
    t, q = se3.to_xyz_quat(T)
    return {"matrix": T.tolist(), "translation": t.tolist(), "quaternion_xyzw": q.tolist(), "frames": {"a": a, "b": b},
            "method": "dqopt", "pairs_used": 10, "version": "0.1.0"}


SUFFIX = {"yaml": ".yaml", "json": ".json", "urdf": ".urdf", "urdf-joint": ".urdf",
          "ros1-launch": ".launch", "ros2-launch": ".launch.py",
          "tf-static": ".sh", "kalibr": ".kalibr.yaml"}


@pytest.mark.parametrize("fmt", ALL_FORMATS)
def test_every_format_round_trips_to_1e9(fmt, tmp_path):
    rng = np.random.default_rng(5)
    for k in range(25):
        X = random_transform(rng, 3.0)
        path = tmp_path / f"x{k}{SUFFIX[fmt]}"
        path.write_text(render_format(_doc(X), fmt))
        nominal = read_nominal(path)
        assert np.abs(nominal.transform("cam0_link", "imu") - X).max() < 1e-9
        assert np.abs(nominal.transform("imu", "cam0_link") - se3.inverse(X)).max() < 1e-9 or fmt == "kalibr"
    expected_kind = {"yaml": "result", "json": "result"}.get(fmt, fmt)
    assert nominal.kind == expected_kind


def test_format_is_chosen_by_the_file_name():
    assert [format_for_output(p, None) for p in ("x.urdf", "x.launch", "a.launch.py", "pub.sh", "r.json", "r.yml")] == \
        ["urdf", "ros1-launch", "ros2-launch", "tf-static", "json", "yaml"]
    assert format_for_output("x.urdf", "kalibr") == "kalibr"
    with pytest.raises(HandEyeError, match="format"):
        render_format(_doc(np.eye(4)), "xml")


URDF = """<?xml version="1.0"?>
<robot name="robot42">
  <link name="base_link"/><link name="mount"/><link name="cam0"/><link name="cam1"/><link name="wheel"/>
  <joint name="base_to_mount" type="fixed"><parent link="base_link"/><child link="mount"/>
    <origin xyz="0.5 0 0.2" rpy="0 0 1.5707963267948966"/></joint>
  <joint name="mount_to_cam0" type="fixed"><parent link="mount"/><child link="cam0"/>
    <origin xyz="0 0.1 0" rpy="0.1 0.2 0.3"/></joint>
  <joint name="mount_to_cam1" type="fixed"><parent link="mount"/><child link="cam1"/>
    <origin xyz="0 -0.1 0"/></joint>
  <joint name="wheel_joint" type="continuous"><parent link="base_link"/><child link="wheel"/>
    <origin xyz="0 0.3 0"/><axis xyz="0 1 0"/></joint>
  <link name="hub_cam"/>
  <joint name="wheel_to_hub_cam" type="fixed"><parent link="wheel"/><child link="hub_cam"/></joint>
</robot>
"""


def _T(xyz, rotation: Rotation) -> np.ndarray:
    return se3.from_xyz_quat(np.array(xyz, float), rotation.as_quat())


def test_urdf_chain_composes_fixed_joints_in_either_direction(tmp_path):
    (tmp_path / "robot.urdf").write_text(URDF)
    nominal = read_nominal(tmp_path / "robot.urdf")
    T_mount_cam0 = _T([0, 0.1, 0], Rotation.from_euler("xyz", [0.1, 0.2, 0.3]))    # R = Rz(yaw) Ry(pitch) Rx(roll)
    expected_R = (Rotation.from_rotvec([0, 0, 0.3]) * Rotation.from_rotvec([0, 0.2, 0])
                  * Rotation.from_rotvec([0.1, 0, 0])).as_matrix()
    assert np.allclose(T_mount_cam0[:3, :3], expected_R, atol=1e-12)
    T_mount_cam1 = _T([0, -0.1, 0], Rotation.identity())
    assert np.allclose(nominal.transform("cam0", "cam1"), se3.inverse(T_mount_cam0) @ T_mount_cam1, atol=1e-12)
    T_base_mount = _T([0.5, 0, 0.2], Rotation.from_rotvec([0, 0, np.pi / 2]))
    assert np.allclose(nominal.transform("base_link", "cam0"), T_base_mount @ T_mount_cam0, atol=1e-12)
    with pytest.raises(HandEyeError, match="no chain of fixed transforms"):       # only a movable joint links it
        nominal.transform("cam0", "hub_cam")
    with pytest.raises(HandEyeError, match="'lidar' is not in the nominal"):
        nominal.transform("cam0", "lidar")


def test_static_transform_publisher_forms():
    q = Rotation.from_euler("xyz", [0.1, -0.2, 0.3]).as_quat()
    expected = _T([1, 2, 3], Rotation.from_quat(q))
    ypr = ["1", "2", "3", "0.3", "-0.2", "0.1", "map", "cam"]                     # yaw pitch roll
    quat = ["1", "2", "3", *(repr(float(v)) for v in q), "map", "cam"]
    flags = ["--x", "1", "--y", "2", "--z", "3", "--roll", "0.1", "--pitch", "-0.2", "--yaw", "0.3",
             "--frame-id", "map", "--child-frame-id", "cam", "--ros-args", "-r", "__node:=x"]
    for args in (ypr, ypr + ["100"], quat, quat + ["100"], flags):                 # ROS 1 tf adds a period [ms]
        edge = static_publisher_transform(args)
        assert (edge.parent, edge.child) == ("map", "cam")
        assert np.allclose(edge.matrix, expected, atol=1e-12), args
    for bad in (["1", "2", "map", "cam"], ["--x", "1"], ["--x", "1", "--qw", "1", "--yaw", "0", "--frame-id", "a",
                                                          "--child-frame-id", "b"], ["--speed", "1"]):
        with pytest.raises(HandEyeError):
            static_publisher_transform(bad)


def test_launch_files_and_command_lines(tmp_path):
    ros1 = tmp_path / "static.launch"
    ros1.write_text('<launch>\n  <node pkg="tf" type="static_transform_publisher" name="p" '
                    'args="0.1 0 0 1.5707963267948966 0 0 base cam 100"/>\n  <node pkg="rviz" type="rviz" name="v"/>\n'
                    "</launch>\n")
    n1 = read_nominal(ros1)
    assert n1.kind == "ros1-launch" and np.allclose(n1.transform("base", "cam"),
                                                   _T([0.1, 0, 0], Rotation.from_rotvec([0, 0, np.pi / 2])))
    ros2 = tmp_path / "static.launch.xml"
    ros2.write_text('<launch><node pkg="tf2_ros" exec="static_transform_publisher" '
                    'args="--x 0.1 --yaw 1.5707963267948966 --frame-id base --child-frame-id cam"/></launch>')
    n2 = read_nominal(ros2)
    assert n2.kind == "ros2-launch" and np.allclose(n2.transform("base", "cam"), n1.transform("base", "cam"))
    line = "ros2 run tf2_ros static_transform_publisher --x 0.1 --yaw 1.5707963267948966 --frame-id base " \
           "--child-frame-id cam"
    n3 = read_nominal(line)                                                     # the command line itself
    assert n3.kind == "tf-static" and np.allclose(n3.transform("base", "cam"), n1.transform("base", "cam"))


def test_kalibr_camchain_imucam(tmp_path):
    rng = np.random.default_rng(2)
    T_c0_i, T_c1_c0 = random_transform(rng, 0.1), random_transform(rng, 0.1)
    path = tmp_path / "camchain-imucam.yaml"
    path.write_text(f"cam0:\n  T_cam_imu: {T_c0_i.tolist()}\n  rostopic: /cam0/image_raw\n"
                    f"cam1:\n  T_cn_cnm1: {T_c1_c0.tolist()}\n  T_cam_imu: {(T_c1_c0 @ T_c0_i).tolist()}\n")
    nominal = read_nominal(path)
    assert nominal.kind == "kalibr" and set(nominal.frames) == {"cam0", "cam1", "imu0"}
    assert np.allclose(nominal.transform("cam0", "cam1"), se3.inverse(T_c1_c0), atol=1e-12)
    assert np.allclose(nominal.transform("imu0", "cam1"), se3.inverse(T_c1_c0 @ T_c0_i), atol=1e-12)


def test_unusable_nominals_are_one_line_errors(tmp_path, capsys):
    (tmp_path / "empty.urdf").write_text('<robot name="r"><link name="a"/></robot>')
    (tmp_path / "notes.yaml").write_text("just: text\n")
    (tmp_path / "bad.launch").write_text("<launch><node")
    (tmp_path / "r.yaml").write_text(f"matrix: {np.eye(4).tolist()}\nframes: {{a: x, b: y}}\n")
    for name, message in (("empty.urdf", "no transform found"), ("notes.yaml", "no transform found"),
                          ("bad.launch", "invalid XML"), ("missing.urdf", "not found")):
        code, out, err = run(capsys, "check", tmp_path / "r.yaml", "--against", tmp_path / name)
        assert code == 2 and out == "" and message in err and "Traceback" not in err
        assert len(err.strip().splitlines()) == 1
