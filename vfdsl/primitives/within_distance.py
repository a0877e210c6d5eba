"""Stay within a distance of a point (lecture, "keep tool tip near a point", slide 44).

|| p + dx_p - P || <= r, approximated by the n x m sphere polytope (as stays_at with eps = r).
"""

from vfdsl.primitives.spec import ArgSpec, ConstraintSpec

SPEC = ConstraintSpec(
    name="within_distance",
    summary="keep the frame origin at most `distance` from a point",
    subject=True,
    args=(ArgSpec("center", "point", "the goal point"),
          ArgSpec("distance", "length", "the largest allowed distance")),
    resolution="sphere",
    source="Taylor, lecture notes, slide 44",
)
