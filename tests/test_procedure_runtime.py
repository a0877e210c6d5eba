"""A procedure compiled into one controller (issue 33, items 2 and 5), on the interpreted path: every phase's rows
and terms in one QP switched by the phases' activity, captures as run-time param slots, the phase machine run
before each solve; the example needle procedure driven by scripted hand forces and button presses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import vfdsl
from vfdsl.codegen import tick_buffers
from vfdsl.compiler.phases import monitor_values
from vfdsl.errors import VfError
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime import phase_machine as pm
from vfdsl.runtime.procedure import machine_table
from vfdsl.runtime.qp import StepStatus

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = REPO / "tasks" / "procedures" / "needle_procedure.vf"
DT = 0.001
TOL = 1e-9          # the compiled controller's feasibility tolerance (vfdsl.pipeline)


@pytest.fixture(scope="module")
def task():
    return vfdsl.load(EXAMPLE)


class Driver:
    """Ticks a controller with a hand force (plus a small wobble, so that the stale-input watchdog stays quiet),
    the button, and records each tick's tip position before the step, phase and events."""

    def __init__(self, task):
        self.ctrl = vfdsl.compile(task, backend="interpreted")
        self.q = np.array(task.start, dtype=float)
        self.k = 0
        self.tip_before: list[np.ndarray] = []
        self.phases: list[str] = []
        self.events: list[tuple[int, object]] = []
        self.axis = self.frame("needle").tool_axis
        self.entry = np.array(task.param("entry").value.xyz)

    def frame(self, name):
        return self.ctrl.frames(self.q)[name]

    def tick(self, hand=(0.0, 0.0, 0.0), go=0.0, dt=DT, wobble=True):
        self.k += 1
        k = self.k
        extra = 1e-3 * np.array([np.sin(k), np.cos(1.3 * k), np.sin(0.7 * k)]) if wobble else np.zeros(3)
        self.tip_before.append(self.frame("tip").position)
        self.q = self.q + self.ctrl.step(self.q, {"hand": np.asarray(hand, float) + extra, "go": [go]}, dt=dt)
        self.phases.append(self.ctrl.phase)
        self.events += [(k, e) for e in self.ctrl.events]

    def ticks(self, n, **kw):
        for _ in range(n):
            self.tick(**kw)

    def capture(self, name):
        return self.ctrl.captures[name]


@pytest.fixture(scope="module")
def run(task):
    """The example end to end: the button at tick 10 (the tip starts at the entry, aligned), `aligned` (held since
    tick 1) at tick 100, a 6 N push along the needle from tick 150, a pull out at dt 10 ms."""
    d = Driver(task)
    d.ticks(9)
    d.tick(go=1.0)
    d.ticks(139)                                    # align, then insert from tick 100 on
    d.ticks(60, hand=6.0 * d.axis)                   # ticks 150-209: over 5 N from tick 150
    while d.ctrl.phase == "retract" and d.k < 400:
        d.tick(hand=-20.0 * d.axis, dt=0.01)
    return d


def test_every_phase_in_order_each_transition_at_its_tick(run):
    assert [(k, e.source, e.target) for k, e in run.events] == [
        (10, "approach", "align"), (100, "align", "insert"), (199, "insert", "retract"),
        (run.events[-1][0], "retract", "done")]
    assert [e.guard for _, e in run.events] == ["near_entry and pressed", "aligned", "pushed or deep", "out"]
    first = [run.phases.index(p) + 1 for p in ("align", "insert", "retract", "done")]
    assert first == [k for k, _ in run.events]      # the phase holds from the transition tick on
    assert run.events[0][1].time == pytest.approx(10 * DT)


def test_the_force_monitor_retracts_at_the_fiftieth_tick_over_the_limit(run):
    k, event = run.events[2]
    assert k - 150 + 1 == 50 and event.target == "retract"
    assert run.phases[k - 2] == "insert"           # one tick earlier (49 over the limit) it was still inserting


def test_captures_are_the_tip_at_the_transition_tick(run):
    assert np.array_equal(run.capture("stop"), run.tip_before[199 - 1])
    assert np.array_equal(run.capture("start"), run.tip_before[100 - 1])
    assert not np.array_equal(run.capture("stop"), run.tip_before[200 - 1])
    assert np.allclose(run.capture("axis0"), run.axis, atol=1e-6)
    # retract's `out` fired 10 mm from stop, along the line
    k, _ = run.events[3]
    assert np.linalg.norm(run.tip_before[k - 1] - run.capture("stop")) > 0.01


