"""Derived geometry (+ - *, cross, normalize, midpoint, line, plane over points, vectors and directions) and
frames from frames: the grammar, kinds and units with their errors, constant folding and run-time evaluation
against numpy, and composed frames against Pinocchio."""

from __future__ import annotations

import logging
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import vfdsl
from vfdsl import VfError
from vfdsl.check.hygiene import unused
from vfdsl.compiler.context import ParamReader
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot
from vfdsl.sim.geometry import Scene
from vfdsl.syntax.parser import grammar_path

HEAD = """task t
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
param a : point = [10, 0, 300]
param b : point = [10, 0, 250]
param v : vector = [0, 5, 0]
param n : direction = [0, 0, 2]
param depth : length = 20
"""
# Appended lines start at line 10.

TASKS = Path(__file__).resolve().parent.parent / "tasks"


def load(tmp_path, body: str) -> ir.Task:
    path = tmp_path / "t.vf"
    path.write_text(body if body.startswith("task") else HEAD + body)
    return vfdsl.load(path)


def fails(tmp_path, body: str, message: str, line: int, column: int, hint: str | None = None) -> VfError:
    with pytest.raises(VfError) as info:
        load(tmp_path, body)
    err = info.value
    assert message in err.message, err.render()
    assert (err.pos.line, err.pos.column) == (line, column), err.render()
    if hint is not None:
        assert hint in (err.hint or ""), err.render()
    return err


def arg(task: ir.Task, k: int, name: str) -> ir.Arg:
    return task.constraints[k].args[name]


def unit(v) -> np.ndarray:
    return np.asarray(v, dtype=float) / np.linalg.norm(v)


# ----------------------------------------------------------------------------------------------- grammar

def test_the_grammar_has_no_lalr_conflicts():
    from lark import Lark
    from lark import logger as lark_logger
    seen: list[str] = []
    handler = logging.Handler()
    handler.emit = lambda record: seen.append(record.getMessage())
    level = lark_logger.level
    lark_logger.addHandler(handler)
    lark_logger.setLevel(logging.DEBUG)
    try:
        Lark(grammar_path().read_text(), parser="lalr", lexer="contextual", debug=True)
    finally:
        lark_logger.removeHandler(handler)
        lark_logger.setLevel(level)
    assert not [m for m in seen if "conflict" in m.lower()], seen


def test_precedence_and_units_next_to_operators(tmp_path):
    """* binds tighter than + and -, which go left to right; '-' is unary too; a '*' inside a unit is written
    without spaces (N*mm), one with a space before it multiplies."""
    task = load(tmp_path, "require tip stays_at([1, 2, 3] mm + 2 * [0, 0, 5] mm - -[1, 0, 0] mm - ([0, 0, 50] mm - "
                          "[0, 0, 10] mm))\n"
                          "require tip stays_at([1, 1, 1] m * 2 * 1e-3)\n"
                          "require tip stays_at(a - - 10 mm * normalize(b - a))\n"
                          "param s : speed = 1 mm/s/N*N\n")
    assert np.allclose(arg(task, 0, "target").value.xyz, [0.002, 0.002, -0.027])
    assert np.allclose(arg(task, 1, "target").value.xyz, [0.002] * 3)
    assert isinstance(arg(task, 2, "target"), ir.Derived)
    assert task.param("s").value.value == pytest.approx(1e-3)
    with pytest.raises(VfError, match="unknown unit 'n'"):
        load(tmp_path, "require tip stays_at(a + 10 mm*n)\n")


def test_long_expressions_are_refused_cleanly(tmp_path):
    err = fails(tmp_path, "require tip stays_at(a" + " + v" * 5000 + ")\n", "nested too deeply", 10, 22)
    assert "operators" in err.hint


# ------------------------------------------------------------------------------------------ constant folding

