"""The Controller API: what it says about itself, run-time params, checked inputs, and safe steps."""

from __future__ import annotations

import re

import numpy as np
import pytest
from conftest import TASKS_DIR

import vfdsl
from vfdsl.export import export
from vfdsl.kinematics.robot import Robot
from vfdsl.runtime.qp import StepStatus


@pytest.fixture(scope="module")
def task_b():
    return vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf")


@pytest.fixture(scope="module")
def ctrl_b(task_b):
    return vfdsl.compile(task_b)


def test_controller_describes_itself(task_b, ctrl_b):
    assert ctrl_b.nq == 7
    assert ctrl_b.input_sizes == {"tau": 3}
    assert ctrl_b.param_names == ["pivot", "axis"]
    np.testing.assert_allclose(ctrl_b.param_defaults["pivot"].xyz, [0, 0, 0.29])
    assert ctrl_b.default_dt == pytest.approx(0.01)
    assert task_b.start.shape == (7,)


def test_task_a_describes_its_params():
    ctrl = vfdsl.compile(vfdsl.load(TASKS_DIR / "paper_a_follow_curve.vf"))
    assert ctrl.input_sizes == {"f": 3}
    assert ctrl.param_names == ["plate"]          # the curve's points are fixed; it moves with its pose


def test_idle_input_keeps_the_robot_still(task_b, ctrl_b):
    dq = ctrl_b.step(task_b.start, {"tau": np.zeros(3)})
    assert np.max(np.abs(dq)) < 1e-9
    assert ctrl_b.status == StepStatus.OPTIMAL and ctrl_b.violations() == []


def test_a_run_time_param_moves_the_constraint(task_b, ctrl_b):
    """Moving the pivot 0.1 mm sideways shifts the stays_at rows' bounds by u . shift (h = -eps + u . delta)."""
    base = ctrl_b.problem(task_b.start, {"tau": np.zeros(3)})
    moved = ctrl_b.problem(task_b.start, {"tau": np.zeros(3)}, params={"pivot": [1e-4, 0, 0.29]})
    rows = [i for i, label in enumerate(base.labels) if label.startswith("stays_at(tip)")]
    assert len(rows) == 6
    U = -base.A[rows, :7] @ np.linalg.pinv(Robot.load("shr7").frame_jacobian(task_b.start, "tool_tip")[:3])
    np.testing.assert_allclose(moved.lb[rows] - base.lb[rows], U @ np.array([-1e-4, 0, 0]), atol=1e-12)


def test_a_scalar_param_takes_a_number_in_every_form_and_a_too_large_one_is_said_so():
    """A 0-D array (np.asarray(0.005)) is a number: it was refused as 'a vector of 1 numbers'. An int too large for a
    float was said to hold NaN or inf ([inf])."""
    task = vfdsl.load(TASKS_DIR / "keep_out.vf")
    ctrl = vfdsl.compile(task)
    q, u = task.start, {d.name: np.zeros(d.size) for d in task.inputs}
    base = ctrl.problem(q, u, params={"margin": 0.004}).lb
    for value in (np.asarray(0.004), np.float64(0.004), [0.004], np.array([0.004])):
        np.testing.assert_array_equal(ctrl.problem(q, u, params={"margin": value}).lb, base)
    with pytest.raises(vfdsl.VfError, match="param 'margin' is a number too large for a float"):
        ctrl.step(q, u, params={"margin": 10 ** 400})


def test_pose_params_take_a_mapping():
    task = vfdsl.load(TASKS_DIR / "paper_a_follow_curve.vf")
    ctrl = vfdsl.compile(task)
    plate = {"translation": [0.001, 0, 0.25], "rpy": np.radians([4, -3, 20])}
    moved = ctrl.problem(task.start, {"f": np.zeros(3)}, params={"plate": plate})
    base = ctrl.problem(task.start, {"f": np.zeros(3)})
    assert not np.allclose(moved.lb, base.lb)