def test_captures_are_public_by_name_in_si(run, task):
    captures = run.ctrl.captures
    assert list(captures) == ["start", "axis0", "stop", "rest", "held"]
    assert np.isclose(np.linalg.norm(captures["axis0"]), 1.0) and captures["start"].shape == (3,)
    captures["start"][:] = 0.0                                        # a copy: the procedure's own is untouched
    assert np.linalg.norm(run.ctrl.captures["start"]) > 0.01
    plain = vfdsl.compile(vfdsl.load(REPO / "tasks" / "needle_insertion.vf"), backend="interpreted")
    assert plain.captures == {}


def test_monitors_are_reported_by_name(run):
    assert set(run.ctrl.monitors) == {m.name for m in run.ctrl.task.monitors}
    assert run.ctrl.monitors["out"] is True and run.ctrl.monitors["stale"] is False
    assert run.ctrl.phase == "done"


def test_a_final_phase_is_never_left_and_reset_restarts(task):
    d = Driver(task)
    d.ticks(25, wobble=False)                       # a constant hand: stale after 20 ms unchanged
    assert [(k, e.target) for k, e in d.events] == [(21, "hold")]
    assert d.ctrl.monitors["stale"] and d.ctrl.phase == "hold" and d.ctrl.events == ()
    held = d.capture("held")
    assert np.array_equal(held, d.tip_before[20])
    d.ctrl.reset()
    assert d.ctrl.phase == "approach" and d.ctrl.events == ()
    d.ticks(3)
    assert d.ctrl.phase == "approach" and not d.ctrl.monitors["stale"]


def test_an_inactive_hard_fixture_does_not_hold_the_tool_the_active_one_does(task):
    d = Driver(task)
    sideways = np.cross(d.axis, [1.0, 0.0, 0.0])
    sideways = 20.0 * sideways / np.linalg.norm(sideways)
    d.ticks(60, hand=sideways)                      # approach: align's stays_at(entry) within 0.5 mm is off
    away = np.linalg.norm(d.frame("tip").position - d.entry)
    assert away > 1e-3 and d.ctrl.phase == "approach"   # twice the tolerance of the fixture that is off
    qp = d.ctrl.problem(d.q, {"hand": sideways, "go": [0]}, dt=DT)
    rows = [k for k, label in enumerate(d.ctrl.row_labels) if label.phase is not None]
    lb, ub = qp.lb[qp.P.shape[0]:], qp.ub[qp.P.shape[0]:]
    assert np.all(np.isneginf(lb[rows]) & np.isposinf(ub[rows]))       # every phase's hard rows off in approach
    assert d.ctrl.violations() == []

    d = Driver(task)
    d.tick(go=1.0)                                  # into align at the first tick
    assert d.ctrl.phase == "align"
    d.ticks(80, hand=sideways)
    offset = np.abs(d.frame("tip").position - d.entry)              # stays_at's box: 0.5 mm per axis
    assert offset.max() <= 0.5e-3 + 1e-8 and offset.max() > 0.4e-3   # pushed against it, held
    on = [label.phase == "align" for label in d.ctrl.row_labels]
    qp = d.ctrl.problem(d.q, {"hand": sideways, "go": [0]}, dt=DT)
    n = qp.P.shape[0]
    assert np.all(np.isfinite(qp.lb[n:][on]) | np.isfinite(qp.ub[n:][on]))
    assert d.ctrl.status == 0


def test_blend_weights_are_in_the_qp(task):
    d = Driver(task)
    d.ticks(9)
    d.tick(go=1.0)
    d.tick()
    assert d.ctrl.phase == "align"
    proc = d.ctrl._procedure
    w = proc.activity[:6]
    blend = task.blend
    assert w[0] == pytest.approx(1 - 2 * DT / blend) and w[1] == pytest.approx(2 * DT / blend)
    assert w.sum() == pytest.approx(1.0) and list(proc.activity[6:12]) == [0, 1, 0, 0, 0, 0]
    u = {"hand": [3.0, -1.0, 2.0], "go": [0]}
    blended = d.ctrl.problem(d.q, u, dt=DT)
    full = proc.activity.copy()
    proc.activity[:6] = [1, 0, 0, 0, 0, 0]
    unblended = d.ctrl.problem(d.q, u, dt=DT)
    proc.activity[:] = full
    R, R1 = blended.levels[0].R, unblended.levels[0].R
    assert np.abs(R1[:3]).max() > 0
    assert np.allclose(R[:3], np.sqrt(w[0]) * R1[:3], rtol=1e-12, atol=1e-15)     # approach's track, scaled
    assert np.all(R[3:] == 0) and np.all(R1[3:] == 0)                               # insert's, retract's: off
    assert blended.levels[0].terms == unblended.levels[0].terms
    r, r1 = blended.levels[0].r, unblended.levels[0].r          # align has no term there: the target ramps too
    assert np.abs(r1[:3]).max() > 0
    assert np.allclose(r[:3], np.sqrt(w[0]) * w[0] * r1[:3], rtol=1e-12, atol=1e-18)


