"""Run-time params: one column of checks, right by construction (vfdsl.compiler.admissible).

Property tests: sound values are accepted and give the dq of the same task with the values written as
constants; degenerate and implausible values are refused with VfError before anything moves; on both
backends, and the generated C's column equals the interpreted one.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import vfdsl
from vfdsl.compiler.admissible import Admissible
from vfdsl.errors import VfError
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime.qp import StepStatus

TASKS = Path(__file__).resolve().parent.parent / "tasks"
BACKENDS = ("native", "interpreted")

HEAD = """task generated
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
{params}minimize track(tip, f, gain = 2 mm/s/N)
minimize damping() weight 1e-6
{body}require joint_limits()
require joint_speed()
"""
START = [0.0, -0.004432266, -0.001035904, 0.4591947, 0.0, 0.0, 0.01]     # paper B's start: tip near (0, 0, 290) mm
PUSH = {"f": [0.3, -0.2, 0.1]}
DT = 0.01

# Each derived argument a user reaches for, with the params it reads and how to make it degenerate.
USES = {
    "line2": ("require tip along(line({a}, {b})) within 1 mm\n", "ab"),
    "midplane": ("require tip above(plane(midpoint({a}, {b}), normalize({b} - {a})))\n", "ab"),
    "cross": ("require tip keeps_direction(cross({u}, {v})) within 2 deg\n", "uv"),
    "tilt": ("require tip tilt_at_most(normalize({b} - {c}), 30 deg)\n", "bc"),
    "plane3": ("require tip above(plane({a}, normalize(cross({b} - {a}, {c} - {a}))))\n", "abc"),
    "middle": ("require tip stays_at(midpoint({a}, {c})) within 2 mm\n", "ac"),
}
POINTS, DIRECTIONS = "abc", "uv"
DEFAULTS = {"a": np.array([0.0, 0.0, 0.29]), "b": np.array([0.01, 0.0, 0.29]), "c": np.array([0.0, 0.01, 0.3]),
            "u": np.array([1.0, 0.0, 0.0]), "v": np.array([0.0, 1.0, 0.0])}


def _literal(name: str, value: np.ndarray) -> str:
    numbers = ", ".join(repr(float(x)) for x in (value * 1000 if name in POINTS else value))
    return f"[{numbers}]" + (" mm" if name in POINTS else "")


def _task(tmp_path: Path, uses: list[str], values: dict[str, np.ndarray] | None, tag: str) -> ir.Task:
    """The generated task; ``values`` given: every param written as a constant in the expressions."""
    names = sorted({n for use in uses for n in USES[use][1]})
    if values is None:
        params = "".join(f"param {n} : {'point' if n in POINTS else 'direction'} = {_literal(n, DEFAULTS[n])}\n"
                         for n in names)
        fill = {n: n for n in names}
    else:
        params, fill = "", {n: _literal(n, values[n]) for n in names}
    body = "".join(USES[use][0].format(**{n: fill.get(n, n) for n in "abcuv"}) for use in uses)
    path = tmp_path / f"{tag}.vf"
    path.write_text(HEAD.format(params=params, body=body))
    return vfdsl.load(path)


def _sound(rng) -> dict[str, np.ndarray]:
    """Random values far from every degeneracy: three points a few cm apart near the tip, two directions
    at least 30 deg apart."""
    while True:
        points = np.array([0.0, 0.0, 0.29]) + rng.uniform(-0.03, 0.03, (3, 3))
        u, v = (d / np.linalg.norm(d) for d in rng.normal(size=(2, 3)))
        sides = np.linalg.norm(np.diff(points[[0, 1, 2, 0]], axis=0), axis=1)
        area = np.linalg.norm(np.cross(points[1] - points[0], points[2] - points[0]))
        if sides.min() > 0.01 and area > 1e-4 and abs(u @ v) < np.cos(np.radians(30)):
            return {"a": points[0], "b": points[1], "c": points[2], "u": u * rng.uniform(0.5, 3), "v": v}


def _degenerate(use: str, values: dict[str, np.ndarray], rng) -> dict[str, np.ndarray]:
    bad = dict(values)
    if use in ("line2", "midplane"):
        bad["b"] = values["a"].copy()
    elif use == "tilt":
        bad["c"] = values["b"].copy()
    elif use == "cross":
        bad["v"] = values["u"] * rng.choice([-2.0, 0.5, 1.0])
    elif use == "plane3":
        bad["c"] = values["a"] + rng.uniform(-2, 3) * (values["b"] - values["a"])          # collinear
    return bad


def assert_same_tick(ctrl, constants, q, inputs, params, what: str) -> None:
    """The tick with ``params`` equals the tick of the task with them written as constants (on the same backend, or
    the constants interpreted: the two backends' agreement is tests/test_generated.py's and test_priorities.py's,
    to 1e-12): the QP's data to
    1e-10, and dq to 1e-10 where both solves are OPTIMAL. (Where the hard rows cannot all hold, the least-violation
    answer of a saturated, degenerate QP moves by up to ~1e-8 rad under 1e-16 changes of its data: 1e-7 there.)"""
    dq, expected = ctrl.step(q, inputs, params=params, dt=DT), constants.step(q, inputs, dt=DT)
    a, b = ctrl.problem(q, inputs, params, dt=DT), constants.problem(q, inputs, dt=DT)
    for name in ("P", "g", "A", "lb", "ub"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-10, atol=1e-10, err_msg=f"{what} {name}")
    optimal = ctrl.status == StepStatus.OPTIMAL and constants.status == StepStatus.OPTIMAL
    np.testing.assert_allclose(dq, expected, rtol=0, atol=1e-10 if optimal else 1e-7, err_msg=what)


def _compile(task: ir.Task, backend: str) -> vfdsl.Controller:
    return vfdsl.compile(task, backend=backend)


@pytest.mark.slow
def test_generated_tasks_accept_sound_values_as_constants_and_refuse_degenerate_ones(tmp_path):
    rng = np.random.default_rng(18)
    degenerate_uses = ("line2", "midplane", "cross", "tilt", "plane3")
    cases = [["middle", "cross"], ["midplane", "tilt", "line2"], ["plane3"], ["cross", "plane3", "middle", "tilt"]]
    cases += [list(rng.permutation(list(USES))[:k]) for k in (2, 4)]
    refused = accepted = 0
    for case_index, uses in enumerate(cases):
        task = _task(tmp_path, uses, None, f"p{case_index}")
        controllers = {backend: _compile(task, backend) for backend in BACKENDS}
        for trial in range(2):
            values = _sound(rng)
            given = {n: values[n] for n in (d.name for d in task.params)}
            # the values written as constants, interpreted (the generated code of constants is every example's)
            constants = _compile(_task(tmp_path, uses, values, f"c{case_index}_{trial}"), "interpreted")
            for backend, ctrl in controllers.items():
                assert_same_tick(ctrl, constants, START, PUSH, given, f"{uses} {backend}")
                accepted += 1
            for use in set(uses) & set(degenerate_uses):
                bad = {n: v for n, v in _degenerate(use, values, rng).items() if n in given}
                for backend, ctrl in controllers.items():
                    with pytest.raises(VfError, match="no direction") as info:
                        ctrl.step(START, PUSH, params=bad, dt=DT)
                    assert info.value.pos is not None and info.value.pos.line > 6, info.value.render()
                    refused += 1
    assert accepted >= 24 and refused >= 30


def _example_tasks(kinds=None) -> list[Path]:
    """The example tasks with run-time params (of ``kinds``, if given)."""
    out = []
    for path in sorted(TASKS.glob("*.vf")):
        task = vfdsl.load(path)
        slots = Admissible(task, Robot.load(task.robots[0].urdf).reach).layout.slots
        if any(slots[d.name].size and (kinds is None or d.type in kinds) for d in task.params):
            out.append(path)
    return out


# A run-time b-spline is interpolated with the parameters of its default points, so moved points are not the
# curve whose default they would be: tests/test_curve_runtime.py checks moved curves against scipy instead.
NOT_CURVES = ("point", "vector", "direction", "line", "plane", "pose", "length", "angle", "speed", "number")


def _perturbed(decl: ir.ParamDecl, rng) -> ir.Value:
    """A sound value near the param's own: points moved by up to 2 mm, directions turned by up to 3 deg,
    scalars scaled by up to 5 %, poses moved by 2 mm and 0.02 rad, curve points by 0.3 mm."""
    value = decl.value

    def turn(d):
        d = np.asarray(d) + rng.uniform(-0.05, 0.05, 3)
        return (d / np.linalg.norm(d)).tolist()
    if isinstance(value, ir.PointValue):
        return ir.PointValue(xyz=(np.asarray(value.xyz) + rng.uniform(-0.002, 0.002, 3)).tolist())
    if isinstance(value, ir.DirectionValue):
        return ir.DirectionValue(xyz=turn(value.xyz))
    if isinstance(value, ir.LineValue):
        return ir.LineValue(point=(np.asarray(value.point) + rng.uniform(-0.002, 0.002, 3)).tolist(),
                            direction=turn(value.direction))
    if isinstance(value, ir.PlaneValue):
        return ir.PlaneValue(point=(np.asarray(value.point) + rng.uniform(-0.002, 0.002, 3)).tolist(),
                             normal=turn(value.normal))
    if isinstance(value, ir.PoseValue):
        return ir.PoseValue(translation=(np.asarray(value.translation) + rng.uniform(-0.002, 0.002, 3)).tolist(),
                            rpy=(np.asarray(value.rpy) + rng.uniform(-0.02, 0.02, 3)).tolist())
    if isinstance(value, ir.ScalarValue):
        return ir.ScalarValue(dimension=value.dimension, value=value.value * rng.uniform(0.95, 1.05))
    if isinstance(value, ir.CurveValue):
        points = np.asarray(value.points) + rng.uniform(-3e-4, 3e-4, np.shape(value.points))
        return value.model_copy(update={"points": points.tolist()})
    raise AssertionError(f"no perturbation for {decl.type}")


def _with_values(task: ir.Task, values: dict[str, ir.Value]) -> ir.Task:
    """``task`` with the params in ``values`` written as constants where they are used (a param that is a
    frame of other params, or a curve, keeps its slot, with the value as its default)."""
    frames = {d.frame for d in task.params if d.frame}
    constant = {name for name, decl in ((d.name, d) for d in task.params)
                if name in values and name not in frames and decl.frame is None and decl.type != "curve"}

    def replace(arg):
        if isinstance(arg, ir.ParamRef) and arg.name in constant:
            return ir.Const(value=values[arg.name])
        if isinstance(arg, ir.Derived):
            return arg.model_copy(update={"operands": [replace(o) for o in arg.operands]})
        return arg

    def statements(items):
        return [s.model_copy(update={"args": {k: replace(a) for k, a in s.args.items()}}) for s in items]
    params = [d.model_copy(update={"value": values.get(d.name, d.value)}) for d in task.params]
    return task.model_copy(update={"params": params, "constraints": statements(task.constraints),
                                   "objectives": statements(task.objectives)})


def _si(value: ir.Value):
    """An IR value as the numbers ``step(params=...)`` takes."""
    if isinstance(value, (ir.PointValue, ir.DirectionValue, ir.VectorValue)):
        return np.array(value.xyz)
    if isinstance(value, ir.LineValue):
        return np.array([*value.point, *value.direction])
    if isinstance(value, ir.PlaneValue):
        return np.array([*value.point, *value.normal])
    if isinstance(value, ir.PoseValue):
        return np.array([*value.translation, *value.rpy])
    if isinstance(value, ir.ScalarValue):
        return value.value
    return np.array(value.points)


def _inputs(task: ir.Task) -> dict:
    rng = np.random.default_rng(7)
    return {d.name: rng.uniform(-0.5, 0.5, d.size) for d in task.inputs}


@pytest.mark.slow
@pytest.mark.parametrize("path", _example_tasks(NOT_CURVES), ids=lambda p: p.stem)
def test_example_tasks_accept_sound_values_as_constants(path):
    task = vfdsl.load(path)
    rng = np.random.default_rng(len(path.stem))
    slots = Admissible(task, 1.0).layout.slots
    runtime = [d for d in task.params if slots[d.name].size and d.type in NOT_CURVES]
    controllers = {backend: _compile(task, backend) for backend in BACKENDS}
    inputs = _inputs(task)
    for _ in range(2):
        values = {d.name: _perturbed(d, rng) for d in runtime}
        constants = _compile(_with_values(task, values), "interpreted")
        given = {name: _si(value) for name, value in values.items()}
        for backend, ctrl in controllers.items():
            assert_same_tick(ctrl, constants, task.start, inputs, given, f"{path.stem} {backend}")


# --------------------------------------------------------------------------- the repros of the defect
REPRO = """task repro
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
param entry : point = [0, 0, 300]
param target : point = [0, 0, 250]
param a : direction = [1, 0, 0]
param b : direction = [0, 1, 0]
minimize track(tip, f, gain = 2 mm/s/N)
require tip stays_at(midpoint(entry, target)) within 30 mm
require tip keeps_direction(cross(a, b)) within 2 deg
require joint_limits()
require joint_speed()
"""


@pytest.fixture(scope="module", params=BACKENDS)
def repro(request, tmp_path_factory):
    path = tmp_path_factory.mktemp("repro") / "repro.vf"
    path.write_text(REPRO)
    return vfdsl.compile(vfdsl.load(path), backend=request.param)


def test_a_zero_cross_product_after_a_midpoint_is_refused(repro):
    """The check column of a task whose first derived argument is a midpoint was read at the wrong entries:
    a parallel to b passed and the keeps_direction rows vanished."""
    for b in ([1, 0, 0], [-2, 0, 0], [1, 1e-13, 0]):
        with pytest.raises(VfError, match="it has no direction") as info:
            repro.step(START, PUSH, params={"a": [1, 0, 0], "b": b}, dt=DT)
        assert (info.value.pos.line, info.value.pos.column) == (12, 29)
    dq = repro.step(START, PUSH, params={"a": [1, 0, 0], "b": [0, 0.01, 1]}, dt=DT)     # 90 deg apart: fine
    assert np.all(np.isfinite(dq))


def test_the_generated_column_equals_the_interpreted_one(tmp_path):
    path = tmp_path / "repro.vf"
    path.write_text(REPRO)
    task = vfdsl.load(path)
    native = vfdsl.compile(task, backend="native")
    admissible = native._values.admissible
    rng = np.random.default_rng(3)
    for _ in range(50):
        p = np.concatenate([rng.normal(0, 0.2, 6), rng.normal(size=6)])
        np.testing.assert_allclose(native._runner.margins(p), np.asarray(admissible.function(p)).ravel(),
                                   rtol=1e-14, atol=1e-15)
    assert len(admissible.margins) == 7      # 2 points, 2 directions, midpoint's value, cross's length and value


TILT = """task tilt
units mm, deg
robot stage = urdf "panda7"
frame tip = stage.link("tool_tip")
input f : force
param apex : point = [0, 0, 280]
param entry : point = [0, 0, 300]
param b : point = [0, 0, 400]
param c : point = [0, 0, 300]
param u : direction = [1, 0, 0]
param v : direction = [0, 1, 0]
param ball : point = [300, 0, 400]
param r : length = 20 mm
param d : point = [10, 0, 280]
param e : point = [0, 10, 280]
minimize track(tip, f, gain = 2 mm/s/N)
require tip above(plane(apex, normalize(entry - apex)))
require tip above(plane(apex, normalize(cross(d - apex, e - apex))))
require tip outside_sphere(ball, r)
require tip tilt_at_most(normalize(b - c), 60 deg)
require tip tilt_at_most(cross(u, v), 60 deg)
require joint_limits()
require joint_speed()
"""


@pytest.fixture(scope="module", params=BACKENDS)
def tilt(request, tmp_path_factory):
    path = tmp_path_factory.mktemp("tilt") / "tilt.vf"
    path.write_text(TILT)
    task = vfdsl.load(path)               # its own defaults (entry above apex, collinear with b) load fine
    return task, vfdsl.compile(task, backend=request.param)


def test_sound_values_with_several_derived_arguments_are_accepted(tilt):
    task, ctrl = tilt
    defaults = {d.name: _si(d.value) for d in task.params}
    ctrl.step(task.start if task.start is not None else np.zeros(7), PUSH, params=defaults, dt=DT)
    q = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
    ctrl.step(q, PUSH, params={"u": defaults["u"]}, dt=DT)           # its own default given back
    ctrl.step(q, PUSH, params={"d": [0.05, 0, 0.28], "apex": [0, 0, 0.28], "e": [0, 0.05, 0.28]}, dt=DT)   # right triangle
    ctrl.step(q, PUSH, params={"entry": [-0.001, 0, 0.3]}, dt=DT)    # a negative coordinate is no length
    ctrl.step(q, PUSH, params={"entry": [1e-10, 0, 0.3]}, dt=DT)


def test_a_point_moved_onto_another_is_refused_before_anything_moves(tilt):
    task, ctrl = tilt
    q = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
    with pytest.raises(VfError, match="this vector is zero") as info:
        ctrl.step(q, PUSH, params={"b": [0, 0, 0.3]}, dt=DT)
    assert info.value.pos.line == 20
    with pytest.raises(VfError, match="it has no direction"):
        ctrl.step(q, PUSH, params={"u": [0, 1, 0]}, dt=DT)


@pytest.mark.parametrize("params, message", [
    ({"entry": [10, 5, 285]}, r"param 'entry' is \[10, 5, 285\] m: beyond 4.27 m"),
    ({"ball": [0.3, 0, 400]}, r"param 'ball' is \[0.3, 0, 400\] m: beyond"),
    ({"r": 20}, r"param 'r' = 20 m: beyond 4.27 m"),
    ({"u": [0, 0, 0]}, r"param 'u' is a zero direction"),
    ({"r": -0.001}, r"param 'r' = -0.001 \(SI\) must be in \(0, 1e\+06\]"),
])
def test_implausible_values_name_the_param_and_the_unit_slip(tilt, params, message):
    task, ctrl = tilt
    with pytest.raises(VfError, match=message) as info:
        ctrl.step(np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8]), PUSH, params=params, dt=DT)
    if "m: beyond" in message:
        assert "millimetres given as metres" in info.value.hint


def test_angles_beyond_a_turn_are_refused(tmp_path):
    path = tmp_path / "cone.vf"
    path.write_text(REPRO.replace("require tip keeps_direction(cross(a, b)) within 2 deg\n", "")
                    .replace("param a : direction = [1, 0, 0]\n", "param plate : pose = pose(translation = [0, 0, 0], "
                             "rpy = [0, 0, 0])\nparam p : point in plate = [0, 0, 290]\n"))
    task = vfdsl.load(path)
    for backend in BACKENDS:
        ctrl = vfdsl.compile(task, backend=backend)
        with pytest.raises(VfError, match=r"param 'plate''s rpy \[0, 0, 90\] rad: beyond a full turn") as info:
            ctrl.step(START, PUSH, params={"plate": [0, 0, 0, 0, 0, 90]}, dt=DT)
        assert "degrees given as radians" in info.value.hint
        ctrl.step(START, PUSH, params={"plate": [0, 0, 0, 0, 0, np.pi / 2]}, dt=DT)


# ----------------------------------------------------------------------- the same rules at load time
def test_scene_values_get_the_run_time_checks_at_their_line(tasks_copy):
    scene = tasks_copy / "needle_insertion.yaml"
    text = scene.read_text()
    scene.write_text(text.replace("entry: [10, 5, 285]", "entry: [10 m, 5 m, 285 m]"))     # mm values as metres
    with pytest.raises(VfError, match=r"param 'entry' is \[10, 5, 285\] m: beyond 1.86 m") as info:
        vfdsl.load(tasks_copy / "needle_insertion.vf")
    line = next(i for i, row in enumerate(text.splitlines(), 1) if row.strip().startswith("entry:"))
    assert info.value.pos.file.endswith("needle_insertion.yaml") and info.value.pos.line == line
    assert any("needle_insertion.vf:15:1" in note for note in info.value.notes)
    scene.write_text(text.replace("target: [20, -5, 235]", "target: [10, 5, 285]"))
    with pytest.raises(VfError, match="the two points of this line coincide"):
        vfdsl.load(tasks_copy / "needle_insertion.vf")


def test_task_defaults_get_the_run_time_checks(tmp_path):
    path = tmp_path / "t.vf"
    path.write_text(REPRO.replace("param entry : point = [0, 0, 300]", "param entry : point = [0, 0, 300] m"))
    with pytest.raises(VfError, match=r"param 'entry' is \[0, 0, 300\] m: beyond") as info:
        vfdsl.load(path)
    assert info.value.pos.line == 6



@pytest.mark.parametrize("body, line, message", [
    ("require tip stays_at([0, 0, 290] m)\n", 8, r"stays_at\(...\) argument 'target' is \[0, 0, 290\] m: beyond"),
    ("require tip above(plane([0, 0, 270] m, [0, 0, 1]))\n", 8, r"above\(...\) argument 'plane''s point is"),
    ("require tip follows([[0, 0, 2.8], [0.01, 0, 2.8], [0.02, 0, 2.8], [0.03, 0, 2.8]] m)\n", 8,
     r"follows\(...\) argument 'curve''s point 1 is \[0, 0, 2.8\] m"),
])
def test_constant_points_get_the_plausible_distance_a_params_point_gets(tmp_path, body, line, message):
    # A point in mm read as m, written in the statement: it loaded, and the tool ran at full speed toward it.
    path = tmp_path / "t.vf"
    path.write_text(HEAD.format(params="", body=body))
    with pytest.raises(VfError, match=message) as info:
        vfdsl.load(path)
    assert (info.value.pos.line, info.value.code) == (line, "E402")
    path.write_text(HEAD.format(params="", body=body.replace("290] m", "290] mm").replace("270] m", "270] mm")
                                .replace("2.8]", "0.29]")))
    vfdsl.load(path)


# -------------------------------------------------------------------------------- fast path with params
def test_preallocated_arrays_take_the_fast_path_and_lists_the_checked_one(tmp_path):
    path = tmp_path / "repro.vf"
    path.write_text(REPRO)
    ctrl = vfdsl.compile(vfdsl.load(path), backend="native")
    fast = ctrl._runner.fast_step
    arrays = {"entry": np.array([0.0, 0.0, 0.3]), "a": np.array([1.0, 0, 0])}
    u = {"f": np.array(PUSH["f"])}
    dq = fast(START, u, arrays, DT)
    assert dq is not NotImplemented
    np.testing.assert_array_equal(dq, ctrl.step(START, PUSH, params={"entry": [0.0, 0.0, 0.3], "a": (1, 0, 0)}, dt=DT))
    handed = []
    ctrl._runner.stepper.checked = lambda stepper, *args: handed.append(args) or "checked"
    refusals = ({"a": np.zeros(3)}, {"entry": np.array([0, 0, 3.0])}, {"nope": np.zeros(3)},
                {"a": np.array([1.0, np.nan, 0])}, {"a": [[1.0, 0, 0]]})
    for refused in refusals:
        assert fast(START, u, refused, DT) == "checked"              # left to the checks that explain
    assert [args[2] for args in handed] == list(refusals)
    ctrl._runner.stepper.checked = None
    assert fast(START, u, refusals[0], DT) is NotImplemented


def test_each_check_reads_the_entry_it_was_written_for():
    """On every example task, zeroing one param's direction (or moving a derived argument's two points together)
    makes the first failing check the one written for it: writer and reader agree on the layout."""
    for path in _example_tasks():
        task = vfdsl.load(path)
        admissible = Admissible(task, Robot.load(task.robots[0].urdf).reach)
        defaults = admissible.layout.defaults
        assert admissible.margins.first_failure(admissible.function(defaults)) == -1, path
        for decl in task.params:
            slot = admissible.layout.slots[decl.name]
            if decl.type in ("direction", "line", "plane") and slot.size:
                p = defaults.copy()
                at = slot.offset + (0 if decl.type == "direction" else 3)
                p[at:at + 3] = 0
                i = admissible.margins.first_failure(admissible.function(p))
                assert admissible.margins.checks[i].param == decl.name, (path, decl.name)
                assert "zero direction" in admissible.margins.error(i, admissible.function(p), p).message
    needle = vfdsl.load(TASKS / "needle_insertion.vf")
    admissible = Admissible(needle, Robot.load("shr7").reach)
    p = admissible.layout.defaults.copy()
    p[0:3] = p[3:6]                                       # entry onto target
    with pytest.raises(VfError, match="the two points of this line coincide") as info:
        admissible.verify(p)
    assert (info.value.pos.line, info.value.pos.column) == (20, 22)


def test_the_checks_are_documented():
    doc = (TASKS.parent / "docs" / "runtime.md").read_text()
    for words in ("vfdsl.compiler.admissible", "MIN_DIRECTION_NORM", "plausible", "CHORD_RATIO", "full turn",
                  "preallocated"):
        assert words in doc, words


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_needle_task_takes_sound_registrations_and_refuses_unit_slips(backend):
    """tasks/needle_insertion.vf: an entry point at x = -1 mm or within 1e-9 m of x = 0 was refused as a zero
    vector (a coordinate read as a length); millimetres given as metres passed."""
    task = vfdsl.load(TASKS / "needle_insertion.vf")
    ctrl = vfdsl.compile(task, backend=backend)
    hand = {"hand": [0.0, 0.0, 0.0]}
    target = [0.020, -0.005, 0.235]
    for x in (-0.001, 1e-10, 0.0, 0.010):
        dq = ctrl.step(task.start, hand, params={"entry": [x, 0.005, 0.285], "target": target})
        assert np.all(np.isfinite(dq))
    with pytest.raises(VfError, match=r"param 'entry' is \[10, 5, 285\] m: beyond 1.86 m") as info:
        ctrl.step(task.start, hand, params={"entry": [10, 5, 285], "target": [20, -5, 235]})
    assert "millimetres given as metres" in info.value.hint


def test_a_degenerate_value_inside_a_fixture_names_its_use_site(tmp_path):
    (tmp_path / "lib.vf").write_text("library lib\nunits mm\n"
                                     "fixture guide(f: frame, a: point, b: point) {\n"
                                     "    require f along(line(a, b)) within 1 mm\n}\n")
    (tmp_path / "t.vf").write_text(REPRO.replace("units mm, deg\n", 'units mm, deg\nimport "lib.vf"\n')
                                   .replace("require tip keeps_direction(cross(a, b)) within 2 deg\n",
                                            "use guide(tip, entry, target)\n"))
    for backend in BACKENDS:
        ctrl = vfdsl.compile(vfdsl.load(tmp_path / "t.vf"), backend=backend)
        with pytest.raises(VfError, match="the two points of this line coincide") as info:
            ctrl.step(START, PUSH, params={"entry": [0, 0, 0.25]}, dt=DT)
        assert info.value.pos.file.endswith("lib.vf") and info.value.pos.line == 4
        assert any(note.startswith("in a fixture used at") and "t.vf:13" in note for note in info.value.notes)


PHASED = """task phased
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
input go : button
param a : point = [0, 0, 290] mm
param b : point = [10, 0, 290] mm
param c : point = [0, 10, 290] mm
param u : direction = [1, 0, 0]
param v : direction = [0, 1, 0]
param r : length = 5 mm
monitor pressed = go
monitor leaning = angle(tip, normalize(c - a)) < 10 deg
minimize damping() weight 1e-6
require joint_limits()
require joint_speed()
phase free initial {
    minimize track(tip, f, gain = 2 mm/s/N)
}
phase guarded {
    capture held = tip.position
    minimize track(tip, f, gain = 2 mm/s/N)
    require tip along(line(a, b)) within 1 mm
    require tip keeps_direction(cross(u, v)) within 2 deg
    require tip outside_sphere(b, r)
    require tip stays_at(held) within 5 mm
}
transition free -> guarded when pressed
transition guarded -> free when leaning
"""


@pytest.fixture(scope="module", params=BACKENDS)
def phased(request, tmp_path_factory):
    path = tmp_path_factory.mktemp("phased") / "phased.vf"
    path.write_text(PHASED)
    return vfdsl.compile(vfdsl.load(path), backend=request.param)


@pytest.mark.parametrize("params, message", [
    ({"a": [0.01, 0.0, 0.29]}, "the two points of this line coincide"),
    ({"u": [0.0, 1.0, 0.0]}, r"with params .u., this vector is zero"),
    ({"r": -0.005}, r"param 'r' = -0.005 \(SI\) must be in \(0, 1e\+06\]"),
    ({"r": 0.0}, r"param 'r' = 0 \(SI\) must be in \(0, 1e\+06\]"),
    ({"c": [0.0, 0.0, 0.29]}, "this vector is zero"),
])
def test_the_params_of_every_phase_and_monitor_are_checked_whichever_phase_is_active(phased, params, message):
    """A degenerate value fed to a phase's fixture or to a monitor is refused as it is without phases, in the phase
    that uses it and in the others alike (before: accepted, the fixture off when its phase came, and the monitor's
    angle to a zero direction 0, so true); nothing the user reads changes."""
    for go in (0.0, 1.0, 0.0):          # free, then guarded (go pressed), then guarded
        ctrl = phased
        dq = ctrl.step(START, {"f": [0.0, 0.0, 0.0], "go": [go]}, dt=DT)
        assert np.all(np.isfinite(dq))
        phase, captures, lb = ctrl.phase, ctrl.captures, ctrl.problem(START, {"f": [0, 0, 0], "go": [go]}, dt=DT).lb
        with pytest.raises(VfError, match=message) as info:
            ctrl.step(START, {"f": [0.0, 0.0, 0.0], "go": [go]}, params=params, dt=DT)
        if "c" in params:
            assert any("in monitor 'leaning'" in note for note in info.value.notes)
        assert ctrl.phase == phase
        assert all(np.array_equal(captures[k], ctrl.captures[k]) for k in captures)
        np.testing.assert_array_equal(ctrl.problem(START, {"f": [0, 0, 0], "go": [go]}, dt=DT).lb, lb)
    assert ctrl.phase == "guarded"
    ctrl.reset()


def test_a_derived_argument_that_reads_a_capture_is_not_checked_as_a_params_one(tmp_path):
    """`normalize(held - a)` has no value before its phase captures `held`: it is not in the params' column, which
    every tick checks (else every tick before the capture would be refused); the task steps in its first phase."""
    columns = []
    captured = "    require tip keeps_direction(normalize(held - a)) within 80 deg\n"
    for k, text in enumerate((PHASED, PHASED.replace("    require tip stays_at(held) within 5 mm\n", captured))):
        path = tmp_path / f"t{k}.vf"
        path.write_text(text)
        task = vfdsl.load(path)
        columns.append(Admissible(task, Robot.load(task.robots[0].urdf).reach).margins.symbolic().numel())
    assert columns[0] == columns[1]
    ctrl = vfdsl.compile(task, backend="interpreted")
    assert np.all(np.isfinite(ctrl.step(START, {"f": [0.3, 0.0, 0.0], "go": [0.0]}, dt=DT)))
