"""pose: a teleoperation master's pose in its base frame, [p; roll, pitch, yaw]: its position p (m) and its
orientation as roll, pitch, yaw about the fixed x, y, z axes (rad: R = Rz(yaw) Ry(pitch) Rx(roll)), the layout of a
pose param and of URDF origins, so that a captured master pose reads as a pose. A set-point, not a rate: no
``track`` reads it (a force or a twist commands a motion; a pose is where the master is), and no monitor reads it
as a button.

Its plausibility checks, one margin per component: every component finite, a position within POSITION_BOUND of
the master's base on each axis and each angle within pi (a rotation given in degrees exceeds it).
"""

import math

import casadi as ca
import numpy as np

from vfdsl import units as u
from vfdsl.inputs.base import FINITE, InputCheck, InputType, Part

POSITION_BOUND = 10.0
"""m: a master's position beyond this from its base on any axis is a unit slip (millimetres given as metres)."""
_BOUNDS = (POSITION_BOUND,) * 3 + (math.pi,) * 3
ANGLES = ("roll", "pitch", "yaw")


def _margin(x):
    """POSITION_BOUND - |p_i| for the position, pi - |a_i| for the angles (NumPy or CasADi)."""
    bounds = ca.DM(_BOUNDS) if isinstance(x, (ca.SX, ca.MX, ca.DM)) else np.asarray(_BOUNDS)
    return bounds - abs(x)


PLAUSIBLE = InputCheck(
    f"the position within {POSITION_BOUND:g} m of the master's base on each axis, each angle within pi rad",
    _margin,
    lambda name, i, value: (f"input '{name}' is a pose: its position is {value[i]:g} m on axis {'xyz'[i]}, beyond "
                            f"{POSITION_BOUND:g} m (millimetres given as metres?)" if i < 3 else
                            f"input '{name}' is a pose: its {ANGLES[i - 3]} is {value[i]:g} rad, beyond pi (degrees "
                            f"given as radians?)"))
POSITION = Part(u.LENGTH, "m", "p", self_test=0.0)
ROTATION = Part(u.ANGLE, "rad", "", self_test=0.0, axes=ANGLES)
INPUT = InputType("pose", "a master's pose: position (m), then roll, pitch, yaw (rad)", linear=None, angular=None,
                  setpoint=(POSITION, ROTATION), checks=(FINITE, PLAUSIBLE))