CLUTCH = """\
task clutch_blend
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input hand : force
input clutch : button
monitor pressed = clutch
monitor released = not clutch
minimize damping() weight 1e-6
phase drive initial {{ minimize track(tip, hand, gain = 2 mm/s/N){other} }}
phase held {{{held} }}
transition drive -> held when pressed blend 100 ms
transition held -> drive when released blend 100 ms
"""
"""A hand drives the tip at 10 mm/s (5 N); the clutch enters ``held``, which has no term on drive's level (or, with
``held`` set, a term there of its own), blending over 10 ticks of 10 ms; releasing it blends back."""


def tip_speeds(tmp_path, backend, presses, other="", held=""):
    """The tip's speed (mm/s, by Pinocchio's kinematics) at each tick, the clutch pressed where ``presses`` is 1."""
    path = tmp_path / f"clutch_{backend}.vf"
    path.write_text(CLUTCH.format(other=other, held=held))
    task = vfdsl.load(path)
    ctrl = vfdsl.compile(task, backend=backend)
    robot = Robot.load(task.robots[0].urdf)
    q = 0.5 * (robot.lower + robot.upper)
    speeds = []
    for press in presses:
        before = robot.frame_pose(q, "tool_tip")[0]
        q = q + ctrl.step(q, {"hand": [5.0, 0.0, 0.0], "clutch": [press]}, dt=0.01)
        speeds.append(np.linalg.norm(robot.frame_pose(q, "tool_tip")[0] - before) * 1e3 / 0.01)
    return np.array(speeds)


@pytest.mark.parametrize("backend", ["interpreted", "native"])
def test_a_blend_into_a_phase_without_terms_on_the_level_ramps_the_motion(tmp_path, backend):
    """Out of drive's level (held has nothing there) the motion ramps down with the weight, 9, 8, ..., 1 mm/s over
    the blend's 10 ticks, 0.45 mm in all (before: 10 mm/s until the blend's end, then 0 at once: 0.9 mm); back
    into it, up from 1 mm/s to 10, not 10 at once."""
    speeds = tip_speeds(tmp_path, backend, [0] * 20 + [1] * 20 + [0] * 20)
    assert np.allclose(speeds[15:20], 10.0, rtol=1e-3)
    assert np.allclose(speeds[20:30], np.arange(9, -1, -1), atol=0.02)
    assert np.all(speeds[30:40] < 1e-6)
    assert np.allclose(speeds[40:50], np.arange(1, 11), atol=0.02)
    assert np.allclose(speeds[50:], 10.0, rtol=1e-3)


def test_a_blend_between_terms_on_one_level_blends_their_weights_alone(tmp_path):
    """held with a term of its own on drive's level (tracking half as fast): the weights alone blend, the level
    keeps its full target (coverage 1), and the speed moves from 10 to 5 mm/s without a dip."""
    speeds = tip_speeds(tmp_path, "interpreted", [0] * 20 + [1] * 20,
                        held="\n    minimize track(tip, hand, gain = 1 mm/s/N)")
    assert np.allclose(speeds[15:20], 10.0, rtol=1e-3) and np.allclose(speeds[31:], 5.0, rtol=1e-3)
    blend = speeds[20:30]
    assert np.allclose(blend, 10 - 5 * np.arange(1, 11) / 10, atol=0.02)


FAR_PHASE = """\
task {name}
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
input go : button
param far : point = [100, 100, 100]
monitor pressed = go
phase a initial {{ minimize track(tip, f, gain = 1 mm/s/N) }}
phase b final {{ require tip stays_at(far) within 1 mm{clause} }}
transition a -> b when pressed
"""
"""Phase a tracks the force; pressing go enters phase b, whose fixture holds the tip at [100, 100, 100] mm."""