@pytest.mark.parametrize("call, message", [
    (lambda c, q: c.step(q, {"tau": [0, 0, np.nan]}), "NaN or inf"),
    (lambda c, q: c.step(q, {"tau": [0, 0, np.inf]}), "NaN or inf"),
    (lambda c, q: c.step(q, {"tau": [0, 0]}), "must have 3 numbers"),
    (lambda c, q: c.step(q, {"tau": [0.0]}), "must have 3 numbers"),            # no broadcasting
    (lambda c, q: c.step(q, {"tau": 0.0}), "must have 3 numbers"),
    (lambda c, q: c.step(q, {"tau": 1}), "must have 3 numbers (a list or array), got an int"),
    (lambda c, q: c.step(0.1, {"tau": [0, 0, 0]}), "q (joint coordinates) must have 7 numbers"),
    (lambda c, q: c.step(q, [0, 0, 0]), "inputs must be a mapping"),
    (lambda c, q: c.step(q, {"torque": [0, 0, 0]}), "unknown input 'torque'"),
    (lambda c, q: c.step(q, {}), "missing input 'tau'"),
    (lambda c, q: c.step(q[:6], {"tau": [0, 0, 0]}), "q (joint coordinates) must have 7 numbers"),
    (lambda c, q: c.step(np.full(7, np.nan), {"tau": [0, 0, 0]}), "NaN or inf"),
    (lambda c, q: c.step(q, {"tau": [0, 0, 0]}, params={"pivto": [0, 0, 0]}), "unknown run-time param 'pivto'"),
    (lambda c, q: c.step(q, {"tau": [0, 0, 0]}, params={"pivot": [0, 0]}), "must have 3 numbers"),
    (lambda c, q: c.step(q, {"tau": [0, 0, 0]}, dt=-0.01), "dt must be a positive number"),
    (lambda c, q: c.step(q, {"tau": [0, 0, 0]}, dt=float("nan")), "dt must be a positive number"),
    (lambda c, q: c.step(q, {"tau": [0, 0, 0]}, dt=10 ** 400), "dt (the control period, s) is a number too large for "
                                                                 "a float"),           # was 'got inf'
    (lambda c, q: c.step(q, {"tau": np.zeros(())}), "must be a vector of 3 numbers, got an array of shape ()"),
    (lambda c, q: c.step(q, {"tau": [0, 0, 0]}, params={"pivot": np.zeros((3, 3))}),
     "must be a vector of 3 numbers, got an array of shape (3, 3)"),
])
def test_bad_inputs_raise_before_solving(task_b, ctrl_b, call, message):
    with pytest.raises(vfdsl.VfError) as info:
        call(ctrl_b, task_b.start)
    assert message in info.value.message
    if "pivto" in message:
        assert "pivot" in info.value.hint


def test_pushed_out_of_tolerance_returns_a_bounded_move_back(task_b, ctrl_b):
    """The tip pushed 2 mm from the pivot: the 0.2 mm-per-tick stage speed forbids a one-tick return, so
    the hard rows conflict. The step stays finite and within the joint bounds, reduces the pivot error,
    and names the violated rows with their source lines."""
    robot = Robot.load("shr7")
    q = task_b.start.copy()
    q[0] += 0.002
    p0, _ = robot.frame_pose(q, "tool_tip")
    dq = ctrl_b.step(q, {"tau": np.zeros(3)})
    assert np.all(np.isfinite(dq))
    assert ctrl_b.status & StepStatus.LEAST_VIOLATION
    speed = robot.velocity_limit * 0.01
    assert np.all(np.abs(dq) <= speed + 1e-10)             # DAQP primal tolerance is 1e-11
    p1, _ = robot.frame_pose(q + dq, "tool_tip")
    pivot = np.array([0, 0, 0.29])
    assert np.linalg.norm(p1 - pivot) < np.linalg.norm(p0 - pivot) - 1e-4
    violated = ctrl_b.violations()
    assert violated and all(v.amount > 0 for v in violated)
    assert any(v.label.primitive == "stays_at" and v.label.span.line == 10 and
               v.label.via[0].line == 18 for v in violated)
    assert "fixtures.vf:10" in str(violated[0]) or "fixtures.vf:11" in str(violated[0])


