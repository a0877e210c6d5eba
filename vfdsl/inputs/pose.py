"""pose: a teleoperation master's pose in its base frame, [p; r]: its position p (m) and its orientation as a
rotation vector r (rad: the axis times the angle, |r| <= pi). A set-point, not a rate: no ``track`` reads it (a
force or a twist commands a motion; a pose is where the master is), and no monitor reads it as a button.

Its plausibility checks, one margin per component: every component finite, a position within POSITION_BOUND of
the master's base on each axis and a rotation vector within pi on each (a rotation given in degrees exceeds it).
"""

import math

import casadi as ca
import numpy as np

from vfdsl import units as u
from vfdsl.inputs.base import FINITE, InputCheck, InputType, Part

POSITION_BOUND = 10.0
"""m: a master's position beyond this from its base on any axis is a unit slip (millimetres given as metres)."""
_BOUNDS = (POSITION_BOUND,) * 3 + (math.pi,) * 3


def _margin(x):
    """POSITION_BOUND - |p_i| for the position, pi - |r_i| for the rotation vector (NumPy or CasADi)."""
    bounds = ca.DM(_BOUNDS) if isinstance(x, (ca.SX, ca.MX, ca.DM)) else np.asarray(_BOUNDS)
    return bounds - abs(x)


PLAUSIBLE = InputCheck(
    f"the position within {POSITION_BOUND:g} m of the master's base on each axis, the rotation vector within pi rad",
    _margin,
    lambda name, i, value: (f"input '{name}' is a pose: its position is {value[i]:g} m on axis {'xyz'[i]}, beyond "
                            f"{POSITION_BOUND:g} m (millimetres given as metres?)" if i < 3 else
                            f"input '{name}' is a pose: component {i - 3} of its rotation vector is {value[i]:g} rad, "
                            f"beyond pi (degrees given as radians?)"))
POSITION = Part(u.LENGTH, "m", "p", self_test=0.0)
ROTATION = Part(u.ANGLE, "rad", "r", self_test=0.0)
INPUT = InputType("pose", "a master's pose: position (m), then rotation vector (rad)", linear=None, angular=None,
                  setpoint=(POSITION, ROTATION), checks=(FINITE, PLAUSIBLE))