def far_phase_task(tmp_path, name: str, clause: str):
    """The task FAR_PHASE named ``name``, with ``clause`` after b's tolerance, written in ``tmp_path``."""
    path = tmp_path / f"{name}.vf"
    path.write_text(FAR_PHASE.format(name=name, clause=clause))
    return path


def test_least_violation_counts_only_the_active_rows(tmp_path):
    path = far_phase_task(tmp_path, "hard", "")
    ctrl = vfdsl.compile(vfdsl.load(path), backend="interpreted")
    q = np.zeros(ctrl.nq)
    ctrl.step(q, {"f": [1.0, 0, 0], "go": [0]}, dt=0.01)
    assert ctrl.phase == "a" and ctrl.status == StepStatus.OPTIMAL and ctrl.violations() == []
    ctrl.step(q, {"f": [1.0, 0, 0], "go": [1]}, dt=0.01)      # b's fixture, far away, on from this tick
    assert ctrl.phase == "b" and ctrl.status & StepStatus.LEAST_VIOLATION
    assert ctrl.violations() and {v.label.phase for v in ctrl.violations()} == {"b"}


def test_the_machine_table_follows_dependencies_and_inline_leaves(tmp_path):
    path = tmp_path / "t.vf"
    path.write_text("""\
task t
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
input go : button
param entry : point = [10, 5, 285]
monitor both = near and pressed for 30 ms
monitor near = distance(tip, entry) < 1 mm
monitor pressed = go
monitor long = elapsed > 2 s
monitor quiet = unchanged(f) > 40 ms
monitor stuck = least_violation for 100 ms
phase a initial { minimize track(tip, f, gain = 1 mm/s/N) }
phase b { }
phase c final { }
transition a -> b when both
transition b -> c when long or quiet or stuck or norm(f) >= 3 N
""")
    task = vfdsl.load(path)
    ctrl = vfdsl.compile(task, backend="interpreted")
    ctx = ctrl.assembled.context
    table, named = machine_table(task, monitor_values(task, ctx), ctx.input_offsets)
    monitors = table.monitors
    assert monitors[named["both"]].kind == pm.LOGIC and monitors[named["both"]].hold == pytest.approx(0.03)
    assert named["near"] < named["both"] and named["pressed"] < named["both"]
    assert monitors[named["long"]] == pm.Monitor(pm.ELAPSED, op=pm.GT, threshold=2.0)
    assert monitors[named["quiet"]] == pm.Monitor(pm.UNCHANGED, watch=0, op=pm.GT, threshold=0.04)
    assert monitors[named["stuck"]].kind == pm.LEAST_VIOLATION
    assert table.watched == ((0, 3),) and table.raw_size == 3     # near, pressed, the guard's norm(f) >= 3 N
    guard = table.transitions[1].guard
    inline = monitors[guard[-2]]
    assert inline.kind == pm.COMPARE and inline.hold == 0 and guard[-1] == pm.OR
    q = np.zeros(ctrl.nq)
    ctrl.step(q, {"f": [0, 0, 4.0], "go": [1]}, dt=0.01)
    raw = ctrl._procedure.raw
    assert raw[inline.raw] == pytest.approx(1.0)                   # |f| - 3 N
    assert raw[monitors[named["pressed"]].raw] == pytest.approx(0.5)
    assert ctrl.monitors["pressed"] and not ctrl.monitors["both"]    # `for 30 ms`: not at the first 10 ms tick
    ctrl.step(q, {"f": [0, 0, 4.0], "go": [1]}, dt=0.01)
    ctrl.step(q, {"f": [0, 0, 4.0], "go": [1]}, dt=0.01)
    assert ctrl.monitors["near"] is False and ctrl.phase == "a"    # q = 0 is far from the entry


def test_a_task_without_phases_is_unchanged():
    task = vfdsl.load(REPO / "tasks" / "paper_b_virtual_rcm.vf")
    ctrl = vfdsl.compile(task, backend="interpreted")
    assert (ctrl.phase, ctrl.monitors, ctrl.events) == (None, {}, ())
    assert tuple(ctrl.assembled.function.name_in()) == tick_buffers.DATA_ARGUMENTS
    assert ctrl.assembled.context.activity.numel() == 0
    assert all(label.phase is None and " in phase " not in str(label) for label in ctrl.row_labels)
    ctrl.reset()
    assert ctrl.phase is None


def test_auto_runs_a_procedure_natively(task):
    assert vfdsl.compile(task, backend="auto").backend == "native"     # tests/test_procedure_native.py


