"""Read a NOMINAL extrinsic (what a sensor's mounting should be) from the files ROS users keep.

Kinds, told apart by content:

* ``result`` — a handeye result (YAML/JSON with ``matrix``, or ``translation`` + ``quaternion_xyzw``);
  its ``frames`` name the transform ``T_a_b``; or a rig result, whose ``transforms`` are ``T_parent_child``.
* ``urdf`` — a URDF: every ``fixed`` joint is the transform ``T_parent_child`` of its ``<origin
  xyz rpy>`` (rpy: fixed-axis roll about x, pitch about y, yaw about z, ``R = Rz·Ry·Rx``).
* ``ros1-launch`` / ``ros2-launch`` — a launch file (ROS 1 or ROS 2 XML, or ROS 2 Python) with
  ``static_transform_publisher`` nodes.
* ``tf-static`` — text holding ``static_transform_publisher`` command lines (``rosrun tf2_ros …``,
  ``ros2 run tf2_ros …``, also given directly as the NOMINAL string).
* ``kalibr`` — a Kalibr camchain / camchain-imucam / IMU YAML: ``camN.T_cam_imu`` (``T_camN_imu0``),
  ``camN.T_imu_cam`` (its inverse, as OpenVINS writes it), ``camN.T_cn_cnm1`` (``T_camN_cam(N-1)``),
  ``imuN.T_i_b`` (``T_imuN_imu0``); the frames are named ``camN`` / ``imuN``.

Every kind becomes a small frame graph of rigid transforms; :meth:`Nominal.transform` composes
the chain between two frames (in either direction). ``T_a_b`` is the pose of frame b in frame a
(maps points from b to a); quaternions are x-y-z-w; metres and radians.
"""
from __future__ import annotations

import ast
import re
import shlex
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml
from numpy.typing import NDArray

from ..errors import ReadError
from ..geometry import dualquat as dq
from ..geometry import se3
from ..untrusted import frame_id_problem, load_yaml, numbers_problem, yaml_problem
from .pairfile import extrinsic_of

if TYPE_CHECKING:
    import xml.etree.ElementTree as ET

__all__ = ["Edge", "Nominal", "NOMINAL_KINDS", "read_nominal", "read_result", "static_publisher_transform"]

NOMINAL_KINDS = ("result", "urdf", "ros1-launch", "ros2-launch", "tf-static", "kalibr")
_STP = "static_transform_publisher"
_FIX = ("pass a handeye result (YAML/JSON), a URDF, a ROS launch file, a static_transform_publisher "
        "command line or a Kalibr camchain YAML")


@dataclass(frozen=True, eq=False)
class Edge:
    """One rigid transform of the nominal: ``matrix`` = ``T_parent_child`` (4x4, metres)."""

    parent: str
    child: str
    matrix: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Nominal:
    """A nominal extrinsic file as a graph of fixed transforms between named frames."""

    source: str
    kind: str
    edges: tuple[Edge, ...]

    @property
    def frames(self) -> list[str]:
        """The frames the file names, in order of appearance."""
        return list(dict.fromkeys(f for e in self.edges for f in (e.parent, e.child)))

    def transform(self, a: str | None = None, b: str | None = None) -> NDArray[np.float64]:
        """``T_a_b`` (4x4): the chain of transforms from frame a to frame b, composed.

        When a or b is not a frame of the file (or not given) and the file relates exactly two
        frames, that one transform is used, read as ``T_parent_child`` of its first entry.
        Raises ReadError when the frames are not connected.
        """
        frames = self.frames
        if (a not in frames or b not in frames) and len(frames) == 2:
            return np.array(self.edges[0].matrix, dtype=np.float64)
        for name in (a, b):
            if name not in frames:
                raise ReadError(f"frame {name!r} is not in the nominal (it names {', '.join(frames)}), and no single "
                                "one of them is named by the stream's topic", self.source,
                                "name the result's frames as the nominal does with ⟦name_a⟧/⟦name_b⟧")
        return self._chain(str(a), str(b))

    def frames_for(self, a: str | None, b: str | None, topics: tuple[str | None, str | None] = (None, None)
                   ) -> tuple[str | None, str | None]:
        """The nominal's frames for a result's frames a and b: each as it is where the nominal names it, else the
        one frame of the nominal its stream's topic names — a '/'-part of the topic or consecutive parts joined by
        '_' (``/cam0/pose`` → ``cam0``; ``/camera/left/pose`` → ``camera_left``): a PoseStamped names no child
        frame, so its result frame is named after the topic (``cam0_pose``). Left as given when no frame or more
        than one matches (:meth:`transform` then names ``--name-a``/``--name-b``)."""
        frames = set(self.frames)
        out = []
        for name, topic in zip((a, b), topics, strict=True):
            if name in frames or not topic:
                out.append(name)
                continue
            parts = [p for p in topic.split("/") if p]
            named = {"_".join(parts[i:j]) for i in range(len(parts)) for j in range(i + 1, len(parts) + 1)} & frames
            out.append(named.pop() if len(named) == 1 else name)
        return out[0], out[1]

    def _chain(self, a: str, b: str) -> NDArray[np.float64]:
        """Breadth-first search from a to b over the edges taken in either direction."""
        links: dict[str, list[tuple[str, NDArray[np.float64]]]] = {}
        for e in self.edges:
            links.setdefault(e.parent, []).append((e.child, e.matrix))
            links.setdefault(e.child, []).append((e.parent, se3.inverse(e.matrix)))
        reached = {a: np.eye(4)}
        queue = deque([a])
        while queue:
            frame = queue.popleft()
            for nxt, T in links.get(frame, []):
                if nxt not in reached:
                    reached[nxt] = reached[frame] @ T
                    queue.append(nxt)
        if b not in reached:
            raise ReadError(f"no chain of fixed transforms between {a!r} and {b!r}", self.source,
                            "check the frame names; movable URDF joints are not part of a nominal chain")
        return reached[b]


