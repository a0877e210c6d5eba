"""The simulated robot: Pinocchio's numeric kinematics of the task's URDF, with the imperfections the paper
blames for its errors. Each is a setting, all off by default:

- command latency L: the joint increment computed at tick t reaches the servos at t + L (past one
  period, the controller does not yet see its last increments, and commands them again);
- joint resolution: the joints hold, and the encoders read, multiples of the URDF sidecar's per-joint
  resolution (SHR: 10 um on the stage); the servos keep their own setpoint unquantized, so increments
  smaller than the resolution add up;
- first-order servo lag T: between events each joint follows its quantized setpoint s as
  q(t + h) = s + (q(t) - s) exp(-h / T) (T = 0: the joint is at its setpoint on arrival);
- an external push on the tool: the joints move by the least-squares displacement J_v^+ dx that moves a
  task frame's origin by dx.

The controller commands the joint increment dq (the paper: solve for dq, then move the robot); the robot
is purely kinematic (stiff, as the SHR), so between commands only the servo lag moves it.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
import pinocchio as pin
from scipy.spatial.transform import Rotation

from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot

_EARLY = 1e-12                       # seconds: an arrival this close to a tick counts as before it


def frame_offset(frame: ir.FrameDecl) -> np.ndarray:
    """The 4x4 transform of a task frame in its link frame."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", frame.rpy).as_matrix()
    T[:3, 3] = frame.offset
    return T


class LinkPose:
    """Pinocchio's forward kinematics of one link, (p, R) in the world, for a stream of configurations:
    the same numbers as ``Robot.frame_pose(q, link)`` without its per-call checks (q comes from the
    simulator, already a float vector of the right length)."""

    def __init__(self, robot: Robot, link: str):
        self.model = robot.model
        self.data = robot.model.createData()
        self.frame = robot.frame_id(link)
        self.convert = robot.to_pinocchio if "continuous" in robot.joint_types else None

    def __call__(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pin.forwardKinematics(self.model, self.data, q if self.convert is None else self.convert(q))
        M = pin.updateFramePlacement(self.model, self.data, self.frame)
        return M.translation, M.rotation


class SimRobot:
    """True joint positions, the joint increments in flight, and the servos that follow them."""

    def __init__(self, robot: Robot, q0: np.ndarray, latency: float = 0.0, servo_lag: float = 0.0,
                 resolution: np.ndarray | None = None):
        self.robot = robot
        self.latency = latency
        self.servo_lag = servo_lag
        self.resolution = resolution
        self.setpoint = np.array(q0, dtype=float)          # the servos' own, unquantized setpoint
        self.q = self.quantize(self.setpoint)
        self._in_flight: deque[tuple[float, np.ndarray]] = deque()

    def quantize(self, q: np.ndarray) -> np.ndarray:
        """The nearest position the joints can hold (and the encoders can read)."""
        if self.resolution is None:
            return q
        return np.round(q / self.resolution) * self.resolution

    def read(self) -> np.ndarray:
        """The encoders: the joint positions, to the joints' resolution (without servo lag the joints only
        ever hold quantized setpoints)."""
        return self.q if self.servo_lag == 0.0 else self.quantize(self.q)

    def command(self, t: float, dq: np.ndarray) -> None:
        """Send a joint increment at time t; it reaches the servos' setpoint after the latency."""
        if self.latency == 0.0 and self.servo_lag == 0.0:
            self.setpoint = self.setpoint + dq
            self.q = self.quantize(self.setpoint)
        else:
            self._in_flight.append((t + self.latency, dq))

    def advance(self, t0: float, t1: float) -> None:
        """Move the joints from time t0 to t1: increments arrive, the servos follow the setpoint."""
        t = t0
        while self._in_flight and self._in_flight[0][0] <= t1 + _EARLY:
            arrival, dq = self._in_flight.popleft()
            self._follow(max(arrival, t) - t)
            t = max(arrival, t)
            self.setpoint = self.setpoint + dq
            if self.servo_lag == 0.0:
                self.q = self.quantize(self.setpoint)
        self._follow(t1 - t)

    def _follow(self, h: float) -> None:
        if self.servo_lag > 0.0 and h > 0.0:
            target = self.quantize(self.setpoint)
            self.q = target + (self.q - target) * math.exp(-h / self.servo_lag)

    def push(self, frame: ir.FrameDecl, displacement) -> None:
        """An external push that moves the frame's origin by ``displacement`` (least-squares joint motion);
        the servos' setpoint moves with it (a stiff, position-controlled robot holds where it was pushed to,
        to its resolution)."""
        J = self.robot.frame_jacobian(self.q, frame.link, frame_offset(frame))[:3]
        dq = np.linalg.lstsq(J, np.asarray(displacement, dtype=float), rcond=None)[0]
        self.q = self.quantize(self.q + dq)
        self.setpoint = self.setpoint + dq
