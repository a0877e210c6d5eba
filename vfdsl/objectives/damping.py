"""Joint damping:  weight * || dq/dt ||^2 (joint rates in rad/s or m/s): regularizes redundant and singular
configurations. A redundancy term: by default it acts below the task terms, in the motions that leave them
optimal."""

import casadi as ca

from vfdsl.compiler.rows import Term
from vfdsl.primitives.spec import REDUNDANCY_LEVEL, ObjectiveSpec

SPEC = ObjectiveSpec(name="damping", summary="penalize joint motion (damped least squares)",
                     priority=REDUNDANCY_LEVEL)


def lower(o, ctx) -> tuple[Term]:
    return (Term(E=ca.SX.eye(ctx.nq), f=ca.DM.zeros(ctx.nq)),)
