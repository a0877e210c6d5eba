"""The primitive registry: every primitive gives each tool what it reads of it, or the test names the tool.

A primitive is its module (vfdsl/primitives/<name>.py: its math, ``SPEC`` and ``lower``) plus one line in
vfdsl/primitives/__init__.py; the tools build their behaviour from ``CONSTRAINTS``, apart from two tables kept
on their own side on purpose: simulate's numpy error functions (an oracle independent of the compiled rows)
and the viewer's drawings.
"""

import importlib
import inspect

import pytest

from vfdsl.primitives import CONSTRAINTS
from vfdsl.primitives.spec import ConstraintSpec
from vfdsl.sim import metrics
from vfdsl.sim import shapes

JOINT_METRICS = ("length", "speed")      # a joint primitive's metric on prismatic joints (revolute: angular)


def missing(name: str, spec: ConstraintSpec) -> list[str]:
    """What each tool lacks of primitive ``name``, one phrase per tool; empty when nothing."""
    gaps = []
    module = importlib.import_module(f"vfdsl.primitives.{name}") if name in CONSTRAINTS else None
    lower = getattr(module, "lower", None)
    if lower is None or list(inspect.signature(lower).parameters) != ["c", "ctx"] \
            or inspect.signature(lower).return_annotation != "Rows":
        gaps.append("compile: no lower(c: ir.Constraint, ctx: Context) -> Rows in its module")
    if name not in metrics.ERRORS:
        gaps.append("simulate: no error function in vfdsl.sim.metrics.ERRORS")
    if spec.metric not in (JOINT_METRICS if not spec.subject else metrics.DISPLAY):
        gaps.append(f"simulate: metric {spec.metric!r} is not a dimension simulate displays")
    if (name in shapes.DRAWINGS) == (name in shapes.NO_GEOMETRY):
        gaps.append("view: neither a drawing in vfdsl.sim.shapes.DRAWINGS nor in NO_GEOMETRY")
    if spec.tolerance is None and spec.row_unit is None:
        gaps.append("run time: no row_unit for rows without a tolerance")
    arg_names = {a.name for a in spec.args}
    for hook, arg in (("stated_by", spec.stated_by and spec.stated_by[1]), ("reference_point", spec.reference_point)):
        if arg is not None and arg not in arg_names:
            gaps.append(f"check: {hook} names {arg!r}, not one of its arguments")
    if spec.error_is_distance and spec.reference_point is None:
        gaps.append("check: error_is_distance without a reference_point")
    if spec.true_angle is not None and not arg_names & {"axis", "direction"}:
        gaps.append("check: a true_angle without an axis or direction argument to measure it from")
    return gaps


@pytest.mark.parametrize("name", sorted(CONSTRAINTS))
def test_every_tool_has_what_it_needs_of_each_primitive(name):
    gaps = missing(name, CONSTRAINTS[name])
    assert not gaps, f"primitive {name}: " + "; ".join(gaps)


def test_the_check_names_every_tool_a_new_primitive_would_miss():
    bare = ConstraintSpec(name="bare", summary="a primitive declared only by its signature", subject=True)
    tools = {gap.split(":")[0] for gap in missing("bare", bare)}
    assert tools == {"compile", "simulate", "view", "run time"}


def test_the_tools_tables_hold_no_name_that_is_not_a_primitive():
    assert set(metrics.ERRORS) <= set(CONSTRAINTS)
    assert set(shapes.DRAWINGS) | shapes.NO_GEOMETRY <= set(CONSTRAINTS)
