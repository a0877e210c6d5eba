"""button: a switch the user presses, one number: 0 released, 1 pressed (any value in [0, 1] is accepted, above 1/2
reads as pressed). It moves nothing: a monitor reads it (``monitor pressed = go``); the simulated and the viewer's
hand leave it at 0, and the export's self-test too."""

from vfdsl import units as u
from vfdsl.inputs.base import FINITE, InputCheck, InputType, Part

IN_RANGE = InputCheck(
    "the button's value lies in [0, 1] (0 released, 1 pressed)",
    lambda x: 0.5 - abs(x - 0.5),        # >= 0 iff 0 <= x <= 1
    lambda name, i, value: f"input '{name}' is a button: 0 (released) to 1 (pressed), got {value[i]:g} "
                           f"(index {i})")
INPUT = InputType("button", "a button, 0 released or 1 pressed", linear=None, angular=None,
                  level=Part(u.DIMENSIONLESS, "1", "pressed", self_test=0.0, axes=("",)),
                  checks=(FINITE, IN_RANGE))
