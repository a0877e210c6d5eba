"""wrench: [f; tau], a force (N) and a torque (N m) from a 6-axis sensor; the force drives translation, the torque
rotation."""

from vfdsl.inputs.base import InputType
from vfdsl.inputs.force import FORCE
from vfdsl.inputs.torque import TORQUE

INPUT = InputType("wrench", "[f; tau], N and N m", linear=FORCE, angular=TORQUE)
