"""The likely cause ``check`` names for a residual far beyond its tolerance comes from the primitive's spec:
``kept_angle`` (the angle its tool axis keeps from its direction or axis) and ``angle_rows`` (what its rows
measure of the angle); a primitive states them with its ``true_angle`` and names a real angle argument."""

from __future__ import annotations

import pytest

from vfdsl.primitives import CONSTRAINTS


@pytest.mark.parametrize("name", sorted(CONSTRAINTS))
def test_a_kept_angle_is_stated_with_a_true_angle_and_names_an_angle_argument(name):
    spec = CONSTRAINTS[name]
    if spec.true_angle is None:
        assert spec.kept_angle is None and spec.angle_rows == "sin"
        return
    assert spec.angle_rows in ("sin", "cos")
    if isinstance(spec.kept_angle, str):
        [arg] = [a for a in spec.args if a.name == spec.kept_angle]
        assert arg.kind == "angle"
    else:
        assert spec.kept_angle is None or 0.0 <= spec.kept_angle <= 3.1416


def test_the_direction_primitives_state_the_angle_their_axis_keeps():
    kept = {name: spec.kept_angle for name, spec in CONSTRAINTS.items() if spec.true_angle}
    assert kept == {"keeps_direction": 0.0, "cone": "angle", "tilt_at_most": "angle", "rotates_around": None}
    assert [name for name, spec in CONSTRAINTS.items() if spec.angle_rows == "cos"] == ["tilt_at_most"]