def test_constant_expressions_fold_to_the_values_numpy_computes(tmp_path):
    task = load(tmp_path, """require tip keeps_direction(cross([1, 0, 0], [0, 1, 1]))
require tip along(line([0, 0, 0] mm, [3, 4, 0] mm))
require tip along(line([0, 0, 280], [1, 1, 0]))
require tip above(plane(midpoint([0, 0, 10] mm, [2, 0, 30] mm), -normalize([0, 0, -4])))
require tip stays_at([0, 0, 1] m + 5 cm * cross([1, 0, 0], [0, 1, 0]))
require tip within_distance([0, 0, 290], 2 * 3 mm - 1 mm)
""")
    assert np.allclose(arg(task, 0, "direction").value.xyz, unit(np.cross([1, 0, 0], [0, 1, 1])))
    assert arg(task, 1, "line").value == ir.LineValue(point=[0, 0, 0], direction=[0.6, 0.8, 0.0])
    legacy = arg(task, 2, "line").value                      # line(point, direction): a direction second
    assert np.allclose(legacy.point, [0, 0, 0.28]) and np.allclose(legacy.direction, unit([1, 1, 0]))
    plane = arg(task, 3, "plane").value
    assert np.allclose(plane.point, [0.001, 0, 0.02]) and np.allclose(plane.normal, [0, 0, 1])
    assert np.allclose(arg(task, 4, "target").value.xyz, [0, 0, 1.05])
    assert arg(task, 5, "distance").value.value == pytest.approx(0.005)


@pytest.mark.parametrize("body, message, line, column, hint", [
    ("require tip stays_at(a + b)\n", "adding two points has no meaning", 10, 22, "midpoint(a, b)"),
    ("require tip keeps_direction(b - a)\n", "expected a direction, got a vector of lengths", 10, 29, "normalize"),
    ("require tip stays_at(a + cross(v, v))\n", "a vector of lengths, got a vector of m^2", 10, 26, None),
    ("require tip stays_at(a + 10 * n)\n", "a vector of lengths, got a vector of plain numbers", 10, 26, "10 mm"),
    ("require tip keeps_direction(cross(v, v))\n", "expected a direction, got a vector of m^2", 10, 29, "normalize"),
    ("require tip keeps_direction(normalize([0, 0, 0]))\n", "this vector is zero", 10, 29, "distinct points"),
    ("require tip keeps_direction(cross([1, 0, 0], [2, 0, 0]))\n", "this vector is zero", 10, 29, None),
    ("require tip along(line([1, 2, 3] mm, [1, 2, 3] mm))\n", "the two points of this line coincide", 10, 19, None),
    ("require tip along(line(a, a))\n", "with the params' values, the two points of this line coincide", 10, 19,
     None),
    ("require tip keeps_direction(normalize(n - n))\n", "this vector is zero", 10, 29, None),
    ("require tip stays_at(midpoint(a, v))\n", "midpoint(a, b) needs two points, got a vector of lengths", 10, 34,
     None),
    ("require tip along(line(a, v))\n", "needs two points, or a point and a direction", 10, 27, "line(a, a + v)"),
    ("require tip stays_at(2 * a)\n", "scaling a point has no meaning", 10, 26, None),
    ("require tip stays_at(-a)\n", "negating a point has no meaning", 10, 22, None),
    ("require tip stays_at(v - a)\n", "subtracting a point from a vector", 10, 22, None),
    ("require tip stays_at(a + v * v)\n", "'*' multiplies a number and a vector", 10, 26, "cross(a, b)"),
    ("require tip keeps_direction(normalize(a))\n", "a point has no direction", 10, 39, "normalize(b - a)"),
    ("require tip stays_at(tip + v)\n", "'tip' is a frame; it cannot be used", 10, 22, None),
    ("require tip stays_at(aa + v)\n", "unknown name 'aa'", 10, 22, "'a'"),
    ("require tip stays_at(a + [1, 2] mm)\n", "needs 3 numbers", 10, 26, None),
    ("require tip stays_at(v)\n", "expected a point, but 'v' is a vector", 10, 22, None),
    ("require tip stays_at(v + v)\n", "expected a point, got a vector of lengths", 10, 22, "p + v"),
    ("require tip stays_at([0, 0, 290] + 2 * [0, 0, 5])\n", "expected a point, got a vector of plain numbers", 10,
     22, "[x, y, z] mm"),
    ("require tip within_distance(a, depth * 2)\n", "arithmetic on run-time scalars", 10, 32, None),
    ("require tip within_distance(a, 2 mm + 3 deg)\n", "cannot add an angle to a length", 10, 32, None),
    ("require tip stays_at(a + bspline(points = [[0, 0, 0]]))\n", "bspline(...) cannot be used", 10, 26, None),
    ("param p : point = a + v\n", "a name ('a') cannot stand here", 10, 19, None),
    ("param d : length = 5 + 3\n", "expected a length, got a plain number", 10, 20, "5 mm + 3 mm"),
    ("require tip stays_at(a) within 1 mm * 2\n", "expected a length, got an expression", 10, 32, None),
])
def test_kind_and_unit_mistakes_are_errors_at_the_expression(tmp_path, body, message, line, column, hint):
    fails(tmp_path, body, message, line, column, hint)


