"""within_sphere, outside_sphere and near_plane against independent computations.

- rows against the formulas of docs/primitives.md, with Pinocchio's pose and Jacobian (``FrameState``), at
  random configurations of both robots and random run-time params;
- rows as the first-order Taylor expansion of the true, nonlinear functions || p(q) - c || and
  d . (p(q) - P) (central differences of Pinocchio's forward kinematics);
- brute force: on shr7 the stage joints translate the tool exactly (p(q + dq) = p(q) + dq), so the rows'
  verdict on a move can be compared with the true ball and band at the moved pose, for thousands of moves;
- the degenerate center (p == c): finite rows on the tool axis, and a tip started at the center of a
  keep-out ball leaves it along the tool axis;
- bad arguments in the file and at run time, ``vfdsl check`` (bounds table, residuals with their true
  distances) and the simulator's metrics;
- closed loop on the 7-DOF arm (nonlinear kinematics): how far past the boundary a hand pushing outward and
  around gets the tip, measured with Pinocchio.
"""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest
from test_primitives import (ATOL, ROBOT_FRAMES, ROBOTS, FrameState, build, compile_task,  # isort: skip
                             random_q, random_unit, rows_of, unit)
from test_row_jacobians import assert_taylor_rows, pose  # isort: skip

import vfdsl
from vfdsl import VfError
from vfdsl.check import check
from vfdsl.check.report import Severity
from vfdsl.primitives.within_sphere import COINCIDENT
from vfdsl.runtime.qp import StepStatus
from vfdsl.sim.geometry import Scene
from vfdsl.sim.metrics import Poses, errors, metric_defs

BODY = """
    param c : point = [0, 0, 0.3]
    param r : length = 0.01
    param band : plane = plane(point = [0, 0, 0.27], normal = [0, 0, 1])
    param w : length = 0.002
    require {frame} within_sphere(c, r)
    require {frame} outside_sphere(c, r)
    require {frame} near_plane(band, w)
    """
TRIALS = 8
STAGE = slice(0, 3)          # shr7's x, y, z stage joints: a pure translation of everything they carry
HEAD = 'task t\nunits mm, deg\nrobot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\n'   # 4 lines


def spheres(tmp_path, robot="shr7", frame="tip"):
    return build(tmp_path, BODY.format(frame=frame), robot)


def rows(ctrl, qp, primitive, frame=None):
    A, _, lb, ub = rows_of(ctrl, qp, primitive, frame)
    assert np.all(np.isinf(ub)) and np.all(ub > 0)
    return A, lb


def random_params(rng, p):
    """A ball around a point near p (so that p is inside or outside it) and a band near p."""
    c = p + rng.normal(scale=0.01, size=3)
    r = rng.uniform(0.002, 0.02)
    d = random_unit(rng)
    return {"c": c, "r": r, "band": {"point": p + rng.normal(scale=0.003, size=3), "normal": 2.5 * d},
            "w": rng.uniform(0.0005, 0.004)}, d


# =============================================================================== rows, Taylor rows

@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_rows_match_the_formulas(tmp_path, robot, frame):
    """within: -n J_v dq >= -r + n.(p - c); outside: n J_v dq >= r - n.(p - c), n = (p - c)/|p - c|;
    near_plane: +-d J_v dq >= -w +- d.(p - P) (d normalized from a run-time normal of length 2.5)."""
    ctrl = spheres(tmp_path, robot, frame)
    rng = np.random.default_rng(31)
    inside = outside = 0
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        params, d = random_params(rng, f.p)
        qp = ctrl.problem(q, {}, params, dt=0.01)
        delta = f.p - params["c"]
        n = delta / np.linalg.norm(delta)
        distance, r = np.linalg.norm(delta), params["r"]
        inside, outside = inside + (distance < r), outside + (distance > r)

        A, lb = rows(ctrl, qp, "within_sphere", frame)
        np.testing.assert_allclose(A, -(n @ f.Jv)[None], atol=ATOL)
        np.testing.assert_allclose(lb, [distance - r], atol=ATOL)

        A, lb = rows(ctrl, qp, "outside_sphere", frame)
        np.testing.assert_allclose(A, (n @ f.Jv)[None], atol=ATOL)
        np.testing.assert_allclose(lb, [r - distance], atol=ATOL)

        A, lb = rows(ctrl, qp, "near_plane", frame)
        depth = d @ (f.p - params["band"]["point"])
        np.testing.assert_allclose(A, np.vstack([d @ f.Jv, -d @ f.Jv]), atol=ATOL)
        np.testing.assert_allclose(lb, [-params["w"] - depth, -params["w"] + depth], atol=ATOL)
    assert inside and outside, "both sides of the sphere should have been visited"
    labels = [(lab.primitive, lab.facet) for lab in ctrl.row_labels]
    assert labels == [("within_sphere", "tangent plane"), ("outside_sphere", "tangent plane"),
                      ("near_plane", "not below band"), ("near_plane", "not above band")]


