"""Allowed ranges of arguments and clause values: every scalar argument states its range in its SPEC, and a
value outside it (a literal, a fixture's actual argument, a param's value) is an error at load time. Each
class has a case that must fail at a known line and column and a near miss that must still load."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

import vfdsl
from vfdsl import VfError
from vfdsl.objectives import OBJECTIVES
from vfdsl.passes import clause_ranges
from vfdsl.pipeline import FEASIBILITY_TOLERANCE
from vfdsl.primitives import CONSTRAINTS
from vfdsl.primitives.spec import SCALAR_DIMENSIONS, Range

HEAD = 'task t\nunits mm, deg\nrobot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\ninput f : force\n'
# Appended lines start at line 6.


def load(tmp_path, body: str, files: dict[str, str] | None = None):
    for name, text in (files or {}).items():
        (tmp_path / name).write_text(text)
    (tmp_path / "t.vf").write_text(HEAD + body)
    return vfdsl.load(tmp_path / "t.vf")


def fails(tmp_path, body: str, line: int, column: int, message: str, files=None) -> VfError:
    with pytest.raises(VfError) as info:
        load(tmp_path, body, files)
    err = info.value
    assert message in err.message, err.render()
    assert (err.line, err.column) == (line, column), err.render()
    return err


# ------------------------------------------------------------------------------------------- Range itself

def test_range_violation_and_description():
    open_interval = Range(0.0, math.pi / 2, low_open=True, high_open=True, unit="deg")
    assert open_interval.describe() == "(0, 90) deg"
    assert open_interval.violation(math.radians(45)) is None
    assert open_interval.violation(0.0) == "must be in (0, 90) deg"
    assert open_interval.violation(math.pi / 2) == "must be in (0, 90) deg"
    assert open_interval.violation(math.nan) == "must be finite"
    half_open = Range(0.0, 1.0, low_open=True)
    assert half_open.describe() == "(0, 1]"
    assert half_open.violation(1.0) is None and half_open.violation(1.0 + 1e-12) is not None
    assert Range(low=0.0, low_open=True).violation(0.0) == "must be > 0"
    assert Range(low=2.0).violation(2.0) is None
    assert Range(high=3.0, high_open=True).describe() == "< 3"
    assert Range().violation(-1e300) is None and Range().violation(math.inf) == "must be finite"


def test_every_scalar_argument_states_its_range():
    specs = list(CONSTRAINTS.values()) + list(OBJECTIVES.values())
    scalar = [(s.name, a) for s in specs for a in s.args if a.kind in SCALAR_DIMENSIONS or "gain" in a.kind]
    assert len(scalar) >= 7
    assert [(name, a.name) for name, a in scalar if a.range is None] == []
    for _, a in scalar:                                     # a spec's own default lies in its range
        if a.default not in (None, "subject") and not a.required:
            assert a.range.violation(a.default.value) is None


# ---------------------------------------------------------------------------------- primitive arguments

@pytest.mark.parametrize("body, column, message", [
    ("require joint_speed(fraction = -0.5)\n", 32, "'fraction' must be in (0, 1], got -0.5"),
    ("require joint_speed(fraction = 1.5)\n", 32, "'fraction' must be in (0, 1]"),
    ("require tip cone([0, 0, 1], 90 deg)\n", 29, "'angle' must be in (0, 90) deg, got 90 deg"),
    ("require tip cone([0, 0, 1], 0)\n", 29, "'angle' must be in (0, 90) deg"),
    ("require tip within_distance([0, 0, 0], -3)\n", 40, "'distance' must be in (0, 1e+06], got -3 mm"),
    ("require tip within_distance([0, 0, 0], 0 mm)\n", 40, "'distance' must be in (0, 1e+06]"),
    ("require tip speed(0)\n", 19, "'max' must be in (0, 1e+06], got 0 mm/s"),
    ("require tip angular_speed(-1 deg/s)\n", 27, "'max' must be in (0, 1e+06]"),
    ("minimize track(tip, f, gain = -1 mm/s/N)\n", 31, "'gain' must be in [1e-06, 1e+06]"),
    # beyond any robot (a unit slip): check refused them, but show, compile and simulate took them (a 1e308 mm
    # tolerance overflowed the generic hand's probe; a gain of 1e300 or 1e-300 passed everything)
    ("require tip speed(1e308)\n", 19, "'max' must be in (0, 1e+06], got 1e+308 mm/s"),
    ("require tip angular_speed(1e30)\n", 27, "'max' must be in (0, 1e+06], got 1e+30 deg/s"),
    ("require tip within_distance([0, 0, 0], 1e300)\n", 40, "'distance' must be in (0, 1e+06], got 1e+300 mm"),
    ("minimize track(tip, f, gain = 1e300)\n", 31, "'gain' must be in [1e-06, 1e+06], got 1e+297 (SI units)"),
    ("minimize track(tip, f, gain = 1e-300)\n", 31, "'gain' must be in [1e-06, 1e+06]"),
])
def test_argument_out_of_range(tmp_path, body, column, message):
    err = fails(tmp_path, body, 6, column, message)
    assert "allowed:" in err.hint


@pytest.mark.parametrize("body", [
    "require joint_speed(fraction = 1)\n",
    "require joint_speed(fraction = 0.01)\n",
    "require tip cone([0, 0, 1], 89.9 deg)\n",
    "require tip cone([0, 0, 1], 0.001)\n",
    "require tip within_distance([0, 0, 0], 1 um)\n",
    "require tip speed(1e-3)\n",
    "minimize track(tip, f, gain = 1e-3 mm/s/N)\n",
    "minimize track(tip, f, gain = 1e6 m/s/N)\n",
    "require tip within_distance([0, 0, 0], 1e6 m)\n",
    "require tip speed(1e6 m/s)\n",
])
def test_argument_near_miss_loads(tmp_path, body):
    load(tmp_path, body)


def test_param_default_out_of_range_points_at_the_value_and_names_the_use(tmp_path):
    err = fails(tmp_path, "param a : angle = 95\nrequire tip cone([0, 0, 1], a)\n", 6, 19,
                "param 'a' is used as cone(...) argument 'angle', which must be in (0, 90) deg; its value is 95 deg")
    assert err.notes == (f"used at {tmp_path / 't.vf'}:7:29",)
    assert "note: used at" in err.render()
    load(tmp_path, "param a : angle = 85\nrequire tip cone([0, 0, 1], a)\n")


def test_param_from_the_scene_is_checked_at_the_scene(tmp_path):
    body = 'param frac : number\nscene "s.yaml"\nrequire joint_speed(frac)\n'
    with pytest.raises(VfError) as info:
        load(tmp_path, body, {"s.yaml": "params:\n  frac: -0.5\n"})
    assert info.value.pos.file.endswith("s.yaml") and info.value.line == 2
    load(tmp_path, body, {"s.yaml": "params:\n  frac: 0.5\n"})


FIXTURE_LIB = """library lib
units mm, deg
fixture slow(fraction: number = 0.5) {
    require joint_speed(fraction = fraction)
}
fixture hold(f: frame, p: point, eps: length = 0.01) {
    require f stays_at(p) within eps
}
"""


def test_fixture_argument_out_of_range_points_at_the_use(tmp_path):
    err = fails(tmp_path, 'import "lib.vf"\nuse slow(-2)\n', 7, 10, "'fraction' must be in (0, 1]",
                {"lib.vf": FIXTURE_LIB})
    assert any(f"{tmp_path / 't.vf'}:7:1" in n for n in err.notes)
    load(tmp_path, 'import "lib.vf"\nuse slow(0.2)\nuse slow()\n', {"lib.vf": FIXTURE_LIB})


# ------------------------------------------------------------------------------------------------ clauses

def test_tolerance_below_the_solver_names_both_numbers_in_the_tasks_units(tmp_path):
    err = fails(tmp_path, "require tip stays_at([0, 0, 290]) within 1e-12\n", 6, 42, "below what the solver can honour")
    solver_mm = f"{FEASIBILITY_TOLERANCE * 1e3:g} mm"
    assert "1e-12 mm" in err.message and solver_mm in err.message
    assert f"{clause_ranges.TOLERANCE_MARGIN * FEASIBILITY_TOLERANCE * 1e3:g} mm" in err.hint
    low = clause_ranges.TOLERANCE_MARGIN * FEASIBILITY_TOLERANCE
    load(tmp_path, f"require tip stays_at([0, 0, 290]) within {low * 1e3 * 1.01!r}\n")


def test_tolerance_beyond_any_robot_is_refused_where_check_refused_it(tmp_path):
    """A length tolerance above limits.ROW_VALUE (the size `check` refused, as rows beyond what it analyses) is
    refused at load: `simulate` crashed on it (OverflowError in the generic hand's probe)."""
    for within, column in (("1e308", 42), ("1e307 mm", 42)):
        fails(tmp_path, f"require tip stays_at([0, 0, 290]) within {within}\n", 6, column,
              "is beyond any robot's size: the limit is 1e+09 mm (1e+06 m)")
    load(tmp_path, "require tip stays_at([0, 0, 290]) within 1e6 m\n")


def test_tolerance_from_a_fixture_formal_points_at_the_use(tmp_path):
    fails(tmp_path, 'import "lib.vf"\nuse hold(tip, [0, 0, 290], 1e-9 um)\n', 7, 28, "below what the solver",
          {"lib.vf": FIXTURE_LIB})


def test_angle_tolerance_below_ninety_degrees(tmp_path):
    fails(tmp_path, "require tip keeps_direction([0, 0, 1]) within 90 deg\n", 6, 47, "below 90 deg")
    load(tmp_path, "require tip keeps_direction([0, 0, 1]) within 89 deg\n")


@pytest.mark.parametrize("weight", ["1e308", "0", "1e10", "1e-10", "-1"])
def test_weight_out_of_range(tmp_path, weight):
    err = fails(tmp_path, f"minimize damping() weight {weight}\n", 6, 27, "a weight must be in [1e-09, 1e+09]")
    assert "plain number" in err.hint


@pytest.mark.parametrize("weight", ["1e9", "1e-9", "1000"])
def test_weight_near_miss(tmp_path, weight):
    task = load(tmp_path, f"minimize damping() weight {weight}\nrequire tip speed(5) soft weight {weight}\n")
    assert task.objectives[0].weight == float(weight) == task.constraints[0].weight


def test_weight_hint_says_plain_number(tmp_path):
    err = fails(tmp_path, "minimize damping() weight [1]\n", 6, 27, "expected a plain number")
    assert err.hint == "write a plain number, e.g. 10"


CHANNEL = Path(__file__).resolve().parent.parent / "tasks" / "anatomy" / "channel.stl"


@pytest.mark.parametrize("argument, column", [("margin = 1e300", 43), ("radius = 1e12 m", 57),
                                              ("reach = 1e300", 56)])
def test_mesh_sizes_beyond_any_robot_are_refused(tmp_path, argument, column):
    """A mesh fixture's margin, radius and reach had no upper bound (a unit slip loaded); they take the limit of
    every other size, limits.ROW_VALUE."""
    mesh = f'param channel : mesh(unit = 1 mm) = "{CHANNEL}"\n'
    if not argument.startswith("margin"):
        argument = "margin = 0.5, " + argument
    line = mesh + f"require tip inside_mesh(channel, {argument})\n"
    err = fails(tmp_path, line, 7, column, "must be in")
    assert "1e+06" in err.message
    load(tmp_path, mesh + "require tip inside_mesh(channel, margin = 0.5, radius = 1, reach = 2)\n")
