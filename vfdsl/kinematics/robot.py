"""Robots: a URDF loaded by Pinocchio, seen through vfdsl's coordinates.

vfdsl uses one coordinate per actuated joint: an angle (rad) for revolute and continuous joints, a
length (m) for prismatic ones; fixed joints are not coordinates. Pinocchio stores a continuous joint as
(cos q, sin q), so :meth:`Robot.to_pinocchio` converts; velocities (and Jacobian columns) are one per
joint in both, in Pinocchio's joint order.

Frame Jacobians follow Pinocchio's LOCAL_WORLD_ALIGNED convention: rows [v; w] (translation first),
expressed in the world (= base) axes, with v the velocity of the task frame's origin.

A task frame is a link plus an optional ``offset``, the 4x4 homogeneous transform of the task frame
relative to the link frame: ``T_world_task = T_world_link @ offset``.

Metadata a URDF cannot hold comes from an optional sidecar ``<stem>.yaml`` next to the URDF::

    description: one line
    resolution: {joint: smallest increment, ...}   # SI units; absent, or given for every joint
    tool_axis: {link: x|y|z, ...}                  # the local axis that is that link's tool axis

Before Pinocchio reads a URDF, its joints are checked (with the URDF's line in the message): limits are
finite numbers with lower <= upper and a velocity >= 0, an axis is not zero, and mimic joints are refused
(vfdsl would drive them as independent joints). A robot needs at least one actuated joint. The sidecar's
values must have the documented types.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from xml.parsers import expat

import numpy as np
import pinocchio as pin
import yaml

from vfdsl.errors import VfError, suggest
from vfdsl.files import BoundedLoader, read_text

ROBOTS_DIR = Path(__file__).resolve().parent.parent / "robots"

# Pinocchio joint model -> vfdsl joint type (every other joint model is unsupported).
_JOINT_TYPES: dict[str, str] = {
    **{f"JointModelR{a}": "revolute" for a in "XYZ"},
    "JointModelRevoluteUnaligned": "revolute",
    **{f"JointModelRUB{a}": "continuous" for a in "XYZ"},
    "JointModelRevoluteUnboundedUnaligned": "continuous",
    **{f"JointModelP{a}": "prismatic" for a in "XYZ"},
    "JointModelPrismaticUnaligned": "prismatic",
}


def shipped_robots() -> list[str]:
    """Names of the robots shipped with vfdsl (``vfdsl/robots/<name>.urdf``)."""
    return sorted(p.stem for p in ROBOTS_DIR.glob("*.urdf"))


_LAST_ROW, _EYE3 = np.array([0.0, 0.0, 0.0, 1.0]), np.eye(3)


def _close(a: np.ndarray, b: np.ndarray, atol: float) -> bool:
    """np.allclose(a, b, atol=atol) for finite arrays (|a - b| <= atol + 1e-5 |b|), without its ~50 us of
    broadcasting and NaN handling: as_offset runs at every call of frame_pose and frame_jacobian."""
    return bool(np.all(np.abs(a - b) <= atol + 1e-5 * np.abs(b)))


def as_offset(offset) -> np.ndarray | None:
    """Validate a task-frame offset: ``None`` or a finite 4x4 homogeneous transform with a rotation block."""
    if offset is None:
        return None
    T = np.asarray(offset, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise VfError(f"a frame offset must be a finite 4x4 homogeneous transform, got shape {T.shape}")
    R = T[:3, :3]
    if not _close(T[3], _LAST_ROW, 1e-12) or not _close(R.T @ R, _EYE3, 1e-9) or np.linalg.det(R) < 0:
        raise VfError("a frame offset must be a homogeneous transform: last row [0 0 0 1] and a rotation block")
    return T


def skew(v) -> np.ndarray:
    """[v]x, the matrix with [v]x w = v x w."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