@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_rows_are_the_taylor_rows_of_the_true_distances(tmp_path, robot, frame):
    """g(q) = || p(q) - c || <= r, r - || p(q) - c || <= 0 and +-d.(p(q) - P) <= w, differentiated by
    central differences of Pinocchio's kinematics: nothing frozen, the rows are the true linearizations."""
    ctrl = spheres(tmp_path, robot, frame)
    rng = np.random.default_rng(32)
    for _ in range(4):
        q0 = random_q(robot, rng)
        p0, _, _ = pose(robot, frame, q0)
        params, d = random_params(rng, p0)
        c, r, P, w = params["c"], params["r"], params["band"]["point"], params["w"]
        qp = ctrl.problem(q0, {}, params, dt=0.01)

        def distance(q):
            return np.array([np.linalg.norm(pose(robot, frame, q)[0] - c)])

        assert_taylor_rows(*rows(ctrl, qp, "within_sphere", frame), distance, r, q0)
        assert_taylor_rows(*rows(ctrl, qp, "outside_sphere", frame), lambda q: r - distance(q), 0.0, q0)
        height = lambda q: np.array([1.0, -1.0]) * (d @ (pose(robot, frame, q)[0] - P))   # noqa: E731
        assert_taylor_rows(*rows(ctrl, qp, "near_plane", frame), height, [w, w], q0)


# ================================================================================== brute force

def test_verdicts_on_moves_against_the_true_ball_and_band(tmp_path):
    """On shr7 a move of the stage joints dq = (dx, 0...) translates the tip by dx exactly: the rows' verdict
    on 4000 moves (up to 0.4 r, around the sphere) is compared with the moved tip's true distance from
    Pinocchio. The tangent plane is exact on the side it guarantees and off by at most the sagitta
    |dx|^2 / 2r on the other: outside_sphere never accepts a move into the ball, within_sphere never
    refuses one that stays in; the band is exact both ways."""
    ctrl = spheres(tmp_path)
    robot = ROBOTS["shr7"]
    rng = np.random.default_rng(33)
    conservative = optimistic = 0
    for _ in range(3):
        q = random_q("shr7", rng, shrink=0.5)
        p, _ = robot.frame_pose(q, "tool_tip")
        r = rng.uniform(0.004, 0.02)
        c = p - rng.uniform(0.9, 1.1) * r * random_unit(rng)          # p within 10% of the sphere
        d = random_unit(rng)
        P, w = p + rng.uniform(-0.001, 0.001) * d, 0.0015
        qp = ctrl.problem(q, {}, {"c": c, "r": r, "band": {"point": P, "normal": d}, "w": w}, dt=0.01)
        dx = rng.uniform(-1, 1, size=(4000, 3)) * 0.4 * r / math.sqrt(3)
        moved = np.array([robot.frame_pose(np.r_[q[STAGE] + x, q[3:]], "tool_tip")[0] for x in dx])
        np.testing.assert_allclose(moved, p + dx, atol=1e-12)         # the premise: a pure translation
        true = np.linalg.norm(moved - c, axis=1)
        sagitta = np.sum(dx ** 2, axis=1) / (2 * r)

        def accepted(primitive):
            A, lb = rows(ctrl, qp, primitive)
            return np.all(dx @ A[:, STAGE].T >= lb - 1e-15, axis=1)

        keep_out, keep_in = accepted("outside_sphere"), accepted("within_sphere")
        assert np.all(true[keep_out] >= r - 1e-12), "outside_sphere accepted a move into the ball"
        assert np.all(true[~keep_out] - r <= sagitta[~keep_out] + 1e-12)
        assert np.all(true[~keep_in] >= r - 1e-12), "within_sphere refused a move that stays inside"
        assert np.all(true[keep_in] - r <= sagitta[keep_in] + 1e-12)
        conservative += np.sum(~keep_out & (true > r))
        optimistic += np.sum(keep_in & (true > r))
        height = (moved - P) @ d
        clear = np.abs(np.abs(height) - w) > 1e-12
        assert np.array_equal(accepted("near_plane")[clear], (np.abs(height) <= w)[clear])
        assert 0 < np.sum(np.abs(height) <= w) < len(dx)
    assert conservative > 0 and optimistic > 0, "the sagitta cases should have been sampled"


