"""Joint damping:  weight * || dq ||^2 (regularizes redundant and singular configurations)."""

import casadi as ca

from vfdsl.compiler.rows import Term
from vfdsl.primitives.spec import ObjectiveSpec

SPEC = ObjectiveSpec(name="damping", summary="penalize joint motion (damped least squares)")


def lower(o, ctx) -> Term:
    return Term(E=ca.SX.eye(ctx.nq), f=ca.DM.zeros(ctx.nq))