def _transform(xyz: NDArray[np.float64], rotation: NDArray[np.float64]) -> NDArray[np.float64]:
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = xyz
    return T


def _rpy(rpy: Any) -> NDArray[np.float64]:
    """The rotation matrix of roll, pitch, yaw [rad] about the fixed x, y, z axes (URDF's and ROS's rpy)."""
    from scipy.spatial.transform import Rotation  # 0.3 s to import: only for a nominal given by rpy

    return np.asarray(Rotation.from_euler("xyz", rpy).as_matrix(), dtype=np.float64)


def _floats(text: str | None, n: int, where: str, field: str) -> NDArray[np.float64]:
    """The ``n`` numbers of ``text`` (blank: zeros), finite and within ``untrusted.MAX_MAGNITUDE``;
    ReadError naming ``field`` otherwise."""
    try:
        values = np.array([float(v) for v in (text or " ".join(["0"] * n)).split()])
    except ValueError:
        values = np.array([])
    if values.shape != (n,):
        raise ReadError(f"{field}: expected {n} number(s), got {text!r}", where, "fix the value")
    problem = numbers_problem(values)
    if problem:
        raise ReadError(f"{field} {text!r}: {problem}", where, "fix the value")
    return values


# --- static_transform_publisher --------------------------------------------------------------
_FLAGS = ("--x", "--y", "--z", "--qx", "--qy", "--qz", "--qw", "--roll", "--pitch", "--yaw", "--frame-id",
          "--child-frame-id")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _flag_args(args: list[str], where: str) -> Edge:
    """ROS 2 style: ``--x X … --qw W | --roll R --pitch P --yaw Y --frame-id F --child-frame-id C``."""
    values: dict[str, str] = {}
    it = iter(args)
    for flag in it:
        if flag not in _FLAGS:
            raise ReadError(f"unknown static_transform_publisher argument {flag!r}", where,
                            "use --x … --child-frame-id")
        values[flag[2:]] = next(it, "")
    if "frame-id" not in values or "child-frame-id" not in values:
        raise ReadError("static_transform_publisher without --frame-id/--child-frame-id", where, "add both frames")
    num = {k: float(_floats(v, 1, where, f"--{k}")[0]) for k, v in values.items() if not k.endswith("id")}
    quat = [k for k in ("qx", "qy", "qz", "qw") if k in num]
    euler = [k for k in ("roll", "pitch", "yaw") if k in num]
    if quat and euler:
        raise ReadError("both a quaternion and roll/pitch/yaw given", where, "give one rotation")
    xyz = np.array([num.get(k, 0.0) for k in ("x", "y", "z")])
    if quat:
        q = np.array([num.get("qx", 0.0), num.get("qy", 0.0), num.get("qz", 0.0), num.get("qw", 1.0)])
        rotation = _quaternion(q, where)
    else:
        rotation = _rpy([num.get(k, 0.0) for k in ("roll", "pitch", "yaw")])
    return _edge(values["frame-id"], values["child-frame-id"], _transform(xyz, rotation), where)


