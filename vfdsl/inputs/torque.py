"""torque: the user's torque on the handle, tau (N m); it drives the frame's rotation."""

from vfdsl import units as u
from vfdsl.inputs.base import InputType, Part

TORQUE = Part(u.TORQUE, "N m", "t", self_test=0.02)
INPUT = InputType("torque", "torque, N m", linear=None, angular=TORQUE)