def test_scalar_params_and_constants_scale_vectors(tmp_path):
    task = load(tmp_path, "param x : length = 5 mm * 2 + 1 mm\nrequire tip stays_at(a + depth * n)\n")
    assert task.param("x").value.value == pytest.approx(0.011)
    target = arg(task, 0, "target")
    assert isinstance(target, ir.Derived) and target.op == "add" and target.operands[1].op == "scale"


# ----------------------------------------------------------------------------------------- run-time values

RUNTIME = HEAD + """param plate : pose = pose(translation = [20, 0, 250], rpy = [0, 30, 0])
param port : point in plate = [0, 0, 5]
require tip along(line(a, b))
require tip along(line(port, n))
require tip above(plane(midpoint(a, port), normalize(cross(b - a, v))))
require tip stays_at(port + depth * normalize(a - b) - v)
require tip keeps_direction(-normalize(b - port))
"""


def _numpy_values(values: dict[str, np.ndarray]) -> list:
    """The five arguments of RUNTIME computed with numpy (port placed by its pose with scipy)."""
    a, b, v, n, depth = (values[k] for k in ("a", "b", "v", "n", "depth"))
    R = Rotation.from_euler("xyz", values["plate"][3:]).as_matrix()
    port = R @ values["port"] + values["plate"][:3]
    return [(a, unit(b - a)), (port, unit(n)), ((a + port) / 2, unit(np.cross(b - a, v))),
            port + depth * unit(a - b) - v, -unit(b - port)]


def test_run_time_expressions_match_numpy(tmp_path):
    task = load(tmp_path, RUNTIME)
    assert all(isinstance(c.args[k], ir.Derived) for c, k in zip(task.constraints, ["line", "line", "plane",
                                                                                    "target", "direction"]))
    assert ir.Task.model_validate_json(task.model_dump_json()) == task
    rng = np.random.default_rng(3)
    for trial in range(5):
        values = {"a": rng.normal(size=3), "b": rng.normal(size=3), "v": rng.normal(size=3),
                  "n": unit(rng.normal(size=3)), "depth": rng.uniform(0.01, 0.1),
                  "plate": np.concatenate([rng.normal(size=3), rng.uniform(-1, 1, 3)]), "port": rng.normal(size=3)}
        p = np.concatenate([np.atleast_1d(values[d.name]) for d in task.params])
        reader = ParamReader(task.params, ca.DM(p))
        got = [tuple(np.array(x).ravel() for x in reader.derived(c.args[k]))
               if k in ("line", "plane") else np.array(reader.derived(c.args[k])).ravel()
               for c, k in zip(task.constraints, ["line", "line", "plane", "target", "direction"])]
        for mine, expected in zip(got, _numpy_values(values)):
            assert np.allclose(np.concatenate(mine) if isinstance(mine, tuple) else mine,
                               np.concatenate(expected) if isinstance(expected, tuple) else expected, atol=1e-12)


