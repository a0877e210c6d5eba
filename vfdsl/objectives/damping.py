"""Joint damping:  weight * || dq ||^2 (regularizes redundant and singular configurations)."""

from vfdsl.primitives.spec import ObjectiveSpec

SPEC = ObjectiveSpec(name="damping", summary="penalize joint motion (damped least squares)")
