"""Units: every literal reaches the IR in SI (m, rad, s, N), whatever unit it was written in.

Expected values are worked out by hand here (1 mm = 1e-3 m, 1 deg = pi/180 rad, ...), not taken from
``vfdsl.units``, so a wrong factor in the front end's table fails these tests.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

import vfdsl
from vfdsl import VfError
from vfdsl.ir import model as ir

PI = math.pi

HEAD = 'task t\n{units}robot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\n'


def load(tmp_path: Path, body: str, units: str | None = None, files: dict[str, str] | None = None):
    text = HEAD.format(units=f"units {units}\n" if units else "") + body
    for name, content in (files or {}).items():
        (tmp_path / name).write_text(content)
    (tmp_path / "t.vf").write_text(text)
    return vfdsl.load(tmp_path / "t.vf")


def param_value(tmp_path: Path, kind: str, literal: str, units: str | None = None):
    task = load(tmp_path, f"param x : {kind} = {literal}\n", units)
    value = task.param("x").value
    return value.value if isinstance(value, ir.ScalarValue) else value


def gains(tmp_path: Path, input_type: str, args: str, units: str | None = None) -> dict[str, float]:
    task = load(tmp_path, f"input u : {input_type}\nminimize track(tip, u, {args})\n", units)
    track = task.objectives[0]
    return {k: a.value.value for k, a in track.args.items() if isinstance(a, ir.Const)}


def close(a, b):
    return a == pytest.approx(b, rel=1e-12, abs=1e-300)


# --------------------------------------------------------------------------------------- the unit table

@pytest.mark.parametrize("kind, literal, si", [
    ("length", "1.5 m", 1.5),                       # params stay within the plausible 1.86 m of shr7
    ("length", "5 cm", 5 * 0.01),
    ("length", "5 mm", 5 * 0.001),
    ("length", "5 um", 5 * 0.000001),
    ("length", "-2.5 mm", -0.0025),
    ("length", "1e3 um", 0.001),
    ("angle", "2 rad", 2.0),
    ("angle", "5 mrad", 0.005),
    ("angle", "90 deg", PI / 2),
    ("angle", "15 deg", 15 * PI / 180),
    ("time", "2 s", 2.0),
    ("time", "10 ms", 0.010),
    ("force", "3 N", 3.0),
    ("number", "0.25", 0.25),
])
@pytest.mark.parametrize("units", [None, "um, mrad, ms"])
def test_unit_table(tmp_path, kind, literal, si, units):
    """An explicit unit wins over the file's default units."""
    assert close(param_value(tmp_path, kind, literal, units), si)


@pytest.mark.parametrize("args, expected", [
    ("angular_gain = 1 rad/s/Nm", 1.0),
    ("angular_gain = 1 rad/s/Nmm", 1.0 / 0.001),                       # per N mm = per 1e-3 N m
    ("angular_gain = 20 deg/s/Nmm", 20 * (PI / 180) / 0.001),          # paper experiment B: 349.07 rad/s/Nm
    ("angular_gain = 20 deg/s/N/mm", 20 * (PI / 180) / 0.001),         # same, written with two divisions
    ("angular_gain = 5 mrad/ms/Nm", 5 * 0.001 / 0.001),
])
def test_torque_units_in_compound_gains(tmp_path, args, expected):
    assert close(gains(tmp_path, "torque", args)["angular_gain"], expected)


@pytest.mark.parametrize("args, expected", [
    ("gain = 1 mm/s/N", 0.001),
    ("gain = 2 mm/s/N", 0.002),
    ("gain = 2 m/s/N", 2.0),
    ("gain = 3 um/ms/N", 3 * 1e-6 / 1e-3),
    ("gain = 1 cm/s/N", 0.01),
])
def test_force_gain_units(tmp_path, args, expected):
    assert close(gains(tmp_path, "force", args)["gain"], expected)


def test_wrench_gains(tmp_path):
    g = gains(tmp_path, "wrench", "gain = 2 mm/s/N, angular_gain = 10 deg/s/Nm")
    assert close(g["gain"], 0.002) and close(g["angular_gain"], 10 * PI / 180)


def test_twist_gains_are_plain_numbers(tmp_path):
    g = gains(tmp_path, "twist", "gain = 0.5, angular_gain = 2", units="mm, deg")
    assert close(g["gain"], 0.5) and close(g["angular_gain"], 2.0)
    g = gains(tmp_path, "twist", "gain = 1")                       # angular_gain defaults to 1 for a twist
    assert close(g["angular_gain"], 1.0)


@pytest.mark.parametrize("kind, literal, si", [
    ("speed", "5 mm/s", 0.005),
    ("speed", "5 mm/ms", 5.0),
    ("speed", "5 m/s", 5.0),
    ("speed", "36 cm/s", 0.36),
    ("angular_speed", "30 deg/s", PI / 6),
    ("angular_speed", "5 mrad/ms", 5.0),
    ("angular_speed", "1 rad/s", 1.0),
])
def test_compound_speeds(tmp_path, kind, literal, si):
    assert close(param_value(tmp_path, kind, literal), si)


