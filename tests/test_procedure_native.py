"""A procedure on the native backend (issue 33, item 2): the phase machine runs in the generated C before each solve
(codegen/procedure_tick.h) and the Controller gives the same phases, events, monitors, captures and dq as on the
interpreted backend, on the fast path and on the checked one."""

from __future__ import annotations

import numpy as np
import pytest

import vfdsl
from vfdsl.runtime.native import NativeProcedure

from test_procedure_funnel import TASK as FUNNEL_TASK, Entry
from test_procedure_runtime import EXAMPLE, Driver

DQ_TOL = 1e-9


class Both:
    """The same script on both backends: per tick the q before, dq, phase, events and monitors of each."""

    def __init__(self, task):
        self.interpreted = Driver(task)
        self.native = Driver(task)
        self.native.ctrl = vfdsl.compile(task, backend="native")
        self.trace = {"interpreted": [], "native": []}

    def tick(self, checked=False, **kw):
        start = self.interpreted.q.copy()
        for name, d in (("interpreted", self.interpreted), ("native", self.native)):
            d.q = start.copy()                          # the same q on both: dq is compared alone
            q = d.q.copy()
            step = d.ctrl.step
            if checked and name == "native":        # a subclass of float: the fast path hands it to the checks
                d.ctrl.step = lambda q, inputs, dt, _step=step: _step(q, inputs, dt=Float(dt))
            d.tick(**kw)
            d.ctrl.step = step
            self.trace[name].append((d.q - q, d.ctrl.phase, d.ctrl.events, d.ctrl.monitors,
                                     d.ctrl._procedure.activity.copy()))

    def ticks(self, n, **kw):
        for _ in range(n):
            self.tick(**kw)


class Float(float):
    pass


@pytest.fixture(scope="module")
def task():
    return vfdsl.load(EXAMPLE)


@pytest.fixture(scope="module")
def both(task):
    """The scripted example of test_procedure_runtime, every fifth tick through the native checked path."""
    b = Both(task)
    b.ticks(9)
    b.tick(go=1.0)
    for k in range(139):
        b.tick(checked=k % 5 == 0)
    b.ticks(60, hand=6.0 * b.interpreted.axis)
    while b.interpreted.ctrl.phase == "retract" and b.interpreted.k < 400:
        b.tick(hand=-20.0 * b.interpreted.axis, dt=0.01)
    return b


def test_the_native_controller_runs_its_machine_in_c(both):
    assert both.native.ctrl.backend == "native"
    assert isinstance(both.native.ctrl._procedure, NativeProcedure)


def test_same_phases_events_and_monitors_every_tick(both):
    interpreted, native = both.trace["interpreted"], both.trace["native"]
    assert [t[1] for t in native] == [t[1] for t in interpreted]
    assert [t[2] for t in native] == [t[2] for t in interpreted]       # source, target, guard text and time
    assert [t[3] for t in native] == [t[3] for t in interpreted]
    assert [e.target for _, e in both.native.events] == ["align", "insert", "retract", "done"]


def test_same_dq_every_tick(both):
    worst = max(np.max(np.abs(a[0] - b[0])) for a, b in zip(both.trace["interpreted"], both.trace["native"]))
    assert worst < DQ_TOL


def test_same_activity_every_tick_funnel_widths_included(both):
    interpreted, native = both.trace["interpreted"], both.trace["native"]
    assert native[0][4].size > 2 * len(both.native.ctrl.task.phases)     # the example has funnelled constraints
    assert max(np.max(np.abs(a[4] - b[4])) for a, b in zip(interpreted, native)) < 1e-12


@pytest.mark.parametrize("blend_ms", [200, 0])
def test_a_fixture_entered_violated_gets_the_same_funnel_in_c(tmp_path, blend_ms):
    path = tmp_path / "funnel.vf"
    path.write_text(FUNNEL_TASK.replace("BLEND", str(blend_ms)))
    task = vfdsl.load(path)
    runs = [Entry(vfdsl.compile(task, backend=backend), 0.5e-3 + 2e-3) for backend in ("interpreted", "native")]
    for run in runs:
        run.enter(260)
    interpreted, native = runs
    widths = np.array(native.widths)[:, 0]
    assert widths.max() == (pytest.approx(2e-3 * (1 - 0.001 / 0.2), abs=1e-9) if blend_ms else 0.0)   # at entry
    assert np.max(np.abs(widths - np.array(interpreted.widths)[:, 0])) < 1e-12
    assert np.max(np.abs(np.array(native.distance) - interpreted.distance)) < 1e-9
    assert native.status == interpreted.status


