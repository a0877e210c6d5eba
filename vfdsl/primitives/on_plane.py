"""Confine to a plane (paper II-B.5, eqs. 16-17).

Keep the frame origin on a plane, within ``eps`` on the free side:
0 <= d . (delta_p + dx_p) <= eps  ->  H = [d^T 0; -d^T 0], h = [0; -eps] - H delta.
"""

from vfdsl.primitives.spec import ArgSpec, ConstraintSpec

SPEC = ConstraintSpec(
    name="on_plane",
    summary="keep the frame origin on a plane, at most `within` above it",
    subject=True,
    args=(ArgSpec("plane", "plane", "the plane, normal toward the free side"),),
    tolerance="length", default_tolerance=1e-5,
    source="Li, Kapoor & Taylor 2005, II-B.5, eqs. (16)-(17)",
)