def test_the_simulators_scene_evaluates_derived_arguments(tmp_path):
    task = load(tmp_path, RUNTIME)
    scene = Scene(task)
    values = {d.name: np.array(ir_flat) for d, ir_flat in
              ((d, d.value.xyz if hasattr(d.value, "xyz") else
                ([*d.value.translation, *d.value.rpy] if d.name == "plate" else [d.value.value]))
               for d in task.params)}
    values["n"] = unit(values["n"])
    values["depth"] = values["depth"][0]
    expected = _numpy_values(values)
    point, direction = scene.line(task.constraints[0].args["line"])
    assert np.allclose(point, expected[0][0]) and np.allclose(direction, expected[0][1])
    point, normal = scene.plane(task.constraints[2].args["plane"])
    assert np.allclose(point, expected[2][0]) and np.allclose(normal, expected[2][1])
    assert np.allclose(scene.point(task.constraints[3].args["target"]), expected[3])


def test_params_used_only_inside_expressions_are_used(tmp_path):
    task = load(tmp_path, RUNTIME)
    assert [f.data["name"] for f in unused(task)] == []


def test_fixtures_take_and_build_derived_values(tmp_path):
    task = load(tmp_path, """fixture needle(f: frame, entry: point, target: point, eps: length = 0.5) {
    require f along(line(entry, target)) within eps
    require f above(plane(target, normalize(entry - target)))
}
use needle(tip, a, b + v)
""")
    line = task.constraints[0].args["line"]
    assert line.op == "line2" and line.operands[0] == ir.ParamRef(name="a") and line.operands[1].op == "add"


# ------------------------------------------------------------------------------------------ frames from frames

FRAMES = """task t
units mm, deg
robot shr = urdf "shr7"
frame holder = shr.link("tool_holder") offset [5, -3, 20] rotate [10, 20, 30]
frame a = holder offset [0, 10, 40] rotate [-30, 45, 60]
frame b = a offset 2 * [3.5, 0, 0] mm axis x
frame c = b rotate [0, 90, 0]
frame d = c
input f : force
minimize track(holder, f, gain = 1 mm/s/N)
"""


def test_frames_from_frames_match_pinocchio(tmp_path):
    """Each frame is its base's pose composed with its own offset and rotation (URDF rpy = scipy's extrinsic
    'xyz'); the tool axis is inherited as the same direction in space unless given."""
    task = load(tmp_path, FRAMES)
    ctrl = vfdsl.compile(task, backend="interpreted")
    robot = Robot.load("shr7")
    assert all(f.link == "tool_holder" for f in task.frames)
    local = {"holder": ([5, -3, 20], [10, 20, 30]), "a": ([0, 10, 40], [-30, 45, 60]), "b": ([7, 0, 0], [0, 0, 0]),
             "c": ([0, 0, 0], [0, 90, 0]), "d": ([0, 0, 0], [0, 0, 0])}
    rng = np.random.default_rng(7)
    for _ in range(5):
        q = rng.uniform(robot.lower, robot.upper)
        p, R = robot.frame_pose(q, "tool_holder")
        poses = ctrl.frames(q)
        for name, (offset, rpy) in local.items():
            p = p + R @ (np.array(offset) * 1e-3)
            R = R @ Rotation.from_euler("xyz", rpy, degrees=True).as_matrix()
            if name in ("holder", "b"):                              # z: the shr7's tool axis of tool_holder
                axis = R @ ([0.0, 0.0, 1.0] if name == "holder" else [1.0, 0.0, 0.0])
            got = poses[name]
            assert np.allclose(got.position, p, atol=1e-12)
            assert np.allclose(got.rotation, R, atol=1e-12)
            assert np.allclose(got.tool_axis, axis, atol=1e-12)