def _edge(parent: str, child: str, T: NDArray[np.float64], where: str) -> Edge:
    """The edge ``T_parent_child``; ReadError when a frame name breaks the frame-id rule."""
    for name in (parent, child):
        problem = frame_id_problem(name)
        if problem:
            raise ReadError(f"frame {name!r} is not a valid frame id: {problem}", where,
                            "fix the frame names in the nominal")
    return Edge(parent, child, T)


def _quaternion(q: NDArray[np.float64], where: str) -> NDArray[np.float64]:
    """The rotation matrix of the x-y-z-w quaternion ``q`` (normalised)."""
    if not (np.isfinite(q).all() and np.linalg.norm(q) > 1e-9):
        raise ReadError("zero or non-finite quaternion", where, "give a unit quaternion qx qy qz qw")
    return dq.to_matrix(q)


def static_publisher_transform(args: list[str], where: str = "static_transform_publisher") -> Edge:
    """The transform a ``static_transform_publisher`` argument list publishes, ``T_frame_child``.

    Accepts the ROS 2 flags (``--x … --frame-id F --child-frame-id C``) and the positional forms
    ``x y z yaw pitch roll F C`` and ``x y z qx qy qz qw F C`` (ROS 1 ``tf`` adds a period [ms]).
    """
    args = args[: args.index("--ros-args")] if "--ros-args" in args else list(args)
    if args and args[0].startswith("--"):
        return _flag_args(args, where)
    n_numbers = next((i for i, a in enumerate(args) if not _is_number(a)), len(args))
    if n_numbers not in (6, 7) or len(args) not in (n_numbers + 2, n_numbers + 3):
        raise ReadError(f"cannot parse static_transform_publisher arguments {' '.join(args)!r}", where,
                        "use 'x y z yaw pitch roll frame child' or 'x y z qx qy qz qw frame child'")
    fields = "x y z yaw pitch roll" if n_numbers == 6 else "x y z qx qy qz qw"
    nums = _floats(" ".join(args[:n_numbers]), n_numbers, where, fields)
    rotation = _rpy(nums[[5, 4, 3]]) if n_numbers == 6 else _quaternion(nums[3:7], where)
    return _edge(args[n_numbers], args[n_numbers + 1], _transform(nums[:3], rotation), where)


def _split(text: str, where: str, comments: bool = False) -> list[str]:
    """Shell words (``shlex``); ReadError for an unbalanced quote."""
    try:
        return shlex.split(text, comments=comments)
    except ValueError as e:
        raise ReadError(f"cannot split into words: {e} ({text.strip()[:80]!r})", where,
                        "balance the quotes") from None


def _command_lines(text: str, where: str) -> tuple[Edge, ...]:
    """Every ``… static_transform_publisher ARGS`` line of a shell text."""
    edges = []
    for n, line in enumerate(text.replace("\\\n", " ").splitlines(), 1):
        if _STP in line and not line.lstrip().startswith("#"):
            at = f"{where}:{n}" if where != "⟦against⟧" else where
            words = _split(line, at, comments=True)
            if _STP in words:
                edges.append(static_publisher_transform(words[words.index(_STP) + 1:], at))
    return _tree(tuple(edges), where)


def _tree(edges: tuple[Edge, ...], where: str) -> tuple[Edge, ...]:
    """``edges`` when they form a forest — every frame the child of one transform at most, no loop —
    as tf2 needs; ReadError naming the frame otherwise (the result would depend on which edge is found first)."""
    parent_of: dict[str, str] = {}
    for e in edges:
        if e.child in parent_of:
            raise ReadError(f"frame {e.child!r} is the child of two transforms (parents {parent_of[e.child]!r} "
                            f"and {e.parent!r})", where, "keep one transform per child frame")
        parent_of[e.child] = e.parent
    done: set[str] = set()
    for start in parent_of:
        path: list[str] = []
        frame = start
        while frame in parent_of and frame not in done:
            if frame in path:
                loop = " -> ".join(path[path.index(frame):] + [frame])
                raise ReadError(f"the transforms form a loop ({loop})", where, "remove one transform of the loop")
            path.append(frame)
            frame = parent_of[frame]
        done.update(path)
    return edges


