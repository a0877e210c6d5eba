"""Rotate around an axis with a fixed angle: a cone (paper III-B, eqs. 22-23).

Keep the tool axis l_t at angle gamma from an axis l_a (a cone of half-angle gamma): the instantaneous
rotation axis w_d = R [cos gamma, sin gamma, 0]^T with d1 = l_t x l_a / ||.||, d2 = d1 x l_a / ||.||,
R = [d2, l_a/||l_a||, -d1] (eq. 22); delta_r = d1 sin gamma - l_t x l_a (eq. 23); then the
"rotate around a line" rows (eq. 13) about w_d.
"""

from vfdsl.primitives.spec import ArgSpec, ConstraintSpec

SPEC = ConstraintSpec(
    name="cone",
    summary="keep the tool axis at a fixed angle from an axis",
    subject=True,
    args=(ArgSpec("axis", "direction", "the cone axis l_a"),
          ArgSpec("angle", "angle", "the cone half-angle gamma")),
    tolerance="angle", default_tolerance=1e-3,
    resolution="polygon",
    source="Li, Kapoor & Taylor 2005, III-B, eqs. (22)-(23)",
)
