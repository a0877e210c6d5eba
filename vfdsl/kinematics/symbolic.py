"""Symbolic forward kinematics and frame Jacobians in CasADi, built from a robot's Pinocchio model.

Joint k (Pinocchio index, parent joint lambda(k)) has world pose

    T_k(q) = T_lambda(k)(q) @ M_k @ X_k(q_k)

with M_k the fixed joint placement (``model.jointPlacements``) and X_k the joint motion about/along its
unit axis a_k (joint frame): a rotation Rot(a_k, q_k) for revolute and continuous joints, a translation
a_k q_k for prismatic ones. A frame (link, fixed joint) is T_k @ F with F its placement on its parent
joint; a task frame adds the user's offset O: T = T_k @ F @ O, origin p, rotation R.

The Jacobian at the task-frame origin, world axes, rows [v; w] (Pinocchio's LOCAL_WORLD_ALIGNED), is
built column by column from the joints that support the frame, with z_j = R_j a_j and o_j = p_j:

    revolute / continuous:  [z_j x (p - o_j); z_j]        prismatic:  [z_j; 0]

and zero columns for joints on other branches. Joint poses are built once per SymbolicKinematics and
shared by every frame it returns.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from vfdsl.errors import VfError
from vfdsl.kinematics.robot import Robot, as_offset, skew


@dataclass
class FrameKinematics:
    """A task frame's symbolic kinematics: origin ``p`` (3x1, world), rotation ``R`` (3x3, world <- frame)
    and Jacobian ``J`` (6 x nq, rows [v; w], world axes, at the frame origin)."""

    p: ca.SX
    R: ca.SX
    J: ca.SX


def _axis_rotation(axis: np.ndarray, angle: ca.SX) -> ca.SX:
    """Rodrigues: Rot(a, t) = cos t I + sin t [a]x + (1 - cos t) a a^T, for a unit axis a."""
    c, s = ca.cos(angle), ca.sin(angle)
    return c * ca.DM.eye(3) + s * ca.DM(skew(axis)) + (1 - c) * ca.DM(np.outer(axis, axis))


class SymbolicKinematics:
    """Symbolic kinematics of ``robot`` in the joint coordinates ``q`` (nq x 1 SX; created if None)."""

    def __init__(self, robot: Robot, q: ca.SX | None = None):
        self.robot = robot
        if q is None:
            q = ca.SX.sym("q", robot.nq)
        if not isinstance(q, ca.SX) or q.shape != (robot.nq, 1):
            raise VfError(f"robot '{robot.name}' needs an SX column of {robot.nq} joint symbols, "
                          f"got {type(q).__name__} of shape {getattr(q, 'shape', '?')}")
        self.q = q
        model = robot.model
        # World pose (R_k, p_k) of every joint frame; index 0 is the universe (= world).
        self._R: list[ca.SX] = [ca.SX.eye(3)]
        self._p: list[ca.SX] = [ca.SX.zeros(3, 1)]
        self._axis: list[ca.SX | None] = [None]  # z_j = R_j a_j in world
        for k in range(1, model.njoints):
            i = k - 1  # vfdsl coordinate of joint k (joints are in Pinocchio order, one coordinate each)
            M = model.jointPlacements[k]
            R0, p0 = self._R[model.parents[k]], self._p[model.parents[k]]
            R = ca.mtimes(R0, ca.DM(M.rotation))
            p = p0 + ca.mtimes(R0, ca.DM(M.translation))
            a = robot.joint_axes[i]
            if robot.joint_types[i] == "prismatic":
                p = p + ca.mtimes(R, ca.DM(a)) * q[i]
            else:
                R = ca.mtimes(R, _axis_rotation(a, q[i]))
            self._R.append(R)
            self._p.append(p)
            self._axis.append(ca.mtimes(R, ca.DM(a)))

    def frame(self, link: str, offset: np.ndarray | None = None) -> FrameKinematics:
        """p, R, J of the task frame ``link`` @ ``offset`` (offset: 4x4 transform in the link frame)."""
        robot, model = self.robot, self.robot.model
        frame = model.frames[robot.frame_id(link)]
        T = frame.placement.homogeneous
        O = as_offset(offset)
        if O is not None:
            T = T @ O
        k = frame.parentJoint
        R = ca.mtimes(self._R[k], ca.DM(T[:3, :3]))
        p = self._p[k] + ca.mtimes(self._R[k], ca.DM(T[:3, 3]))
        columns = [ca.SX.zeros(6, 1) for _ in range(robot.nq)]
        for j in list(model.supports[k])[1:]:
            z = self._axis[j]
            if robot.joint_types[j - 1] == "prismatic":
                columns[j - 1] = ca.vertcat(z, ca.SX.zeros(3, 1))
            else:
                columns[j - 1] = ca.vertcat(ca.cross(z, p - self._p[j]), z)
        J = ca.horzcat(*columns) if columns else ca.SX.zeros(6, 0)
        return FrameKinematics(p=p, R=R, J=J)
