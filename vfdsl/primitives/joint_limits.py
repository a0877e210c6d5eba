"""Joint position limits (lecture, slide 44):  q_lo - q <= dq <= q_hi - q."""

from vfdsl.primitives.spec import ConstraintSpec

SPEC = ConstraintSpec(
    name="joint_limits",
    summary="keep every joint within its URDF limits",
    subject=False,
    source="Taylor, lecture notes, slide 44",
)