def test_a_soft_fixture_of_an_idle_phase_weighs_nothing_and_is_not_reported(tmp_path):
    path = far_phase_task(tmp_path, "soft", " soft weight 10")
    task = vfdsl.load(path)
    ctrl = vfdsl.compile(task, backend="interpreted")
    q = np.zeros(ctrl.nq)
    ctrl.step(q, {"f": [1.0, 0, 0], "go": [0]}, dt=0.01)
    assert ctrl.phase == "a"
    slack = ctrl.assembled.nq                           # the one slack: b's stays_at, far from the tip
    P = ctrl.problem(q, {"f": [1.0, 0, 0], "go": [0]}, dt=0.01).P
    assert P[slack, slack] < 1e-8                       # only the Hessian's floor: b weighs 0
    assert ctrl._runner.x[slack] > 1e-3 and ctrl.violations() == []
    ctrl.step(q, {"f": [1.0, 0, 0], "go": [1]}, dt=0.01)
    assert ctrl.phase == "b" and ctrl.events[0].target == "b"
    assert [v.label.phase for v in ctrl.violations()] == ["b"]      # b weighs: far off, reported
    assert ctrl.problem(q, {"f": [1.0, 0, 0], "go": [1]}, dt=0.01).P[slack, slack] > 1.0



def test_a_frame_pose_is_captured_as_origin_then_roll_pitch_yaw(tmp_path):
    """`capture s0 = tip.pose` holds the tip's pose at the tick its phase is entered: the origin, then the roll,
    pitch, yaw whose rotation is the tip's (Pinocchio, 1e-12), on both paths alike."""
    from vfdsl.compiler.geometry import rotation
    from vfdsl.kinematics import Robot
    path = tmp_path / "pose_capture.vf"
    path.write_text('task pose_capture\nunits mm, deg\nrobot psm = urdf "psm6"\nframe tip = psm.link("tool_tip")\n'
                    "input f : force\ninput go : button\nmonitor pressed = go\n"
                    "phase free initial { minimize track(tip, f, gain = 2 mm/s/N) }\n"
                    "phase held final {\n    capture s0 = tip.pose\n    minimize damping()\n}\n"
                    "transition free -> held when pressed\n")
    (tmp_path / "pose_capture.yaml").write_text("start: [0.2, -0.1, 100 mm, 0.3, 0.2, -0.4]\nperiod: 1 ms\n")
    task = vfdsl.load(path)
    robot = Robot.load("psm6")
    captured = {}
    for backend in ("interpreted", "native"):
        ctrl = vfdsl.compile(task, backend=backend)
        q = np.array(task.start, dtype=float)
        for k in range(30):
            if k == 20:
                entered = q.copy()          # the transition's tick: its captures are taken from this q
            q = q + ctrl.step(q, {"f": [1.0, 2.0, 0.0], "go": [1.0 if k == 20 else 0.0]}, dt=DT)
        assert ctrl.phase == "held"
        captured[backend] = s0 = ctrl.captures["s0"]
        p, R = robot.frame_pose(entered, "tool_tip")
        np.testing.assert_allclose(s0[:3], p, rtol=0, atol=1e-12)
        np.testing.assert_allclose(rotation(s0[3:]), R, rtol=0, atol=1e-12)
    assert np.abs(captured["interpreted"] - captured["native"]).max() < 1e-12


CAPTURED_DIRECTION = """task captured
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
input go : button
monitor pressed = go
minimize damping() weight 1e-6
require joint_limits()
require joint_speed()
phase first initial {
    capture a = tip.position
    minimize track(tip, f, gain = 2 mm/s/N)
}
phase second {
    capture b = tip.position
    minimize track(tip, f, gain = 2 mm/s/N)
    require tip keeps_direction(normalize(b - a)) within 2 deg
}
transition first -> second when pressed
"""


