"""Joint centering:  weight * sum_i ((q_i + dq_i - c_i) / r_i)^2, c_i the middle and r_i the half range of
joint i's limits (joints without limits are skipped): keeps joints away from their limits."""

from vfdsl.primitives.spec import ObjectiveSpec

SPEC = ObjectiveSpec(name="centering", summary="pull joints toward the middle of their range")
