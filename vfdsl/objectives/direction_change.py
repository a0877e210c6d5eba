"""Keep the tool direction (lecture, slide 45, the eta term):  weight * || omega x l_t ||^2, omega = J_w dq/dt the
angular velocity and l_t the tool axis (rad/s): penalizes any turning of the tool direction."""

import casadi as ca

from vfdsl.compiler.geometry import skew
from vfdsl.compiler.rows import Term
from vfdsl.primitives.spec import ArgSpec, ObjectiveSpec

SPEC = ObjectiveSpec(
    name="direction_change",
    summary="penalize changes of the tool axis direction",
    args=(ArgSpec("frame", "frame", "the task frame whose tool axis should stay steady"),),
    source="Taylor, lecture notes, slide 45",
)


def lower(o, ctx) -> tuple[Term]:
    f = ctx.frame(o.args["frame"].name)
    return (Term(E=skew(f.axis) @ f.Jw, f=ca.DM.zeros(3)),)     # l x omega = -(omega x l): same norm