# --- URDF and launch files ------------------------------------------------------------------
def _urdf(root: ET.Element, where: str) -> tuple[Edge, ...]:
    """The fixed joints; every joint (fixed or not) counts for the tree check: a URDF is a tree."""
    edges, links = [], []
    for joint in root.iter("joint"):
        parent, child, origin = joint.find("parent"), joint.find("child"), joint.find("origin")
        if parent is None or child is None:
            raise ReadError(f"joint {joint.get('name')!r} lacks <parent> or <child>", where, "fix the URDF")
        name = f"{where}: joint {joint.get('name')}"
        T = np.eye(4)
        if joint.get("type") == "fixed":
            xyz = _floats(None if origin is None else origin.get("xyz"), 3, name, "origin xyz")
            rpy = _floats(None if origin is None else origin.get("rpy"), 3, name, "origin rpy")
            T = _transform(xyz, _rpy(rpy))
        edge = _edge(str(parent.get("link")), str(child.get("link")), T, name)
        links.append(edge)
        if joint.get("type") == "fixed":
            edges.append(edge)
    _tree(tuple(links), where)
    return tuple(edges)


def _launch_xml(root: ET.Element, where: str) -> tuple[str, tuple[Edge, ...]]:
    nodes = [n for n in root.iter("node") if _STP in (n.get("type"), n.get("exec"), n.get("executable"))]
    ros2 = any(n.get("type") is None for n in nodes)
    return ("ros2-launch" if ros2 else "ros1-launch",
            _tree(tuple(static_publisher_transform(_split(n.get("args", ""), where), where) for n in nodes), where))


def _launch_python(text: str, where: str) -> tuple[Edge, ...]:
    """``Node(package='tf2_ros', executable='static_transform_publisher', arguments=[...])`` calls."""
    try:
        tree = ast.parse(text)             # parsed, never run; literal_eval reads only literals
    except SyntaxError as e:
        raise ReadError(f"not valid Python: {e.msg}", f"{where}:{e.lineno}", _FIX) from None
    except (RecursionError, MemoryError):
        raise ReadError("Python nested too deeply to parse", where,
                        "write the launch file with plain literals") from None
    edges = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        kw = {k.arg: k.value for k in node.keywords if k.arg}
        exe = kw.get("executable", kw.get("node_executable"))
        if isinstance(exe, ast.Constant) and exe.value == _STP and "arguments" in kw:
            try:
                args = [str(a) for a in ast.literal_eval(kw["arguments"])]
            except (ValueError, TypeError, SyntaxError, RecursionError, MemoryError):
                raise ReadError("static_transform_publisher arguments are not a list of literal strings",
                                f"{where}:{node.lineno}", "write the numbers and frames as literals") from None
            edges.append(static_publisher_transform(args, f"{where}:{node.lineno}"))
    return _tree(tuple(edges), where)


# --- YAML: handeye results and Kalibr --------------------------------------------------------
_KALIBR_KEYS = {"T_cam_imu": "imu0", "T_imu_cam": "imu0", "T_cn_cnm1": None, "T_i_b": "imu0"}


def _kalibr(doc: dict[str, Any], where: str) -> tuple[Edge, ...]:
    edges = []
    for name, entry in doc.items():
        if not isinstance(entry, dict):
            continue
        for key, other in _KALIBR_KEYS.items():
            if key not in entry:
                continue
            try:
                T = np.asarray(entry[key], dtype=float)
            except (TypeError, ValueError):
                T = np.zeros(0)
            problem = numbers_problem(T) if T.shape == (4, 4) else "it is not 4x4 numbers"
            if problem or not se3.is_rotation(T[:3, :3], 1e-6):
                raise ReadError(f"{name}.{key} is not a 4x4 rigid transform ({problem or 'no rotation'})", where,
                                "fix the Kalibr YAML")
            match = re.fullmatch(r"cam(\d+)", str(name))
            if other is None:
                if not match or match.group(1) == "0":
                    raise ReadError(f"{name}.T_cn_cnm1 needs a previous camera", where, "fix the Kalibr YAML")
                other = f"cam{int(match.group(1)) - 1}"
            edges.append(_edge(other, str(name), T, where) if key == "T_imu_cam" else _edge(str(name), other, T, where))
    return tuple(edges)