@pytest.mark.parametrize("text, message, line, column, hint", [
    ("frame s = s offset [0, 0, 1]", "frame 's' is defined from itself", 5, 11, "link"),
    ("frame s = later offset [0, 0, 1]\nframe later = shr.link(\"tool_tip\")",
     "frame 'later' is declared later (line 6)", 5, 11, "move frame 'later' above"),
    ("frame s = shr offset [0, 0, 1]", "'shr' is a robot, not a frame", 5, 11, 'shr.link("...")'),
    ("frame s = tip.link(\"tool_tip\")", "unknown robot 'tip'", 5, 11, "frame s = tip offset"),
    ("frame s = tpi offset [0, 0, 1]", "unknown frame 'tpi'", 5, 11, "'tip'"),
    ("input f : force\nframe s = f", "'f' is not a frame", 6, 11, None),
    ("frame s = tip offset [0, 0, 1] axis [0, 0, 0]", "a direction cannot be zero", 5, 37, None),
    ("frame s = tip offset [0, 0, 1] offset [0, 0, 2]", "the 'offset' clause is given twice", 5, 39, None),
    ("frame s = tip offset [0, 0, 1] m * 2 - [0, 0, 1] mm axis normalize([1, 0, 0] - [1, 0, 0])",
     "this vector is zero", 5, 58, None),
    ("frame s = tip offset 2 * [0, 0, 1]", "expected a vector, got a vector of plain numbers", 5, 22, "[x, y, z] mm"),
    ("frame s = tip offset [1e308, 0, 0] m\nframe s2 = s offset [1e308, 0, 0] m",
     "frame 's' is 1e+308 m from its link: the limit is 1000 m", 5, 22, None),
    ("frame s = tip offset [1.5, 0, 0] m\nframe s2 = s offset [1.5, 0, 0] m",
     "frame 's2' is 3 m from its link: beyond 1.86 m, 3 x robot 'shr''s reach", 6, 21, "millimetres given as metres?"),
    ("frame s = tip rotate [0, 0, 400]", "frame 's' rotates by [0, 0, 6.98132] rad: beyond a full turn", 5, 22,
     "degrees given as radians?"),
])
def test_frame_mistakes(tmp_path, text, message, line, column, hint):
    body = 'task t\nunits mm, deg\nrobot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\n' + text + "\n"
    err = fails(tmp_path, body, message, line, column, hint)
    assert err.pos.file.endswith("t.vf")


def test_composed_rotations_round_trip_through_rpy_also_at_gimbal_lock():
    """A composed frame is stored as rpy: rotation(rpy_of(R)) = R, to 1e-12 in general and to 1e-7 within
    1e-14..1e-2 rad of pitch +-90 deg (where roll and yaw share one axis)."""
    from vfdsl.compiler.geometry import rotation, rpy_of
    rng = np.random.default_rng(0)
    for k in range(500):
        R = Rotation.random(random_state=k).as_matrix()
        assert np.abs(rotation(rpy_of(R)) - R).max() < 1e-12
        near = [rng.uniform(-3, 3), rng.choice([-1, 1]) * (np.pi / 2 - 10 ** rng.uniform(-14, -2)), rng.uniform(-3, 3)]
        assert np.abs(rotation(rpy_of(rotation(near))) - rotation(near)).max() < 1e-7
    assert np.abs(rotation(rpy_of(rotation([0.3, np.pi / 2, 0.2]))) - rotation([0.3, np.pi / 2, 0.2])).max() < 1e-12


@pytest.mark.parametrize("body, message, column", [
    ("require tip stays_at([0, 0, 1] m + 1e300 m * [1e300, 0, 0] m)\n", "too large", 36),
    ("require tip keeps_direction(normalize([1e300, 1e300, 0] m - [-1e300, -1e300, 0] m))\n", "too large", 29),
    ("require tip keeps_direction(normalize(1e200 m * [1, 0, 0] mm))\n", "too large", 29),
    ("require tip keeps_direction(normalize([1e-200, 0, 0]))\n", "this vector is zero", 29),
    ("require tip within_distance(a, 1e300 m * 1e300)\n", "too large", 32),
])
def test_overflow_and_underflow_are_errors_not_nan(tmp_path, body, message, column):
    fails(tmp_path, body, message, 10, column)


@pytest.mark.parametrize("constraint, params, column", [
    ("above(plane(a, normalize(k * [1, 0, 0] m + k * [1, 0, 0] m)))", {"k": 1.7e308}, 28),   # points and vectors
    ("stays_at(a + k * [1, 0, 0] m + k * [1, 0, 0] m) within 1 mm", {"k": 1.7e308}, 22),     # are bounded: numbers
    #                                                                                          scaling them overflow
])
def test_run_time_overflow_is_refused(tmp_path, constraint, params, column):
    task = load(tmp_path, f"param k : number = 1\ninput f : force\nminimize track(tip, f, gain = 1 mm/s/N)\n"
                          f"require tip {constraint}\n")
    ctrl = vfdsl.compile(task, backend="interpreted")
    q = np.zeros(ctrl.nq)
    with pytest.raises(VfError, match="too large") as info:
        ctrl.step(q, {"f": [0, 0, 0]}, params=params, dt=0.01)
    assert (info.value.pos.line, info.value.pos.column) == (13, column)
    assert np.all(np.isfinite(ctrl.step(q, {"f": [0, 0, 0]}, params={"a": [0, 0, 0.2]}, dt=0.01)))