def test_within_sphere_overshoot_bound_holds_for_any_step(tmp_path):
    """From anywhere in the ball (the center included), every stage move the row accepts ends within
    sqrt(r^2 + s^2) of the center, s = |dx|, for steps up to 3 r: the bound the docs state, with no
    assumption on s."""
    ctrl = spheres(tmp_path)
    robot = ROBOTS["shr7"]
    rng = np.random.default_rng(34)
    for inside in (0.0, 0.3, 0.999):
        q = random_q("shr7", rng, shrink=0.5)
        p, _ = robot.frame_pose(q, "tool_tip")
        r = 0.005
        c = p - inside * r * random_unit(rng)
        qp = ctrl.problem(q, {}, {"c": c, "r": r}, dt=0.01)
        A, lb = rows(ctrl, qp, "within_sphere")
        dx = np.array([random_unit(rng) for _ in range(3000)]) * rng.uniform(0, 3 * r, size=(3000, 1))
        keep = dx @ A[0, STAGE] >= lb[0] - 1e-15
        moved = np.array([robot.frame_pose(np.r_[q[STAGE] + x, q[3:]], "tool_tip")[0] for x in dx[keep]])
        s = np.linalg.norm(dx[keep], axis=1)
        assert keep.sum() > 1000 and s.max() > 2 * r
        assert np.all(np.linalg.norm(moved - c, axis=1) <= np.sqrt(r ** 2 + s ** 2) + 1e-12)


# ============================================================================== degenerate center

GUIDED = """
    input f : force
    param c : point = [0, 0, 0.3]
    param r : length = 0.005
    minimize track(tip, f, gain = 1 mm/s/N)
    minimize damping() weight 1e-6
    require joint_limits()
    require joint_speed()
    """


def guided(tmp_path, *requirements: str):
    """An interpreted controller of shr7's tip guided by a force, within its joint limits and speeds."""
    return build(tmp_path, GUIDED + "".join(f"require tip {r}\n" for r in requirements))


def hands_off(ctrl, q, c, ticks):
    """Tip positions (Pinocchio) and statuses over ``ticks`` ticks of zero force with the center c."""
    positions, statuses = [], []
    for _ in range(ticks):
        dq = ctrl.step(q, {"f": [0.0, 0.0, 0.0]}, {"c": c}, dt=0.01)
        assert np.all(np.isfinite(dq))
        q = q + dq
        statuses.append(ctrl.status)
        positions.append(ROBOTS["shr7"].frame_pose(q, "tool_tip")[0])
    return np.array(positions), statuses

@pytest.mark.parametrize("offset", [0.0, 0.1 * COINCIDENT, 1e6 * COINCIDENT])
def test_rows_at_the_center_are_finite_and_use_the_tool_axis(tmp_path, offset):
    """At p == c (and within COINCIDENT of it) n is the tool axis l: within gives -l J_v dq >= -r (harmless),
    outside l J_v dq >= r (retract by r). Just beyond COINCIDENT, n is the radial direction again."""
    ctrl = spheres(tmp_path)
    q = np.array([0.01, -0.02, 0.005, 0.3, -0.2, 0.4, 0.03])           # a tilted tool
    f = FrameState("shr7", "tip", q)
    radial = unit(np.cross(f.l, [1.0, 0, 0]))                            # a direction other than l
    c = f.p - offset * radial
    qp = ctrl.problem(q, {}, {"c": c, "r": 0.005}, dt=0.01)
    constraint_rows = slice(qp.P.shape[0], None)                       # after the variable bounds
    assert np.all(np.isfinite(qp.A)) and np.all(np.isfinite(qp.lb[constraint_rows]))
    n = f.l if offset < COINCIDENT else radial
    A, lb = rows(ctrl, qp, "within_sphere")
    np.testing.assert_allclose(A, -(n @ f.Jv)[None], atol=1e-9)
    np.testing.assert_allclose(lb, [-0.005 + offset], atol=1e-12)
    A, lb = rows(ctrl, qp, "outside_sphere")
    np.testing.assert_allclose(A, (n @ f.Jv)[None], atol=1e-9)
    np.testing.assert_allclose(lb, [0.005 - offset], atol=1e-12)