def test_operators_apply_left_to_right(tmp_path):
    """deg/s/N*mm is ((deg/s)/N)*mm, an angle times a length per time per force: not an angular gain."""
    with pytest.raises(VfError) as info:
        gains(tmp_path, "torque", "angular_gain = 1 deg/s/N*mm")
    assert "expected a quantity in rad/(m*s*N)" in info.value.message
    assert "'deg/s/N*mm' is a quantity in m*rad/(s*N)" in info.value.message


def test_a_speed_literal_where_a_length_is_expected(tmp_path):
    with pytest.raises(VfError) as info:
        load(tmp_path, "param p : point = [0, 0, 290]\nrequire tip stays_at(p) within 5 mm/s\n", "mm")
    assert info.value.message == "expected a length, but 'mm/s' is a speed"
    with pytest.raises(VfError) as info:
        load(tmp_path, "require tip speed(5 mm)\n", "mm")
    assert info.value.message == "expected a speed, but 'mm' is a length"
    assert info.value.hint == "write it like 5 mm/s"


def test_unit_names_are_case_sensitive(tmp_path):
    with pytest.raises(VfError) as info:
        param_value(tmp_path, "length", "5 MM")
    assert info.value.message == "unknown unit 'MM'"


# ----------------------------------------------------------------------------------------- default units

def test_bare_numbers_are_si_without_a_units_statement(tmp_path):
    assert close(param_value(tmp_path, "length", "0.5"), 0.5)
    assert close(param_value(tmp_path, "angle", "5"), 5.0)
    assert close(param_value(tmp_path, "speed", "5"), 5.0)


@pytest.mark.parametrize("units, kind, literal, si", [
    ("mm", "speed", "5", 0.005),                        # the brief's example: 5 -> 5 mm/s = 0.005 m/s
    ("mm", "length", "5", 0.005),
    ("mm", "angle", "0.5", 0.5),                        # no angle unit given: radians
    ("mm, deg", "angle", "90", PI / 2),
    ("deg, mm", "angle", "90", PI / 2),                 # order does not matter
    ("mm, deg", "angular_speed", "30", PI / 6),         # deg/s
    ("mm, ms", "speed", "5", 5.0),                      # mm/ms = m/s
    ("mm, ms", "time", "10", 0.010),
    ("um", "length", "5", 5e-6),
    ("cm, mrad", "angle", "5", 0.005),
    ("cm, mrad", "length", "5", 0.05),
    ("mm, deg, ms, N", "force", "2", 2.0),
    ("mm, deg", "number", "0.5", 0.5),                  # plain numbers never scale
])
def test_bare_number_takes_the_default_unit_of_its_expected_dimension(tmp_path, units, kind, literal, si):
    assert close(param_value(tmp_path, kind, literal, units), si)


def test_bare_numbers_in_statements(tmp_path):
    task = load(tmp_path, "input f : force\n"
                          "param p : point = [0, 0, 290]\n"
                          "param ax : direction = [0, 0, 2]\n"
                          "minimize track(tip, f, gain = 2)\n"
                          "minimize damping() weight 1e-6\n"
                          "require tip stays_at(p) within 0.5\n"
                          "require tip speed(5)\n"
                          "require tip angular_speed(30)\n"
                          "require tip cone(ax, 15) within 0.5\n"
                          "require joint_speed(fraction = 0.5)\n", "mm, deg")
    by_name = {c.primitive: c for c in task.constraints}
    assert close(task.param("p").value.xyz[2], 0.290)
    assert task.param("ax").value.xyz == [0.0, 0.0, 1.0]                        # normalized, never scaled
    assert close(task.objectives[0].args["gain"].value.value, 0.002)            # 2 mm/s/N
    assert close(task.objectives[1].weight, 1e-6)                               # weights are plain numbers
    assert close(by_name["stays_at"].tolerance, 0.0005)                         # 0.5 mm
    assert close(by_name["speed"].args["max"].value.value, 0.005)               # 5 mm/s
    assert close(by_name["angular_speed"].args["max"].value.value, PI / 6)      # 30 deg/s
    assert close(by_name["cone"].args["angle"].value.value, 15 * PI / 180)
    assert close(by_name["cone"].tolerance, 0.5 * PI / 180)                     # 0.5 deg
    assert close(by_name["joint_speed"].args["fraction"].value.value, 0.5)


def test_bare_angular_gain_uses_default_angle_and_length(tmp_path):
    # rad/s per N m: 20 (deg) / (1 N * 1 mm) = 20 * (pi/180) / 1e-3
    assert close(gains(tmp_path, "torque", "angular_gain = 20", "mm, deg")["angular_gain"], 20 * (PI / 180) / 1e-3)


def test_vector_units(tmp_path):
    assert param_value(tmp_path, "point", "[0, 0, 0.29] m", "mm").xyz == pytest.approx([0, 0, 0.29])
    assert param_value(tmp_path, "point", "[1 cm, 2 mm, 3]", "mm").xyz == pytest.approx([0.01, 0.002, 0.003])
    assert param_value(tmp_path, "point", "[1 cm, 2, 3] um", "mm").xyz == pytest.approx([0.01, 2e-6, 3e-6])
    assert param_value(tmp_path, "vector", "[0, 0, 100]", "mm").xyz == pytest.approx([0, 0, 0.1])