@pytest.mark.parametrize("backend", ["interpreted", "native"])
def test_a_vector_is_as_plausible_as_a_point(tmp_path, backend):
    """A displacement no longer than a point may lie away: `follows(c, shift = [0, 0, 1e9])` (mm: 1000 km) is
    refused at its statement, and a vector param given 100 km at run time is refused before anything moves, on both
    paths (both were accepted: the tool drove toward a curve 1000 km away, least violation every tick)."""
    curve = "param c : curve(degree = 1) = [[0, 0, 280], [10, 0, 280]]\ninput f : force\n" \
            "minimize track(tip, f, gain = 1 mm/s/N)\n"
    with pytest.raises(VfError, match=r"follows\(\.\.\.\) argument 'shift' is \[0, 0, 1e\+06\] m: beyond 1.86 m"):
        load(tmp_path, curve + "require tip follows(c, shift = [0, 0, 1e9]) within 0.1\n")
    ctrl = vfdsl.compile(load(tmp_path, curve + "require tip follows(c, shift = v) within 0.1\n"), backend=backend)
    q = np.zeros(ctrl.nq)
    with pytest.raises(VfError, match=r"param 'v' is \[0, 0, 100000\] m: beyond 1.86 m"):
        ctrl.step(q, {"f": [0, 0, 0]}, params={"v": [0, 0, 1e5]}, dt=0.01)
    assert np.all(np.isfinite(ctrl.step(q, {"f": [0, 0, 0]}, params={"v": [0, 0, 1e-3]}, dt=0.01)))


def test_lists_take_their_dimension_from_their_use(tmp_path):
    """Bare lists are lengths where a point or vector is wanted (also summed or negated), plain numbers when
    normalized; a constant, or a vector placed by a literal (literal + v, literal - v), stands where a point is
    expected."""
    task = load(tmp_path, """require tip stays_at([0, 0, 290] + [0, 0, 10] - -[1, 0, 0])
require tip keeps_direction(normalize([1, 0, 0] + [0, 1, 0]))
require tip stays_at([0, 0, 290] + v)
require tip stays_at([0, 0, 290] mm - v + 2 * v)
require tip along(line(a, [0, 0, 290] + v))
require tip follows([[0, 0, 0], [10, 0, 0], [20, 5, 0], [30, 0, 0]], shift = -[0, 0, 10])
""")
    assert arg(task, 0, "target").value == ir.PointValue(xyz=[0.001, 0.0, 0.3])
    assert np.allclose(arg(task, 1, "direction").value.xyz, unit([1, 1, 0]))
    assert [arg(task, k, "target").kind for k in (2, 3)] == ["point", "point"]
    assert arg(task, 4, "line").op == "line2"
    assert arg(task, 5, "shift").value == ir.VectorValue(xyz=[0.0, 0.0, -0.01])
    fails(tmp_path, "require tip stays_at(v + v)\n", "expected a point, got a vector of lengths", 10, 22)
    fails(tmp_path, "require tip stays_at(v - [0, 0, 290])\n", "expected a point, got a vector of lengths", 10, 22)


def test_a_negated_list_is_a_constant_point(tmp_path):
    task = load(tmp_path, "require tip stays_at(-[0, 0, -290])\n"
                          "require tip stays_at(midpoint(-[0, 0, -280], [10, 0, 300]))\n")
    assert arg(task, 0, "target").value == ir.PointValue(xyz=[0.0, 0.0, 0.29])
    assert arg(task, 1, "target").value.xyz == pytest.approx([0.005, 0.0, 0.29])