FAR = """
    input f : force
    param c : point = [0, 0, 0.3]
    param v : vector = [0, 0, 0]
    param k : number = 1
    param r : length = 0.01
    minimize track(tip, f, gain = 0.001)
    minimize damping() weight 1e-6
    require joint_limits()
    require joint_speed()
    """


def test_centers_far_away_do_not_overflow(tmp_path):
    """A center given 1e200 m away is refused before anything moves (an implausible point, as a vector would be).
    Computed that far (a point plus a run-time vector scaled by a number, which has no plausible size), |p - c|^2
    would overflow (and underflow at 1e-200 m): the rows stay exact. A step then reports the ball violated and does
    not move (its least-violation solve fails on numbers that large, and the fallback is the zero motion)."""
    q = np.array([0.01, -0.02, 0.005, 0.3, -0.2, 0.4, 0.03])
    f = FrameState("shr7", "tip", q)
    with pytest.raises(VfError, match=r"param 'c' is .* m: beyond 2.16 m"):
        spheres(tmp_path).problem(q, {}, {"c": f.p - np.array([1e200, -1e200, 3e199]), "r": 0.005}, dt=0.01)
    plain = build(tmp_path, FAR + "require tip outside_sphere(c + v, r)\n", name="far_v")
    with pytest.raises(VfError, match=r"param 'v' is .* m: beyond 2.16 m"):
        plain.problem(q, {"f": [0, 0, 0]}, {"c": f.p, "v": [-1e200, 0, 0], "r": 0.005}, dt=0.01)
    ctrl = build(tmp_path, FAR + "require tip outside_sphere(c + k * v, r)\n", name="far")
    for offset, scale in (([1.0, -1.0, 0.3], 1e200), ([1.0, 0, 0], 1e-200)):
        n = unit(np.asarray(offset))
        qp = ctrl.problem(q, {"f": [0, 0, 0]}, {"c": f.p, "v": -np.asarray(offset), "k": scale, "r": 0.005}, dt=0.01)
        far = scale > 1
        A, lb = rows(ctrl, qp, "outside_sphere")
        np.testing.assert_allclose(A, ((n if far else f.l) @ f.Jv)[None], atol=1e-9)
        assert np.isfinite(lb).all() and (lb[0] < -1e199 if far else lb[0] == pytest.approx(0.005))
    ctrl = build(tmp_path, FAR + "require tip within_sphere(c + k * v, 0.005)\n"
                 "require tip outside_sphere(c + k * v, 0.004)\n", name="far_guided")
    dq = ctrl.step(q, {"f": [1.0, 0, 0]}, {"v": [1.0, 0, 0], "k": 1e200}, dt=0.01)   # 1e200 m outside: no motion
    assert ctrl.status & StepStatus.LEAST_VIOLATION and np.all(dq == 0)
    assert [(v.label.primitive, v.amount) for v in ctrl.violations()] == [("within_sphere", 1e200)]