def test_composite_literals(tmp_path):
    pose = param_value(tmp_path, "pose", "pose(translation = [0, 0, 250], rpy = [4, -3, 20])", "mm, deg")
    assert pose.translation == pytest.approx([0, 0, 0.25])
    assert pose.rpy == pytest.approx([4 * PI / 180, -3 * PI / 180, 20 * PI / 180])
    plane = param_value(tmp_path, "plane", "plane(point = [0, 0, 27] cm, normal = [0, 0, 5])", "mm")
    assert plane.point == pytest.approx([0, 0, 0.27]) and plane.normal == pytest.approx([0, 0, 1])
    curve = param_value(tmp_path, "curve", "bspline(points = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0] cm])",
                        "mm")
    assert curve.degree == 3                                                     # the default degree
    assert curve.points[1] == pytest.approx([0.001, 0, 0])
    assert curve.points[3] == pytest.approx([0.03, 0, 0])


def test_frame_offset_and_rotate(tmp_path):
    task = load(tmp_path, 'frame shaft = shr.link("tool_tip") offset [0, 0, 100] rotate [0, 0, 90]\n', "mm, deg")
    assert task.frame("shaft").offset == pytest.approx([0, 0, 0.1])
    assert task.frame("shaft").rpy == pytest.approx([0, 0, PI / 2])


@pytest.mark.parametrize("units, message", [
    ("mm, cm", "two units for a length: 'mm' and 'cm'"),
    ("Nmm", "'Nmm' is not a base unit"),
    ("mm/s", "unexpected '/'"),
    ("inch", "unknown unit 'inch'"),
])
def test_bad_units_statements(tmp_path, units, message):
    with pytest.raises(VfError) as info:
        load(tmp_path, "", units)
    assert message in info.value.message


# --------------------------------------------------------------------------------------- scenes, fixtures

def test_scene_numbers_take_the_scene_units(tmp_path):
    scene = ("units: m, deg\nperiod: 10 ms\n"
             "start: {x: 0, y: 0, z: 0, rcm_a: 10, rcm_b: 0, roll: 0, insert: 0.02}\n"
             "params: {p: [0, 0, 0.29]}\n")
    task = load(tmp_path, 'param p : point\nscene "s.yaml"\n', "mm", files={"s.yaml": scene})
    assert task.param("p").value.xyz == pytest.approx([0, 0, 0.29])
    assert task.scene.period == pytest.approx(0.01)
    assert task.scene.start == pytest.approx([0, 0, 0, 10 * PI / 180, 0, 0, 0.02])   # angles, lengths by joint


def test_scene_without_units_uses_the_task_units(tmp_path):
    scene = "period: 10\nstart: [0, 0, 0, 10, 0, 0, 20]\nparams: {p: [0, 0, 290]}\n"
    task = load(tmp_path, 'param p : point\nscene "s.yaml"\n', "mm, deg, ms", files={"s.yaml": scene})
    assert task.param("p").value.xyz == pytest.approx([0, 0, 0.29])
    assert task.scene.period == pytest.approx(0.01)
    assert task.scene.start == pytest.approx([0, 0, 0, 10 * PI / 180, 0, 0, 0.02])


def test_scene_quantities_as_strings(tmp_path):
    scene = 'period: "40 ms"\nparams: {p: ["1 cm", 0, "0.29 m"]}\n'
    task = load(tmp_path, 'param p : point\nscene "s.yaml"\n', "mm", files={"s.yaml": scene})
    assert task.param("p").value.xyz == pytest.approx([0.01, 0, 0.29])
    assert task.scene.period == pytest.approx(0.04)


def test_fixture_literals_keep_the_units_of_their_file(tmp_path):
    """A library in metres used from a task in millimetres: body literals and formal defaults are read in
    metres, arguments at the `use` site in millimetres."""
    lib = ("library lib\nunits m\n"
           "fixture hold(f: frame, at: point, eps: length = 0.002) {\n"
           "    require f stays_at(at) within eps\n"
           "    require f speed(0.01)\n"
           "}\n")
    task = load(tmp_path, 'import "lib.vf"\nuse hold(tip, [0, 0, 290])\nuse hold(tip, [0, 0, 290], eps = 3)\n',
                "mm", files={"lib.vf": lib})
    stays = [c for c in task.constraints if c.primitive == "stays_at"]
    speeds = [c for c in task.constraints if c.primitive == "speed"]
    assert const_xyz(stays[0].args["target"]) == pytest.approx([0, 0, 0.29])   # use site: mm
    assert close(stays[0].tolerance, 0.002)                                   # default: library's m
    assert close(stays[1].tolerance, 0.003)                                   # argument: task's mm
    assert all(close(c.args["max"].value.value, 0.01) for c in speeds)        # body literal: m/s


def const_xyz(arg):
    assert isinstance(arg, ir.Const)
    return arg.value.xyz
