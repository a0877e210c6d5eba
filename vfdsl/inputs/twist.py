"""twist: a commanded velocity [v; w] (m/s, rad/s), e.g. from a joystick; ``track`` scales it by its gains, which
default to 1 (the frame moves at the commanded velocity)."""

from vfdsl import units as u
from vfdsl.inputs.base import InputType, Part

INPUT = InputType("twist", "commanded velocity [v; w], m/s and rad/s (e.g. a joystick)",
                  linear=Part(u.SPEED, "m/s", "v", self_test=0.01),          # a slow joystick
                  angular=Part(u.ANGULAR_SPEED, "rad/s", "w", self_test=0.05),
                  default_gain=1.0)
