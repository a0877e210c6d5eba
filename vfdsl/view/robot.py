"""The robot as the viewer draws it: its URDF's visual geometry when it has some, else a skeleton of capsules.

Without ``<visual>`` elements (vfdsl's own robots have none), every link is a capsule between joint origins
from Pinocchio's forward kinematics: for each joint, the rigid part from its parent joint's origin to its
placement, then (a prismatic joint) the slide from the placement to the joint's moved origin; and for each
link frame, its parent joint's origin to the frame. With visual geometry, Pinocchio's visual model gives
each geometry object's pose; boxes, cylinders, spheres, capsules and meshes (read by trimesh, scaled) are
drawn as meshes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import trimesh

from vfdsl.kinematics.robot import Robot

MIN_LENGTH = 1e-5          # m: shorter segments are not drawn
LINK_RADIUS = 0.004        # m: capsule radius of a rigid link
SLIDE_RADIUS = 0.003       # m: capsule radius of a prismatic slide


@dataclass
class Part:
    """One drawn piece: a mesh in its own coordinates and, per configuration, its pose (R, p) in the world.
    A capsule part is a unit-length cylinder along z scaled to its segment's length."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    capsule: bool


def _unit_cylinder(radius: float) -> trimesh.Trimesh:
    mesh = trimesh.creation.cylinder(radius=radius, height=1.0, sections=16)
    mesh.apply_translation([0.0, 0.0, 0.5])
    return mesh


def rotation_to_z(d: np.ndarray) -> np.ndarray:
    """A rotation taking +z to the unit vector d."""
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(z, d)
    c = float(np.dot(z, d))
    if c > 1.0 - 1e-12:
        return np.eye(3)
    if c < -1.0 + 1e-9:                          # anti-parallel: half a turn about x
        return np.diag([1.0, -1.0, -1.0])
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx * (1 / (1 + c))


class RobotDrawing:
    """The parts of a robot and their world poses at a configuration q (vfdsl joint coordinates)."""

    def __init__(self, robot: Robot):
        self.robot = robot
        self.model = robot.model
        self.data = self.model.createData()
        self.visual = self._visual_model()
        self.parts: list[Part] = []
        self._segments: list[tuple[str, int, object]] = []
        if self.visual is not None and self.visual.ngeoms:
            self.kind = "urdf"
            self.visual_data = pin.GeometryData(self.visual)
            for k, obj in enumerate(self.visual.geometryObjects):
                mesh = _mesh_of(obj)
                if mesh is not None:
                    self.parts.append(Part(f"geom_{k}", np.asarray(mesh.vertices), np.asarray(mesh.faces), False))
        else:
            self.kind = "skeleton"
            self._build_skeleton()

    def _visual_model(self):
        try:
            return pin.buildGeomFromUrdf(self.model, str(self.robot.urdf_path), pin.GeometryType.VISUAL,
                                         package_dirs=[str(self.robot.urdf_path.parent)])
        except Exception:                      # no coal, unreadable meshes: draw the skeleton
            return None

    def _build_skeleton(self) -> None:
        """Segments from the neutral configuration's structure: (kind, index, radius) per part."""
        link = _unit_cylinder(LINK_RADIUS)
        slide = _unit_cylinder(SLIDE_RADIUS)
        model = self.model
        pin.forwardKinematics(model, self.data, pin.neutral(model))
        for j in range(1, model.njoints):
            if np.linalg.norm(model.jointPlacements[j].translation) > MIN_LENGTH:
                self._segments.append(("rigid", j, None))
                self.parts.append(Part(f"link_{len(self.parts)}", link.vertices, link.faces, True))
            if model.joints[j].shortname().startswith("JointModelP"):
                self._segments.append(("slide", j, None))
                self.parts.append(Part(f"link_{len(self.parts)}", slide.vertices, slide.faces, True))
        for f, frame in enumerate(model.frames):
            if frame.type == pin.FrameType.BODY and np.linalg.norm(frame.placement.translation) > MIN_LENGTH:
                self._segments.append(("frame", f, None))
                self.parts.append(Part(f"link_{len(self.parts)}", link.vertices, link.faces, True))

    def joints(self, q) -> np.ndarray:
        """World positions of the joint origins at q (N x 3), for the joint spheres."""
        pin.forwardKinematics(self.model, self.data, self.robot.to_pinocchio(q))
        return np.array([self.data.oMi[j].translation for j in range(self.model.njoints)])

    def poses(self, q) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per part: (R, p, scale) in the world at q."""
        qp = self.robot.to_pinocchio(q)
        if self.kind == "urdf":
            pin.forwardKinematics(self.model, self.data, qp)
            pin.updateGeometryPlacements(self.model, self.data, self.visual, self.visual_data)
            out = []
            for k, obj in enumerate(self.visual.geometryObjects):
                M = self.visual_data.oMg[k]
                out.append((M.rotation.copy(), M.translation.copy(), np.ones(3)))
            return out
        pin.forwardKinematics(self.model, self.data, qp)
        pin.updateFramePlacements(self.model, self.data)
        out = []
        for kind, index, _ in self._segments:
            if kind == "rigid":
                parent = self.data.oMi[self.model.parents[index]]
                a, b = parent.translation, (parent * self.model.jointPlacements[index]).translation
            elif kind == "slide":
                parent = self.data.oMi[self.model.parents[index]]
                a, b = (parent * self.model.jointPlacements[index]).translation, self.data.oMi[index].translation
            else:
                a = self.data.oMi[self.model.frames[index].parentJoint].translation
                b = self.data.oMf[index].translation
            d = b - a
            length = float(np.linalg.norm(d))
            R = rotation_to_z(d / length) if length > 1e-12 else np.eye(3)
            out.append((R, a.copy(), np.array([1.0, 1.0, max(length, 1e-9)])))
        return out


def _mesh_of(obj) -> trimesh.Trimesh | None:
    """A trimesh for a Pinocchio geometry object (coal shape or mesh file), in the object's frame."""
    import coal
    g = obj.geometry
    try:
        if isinstance(g, coal.Box):
            return trimesh.creation.box(extents=2 * np.asarray(g.halfSide))
        if isinstance(g, coal.Cylinder):
            return trimesh.creation.cylinder(radius=g.radius, height=2 * g.halfLength)
        if isinstance(g, coal.Capsule):
            return trimesh.creation.capsule(radius=g.radius, height=2 * g.halfLength)
        if isinstance(g, coal.Sphere):
            return trimesh.creation.icosphere(subdivisions=2, radius=g.radius)
        if obj.meshPath:
            mesh = trimesh.load(obj.meshPath, force="mesh")
            mesh.apply_scale(np.asarray(obj.meshScale))
            return mesh
    except Exception:
        return None
    return None
