"""force: the user's push on the handle, f (N), read from a force sensor; it drives the frame's translation."""

from vfdsl import units as u
from vfdsl.inputs.base import InputType, Part

FORCE = Part(u.FORCE, "N", "f", self_test=3.0)            # a firm hand
INPUT = InputType("force", "force on the handle, N", linear=FORCE, angular=None)