def test_a_tip_at_the_center_of_a_keep_out_ball_retracts_along_the_tool(tmp_path):
    """Hands off, the tip exactly at the center of a 2 mm keep-out ball: no NaN; the first (least-violation)
    tick moves it toward the handle, mostly along the tool axis (the joint box lets the stage help); from
    then on n is radial and the tip leaves the ball by the shortest way, then stays still on its surface."""
    ctrl = guided(tmp_path, "outside_sphere(c, 2 mm)")
    q = np.array([0.0, 0.0, 0.0, 0.25, -0.15, 0.0, 0.03])
    start, R = ROBOTS["shr7"].frame_pose(q, "tool_tip")
    positions, statuses = hands_off(ctrl, q, start, 30)
    moved = positions - start
    distance = np.linalg.norm(moved, axis=1)
    assert unit(moved[0]) @ R[:, 2] > 0.8, "the first tick retracts along the tool axis"
    assert statuses[0] != StepStatus.OPTIMAL and statuses[-1] == StepStatus.OPTIMAL
    assert np.all(np.diff(distance) >= -1e-12) and distance[-1] >= 0.002 - 1e-12
    assert np.linalg.norm(moved[-1] - moved[-2]) < 1e-12, "out of the ball, hands off: still"


def test_a_ball_moved_away_at_run_time_pulls_the_tip_back_onto_it(tmp_path):
    """The workspace ball is moved at run time so that the tip is 3 mm outside it: hands off, the tip's
    distance to the center falls every tick (least-violation ticks at the joint speed limits) to the radius,
    and there it stops. (The least-violation move saturates every joint that helps, so the path is not
    straight: see docs/runtime.md, phase 2.)"""
    ctrl = guided(tmp_path, "within_sphere(c, 4 mm)")
    q = np.array([0.0, 0.0, 0.0, 0.2, 0.1, 0.0, 0.02])
    c = ROBOTS["shr7"].frame_pose(q, "tool_tip")[0] + 0.007 * unit([1.0, -2.0, 0.5])
    positions, statuses = hands_off(ctrl, q, c, 40)
    distance = np.linalg.norm(positions - c, axis=1)
    assert np.all(np.diff(distance) <= 1e-12) and distance[-1] == pytest.approx(0.004, abs=1e-9)
    assert distance[-2] == pytest.approx(distance[-1], abs=1e-12), "on the sphere, hands off: still"
    assert statuses[0] != StepStatus.OPTIMAL and statuses[-1] == StepStatus.OPTIMAL


def test_generated_c_agrees_at_and_near_the_center(tmp_path):
    """The generated C (its if_else included) takes the same steps as the interpreted path with the tip at
    the center of both balls (a 0.1 mm keep-out ball: one tick can leave it, along the tool axis), within
    COINCIDENT of it, and off it; its extension refuses a radius out of range."""
    interpreted = guided(tmp_path, "within_sphere(c, r)", "outside_sphere(c, 0.1 mm)")
    native = vfdsl.compile(interpreted.task, backend="native")
    robot = ROBOTS["shr7"]
    q = np.array([0.003, -0.002, 0.001, 0.3, -0.2, 0.4, 0.03])
    p, R = robot.frame_pose(q, "tool_tip")
    for offset in (0.0, 0.5 * COINCIDENT, 1e-5):
        c = p - offset * unit([1.0, 2.0, 3.0])
        steps = [ctrl.step(q, {"f": [1.0, -2.0, 0.5]}, {"c": c}, dt=0.01) for ctrl in (native, interpreted)]
        assert native.status == interpreted.status == StepStatus.OPTIMAL
        np.testing.assert_allclose(steps[0], steps[1], atol=1e-12)
        moved = robot.frame_pose(q + steps[0], "tool_tip")[0] - c
        assert np.linalg.norm(moved) >= 1e-4 - 1e-9
        if offset < COINCIDENT:
            assert moved @ R[:, 2] >= 1e-4 - 1e-9, "out along the tool axis"
    for bad in (0.0, -0.001, math.nan):
        with pytest.raises(VfError, match="'r'"):
            native.step(q, {"f": [0.0, 0.0, 0.0]}, {"r": bad}, dt=0.01)


# ================================================================================= bad arguments