class Robot:
    """A robot model: Pinocchio's model of a URDF, its joints in vfdsl coordinates, and sidecar metadata."""

    name: str                       # the URDF's robot name
    urdf_path: Path
    model: pin.Model
    nq: int                         # one coordinate per actuated joint, in Pinocchio's joint order
    joint_names: list[str]
    joint_types: list[str]          # "revolute" | "prismatic" | "continuous"
    joint_axes: list[np.ndarray]    # unit axis of each joint, in its joint frame
    lower: np.ndarray               # -inf for continuous joints
    upper: np.ndarray               # +inf for continuous joints
    velocity_limit: np.ndarray
    resolution: np.ndarray | None   # from the sidecar, when it gives one
    description: str                # from the sidecar ("" without one)
    tool_axis: dict[str, str]       # from the sidecar: link -> "x" | "y" | "z"

    def __init__(self, urdf_path: Path):
        self.urdf_path = Path(urdf_path)
        self.model = _build_model(self.urdf_path)
        self.name = self.model.name or self.urdf_path.stem
        self._data = self.model.createData()
        joints = list(self.model.joints)[1:]  # joint 0 is the universe
        self.nq = len(joints)
        if self.nq == 0:
            raise VfError(f"{self.urdf_path}: robot '{self.name}' has no actuated joint",
                          hint="a task moves a robot's joints: give the URDF a revolute, continuous or prismatic joint")
        self.joint_names = list(self.model.names)[1:]
        self.joint_types = []
        self.joint_axes = []
        # The joint axis (joint frame) is the motion subspace S = [v; w]: w for rotations, v for slides.
        pin.forwardKinematics(self.model, self._data, pin.neutral(self.model))
        for k, (name, joint) in enumerate(zip(self.joint_names, joints), start=1):
            kind = _JOINT_TYPES.get(joint.shortname())
            if kind is None:
                raise VfError(f"{self.urdf_path}: joint '{name}' ({joint.shortname()}) is not supported",
                              hint="vfdsl supports revolute, continuous, prismatic and fixed joints")
            S = np.asarray(self._data.joints[k].S, dtype=float).ravel()
            self.joint_types.append(kind)
            self.joint_axes.append(S[:3] if kind == "prismatic" else S[3:])
        self._idx_q = np.array([j.idx_q for j in joints], dtype=int)
        self._continuous = np.array([t == "continuous" for t in self.joint_types], dtype=bool)
        idx_v = np.array([j.idx_v for j in joints], dtype=int)
        self.lower = np.where(self._continuous, -np.inf, self.model.lowerPositionLimit[self._idx_q])
        self.upper = np.where(self._continuous, np.inf, self.model.upperPositionLimit[self._idx_q])
        self.velocity_limit = np.asarray(self.model.velocityLimit[idx_v], dtype=float)
        self._links = {f.name: i for i, f in enumerate(self.model.frames) if f.type == pin.FrameType.BODY}
        self.description, self.resolution, self.tool_axis = self._read_sidecar()

    @classmethod
    def load(cls, name_or_path: str | Path, base_dir: Path | None = None) -> "Robot":
        """A shipped robot ("shr7", "panda7", "psm6", with or without ".urdf") or a URDF path (relative to base_dir).

        An existing file wins over a shipped robot of the same name.
        """
        path = Path(name_or_path).expanduser()
        if not path.is_absolute() and base_dir is not None:
            path = Path(base_dir) / path
        if path.is_file() or (path.suffix == ".urdf" and path.exists()):     # a FIFO or device: refused on reading
            return cls(path.resolve())
        stem = str(name_or_path).removesuffix(".urdf")
        shipped = shipped_robots()
        if stem in shipped:
            return cls(ROBOTS_DIR / f"{stem}.urdf")
        raise VfError(f"no robot '{name_or_path}': not a shipped robot, and no file {path}",
                      hint=suggest(stem, shipped, "shipped robots"))

    def link_names(self) -> list[str]:
        """The URDF's link names (Pinocchio BODY frames), in model order."""
        return list(self._links)

    @cached_property
    def reach(self) -> float:
        """An upper bound (m) of how far any link frame can be from the base: along each chain, the sum of
        the joints' placement offsets, each prismatic joint's longest extension and the frame's offset."""
        model = self.model
        joint_reach = np.zeros(model.njoints)
        for j in range(1, model.njoints):
            k = j - 1
            extension = max(abs(self.lower[k]), abs(self.upper[k])) if self.joint_types[k] == "prismatic" else 0.0
            joint_reach[j] = (joint_reach[model.parents[j]] + np.linalg.norm(model.jointPlacements[j].translation)
                              + extension)
        return float(max(joint_reach[f.parentJoint] + np.linalg.norm(f.placement.translation) for f in model.frames))

    def frame_id(self, link: str) -> int:
        """Pinocchio frame index of ``link``; VfError with close matches if there is no such link."""
        try:
            return self._links[link]
        except KeyError:
            raise VfError(f"robot '{self.name}' has no link '{link}'",
                          hint=suggest(link, self._links, "links")) from None

    def to_pinocchio(self, q) -> np.ndarray:
        """Pinocchio's configuration for joint coordinates ``q``: continuous angles become (cos, sin)."""
        q = self.check_q(q)
        c = self._continuous
        qp = np.empty(self.model.nq)
        qp[self._idx_q[~c]] = q[~c]
        qp[self._idx_q[c]] = np.cos(q[c])
        qp[self._idx_q[c] + 1] = np.sin(q[c])
        return qp

    def check_q(self, q) -> np.ndarray:
        """``q`` as a float vector of length nq; VfError on a wrong length or a non-finite entry."""
        try:
            q = np.asarray(q, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise VfError(f"robot '{self.name}': joint positions must be numbers") from None
        if q.size != self.nq:
            raise VfError(f"robot '{self.name}' has {self.nq} joints ({', '.join(self.joint_names)}), "
                          f"got {q.size} joint positions")
        if not np.all(np.isfinite(q)):
            bad = [n for n, v in zip(self.joint_names, q) if not np.isfinite(v)]
            raise VfError(f"robot '{self.name}': joint positions are not finite for {', '.join(bad)}")
        return q

    def frame_pose(self, q, link: str, offset=None) -> tuple[np.ndarray, np.ndarray]:
        """(p, R) of the task frame in world: T = T_world_link(q) @ offset."""
        fid = self.frame_id(link)
        T = as_offset(offset)
        pin.framesForwardKinematics(self.model, self._data, self.to_pinocchio(q))
        M = self._data.oMf[fid]
        p, R = M.translation.copy(), M.rotation.copy()
        if T is not None:
            p, R = p + R @ T[:3, 3], R @ T[:3, :3]
        return p, R

    def frame_jacobian(self, q, link: str, offset=None) -> np.ndarray:
        """6 x nq Jacobian, rows [v; w], world axes, at the task frame's origin.

        For an offset t (in link axes) the origin moves by r = R_link t, so v_task = v_link + w x r,
        i.e. J_v -= [r]x J_w.
        """
        fid = self.frame_id(link)
        T = as_offset(offset)
        J = pin.computeFrameJacobian(self.model, self._data, self.to_pinocchio(q), fid,
                                     pin.ReferenceFrame.LOCAL_WORLD_ALIGNED).copy()
        if T is not None:
            r = self._data.oMf[fid].rotation @ T[:3, 3]
            J[:3] -= skew(r) @ J[3:]
        return J

    def _read_sidecar(self) -> tuple[str, np.ndarray | None, dict[str, str]]:
        path = self.urdf_path.with_suffix(".yaml")
        if not path.is_file():
            return "", None, {}
        try:
            meta = yaml.load(read_text(path, "robot sidecar"), Loader=BoundedLoader) or {}
        except yaml.YAMLError as e:
            mark = getattr(e, "problem_mark", None)
            where = f":{mark.line + 1}" if mark else ""
            raise VfError(f"{path}{where}: not valid YAML: {getattr(e, 'problem', None) or e}") from None
        if not isinstance(meta, dict):
            raise VfError(f"{path}: expected a mapping with description, resolution, tool_axis")
        unknown = set(meta) - {"description", "resolution", "tool_axis"}
        if unknown:
            raise VfError(f"{path}: unknown key(s) {', '.join(sorted(map(str, unknown)))}",
                          hint="known keys: description, resolution, tool_axis")
        description = meta.get("description", "")
        if not isinstance(description, str):
            raise VfError(f"{path}: description must be one line of text")
        resolution = None
        if meta.get("resolution") is not None:
            res = meta["resolution"]
            if not isinstance(res, dict) or set(res) != set(self.joint_names):
                raise VfError(f"{path}: resolution must give a value for every joint: "
                              f"{', '.join(self.joint_names)}")
            for name in self.joint_names:
                value = res[name]
                if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < math.inf:
                    raise VfError(f"{path}: the resolution of joint '{name}' must be a positive number, got "
                                  f"{type(value).__name__ if isinstance(value, (list, dict)) else repr(value)}")
            resolution = np.array([float(res[n]) for n in self.joint_names])
        axes = meta.get("tool_axis") or {}
        if not isinstance(axes, dict) or not all(isinstance(v, str) for v in axes.values()):
            raise VfError(f"{path}: tool_axis maps link names to x, y or z", hint="e.g. tool_axis: {tool_tip: z}")
        tool_axis = {str(k): v for k, v in axes.items()}
        for link, axis in tool_axis.items():
            if link not in self._links:
                raise VfError(f"{path}: tool_axis names unknown link '{link}'",
                              hint=suggest(link, self._links, "links"))
            if axis not in ("x", "y", "z"):
                raise VfError(f"{path}: tool axis of '{link}' must be x, y or z, got '{axis}'")
        return description, resolution, tool_axis


def _build_model(path: Path) -> pin.Model:
    """Pinocchio's model of the URDF at ``path``; VfError (never a raw parser error) if it is not one."""
    text = read_text(path, "URDF file")
    try:
        root, joints = _read_joints(text)
    except expat.ExpatError as e:
        raise VfError(f"{path}: malformed URDF (not well-formed XML: {e})") from None
    if root != "robot":
        raise VfError(f"{path}: malformed URDF (root element is <{root}>, expected <robot>)")
    for joint in joints:
        _check_joint(joint, f"{path}:{joint.line}")
    try:
        return pin.buildModelFromXML(text)
    except (ValueError, RuntimeError) as e:
        raise VfError(f"{path}: malformed URDF ({(str(e).splitlines() or ['no reason given'])[0]})") from None


@dataclass
class _JointXml:
    """A URDF <joint>: its attributes, its line, and the attributes of its first child of each tag."""

    attrs: dict[str, str]
    line: int
    children: dict[str, dict[str, str]] = field(default_factory=dict)


def _read_joints(text: str) -> tuple[str, list[_JointXml]]:
    """The root tag of the XML ``text`` and its <joint> elements (children of the root), with lines."""
    parser = expat.ParserCreate()
    open_tags: list[str] = []
    joints: list[_JointXml] = []
    root: list[str] = []

    def start(tag, attrs):
        if not root:
            root.append(tag)
        if tag == "joint" and len(open_tags) == 1:
            joints.append(_JointXml(attrs, parser.CurrentLineNumber))
        elif len(open_tags) == 2 and open_tags[-1] == "joint":
            joints[-1].children.setdefault(tag, attrs)
        open_tags.append(tag)

    parser.StartElementHandler = start
    parser.EndElementHandler = lambda tag: open_tags.pop()
    parser.Parse(text, True)
    return (root or [""])[0], joints


def _numbers(attrs: dict[str, str], tag: str, attribute: str, count: int, where: str, default: str) -> list[float]:
    text = attrs.get(attribute, default)
    try:
        values = [float(x) for x in text.split()]
    except ValueError:
        values = []
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise VfError(f"{where}: <{tag} {attribute}=\"{text[:40]}\"> must be {count} finite number(s)")
    return values


def _check_joint(joint: _JointXml, where: str) -> None:
    """What Pinocchio would accept silently but vfdsl must not: mimic joints, zero axes, inverted limits."""
    name, kind = joint.attrs.get("name", "?"), joint.attrs.get("type", "?")
    if kind == "fixed":
        return
    if "mimic" in joint.children:
        raise VfError(f"{where}: joint '{name}' mimics joint '{joint.children['mimic'].get('joint', '?')}'; mimic "
                      "joints are not supported", hint="vfdsl would move it as an independent joint: make it fixed, "
                                                      "or model the coupling as one joint")
    if "axis" in joint.children:
        if math.hypot(*_numbers(joint.children["axis"], "axis", "xyz", 3, where, "1 0 0")) < 1e-12:
            raise VfError(f"{where}: joint '{name}' has a zero axis", hint='give a unit axis, e.g. <axis xyz="0 0 1"/>')
    if "limit" not in joint.children:
        return
    limit = joint.children["limit"]
    velocity, = _numbers(limit, "limit", "velocity", 1, where, "0")
    if velocity < 0:
        raise VfError(f"{where}: joint '{name}' has a negative velocity limit ({velocity:g})")
    if kind in ("revolute", "prismatic"):
        lower, = _numbers(limit, "limit", "lower", 1, where, "0")
        upper, = _numbers(limit, "limit", "upper", 1, where, "0")
        if lower > upper:
            raise VfError(f"{where}: joint '{name}' has lower limit {lower:g} above its upper limit {upper:g}")
