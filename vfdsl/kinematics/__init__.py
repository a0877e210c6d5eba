"""Robot models (URDF via Pinocchio) and their symbolic kinematics in CasADi."""

from vfdsl.kinematics.robot import Robot, shipped_robots
from vfdsl.kinematics.symbolic import FrameKinematics, SymbolicKinematics

__all__ = ["FrameKinematics", "Robot", "SymbolicKinematics", "shipped_robots"]