@pytest.mark.parametrize("line,column,message", [
    ("require tip within_sphere([0, 0, 280], 0 mm)", 40, "argument 'radius' must be in (0, 1e+06], got 0 mm"),
    ("require tip outside_sphere([0, 0, 280], -3 mm)", 41, "argument 'radius' must be in (0, 1e+06], got -3 mm"),
    ("require tip within_sphere([0, 0, 280], 20 deg)", 40, "expected a length, but 'deg' is an angle"),
    ("require tip outside_sphere([0, 0, 280], 1e999 mm)", 41, "numbers must be finite"),
    ("require tip outside_sphere([0, 0, 280])", 13, "radius"),
    ("require tip near_plane(plane(point = [0, 0, 0], normal = [0, 0, 1]), 0 mm)", 70,
     "argument 'half_width' must be in (0, 1e+06]"),
    ("require tip near_plane(plane(point = [0, 0, 0], normal = [0, 0, 0]), 1 mm)", 58, "is zero"),
    ("require tip within_sphere([0, 0, 280], 20 mm) within 1 mm", 54, "takes no tolerance"),
    ("require tip outside_sphere([0, 0, 280], 2 mm) resolution 8x8", 58, "takes no polytope resolution"),
])
def test_bad_arguments_are_errors_at_the_argument(tmp_path, line, column, message):
    (tmp_path / "t.vf").write_text(HEAD + line + "\n")
    with pytest.raises(VfError) as info:
        vfdsl.load(tmp_path / "t.vf")
    err = info.value
    assert message in err.message, err.render()
    assert err.line == 5 and err.column == column, err.render()


def test_a_param_radius_is_range_checked_at_load_and_at_run_time(tmp_path):
    (tmp_path / "t.vf").write_text(HEAD + "param r : length = -2 mm\nrequire tip outside_sphere([0, 0, 280], r)\n")
    with pytest.raises(VfError) as info:
        vfdsl.load(tmp_path / "t.vf")
    assert info.value.line == 5 and "outside_sphere" in info.value.message, info.value.render()
    ctrl = spheres(tmp_path)
    q = np.array([0, 0, 0, 0, 0, 0, 0.02])
    for bad in ({"r": 0.0}, {"r": -0.001}, {"r": math.nan}, {"w": 0.0}, {"c": [0, 0, math.inf]},
                {"band": {"point": [0, 0, 0.27], "normal": [0, 0, 0]}}):
        with pytest.raises(VfError) as info:
            ctrl.step(q, {}, bad, dt=0.01)
        assert next(iter(bad)) in info.value.message, info.value.message
    assert np.all(np.isfinite(ctrl.step(q, {}, {"r": 0.001, "c": [0, 0, 0.25]}, dt=0.01)))


# ========================================================================== check and simulate

PROBE = """\
task probe
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
param c : point = {c}
param artery : point = {artery}
param band : plane = plane(point = [0, 0, 290], normal = [0, 0, 1])
minimize track(tip, f, gain = 1 mm/s/N)
minimize damping() weight 1e-6
require tip within_sphere(c, 20 mm)
require tip outside_sphere(artery, 4 mm)
require tip near_plane(band, {w})
require joint_limits()
require joint_speed()
"""
SCENE = "units: mm, deg\nperiod: 10 ms\nstart: {x: 0, y: 0, z: 0, rcm_a: 0, rcm_b: 0, roll: 0, insert: 10}\n"
TIP = np.array([0.0, 0.0, 0.29])           # at the start (insert 10 mm)


def probe(tmp_path, c="[0, 0, 280]", artery="[10, 0, 280]", w="1 mm"):
    (tmp_path / "probe.yaml").write_text(SCENE)
    (tmp_path / "probe.vf").write_text(PROBE.format(c=c, artery=artery, w=w))
    return vfdsl.load(tmp_path / "probe.vf")


def findings(report, name):
    return {f.subject.split(" at ")[0]: f for f in report.findings if f.name == name}