# ------------------------------------------------------------------------------------------------- fuzz

_LEAVES = ["a", "b", "v", "n", "depth", "tip", "[1, 2, 3]", "[0, 0, 0]", "[1, 0, 0] mm", "[1e300, 0, 0] m", "2",
           "3 mm", "0", "-1e-300", "1e308", "line(a, b)", "plane(a, n)", "10 deg", "true"]


def _expressions():
    from hypothesis import strategies as st
    leaves = st.sampled_from(_LEAVES)

    def extend(inner):
        return st.one_of(
            st.tuples(inner, st.sampled_from([" + ", " - ", " * "]), inner).map("".join),
            inner.map(lambda x: f"-({x})"),
            st.tuples(st.sampled_from(["cross", "midpoint", "line", "plane"]), inner, inner)
            .map(lambda t: f"{t[0]}({t[1]}, {t[2]})"),
            inner.map(lambda x: f"normalize({x})"),
            inner.map(lambda x: f"({x})"))
    return st.recursive(leaves, extend, max_leaves=6)


_USES = ["require tip stays_at({})", "require tip keeps_direction({})", "require tip along({})",
         "require tip above({})", "require tip within_distance(a, {})", "param x : point = {}",
         "frame s = tip offset {}", "require tip follows([[0, 0, 0], [10, 0, 0], [20, 5, 0], [30, 0, 0]], shift = {})"]


def test_any_expression_loads_or_is_a_clean_error(tmp_path):
    """Random expressions in every place a value stands: load succeeds (then every derived argument is finite
    at the params' values and the IR round-trips through JSON) or raises VfError inside the file."""
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    @settings(max_examples=300, derandomize=True, deadline=None, suppress_health_check=list(HealthCheck))
    @given(_expressions(), st.sampled_from(_USES))
    def run(expression, use):
        try:
            task = load(tmp_path, use.format(expression) + "\n")
        except VfError as err:
            assert err.pos is not None and err.pos.line == 10, err.render()
            err.render()
            return
        assert ir.Task.model_validate_json(task.model_dump_json()) == task
        p = np.concatenate([np.atleast_1d(flat) for flat in
                            (ParamReader(task.params).layout.defaults,)])
        reader = ParamReader(task.params, ca.DM(p))
        for c in task.constraints:
            for value in c.args.values():
                if isinstance(value, ir.Derived):
                    out = reader.derived(value)
                    flat = np.concatenate([np.array(x).ravel() for x in (out if isinstance(out, tuple) else (out,))])
                    assert np.all(np.isfinite(flat)), (expression, use)
    run()


def test_an_expression_error_in_a_fixture_names_the_use(tmp_path):
    err = fails(tmp_path, "fixture f(t: frame, p: point, q: point) {\n    require t along(line(p, q))\n}\n"
                          "use f(tip, a, a + 0 * v)\n", "the two points of this line coincide", 11, 21)
    assert any("in a fixture used at" in note and ":13:1" in note for note in err.notes), err.render()


@pytest.mark.parametrize("statement, column", [
    ("require tip stays_at([0, 0, 5000]) within 0.001", 22),                      # positional
    ("require tip within_sphere(radius = 0.01, center = [9000, 0, 0])", 51),      # keyword, after another
    ("use virtual_rcm(tip, [0, 0, 2900], [0, 0, 1], 0.2, eps_p = 0.001, eps_r = 0.001)", 22),   # at the use
])
def test_a_far_constant_is_reported_at_the_argument(tmp_path, statement, column):
    """A point beyond the plausible distance (millimetres read as metres) is reported where it is written, not at the
    statement's first column; one given to a fixture, at the use's argument."""
    (tmp_path / "far.vf").write_text(
        f'task far\nimport "{TASKS / "library" / "fixtures.vf"}"\nrobot shr = urdf "shr7"\n'
        f'frame tip = shr.link("tool_tip")\n{statement}\n')
    with pytest.raises(VfError, match="beyond 1.86 m") as info:
        vfdsl.load(tmp_path / "far.vf")
    assert (info.value.pos.line, info.value.pos.column) == (5, column), str(info.value)