def test_same_captures(both):
    for name in ("start", "axis0", "stop"):
        assert np.allclose(both.native.capture(name), both.interpreted.capture(name), rtol=0, atol=1e-12)


def test_the_activity_and_the_full_params_are_the_machines(both):
    native, interpreted = both.native.ctrl._procedure, both.interpreted.ctrl._procedure
    assert np.array_equal(native.activity, interpreted.activity)
    phases = [phase.name for phase in both.native.ctrl.task.phases]
    assert native.activity[phases.index("done")] > 0 and native.activity[phases.index("insert")] == 0
    qp = both.native.ctrl.problem(both.native.q, {"hand": [0.0, 0.0, 0.0], "go": [0.0]})
    same = both.interpreted.ctrl.problem(both.native.q, {"hand": [0.0, 0.0, 0.0], "go": [0.0]})
    assert np.allclose(qp.P, same.P, rtol=0, atol=1e-12) and np.allclose(qp.lb, same.lb, rtol=0, atol=1e-12) and np.allclose(qp.g, same.g, rtol=0, atol=1e-12)


def test_a_stale_input_holds_and_reset_restarts_in_c(task):
    d = Driver(task)
    d.ctrl = vfdsl.compile(task, backend="native")
    d.ticks(25, wobble=False)
    assert [(k, e.target) for k, e in d.events] == [(21, "hold")]
    assert d.ctrl.monitors["stale"] and d.ctrl.phase == "hold" and d.ctrl.events == ()
    assert np.array_equal(d.capture("held"), d.tip_before[20])
    d.ctrl.reset()
    assert d.ctrl.phase == "approach" and d.ctrl.events == () and not d.ctrl.monitors["stale"]
    d.ticks(3)
    assert d.ctrl.phase == "approach" and not d.ctrl.monitors["stale"]


def test_a_refused_tick_does_not_advance_the_machine(task):
    ctrl = vfdsl.compile(task, backend="native")
    q = np.array(task.start, dtype=float)
    still = {"hand": [0.0, 0.0, 0.0], "go": [0.0]}
    for _ in range(3):
        with pytest.raises(vfdsl.VfError):
            ctrl.step(q, {"hand": [np.nan, 0.0, 0.0], "go": [1.0]}, dt=0.001)
        with pytest.raises(vfdsl.VfError):
            ctrl.step(q, {"hand": [0.0, 0.0, 0.0], "go": [2.0]}, dt=0.001)     # a button is 0 or 1
        with pytest.raises(vfdsl.VfError):
            ctrl.step(q, still, dt=float("nan"))
    assert ctrl.events == () and ctrl._procedure.activity[0] == 1.0
    for _ in range(20):             # constant inputs: 'stale' (20 ms unchanged) at the 21st accepted tick
        ctrl.step(q, still, dt=0.001)
    assert ctrl.phase == "approach"
    ctrl.step(q, still, dt=0.001)
    assert ctrl.phase == "hold" and ctrl.events[0].time == pytest.approx(0.021)


def test_controllers_of_one_procedure_have_their_own_machine(task):
    a, b = vfdsl.compile(task, backend="native"), vfdsl.compile(task, backend="native")
    q = np.array(task.start, dtype=float)
    for _ in range(21):
        a.step(q, {"hand": [0.0, 0.0, 0.0], "go": [0.0]}, dt=0.001)
    assert a.phase == "hold" and b.phase == "approach" and b.events == ()


def test_params_on_the_checked_path_are_checked_and_used(task):
    ctrl, same = vfdsl.compile(task, backend="native"), vfdsl.compile(task, backend="interpreted")
    q = np.array(task.start, dtype=float)
    still = {"hand": [0.0, 0.0, 0.0], "go": [0.0]}
    entry = np.array(task.param("entry").value.xyz) + [0.0, 0.0, 5e-3]     # the tip starts at the entry
    moved = [Float(x) for x in entry]                   # not plain: the Python checks take it, then Stepper.tick
    for _ in range(3):
        dq = ctrl.step(q, still, {"entry": moved}, 0.001)
        assert np.max(np.abs(dq - same.step(q, still, {"entry": entry}, 0.001))) < DQ_TOL
    assert ctrl.monitors == same.monitors and not ctrl.monitors["near_entry"]     # the moved entry was used
    ctrl.step(q, still, None, 0.001)
    assert ctrl.monitors["near_entry"]
    with pytest.raises(vfdsl.VfError, match="entry"):
        ctrl.step(q, still, {"entry": [Float(0.0), 0.0, 1e3]}, 0.001)   # 1 km: a unit slip the checks refuse
    assert ctrl.problem(q, still, {"entry": entry}).P.shape == same.problem(q, still, {"entry": entry}).P.shape