def test_check_reports_exact_bounds_and_true_residuals(tmp_path):
    """Sound at a start inside everything: the bounds table says the ball is exact (tangent plane), no
    polytope circumradius. Started 25 mm from a 20 mm ball's center and 1 mm inside a 4 mm keep-out ball:
    each residual is the true distance, from Pinocchio."""
    report = check(probe(tmp_path), backend="interpreted", samples=20)
    assert report.exit_status() == 0, report.render_text()
    bounds = {b.subject: b for b in report.bounds}
    assert set(bounds) == {"within_sphere(tip)", "near_plane(tip)"}
    ball, band = bounds["within_sphere(tip)"], bounds["near_plane(tip)"]
    assert (ball.resolution, ball.facets, ball.stated, ball.worst) == ("exact (tangent plane)", None, 0.02, 0.02)
    assert (band.resolution, band.stated, band.worst) == ("exact", 0.001, 0.001)
    assert "exact (tangent plane)" in report.render_text()
    assert not findings(report, "residual-outside") and not findings(report, "residual-far")

    task = probe(tmp_path, c="[15, 0, 310]", artery="[3, 0, 290]")
    tip, _ = ROBOTS["shr7"].frame_pose(task.start, "tool_tip")
    np.testing.assert_allclose(tip, TIP, atol=1e-12)
    report = check(task, backend="interpreted", samples=0)
    ball = findings(report, "residual-outside")["within_sphere(tip)"]
    assert ball.data["error"] == pytest.approx(np.linalg.norm(tip - [0.015, 0, 0.31]), abs=1e-12)
    keep_out = findings(report, "residual-far")["outside_sphere(tip)"]     # 1 mm past an exact boundary
    assert keep_out.severity == Severity.ERROR and "on the wrong side" in keep_out.message
    assert keep_out.data["error"] == pytest.approx(0.004 - np.linalg.norm(tip - [0.003, 0, 0.29]), abs=1e-12)


def test_check_residual_of_a_band_and_a_center_in_the_wrong_unit(tmp_path):
    """The band's residual is |d.(p - P)| (10 mm below a plane at 300 mm: 10 mm, 20 x its 0.5 mm); a ball's
    center written in m in a mm file is named as a unit slip."""
    text = PROBE.format(c="[0, 0, 0.28]", artery="[10, 0, 280]", w="0.5 mm").replace("290], normal", "300], normal")
    (tmp_path / "probe.yaml").write_text(SCENE)
    (tmp_path / "probe.vf").write_text(text)
    report = check(vfdsl.load(tmp_path / "probe.vf"), backend="interpreted", samples=0)
    far = findings(report, "residual-far")
    assert far["near_plane(tip)"].data["error"] == pytest.approx(0.01, abs=1e-12)
    assert far["within_sphere(tip)"].data["error"] == pytest.approx(np.linalg.norm(TIP - [0, 0, 0.28e-3]))
    assert "wrong unit" in far["within_sphere(tip)"].message, far["within_sphere(tip)"].message