def _rig_entry(entry: Any, where: str) -> Edge:
    """One ``{parent, child, translation, quaternion_xyzw}`` of a rig result's ``transforms``."""
    if not (isinstance(entry, dict) and {"parent", "child"} <= set(entry)):
        raise ReadError("a transform needs parent, child, translation and quaternion_xyzw", where,
                        "pass a file written by handeye rig")
    return _edge(str(entry["parent"]), str(entry["child"]), extrinsic_of(entry, where), where)


def _parse_file(path: Path) -> tuple[str, tuple[Edge, ...]]:
    """The kind and edges of a nominal file, told apart by content: XML; else a YAML/JSON mapping
    holding a handeye result; else a Python launch file; else ``static_transform_publisher`` lines;
    else a Kalibr YAML. A result is tried before the command lines: its ``ros2_static_transform``
    holds one, and in JSON a quoted one (issue 23)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise ReadError(f"cannot read the nominal: {e}", str(path), _FIX) from None
    where = str(path)
    if text.lstrip().startswith("<"):
        import xml.etree.ElementTree as ET  # 20 ms to import: only for URDF and launch XML

        snippet = re.sub(r"<!--.*?-->", "", text, flags=re.S).lstrip().startswith("<joint")    # urdf-joint
        try:
            root = ET.fromstring(f"<robot>{text}</robot>" if snippet else text)
        except ET.ParseError as e:
            raise ReadError(f"invalid XML: {e}", where, _FIX) from None
        if snippet:
            return "urdf-joint", _urdf(root, where)
        return ("urdf", _urdf(root, where)) if root.tag == "robot" else _launch_xml(root, where)
    try:
        doc, problem = load_yaml(text), None
    except yaml.YAMLError as e:
        doc, problem = None, yaml_problem(e, where)
    if isinstance(doc, dict) and ("matrix" in doc or "translation" in doc):
        frames = doc["frames"] if isinstance(doc.get("frames"), dict) else {}
        return "result", (_edge(str(frames.get("a", "a")), str(frames.get("b", "b")), extrinsic_of(doc, where),
                                f"{where}: frames"),)
    if isinstance(doc, dict) and isinstance(doc.get("transforms"), list):
        return "result", _tree(tuple(_rig_entry(t, f"{where}: transforms[{i}]")
                                     for i, t in enumerate(doc["transforms"])), where)
    if re.search(r"^\s*(from|import)\s+launch", text, re.M):
        return "ros2-launch", _launch_python(text, where)
    if _STP in text:
        return "tf-static", _command_lines(text, where)
    if problem is not None:
        raise ReadError(f"not a nominal extrinsic (read as YAML: {problem[0]})", problem[1], _FIX)
    return "kalibr", (_kalibr(doc, where) if isinstance(doc, dict) else ())


def read_nominal(nominal: str | Path) -> Nominal:
    """Read a nominal extrinsic file (see the module docstring), or a ``static_transform_publisher``
    command line given as the string itself. Raises ReadError when nothing usable is found."""
    text = str(nominal)
    path = Path(nominal)
    if not path.is_file():
        if _STP in text:
            return Nominal("command line", "tf-static", _command_lines(text, "⟦against⟧"))
        raise ReadError("nominal file not found", text, "check the ⟦against⟧ path")
    kind, edges = _parse_file(path)
    if not edges:
        raise ReadError(f"no transform found in this {kind} file", text, _FIX)
    return Nominal(text, kind, edges)


def read_result(path: str | Path) -> dict[str, Any]:
    """A handeye result document (YAML or JSON) whose ``matrix`` is a valid ``T_a_b``; ReadError otherwise."""
    p = Path(path)
    if not p.is_file():
        raise ReadError("result file not found", str(p), "check the path")
    try:
        doc = load_yaml(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as e:
        raise ReadError(f"cannot read the result: {e.__class__.__name__}", str(p), "check the file") from None
    except yaml.YAMLError as e:
        what, where = yaml_problem(e, str(p))
        raise ReadError(f"not a handeye result: {what}", where, "pass a file written by handeye calibrate") from None
    if not (isinstance(doc, dict) and "matrix" in doc):
        raise ReadError("not a handeye result (no 'matrix')", str(p), "pass a file written by handeye calibrate")
    return {**doc, "matrix": extrinsic_of(doc, str(p)).tolist()}
