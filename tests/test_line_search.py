"""Phase 2's step goes only as far as it truly brings the fixtures back (vfdsl.runtime.line_search).

The rule is restated here in numpy on a one-joint fixture whose true error is known in closed form, and checked on
both paths; then on panda7, where without it a least-violation equilibrium the arm cannot reach made every joint
reverse at its speed limit each tick for as long as the task ran (131.20 / 130.54 mm from a sphere 1 m away), and a
conflict left a held port 1.18 mm off, unnamed, at full speed; and in an exported build, which answers as the
controller.
"""

from __future__ import annotations

import math
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import vfdsl
from vfdsl.codegen import build_library
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime import BufferedFunction, StepStatus, build_step_function
from vfdsl.runtime.line_search import FIRST_ORDER_AGREEMENT, LINE_SEARCH_TRIALS, SLOPE_STEP, SUFFICIENT_DECREASE

NO_CHECKS = ca.Function("admissible", [ca.SX.sym("p", 1)], [ca.SX(0, 1)])
SPEED, GOAL, RHO, FLOOR, TOL = 0.5, 1.5, 1.0, 1e-4, 1e-6
READY = [0, -45, 0, -135, 0, 90, 45]


def unreachable_qp_data() -> ca.Function:
    """One joint, the fixture sin(q) >= GOAL (never met: its least violation is at q = pi/2), linearized at q:
    p cos(q) dq >= GOAL - sin(q), |dq| <= SPEED; p = 1 is its derivative, p = 3 a linearization that promises three
    times the progress (as the paper's rotation rows far from their fixture)."""
    q, u, p, dt = ca.SX.sym("q"), ca.SX.sym("u"), ca.SX.sym("p"), ca.SX.sym("dt")
    return ca.Function("qp", [q, u, p, dt], [ca.SX(1), -u, p * ca.cos(q), GOAL - ca.sin(q), ca.inf, -SPEED, SPEED],
                       ["q", "u", "p", "dt"], ["H", "g", "A", "lba", "uba", "lbx", "ubx"])


def expected_length(q: float, dq: float, scale: float) -> float:
    """The rule (docs/runtime.md, Phase 2), from the fixture's true error t(q') = GOAL - sin(q') and its rows."""
    w = max(GOAL - math.sin(q), FLOOR)

    def measure(t):
        t = t if t > TOL else 0.0
        return RHO * t / w + t * t / 2

    def phi(a):
        return measure(GOAL - math.sin(q + a * dq))

    slope = (phi(SLOPE_STEP) - phi(0)) / SLOPE_STEP
    predicted = (measure(GOAL - math.sin(q) - scale * math.cos(q) * SLOPE_STEP * dq) - phi(0)) / SLOPE_STEP
    if slope > FIRST_ORDER_AGREEMENT * predicted:
        return 1.0
    for k in range(LINE_SEARCH_TRIALS):
        a = 0.5 ** k
        if phi(a) < phi(0) + SUFFICIENT_DECREASE * a * min(slope, 0.0):
            return a
    return 0.0


@pytest.fixture(scope="module")
def unreachable_paths(tmp_path_factory):
    qp_data = unreachable_qp_data()
    library = build_library(build_step_function(qp_data, "vf_test_search", native=True), "vf_test_search",
                            tmp_path_factory.mktemp("cache"), {}, NO_CHECKS)
    whole = BufferedFunction.interpreted(build_step_function(qp_data, "vf_test_whole", backtrack=False))
    return whole, (BufferedFunction.native(library.so_path, "vf_test_search"),
                   BufferedFunction.interpreted(build_step_function(qp_data, "vf_test_search")))


def test_the_step_length_is_the_rules_on_both_paths(unreachable_paths):
    """Far from pi/2 the whole step (a = 1); nearer, halved until the true error falls enough (1/2, 1/32); where
    every step overshoots the least violation, none (the joint holds still); with rows that promise three times the
    progress, the step whole wherever the true error falls less than 0.9 times as fast as they say at its start:
    each as the rule computed here."""
    whole, paths = unreachable_paths
    seen = {1.0: set(), 3.0: set()}
    for scale in seen:
        for q in (0.3, 1.0, 1.3, math.pi / 2 - 0.01, math.pi / 2 - 0.001, 2.0, 2.9):
            args = (np.array([q]), np.zeros(1), np.array([scale]), np.array([0.01]), 0.0)
            x_whole, status = (float(np.array(v).ravel()[0]) for v in whole(*args)[:2])
            if status == StepStatus.OPTIMAL:        # rows that promise three times: some states feasible to them
                assert scale == 3.0
                continue
            a = expected_length(q, x_whole, scale)
            seen[scale].add((q, a))
            for path in paths:
                x, status, violation = (np.array(v).copy() for v in path(*args))
                assert int(status[0]) == StepStatus.LEAST_VIOLATION
                assert float(x[0]) == pytest.approx(a * x_whole, abs=1e-12), (q, scale, a)
                assert violation[0] > 0      # named, even when it holds still
    assert {1.0, 0.5, 1 / 32, 0.0} <= {a for _, a in seen[1.0]} and len(seen[1.0]) == 7, seen
    assert {a for _, a in seen[3.0]} == {1.0} and len(seen[3.0]) >= 3, seen


def _panda_task(folder: Path, name: str, body: str):
    """A panda7 task at its ready pose (units m, rad; 10 ms)."""
    (folder / f"{name}.vf").write_text(f'task {name}\nunits m, rad\nrobot arm = urdf "panda7"\n'
                                       f'frame tip = arm.link("tool_tip")\n{body}')
    (folder / f"{name}.yaml").write_text(f"units: mm, deg\nperiod: 10 ms\nstart: {READY}\n")
    return vfdsl.load(folder / f"{name}.vf")