def test_simulator_metrics_of_hand_placed_tips(tmp_path):
    """Tip 25 mm from the 20 mm ball's center: 5 mm out of the ball; 1 mm from the artery's center: 3 mm
    into its 4 mm keep-out ball; 1.5 mm off the middle plane of a 1 mm band: 0.5 mm out of the band."""
    task = probe(tmp_path)
    robot = ROBOTS["shr7"]
    c, artery = np.array([0, 0, 0.28]), np.array([0.01, 0, 0.28])
    p = np.array([c + [0.025, 0, 0], artery + [0, 0.001, 0], [0.002, 0.0, 0.2915], [0.002, 0.0, 0.29]])
    poses = Poses({"tip": p}, {"tip": np.repeat(np.eye(3)[None], 4, axis=0)})
    scene = Scene(task)
    got = {d.name: errors(d, task, robot, scene, poses, np.zeros((4, 7)), 0.01)
           for d in metric_defs(task, robot, ())}
    np.testing.assert_allclose(got["tip_within_sphere_error_mm"], [5.0, 0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(got["tip_outside_sphere_error_mm"], [0, 3.0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(got["tip_near_plane_error_mm"], [9.0, 9.0, 0.5, 0], atol=1e-9)


# ================================================================================== closed loop

def arm_task(tmp_path, body):
    text = textwrap.dedent("""\
        task arm
        units mm, deg
        robot arm = urdf "panda7"
        frame tip = arm.link("tool_tip")
        input f : force
        minimize track(tip, f, gain = 1 mm/s/N)
        minimize damping() weight 1e-6
        require joint_limits()
        require joint_speed()
        """) + textwrap.dedent(body)
    (tmp_path / "arm.vf").write_text(text)
    (tmp_path / "arm.yaml").write_text("units: mm, deg\nperiod: 10 ms\nstart: [0, -45, 0, -135, 0, 90, 45]\n")
    return vfdsl.load(tmp_path / "arm.vf")


def push(task, hand, ticks=1500):
    """q <- q + step(q, hand(k, p)) from the scene's start; the tip positions from Pinocchio."""
    ctrl = compile_task(task)
    robot = ROBOTS["panda7"]
    q = task.start.copy()
    p, statuses, tips = robot.frame_pose(q, "tool_tip")[0], set(), []
    for k in range(ticks):
        q = q + ctrl.step(q, {"f": hand(k, p)})
        statuses.add(ctrl.status)
        p = robot.frame_pose(q, "tool_tip")[0]
        tips.append(p)
    assert statuses == {StepStatus.OPTIMAL}
    return np.array(tips)


def around(outward, k):
    """A unit vector normal to ``outward``, turning slowly about it: the hand drags the tip around."""
    e1 = unit(np.cross(outward, [0.0, 0.0, 1.0]))
    e2 = np.cross(outward, e1)
    return math.cos(0.004 * k) * e1 + math.sin(0.004 * k) * e2


@pytest.mark.slow
def test_within_sphere_on_the_arm_pushed_outward_and_around(tmp_path):
    """A hand pushes 10 N outward and 17 N along the boundary (turning slowly), at the 1 mm/s/N gain: the tip
    travels 256 mm around the 15 mm ball and leaves it by no more than the sagitta of one tick's step,
    s^2 / 2r (s = 0.197 mm: 1.30 um); measured with Pinocchio: 1.01 um."""
    center = np.array([0.3069, 0.0, 0.4769])          # 10 mm below the start tip (306.9, 0, 486.9) mm
    task = arm_task(tmp_path, "require tip within_sphere([306.9, 0, 476.9], 15 mm)\n")
    tips = push(task, lambda k, p: 10 * unit(p - center) + 17 * around(unit(p - center), k))
    distance = np.linalg.norm(tips - center, axis=1)
    excess = distance.max() - 0.015
    step = np.linalg.norm(np.diff(tips, axis=0), axis=1).max()
    assert np.sum(distance > 0.015 - 1e-6) > 1000, "the hand should hold the tip on the boundary"
    assert np.linalg.norm(np.diff(tips, axis=0), axis=1).sum() > 0.1, "and drag it around"
    assert excess <= step ** 2 / (2 * 0.015)
    assert 0 < excess < 1.1e-6


@pytest.mark.slow
def test_outside_sphere_on_the_arm_pushed_in_and_around(tmp_path):
    """The hand pushes the tip straight into a 5 mm keep-out ball (10 N), then also sideways (8 N about the y
    axis): the tip stays out (the row is conservative; the arm's curved motion within a tick costs it
    1.7 nm, measured with Pinocchio) and slides around the ball, more than once."""
    center = np.array([0.3069, 0.0, 0.4719])          # 15 mm below the start tip
    task = arm_task(tmp_path, "require tip outside_sphere([306.9, 0, 471.9], 5 mm)\n")

    def hand(k, p):
        n = unit(p - center)
        return -10 * n + (0 if k < 200 else 8) * unit(np.cross(n, [0.0, 1.0, 0.0]))

    tips = push(task, hand)
    distance = np.linalg.norm(tips - center, axis=1)
    assert distance.min() >= 0.005 - 1e-8
    on_ball = distance < 0.005 + 1e-6
    assert on_ball[150:].all(), "pushed in, the tip rests on the ball"
    u = (tips - center) / distance[:, None]
    swept = np.degrees(np.unwrap(np.arctan2(u[:, 0], u[:, 2])))
    assert abs(swept[199] - swept[0]) < 1 and abs(swept[-1] - swept[199]) > 360, "it slides around the ball"


@pytest.mark.slow
def test_near_plane_on_the_arm_pushed_across_the_band(tmp_path):
    """Pushed across a 1 mm band, back and forth and along it: the tip never leaves it by more than 10 nm."""
    task = arm_task(tmp_path, "require tip near_plane(plane(point = [300, 0, 487], normal = [1, 0, 1]), 1 mm)\n")
    d = unit([1.0, 0.0, 1.0])
    tips = push(task, lambda k, p: 10 * d * (1 if (k // 300) % 2 == 0 else -1) + [0, 5, 0], ticks=1200)
    height = (tips - [0.3, 0, 0.487]) @ d
    assert np.abs(height).max() <= 0.001 + 1e-8
    assert height.max() > 0.001 - 1e-6 and height.min() < -0.001 + 1e-6, "both sides were reached"