def test_repeated_steps_walk_back_into_the_fixture(task_b, ctrl_b):
    robot = Robot.load("shr7")
    q = task_b.start.copy()
    q[0] += 0.002
    for _ in range(40):
        q = q + ctrl_b.step(q, {"tau": np.zeros(3)})
    p, _ = robot.frame_pose(q, "tool_tip")
    assert np.linalg.norm(p - [0, 0, 0.29]) <= np.sqrt(3) * 1e-6 + 1e-7
    assert ctrl_b.status == StepStatus.OPTIMAL


def test_params_of_one_tick_do_not_stick(task_b, ctrl_b):
    """A param passed for one tick applies to that tick only; the next tick uses the defaults again."""
    tau = {"tau": [0.0, 0.0, 0.01]}
    default = ctrl_b.step(task_b.start, tau)
    moved = ctrl_b.step(task_b.start, tau, params={"pivot": [1e-4, 0, 0.29]})
    assert not np.allclose(moved, default)
    # equal up to the last bits a warm-started solve may differ in after another tick's working set
    np.testing.assert_allclose(ctrl_b.step(task_b.start, tau), default, rtol=1e-12, atol=1e-18)


def test_step_result_is_a_copy(task_b, ctrl_b):
    first = ctrl_b.step(task_b.start, {"tau": [0.0, 0.0, 0.01]})
    kept = first.copy()
    ctrl_b.step(task_b.start, {"tau": [0.0, 0.0, -0.01]})
    np.testing.assert_array_equal(first, kept)


@pytest.mark.parametrize("entry", ["check", "compile", "export"])
@pytest.mark.parametrize("given", [str(TASKS_DIR / "paper_b_virtual_rcm.vf"), TASKS_DIR / "paper_b_virtual_rcm.vf", None])
def test_entry_points_refuse_what_is_not_a_loaded_task(tmp_path, entry, given):
    # A path given where the task belongs raised an AttributeError from deep inside.
    calls = {"check": lambda: vfdsl.check(given), "compile": lambda: vfdsl.compile(given),
             "export": lambda: export(given, tmp_path / "out")}
    with pytest.raises(vfdsl.VfError, match=rf"{entry}\(\) takes a task loaded by vfdsl.load") as info:
        calls[entry]()
    assert given is None or "vfdsl.load(" in info.value.hint


@pytest.mark.parametrize("given", [None, 3, b"tasks/paper_b_virtual_rcm.vf"])
def test_load_refuses_what_is_not_a_path(given):
    with pytest.raises(vfdsl.VfError, match="load\\(\\) takes the path of a .vf task file"):
        vfdsl.load(given)


@pytest.mark.parametrize(("given", "entry"), [(given, entry) for given in (None, 3, b"build", "")
                                              for entry in ("load", "compile", "export", "export cache")
                                              if not (given is None and entry in ("compile", "export cache"))])
def test_the_api_refuses_a_path_that_is_not_one(tmp_path, monkeypatch, entry, given):
    """Every path of the Python API is checked as the command line's: a number or None raised TypeError from deep
    inside (compile(task, cache_dir=3), export(task, None)); an empty cache_dir was taken as not given, an empty
    path to load as the current directory ('cannot read file .'). (cache_dir=None is the default cache.)"""
    monkeypatch.chdir(tmp_path)
    task = vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf")
    calls = {"load": lambda: vfdsl.load(given), "compile": lambda: vfdsl.compile(task, cache_dir=given),
             "export": lambda: export(task, given), "export cache": lambda: export(task, "out", cache_dir=given)}
    caller = entry.split()[0]
    said = f"{caller}(): an empty path names no" if given == "" else f"{caller}() takes the path of a"
    with pytest.raises(vfdsl.VfError, match=re.escape(said)):
        calls[entry]()
    assert list(tmp_path.iterdir()) == []