@pytest.mark.parametrize("backend", ["native", "interpreted"])
def test_a_direction_from_captures_that_coincide_holds_the_tool_and_says_so(tmp_path, backend):
    """`normalize(b - a)` of two captures of the tip's position: when the tip did not move between them it has no
    direction. Before, its rows' bounds were 0 / 0 guarded to 0, the fixture silently off (OPTIMAL, nothing named);
    now its rows are undefined: the tick holds still (LEAST_VIOLATION | FALLBACK, dq = 0, the box holding 0) and
    violations() names every row of the fixture as undefined. Moved between the captures, the fixture acts."""
    (tmp_path / "captured.vf").write_text(CAPTURED_DIRECTION)
    (tmp_path / "captured.yaml").write_text("units: mm, deg\nperiod: 10 ms\nstart: [0, 0, 0, 0, 0, 0, 20]\n")
    task = vfdsl.load(tmp_path / "captured.vf")
    ctrl = vfdsl.compile(task, backend=backend)
    for push, undefined in (([0.0, 0.0, 0.0], True), ([3.0, 0.0, 0.0], False)):
        ctrl.reset()
        q = np.array(task.start, dtype=float)
        for k in range(40):
            dq = ctrl.step(q, {"f": push, "go": [1.0 if k >= 30 else 0.0]}, dt=0.01)
            assert np.all(np.isfinite(dq))
            q = q + dq
        assert ctrl.phase == "second"
        named = [v for v in ctrl.violations() if v.label.primitive == "keeps_direction"]
        if undefined:
            assert ctrl.status == StepStatus.LEAST_VIOLATION | StepStatus.FALLBACK
            assert np.all(dq == 0) and len(named) == 8 and all(v.amount == np.inf for v in named)
            assert "undefined" in str(named[0])
        else:
            assert not ctrl.status & StepStatus.FALLBACK and np.abs(dq).max() > 0
            assert all(np.isfinite(v.amount) for v in named)


@pytest.mark.parametrize("written", ["keeps_direction(normalize(a - a)) within 2 deg",
                                     "along(line(a, a)) within 0.5 mm"])
def test_a_direction_from_one_capture_minus_itself_is_refused(tmp_path, written):
    """`normalize(a - a)` is zero at every tick. CasADi folds a - a to 0 and the NaN that stands for "no direction" to a
    constant, which later folds on (nan / nan is 1): keeps_direction read the direction [1, 1, 1] / 1, and shr7 turned
    at its speed limit toward it, violated by 0.985 rad, not the documented hold-still. Refused when compiled, at the
    expression (E402), as a zero direction of params is when the task loads."""
    text = CAPTURED_DIRECTION.replace("keeps_direction(normalize(b - a)) within 2 deg", written)
    (tmp_path / "self.vf").write_text(text)
    with pytest.raises(VfError) as caught:
        vfdsl.compile(vfdsl.load(tmp_path / "self.vf"), backend="interpreted")
    assert caught.value.code == "E402" and "whatever the captures hold" in caught.value.message
    assert caught.value.pos.line == 18


AT_EQUALITY = """task at_equality
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input hand : force
param here : point = [0, 0, 280]
monitor idle = norm(hand) <= 0 N
monitor busy = norm(hand) > 0 N
monitor anywhere = distance(tip, here) >= 0 mm
monitor away = distance(tip, here) > 0 mm
monitor upright = angle(tip, [0, 0, 1]) <= 0 deg
minimize track(tip, hand, gain = 1 mm/s/N)
phase rest initial { }
phase done final { }
transition rest -> done when idle and anywhere and upright
"""


@pytest.mark.parametrize("backend", ["native", "interpreted"])
def test_a_non_strict_comparison_holds_at_equality(tmp_path, backend):
    """`<=` and `>=` hold where the measure equals the threshold, `<` and `>` do not. Before, both compiled to the
    same strict margin: `norm(hand) <= 0 N` never held with the hands exactly off, and `distance(tip, here) >= 0 mm`,
    which `vfdsl check` calls always true (VF955), never held with the tip on the point: the transition never fired."""
    (tmp_path / "eq.vf").write_text(AT_EQUALITY)
    (tmp_path / "eq.yaml").write_text("units: mm, deg\nperiod: 10 ms\nstart: [0, 0, 0, 0, 0, 0, 20]\n")
    task = vfdsl.load(tmp_path / "eq.vf")              # the tip at (0, 0, 280) mm, its axis along z
    ctrl = vfdsl.compile(task, backend=backend)
    ctrl.step(task.start, {"hand": [0.0, 0.0, 0.0]}, dt=0.01)
    assert ctrl.monitors == {"idle": True, "busy": False, "anywhere": True, "away": False, "upright": True}
    assert ctrl.phase == "done"
    ctrl.reset()
    ctrl.step(task.start, {"hand": [0.0, 0.0, 1e-3]}, dt=0.01)
    assert ctrl.monitors["idle"] is False and ctrl.monitors["busy"] is True and ctrl.phase == "rest"