ROBOT = Robot.load("panda7")
P0, R0 = ROBOT.frame_pose(np.radians(READY), "tool_tip")
FAR = P0 + [0, -1.005, 0]           # a sphere of 5 mm 1 m from the tip, further than the arm reaches


def _far_sphere(folder: Path):
    c = ", ".join(repr(float(v)) for v in FAR)
    return _panda_task(folder, "far", f"param c : point = [{c}]\nrequire tip within_sphere(c, 0.005)\n")


def _distance(q) -> float:
    return float(np.linalg.norm(ROBOT.frame_pose(q, "tool_tip")[0] - FAR)) - 0.005


@pytest.mark.parametrize("backend", ["native", "interpreted"])
def test_an_unreachable_fixture_comes_as_near_as_it_can_and_holds_still(tmp_path, backend):
    """200 ticks of q += step(q): the true distance never grows, the arm comes nearer than where it alternated
    without the rule (130.54 mm), and then holds still (dq = 0), the fixture named every tick."""
    ctrl = vfdsl.compile(_far_sphere(tmp_path), backend=backend)
    q = np.array(ctrl.task.start, float)
    distances, moves = [_distance(q)], []
    for _ in range(200):
        dq = ctrl.step(q)
        assert ctrl.status == StepStatus.LEAST_VIOLATION
        assert [v.label.primitive for v in ctrl.violations()] == ["within_sphere"]
        q = q + dq
        distances.append(_distance(q))
        moves.append(float(np.abs(dq).max()))
    assert np.all(np.diff(distances) <= 1e-12), np.max(np.diff(distances))
    assert distances[-1] < 0.12, distances[-1]
    assert max(moves[-30:]) == 0.0, moves[-30:]


def _conflict(folder: Path):
    """A port 60 mm up the tool within 0.5 mm, the tool within 0.2 rad of its start, and a sphere 100 mm aside: the
    sphere cannot be reached while the two hold."""
    axis = R0[:, 2]
    up = axis if axis[2] > 0 else -axis
    fmt = lambda v: "[" + ", ".join(repr(float(x)) for x in v) + "]"   # noqa: E731
    return _panda_task(folder, "conflict", f"param port : point = {fmt(P0 + 0.06 * up)}\n"
                       f"param c : point = {fmt(P0 + [0.1, 0, 0])}\nparam ax : direction = {fmt(axis)}\n"
                       "input stick : twist\nminimize track(tip, stick, gain = 1, angular_gain = 1)\n"
                       "minimize damping() weight 1e-4\nrequire tip passes_through(port) within 0.0005 resolution 8\n"
                       "require tip tilt_at_most(ax, 0.2)\nrequire tip within_sphere(c, 0.005)\n"
                       "require joint_limits()\nrequire joint_speed()\n"), P0 + 0.06 * up, axis


@pytest.mark.parametrize("backend", ["native", "interpreted"])
def test_a_conflict_settles_with_the_held_fixtures_kept(tmp_path, backend):
    """300 ticks: the port comes back within its 0.5 mm after the first tick's second-order remainder (1.28 mm,
    docs/runtime.md) and stays, the tilt within 0.2 rad (by the true geometry, to the polygon's corner); the sphere
    is named (anything else only to rounding), and the arm comes to rest."""
    task, port, axis = _conflict(tmp_path)
    ctrl = vfdsl.compile(task, backend=backend)
    q = np.array(task.start, float)
    moves, ports = [], []
    for _ in range(300):
        dq = ctrl.step(q, {"stick": np.zeros(6)})
        q = q + dq
        moves.append(float(np.abs(dq).max()))
        p, R = ROBOT.frame_pose(q, "tool_tip")
        v = port - p
        ports.append(np.linalg.norm(v - (v @ R[:, 2]) * R[:, 2]))
        assert math.acos(min(1.0, R[:, 2] @ axis)) <= 0.2 + 1e-3
    assert max(ports) < 1.3e-3 and max(ports[20:]) <= 0.0005 / math.cos(math.pi / 8) + 1e-6, max(ports[20:])
    assert ctrl.status == StepStatus.LEAST_VIOLATION
    named = {v.label.primitive: v.amount for v in ctrl.violations()}
    assert named.pop("within_sphere") > 0.05 and all(amount < 1e-8 for amount in named.values()), named
    assert max(moves[-50:]) == 0.0, moves[-50:]


def test_an_exported_build_backtracks_as_the_controller(tmp_path):
    """The exported C library answers the far sphere's closed loop (whole, halved and held steps) as
    Controller.step(), to 1e-12."""
    from test_export import make

    from vfdsl.export import export
    from vfdsl.export.selftest import replay
    task = _far_sphere(tmp_path)
    export(task, tmp_path / "far")
    make(tmp_path / "far")
    ctrl = vfdsl.compile(task, backend="native")
    q = np.array(task.start, float)
    lines, expected = [], []
    for _ in range(200):
        lines.append(" ".join(f"{x:.17g}" for x in (*q, *ctrl.assembled.context.layout.defaults)))
        dq = ctrl.step(q)
        expected.append((int(ctrl.status), dq))
        q = q + dq
    answers = replay(tmp_path / "far", lines, task.scene.period)
    assert [status for status, _ in answers] == [status for status, _ in expected]
    assert max(float(np.max(np.abs(a[1] - e[1]))) for a, e in zip(answers, expected)) <= 1e-12
    sizes = [float(np.abs(dq).max()) for _, dq in expected]
    assert min(sizes) == 0 and any(0 < s < 0.6 * max(sizes) for s in sizes)    # held and shortened steps replayed
