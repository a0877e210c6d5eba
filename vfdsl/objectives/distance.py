"""Stay close to a point (lecture, slide 44):  weight * || p + J_v dq - P ||^2."""

from vfdsl.primitives.spec import ArgSpec, ObjectiveSpec

SPEC = ObjectiveSpec(
    name="distance",
    summary="pull the frame origin toward a point",
    args=(ArgSpec("frame", "frame", "the task frame"), ArgSpec("target", "point", "the goal point")),
    source="Taylor, lecture notes, slide 44",
)
