"""The runtime off the happy path: threads, run-time values, extreme numbers, fallbacks, observability."""

from __future__ import annotations

import ctypes
import gc
import subprocess
import sys
import threading

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import vfdsl
from vfdsl import pipeline
from vfdsl.errors import VfError
from vfdsl.kinematics.robot import Robot
from vfdsl.compiler.geometry import homogeneous
from vfdsl.runtime.qp import StepStatus
from conftest import TASKS_DIR

EXAMPLES = sorted(p.name for p in TASKS_DIR.glob("*.vf"))


@pytest.fixture(scope="module")
def task_b():
    return vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf")


def _walk(task, ticks: int, seed: int = 0):
    """(q, inputs) of a seeded random walk near the start: feasible and least-violation ticks alike."""
    robot = Robot.load(task.robots[0].urdf)
    rng = np.random.default_rng(seed)
    out = []
    for k in range(ticks):
        spread = 1e-3 if (k // 50) % 2 else 1e-7
        q = np.clip(task.start + rng.normal(scale=spread, size=robot.nq), robot.lower, robot.upper)
        out.append((q, {d.name: rng.normal(scale=0.02, size=d.size) for d in task.inputs}))
    return out


# ------------------------------------------------------------------------------------------- threads
def test_controllers_of_one_task_in_eight_threads_equal_single_thread_bit_for_bit(task_b):
    walk = _walk(task_b, 10_000)
    alone = vfdsl.compile(task_b)
    assert alone.backend == "native"
    expected = np.array([alone.step(q, u) for q, u in walk])
    statuses = set()
    controllers = [vfdsl.compile(task_b) for _ in range(8)]
    results: list = [None] * 8

    def run(k: int) -> None:
        results[k] = np.array([controllers[k].step(q, u) for q, u in walk])
        statuses.add(int(controllers[k].status))

    threads = [threading.Thread(target=run, args=(k,)) for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k in range(8):
        assert np.array_equal(results[k], expected), f"thread {k} differs"
    assert len({c._runner.stepper.slot for c in controllers}) == 8      # each its own memory slot


@pytest.mark.parametrize("backend", ["native", "interpreted"])
def test_one_controller_from_two_threads_is_serialised(task_b, backend):
    walk = _walk(task_b, 2_000 if backend == "native" else 200, seed=1)
    reference = vfdsl.compile(task_b, backend=backend)
    expected = [reference.step(q, u) for q, u in walk]
    shared = vfdsl.compile(task_b, backend=backend)
    errors, got = [], [[], []]

    def run(k: int) -> None:
        try:
            got[k] = [shared.step(q, u) for q, u in walk]
        except Exception as exc:  # noqa: BLE001 - any exception is the failure under test
            errors.append(exc)

    threads = [threading.Thread(target=run, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    # Every call got its own answer: another tick's answer is off by 4.6e-3 rad (the median change between
    # consecutive answers of this walk). The warm start differs from the reference's: a lower level is solved
    # within its band, and a warm start from another history may land elsewhere in it: up to 1.5e-6 rad seen.
    for k in range(2):
        np.testing.assert_allclose(np.array(got[k]), np.array(expected), atol=1e-5)


@pytest.mark.parametrize("backend", ["native", "interpreted"])
def test_violations_read_from_another_thread_are_one_ticks(task_b, backend):
    """One thread ticks alternately at a state with five violated rows and at one with none; another reads
    violations() all along: every read is one tick's, never rows of one with amounts or rows of the other (before
    the read took the tick's lock: 57 mixed reads of 171,775 in 5 s on the generated path, 22 interpreted)."""
    ctrl = vfdsl.compile(task_b, backend=backend)
    far = {"pivot": [0.05, 0, 0.29], "axis": [1.0, 0, 0.2]}
    ctrl.step(task_b.start, TAU, far)
    off = [(str(v), v.amount) for v in ctrl.violations()]
    ctrl.step(task_b.start, TAU)
    assert len(off) == 5 and not ctrl.violations()
    done, mixed, reads = threading.Event(), [], []

    def tick() -> None:
        while not done.is_set():
            ctrl.step(task_b.start, TAU, far)
            ctrl.step(task_b.start, TAU)

    def read() -> None:
        while not done.is_set():
            got = [(str(v), v.amount) for v in ctrl.violations()]
            reads.append(1)
            if got and got != off:
                mixed.append(got)

    threads = [threading.Thread(target=tick), threading.Thread(target=read)]
    for t in threads:
        t.start()
    done.wait(2.0)
    done.set()
    for t in threads:
        t.join()
    assert len(reads) > 1000 and not mixed, (len(reads), mixed[:2])


@pytest.mark.parametrize("example", ["procedures/needle_procedure.vf", "teleop/teleop_guide_line.vf"])
def test_reset_waits_for_a_tick_in_another_thread(example, monkeypatch):
    """reset() takes the ticks' locks (the procedure's, the teleoperation readout's): a tick in another thread runs
    before or after it, never on a machine or a readout half reset (the interpreted path's reset did not)."""
    ctrl = vfdsl.compile(vfdsl.load(TASKS_DIR / example), backend="interpreted")
    ctrl.step(ctrl.task.start, {d.name: np.zeros(d.size) for d in ctrl.task.inputs})
    held = []
    for part, lock in ((ctrl._procedure, ctrl._procedure and ctrl._procedure.lock),
                       (ctrl._teleoperation, ctrl._teleop_lock)):
        if part is not None:
            reset = part.reset
            monkeypatch.setattr(part, "reset", lambda reset=reset, lock=lock: (held.append(lock.locked()), reset()))
    ctrl.reset()
    assert held and all(held), held


def test_a_dropped_controller_frees_its_memory_slot_at_once(task_b):
    """step is the task's C method, whose detailed checks do not hold the controller: no reference cycle, so a
    controller no longer referenced gives its memory slot back at once (not at the next garbage collection); a
    kept ``step`` keeps its slot and still explains a bad value."""
    gc.disable()
    try:
        first = vfdsl.compile(task_b)
        slot = first._runner.stepper.slot
        del first
        second = vfdsl.compile(task_b)
        assert second._runner.stepper.slot == slot
        step = vfdsl.compile(task_b).step
        kept = step.__self__.slot
        del second
        assert vfdsl.compile(task_b)._runner.stepper.slot == slot      # (and freed again at once)
        assert vfdsl.compile(task_b)._runner.stepper.slot != kept
        assert np.all(np.isfinite(step(task_b.start, {"tau": [0.0, 0.0, 0.01]})))
        with pytest.raises(VfError, match="tau"):
            step(task_b.start, {"tau": [0.0, float("nan"), 0.01]})
    finally:
        gc.enable()


def test_keywords_and_positions_give_the_same_tick(task_b):
    ctrl = vfdsl.compile(task_b)
    u = {"tau": [0.0, 0.002, 0.01]}
    by_position = ctrl.step(task_b.start, u, None, 0.01)
    ctrl_2 = vfdsl.compile(task_b)
    assert np.array_equal(ctrl_2.step(q=task_b.start, inputs=u, dt=0.01), by_position)
    for wrong in (lambda: ctrl.step(task_b.start, u, None, 0.01, 1), lambda: ctrl.step(),
                  lambda: ctrl.step(task_b.start, u, dtt=0.01)):
        with pytest.raises(TypeError, match=r"Controller\.step\(\)"):     # (Python's words, on the call made)
            wrong()


def test_the_c_entry_point_refuses_a_slot_it_did_not_hand_out(task_b, tmp_path):
    _, library = pipeline.build(task_b, backend="native", cache_dir=tmp_path)
    so = ctypes.CDLL(str(library.so_path))
    prefix = pipeline.symbol_prefix(task_b)
    entry = getattr(so, prefix)
    entry.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_int]
    assert entry(None, None, None, None, 5) == 2          # not checked out: refused, nothing touched
    assert entry(None, None, None, None, -1) == 2
    slot = getattr(so, f"{prefix}_checkout")()
    assert slot >= 0
    getattr(so, f"{prefix}_release")(slot)
    header = library.h_path.read_text()
    assert f"{prefix}_checkout()" in header and "returns 3" in header


# ------------------------------------------------------------------------------------ run-time values
@pytest.fixture(scope="module")
def ctrl_b(task_b):
    return vfdsl.compile(task_b)


TAU = {"tau": [0.0, 0.0, 0.01]}


@pytest.mark.parametrize("call, message", [
    (lambda c, q: c.step(q, TAU, params={"axis": [0, 0, 0]}), "zero direction"),
    (lambda c, q: c.step(q, TAU, params={"axis": [1e-150, 0, 0]}), "zero direction"),
    (lambda c, q: c.step(q, TAU, params={"axis": np.array([0.0, 1e-300, 0])}), "zero direction"),
    (lambda c, q: c.step(q, {"tau": "123"}), "input 'tau' must have 3 numbers"),
    (lambda c, q: c.step(q, {"tau": ["1", 2, 3]}), "item 0 is the string"),
    (lambda c, q: c.step(q, {"tau": [True, 0, 0]}), "item 0 is the boolean"),
    (lambda c, q: c.step(q, {"tau": [1j, 0, 0]}), "complex"),
    (lambda c, q: c.step(q, {"tau": [None, 0, 0]}), "item 0 is a NoneType"),
    (lambda c, q: c.step(q, {"tau": [[0, 0, 0]]}), "item 0 is a list"),
    (lambda c, q: c.step(q, {"tau": np.zeros(3, dtype=complex)}), "real numbers"),
    (lambda c, q: c.step(q, {"tau": np.array(["1", "2", "3"])}), "real numbers"),
    (lambda c, q: c.step(q, {"tau": [10**400, 0, 0]}), "too large"),
    (lambda c, q: c.step(q.astype(complex), TAU), "real numbers"),
    (lambda c, q: c.step(list(q[:6]) + [1j], TAU), "complex"),
    (lambda c, q: c.step(q, TAU, dt=[0.01]), "dt (the control period, s) must be a real number"),
    (lambda c, q: c.step(q, TAU, dt="fast"), "must be a real number"),
    (lambda c, q: c.step(q, TAU, dt=True), "must be a real number"),
    (lambda c, q: c.step(q, TAU, dt=0.0), "dt must be a positive number"),
    (lambda c, q: c.step(q, TAU, dt=5.0), "is far from the task's period (10 ms"),
    (lambda c, q: c.step(q, TAU, params={"pivot": ["0", 0, 0.29]}), "param 'pivot'"),
    (lambda c, q: c.step(q, TAU, params={"pivot": {"x": 1}}), "param 'pivot' is a point"),
    (lambda c, q: c.step(q, TAU, params=[1, 2]), "params must be a mapping"),
    (lambda c, q: c.step(q + np.r_[0, 0, 0, 10.0, 0, 0, 0], TAU), "far outside joint"),
    (lambda c, q: c.step(np.degrees(q) + 50, TAU), "far outside joint"),
])
def test_bad_run_time_values_raise_vferror_naming_them(task_b, ctrl_b, call, message):
    with pytest.raises(VfError, match=None) as info:
        call(ctrl_b, np.array(task_b.start))
    assert message in info.value.message


def test_a_huge_direction_is_normalized_not_overflowed(task_b, ctrl_b):
    axis = np.array([0, -0.2, 1.0])
    a = ctrl_b.step(task_b.start, TAU, params={"axis": axis / np.linalg.norm(axis)})
    b = ctrl_b.step(task_b.start, TAU, params={"axis": axis * 1e160})
    np.testing.assert_allclose(a, b, atol=1e-15)
    assert ctrl_b.status == StepStatus.OPTIMAL


def test_fast_and_checked_paths_take_every_real_container_alike(task_b, ctrl_b):
    q = np.array(task_b.start)
    expected = ctrl_b.step(q, TAU)
    for q_form in (list(q), tuple(q), q.reshape(-1, 1), [np.float64(x) for x in q]):
        np.testing.assert_array_equal(ctrl_b.step(q_form, TAU), expected)
    for tau in ([0, 0, 0.01], (0, 0, 0.01), np.array([0, 0, 0.01]), np.array([0, 0, 0.01], dtype=np.float32)):
        np.testing.assert_allclose(ctrl_b.step(q, {"tau": tau}), expected, atol=1e-12)
    np.testing.assert_array_equal(ctrl_b.step(q, TAU, dt=np.float64(0.01)), ctrl_b.step(q, TAU, dt=0.01))


RANGED = """task ranged
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input tau : torque
param pivot : point = [0, 0, 290]
param axis : direction = [0, -0.2, 1]
param gamma : angle = 15 deg
minimize track(tip, tau, angular_gain = 20 deg/s/Nmm)
minimize damping() weight 1e-6
require tip stays_at(pivot) within 0.001 resolution 4x4
require tip cone(axis, gamma) within 0.001 rad resolution 8
require joint_limits()
require joint_speed()
"""


def test_a_scalar_param_meets_the_range_of_the_argument_it_feeds(tmp_path, task_b):
    (tmp_path / "ranged.vf").write_text(RANGED)
    (tmp_path / "ranged.yaml").write_text((TASKS_DIR / "paper_b_virtual_rcm.yaml").read_text())
    task = vfdsl.load(tmp_path / "ranged.vf")
    ctrl = vfdsl.compile(task, backend="interpreted")
    q = task_b.start
    ctrl.step(q, TAU, params={"gamma": np.radians(20)}, dt=0.01)          # a near miss: fine
    for bad in (np.radians(95), 0.0, -0.1, np.radians(90)):
        with pytest.raises(VfError, match="param 'gamma'"):
            ctrl.step(q, TAU, params={"gamma": bad}, dt=0.01)


# ------------------------------------------------------------------------------- extreme numbers
def _in_bounds(ctrl, q, inputs, dq, dt=None) -> bool:
    qp = ctrl.problem(q, inputs, dt=dt)
    lb, ub = qp.lb[:ctrl.nq], qp.ub[:ctrl.nq]
    lo, hi = np.minimum(lb, ub), np.maximum(lb, ub)          # crossed bounds are pinned inside [lo, hi]
    return bool(np.all(dq >= lo - 1e-12) and np.all(dq <= hi + 1e-12))


_controllers: dict = {}


def _controller(name: str, backend: str):
    if (name, backend) not in _controllers:
        task = vfdsl.load(TASKS_DIR / name)
        _controllers[name, backend] = (task, vfdsl.compile(task, backend=backend))
    return _controllers[name, backend]


magnitudes = st.one_of(st.floats(min_value=1e-300, max_value=1e300), st.sampled_from([3.4e38, 1.7e308]),
                       st.just(0.0), st.sampled_from([float("nan"), float("inf")]))
signed = st.builds(lambda m, s: m * s, magnitudes, st.sampled_from([-1.0, 1.0]))


@pytest.mark.parametrize("backend", ["native", "interpreted"])
@pytest.mark.parametrize("name", EXAMPLES)
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(values=st.lists(signed, min_size=6, max_size=6))
def test_any_input_gives_finite_dq_within_bounds_or_a_vferror(name, backend, values):
    task, ctrl = _controller(name, backend)
    inputs = {d.name: values[:d.size] for d in task.inputs}
    finite = all(np.isfinite(v) for d in task.inputs for v in inputs[d.name])
    if not finite:
        with pytest.raises(VfError, match="NaN or inf"):
            ctrl.step(task.start, inputs)
        return
    dq = ctrl.step(task.start, inputs)
    assert np.all(np.isfinite(dq))
    assert _in_bounds(ctrl, task.start, inputs, dq)


ONLY_BOUNDS = """task only_bounds
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
minimize track(tip, f, gain = 1 mm/s/N)
minimize damping() weight 1e-6
require joint_limits()
require joint_speed()
"""


@pytest.mark.parametrize("backend", ["native", "interpreted"])
def test_a_float32_max_push_on_a_bounds_only_task_saturates_along_the_push(tmp_path, task_b, backend):
    (tmp_path / "only_bounds.vf").write_text(ONLY_BOUNDS)
    task = vfdsl.load(tmp_path / "only_bounds.vf")
    ctrl = vfdsl.compile(task, backend=backend)
    q = task_b.start
    J = Robot.load("shr7").frame_jacobian(q, "tool_tip")[:3]
    for push in ([1.0, 0, 0], [0, -1.0, 0], [0.3, 0.2, -1.0]):
        small = ctrl.step(q, {"f": push}, dt=0.01)
        huge = ctrl.step(q, {"f": np.array(push) * 3.4e38}, dt=0.01)
        assert np.all(np.isfinite(huge)) and ctrl.status == StepStatus.OPTIMAL
        assert _in_bounds(ctrl, q, {"f": push}, huge, dt=0.01)
        assert (J @ huge) @ np.array(push) > 0 and (J @ huge) @ (J @ small) > 0   # with the push, not against


@pytest.mark.parametrize("backend", ["native", "interpreted"])
def test_an_unreachable_pivot_falls_back_safely_and_names_the_rows(task_b, backend):
    ctrl = vfdsl.compile(task_b, backend=backend)
    for pivot in ([0, 0, 1.8], [-1.5, 1.5, 0.29], [0.05, 0, 0.29]):       # plausible (within 1.86 m), not reachable
        dq = ctrl.step(task_b.start, TAU, params={"pivot": pivot})
        assert np.all(np.isfinite(dq)) and _in_bounds(ctrl, task_b.start, TAU, dq)
        assert ctrl.status & StepStatus.LEAST_VIOLATION
        assert any(v.label.primitive == "stays_at" and v.unit == "m" for v in ctrl.violations())
    for pivot in ([0, 0, 1e300], [1e154, -1e154, 0.29], [0, 0, 1.9]):      # beyond: refused before anything moves
        with pytest.raises(VfError, match="param 'pivot' is .* m: beyond 1.86 m, the largest coordinate plausible"):
            ctrl.step(task_b.start, TAU, params={"pivot": pivot})


# ---------------------------------------------------------------------------------- observability
SOFT = """task soft_line
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
param guide : line = line([0, 0, 290], [0, 0, 1])
minimize track(tip, f, gain = 20 mm/s/N)
minimize damping() weight 1e-6
require tip along(guide) within 0.01 soft weight 0.01
require joint_limits()
require joint_speed()
"""


def test_violations_report_how_far_a_soft_constraint_is_off(tmp_path, task_b):
    (tmp_path / "soft.vf").write_text(SOFT)
    task = vfdsl.load(tmp_path / "soft.vf")
    ctrl = vfdsl.compile(task)
    robot = Robot.load("shr7")
    q = np.array(task_b.start)
    for _ in range(200):                                # push sideways: the soft line gives way
        q = q + ctrl.step(q, {"f": [5.0, 0, 0]}, dt=0.01)
    found = [v for v in ctrl.violations() if v.label.soft]
    assert found and found[0].unit == "m" and found[0].label.primitive == "along"
    p, _ = robot.frame_pose(q, "tool_tip")
    distance = np.hypot(p[0], p[1])                     # from the guide line x = y = 0
    assert found[0].amount > 1e-4 and distance > 1e-3
    assert found[0].amount <= distance + 1e-6


def test_frames_are_what_pinocchio_says(task_b, ctrl_b):
    robot = Robot.load("shr7")
    rng = np.random.default_rng(5)
    for _ in range(5):
        q = np.clip(task_b.start + rng.normal(scale=0.05, size=7), robot.lower, robot.upper)
        frames = ctrl_b.frames(q)
        assert set(frames) == {f.name for f in task_b.frames}
        for decl in task_b.frames:
            p, R = robot.frame_pose(q, decl.link, np.array(homogeneous(decl.offset, decl.rpy)))
            np.testing.assert_allclose(frames[decl.name].position, p, atol=1e-12)
            np.testing.assert_allclose(frames[decl.name].rotation, R, atol=1e-12)
            np.testing.assert_allclose(frames[decl.name].tool_axis, R @ decl.tool_axis, atol=1e-12)


# ------------------------------------------------------------------- values that only look like numbers
class _Lies(float):
    """A float whose __float__ says another number: the value is what float() gives, on both paths."""

    def __float__(self):
        return 0.05


class _Raises(float):
    def __float__(self):
        raise ZeroDivisionError("no value")


@pytest.mark.parametrize("backend", ["native", "interpreted"])
def test_values_that_only_look_like_numbers_are_read_alike_on_both_paths(task_b, backend):
    """Masked arrays (a masked entry is a missing value: refused, whatever lies under the mask), float subclasses
    (read through their own __float__ on both paths: the C fast path leaves them to the Python checks) and numbers
    whose conversion fails (a VfError, not the user type's exception)."""
    ctrl = vfdsl.compile(task_b, backend=backend)
    q0, u = np.array(task_b.start), {"tau": [0.0, 0.0, 0.02]}
    masked = [lambda: ctrl.step(np.ma.array(np.r_[q0[:6], np.nan], mask=[0] * 6 + [1]), u),
              lambda: ctrl.step(np.ma.array(np.r_[0.05, q0[1:]], mask=[1] + [0] * 6), u),     # a sound value under it
              lambda: ctrl.step(q0, {"tau": np.ma.array([np.nan, 0, 0.02], mask=[1, 0, 0])}),
              lambda: ctrl.step(q0, u, {"pivot": np.ma.array([np.nan, 0, 0.29], mask=[1, 0, 0])})]
    for call in masked:
        with pytest.raises(VfError, match="masked"):
            call()
    assert np.array_equal(ctrl.step(np.ma.array(q0), u), vfdsl.compile(task_b, backend=backend).step(q0, u))
    lied = ctrl.step([_Lies(0.0), *q0[1:]], u)
    np.testing.assert_allclose(lied, vfdsl.compile(task_b, backend=backend).step([0.05, *q0[1:]], u), atol=1e-12)
    for call in (lambda: ctrl.step([_Raises(0.0), *q0[1:]], u), lambda: ctrl.step(q0, u, None, _Raises(0.01))):
        with pytest.raises(VfError, match="cannot be read as a number"):
            call()


def test_a_line_param_as_a_2x3_array_is_refused_on_both_paths():
    """The C fast path takes N x 3 arrays only for run-time curves; elsewhere the Python checks decide (and refuse)."""
    task = vfdsl.load(TASKS_DIR / "lecture_follow_path.vf")
    for backend in ("native", "interpreted"):
        ctrl = vfdsl.compile(task, backend=backend)
        u = {name: np.zeros(size) for name, size in ctrl.input_sizes.items()}
        slot = ctrl._values.layout.slots["path"]
        line = ctrl._values.layout.defaults[slot.offset:slot.offset + slot.size]
        assert np.all(np.isfinite(ctrl.step(task.start, u, {"path": line.copy()})))
        with pytest.raises(VfError, match="path"):
            ctrl.step(task.start, u, {"path": line.reshape(2, 3).copy()})


_IN_A_PROCESS = """
import numpy as np, vfdsl
from vfdsl.errors import VfError
task = vfdsl.load({path!r})
ctrl = vfdsl.compile(task)
assert ctrl.backend == "native"
q0, u = task.start, {{"tau": [0.0, 0.0, 0.02]}}
{body}
print("done")
"""


def _run(body: str) -> str:
    code = _IN_A_PROCESS.format(path=str(TASKS_DIR / "paper_b_virtual_rcm.vf"), body=body)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip().endswith("done"), (done.returncode, done.stderr[-2000:])
    return done.stdout


def test_a_key_that_runs_code_in_its_comparison_cannot_hang_the_step():
    """A key hashing like 'tau' whose __eq__ calls step again: the C path looks up only exact str keys (no user
    code while it holds the controller's lock); the Python checks refuse the key."""
    _run("""
class Key:
    def __hash__(self):
        return hash("tau")
    def __eq__(self, other):
        ctrl.step(q0, u)
        return False
try:
    ctrl.step(q0, {Key(): [0.0, 0.0, 0.02]})
except VfError as e:
    assert "unknown input" in str(e), e
else:
    raise AssertionError("accepted")
""")


def test_the_extension_type_refuses_a_second_init_and_a_missing_one():
    """Stepper.__init__ runs once (a second call is refused before it changes anything: the period limit and the
    default params stay); a Stepper made without __init__ raises instead of reading memory it does not have."""
    _run("""
stepper = ctrl._runner.stepper
before = ctrl.step(q0, u)
try:
    stepper.__init__(tuple(np.zeros(1) for _ in range(8)), np.zeros(1), (), (), (), np.zeros(2), 0.0, 100.0, (), (),
                     (), (), np.zeros(0, np.uint8))
except RuntimeError as e:
    assert "once" in str(e)
else:
    raise AssertionError("initialised twice")
try:
    ctrl.step(q0, u, None, 50.0)
except VfError:
    pass
else:
    raise AssertionError("dt 50 accepted")
assert np.array_equal(ctrl.step(q0, u), vfdsl.compile(task).step(q0, u))
bare = type(stepper).__new__(type(stepper))
for call in (lambda: bare.step(q0), lambda: bare.run(np.zeros(7), np.zeros(3), None, 0.01, 0.0),
             lambda: bare.margins(np.zeros(1))):
    try:
        call()
    except RuntimeError as e:
        assert "not initialised" in str(e)
    else:
        raise AssertionError("an uninitialised Stepper ran")
""")
