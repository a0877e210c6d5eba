"""`vfdsl export` of a procedure (issue 33, item 2): the exported library runs the phase machine before each solve
(codegen/procedure_tick.h, the code the Python extension runs), and ./replay gives the native Controller.step()'s
dq to 1e-12 and the same phase, tick by tick, across every transition of the example."""

from __future__ import annotations

import ctypes
import shutil

import numpy as np
import pytest

import vfdsl
from vfdsl.export.selftest import replay

from test_export import _contract, _run_contract, api_caller, built_export, heap_calls
from test_procedure_runtime import EXAMPLE, Driver

pytestmark = pytest.mark.skipif(shutil.which("make") is None or shutil.which("cc") is None,
                                reason="needs make and a C compiler")
DT = 0.001


class Recorder(Driver):
    """The scripted example on the native backend at one dt (replay takes one), with each tick's line for replay
    (q, then the inputs) and Python's status, dq and phase."""

    def __init__(self, task):
        super().__init__(task)
        self.ctrl = vfdsl.compile(task, backend="native")
        self.ticks: list[tuple[str, int, np.ndarray, str]] = []

    def tick(self, hand=(0.0, 0.0, 0.0), go=0.0, dt=DT, wobble=True):
        step, recorded = self.ctrl.step, {}

        def recording(q, inputs, dt):
            recorded.update(q=np.array(q), u=np.concatenate([inputs["hand"], inputs["go"]]))
            return step(q, inputs, dt=dt)

        self.ctrl.step = recording
        try:
            super().tick(hand, go, dt, wobble)
        finally:
            self.ctrl.step = step
        line = " ".join(f"{x:.17g}" for x in (*recorded["q"], *recorded["u"]))
        self.ticks.append((line, int(self.ctrl.status), self.q - recorded["q"], self.ctrl.phase))


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    task = vfdsl.load(EXAMPLE)
    return task, built_export(task, tmp_path_factory.mktemp("procedure"))


@pytest.fixture(scope="module")
def recorded(exported):
    r = Recorder(exported[0])
    for _ in range(9):
        r.tick()
    r.tick(go=1.0)
    for _ in range(139):
        r.tick()
    for _ in range(60):
        r.tick(hand=6.0 * r.axis)
    while r.ctrl.phase == "retract" and r.k < 3000:
        r.tick(hand=-20.0 * r.axis)
    return r


def test_replay_gives_the_native_controllers_dq_and_phases_across_transitions(exported, recorded):
    _, result = exported
    answers = replay(result.directory, [t[0] for t in recorded.ticks], DT)
    assert [a[0] for a in answers] == [t[1] for t in recorded.ticks]
    assert [a[2] for a in answers] == [t[3] for t in recorded.ticks]
    assert [e.target for _, e in recorded.events] == ["align", "insert", "retract", "done"]
    worst = max(float(np.max(np.abs(a[1] - t[2]))) for a, t in zip(answers, recorded.ticks))
    assert worst <= 1e-12


def test_the_api_names_phases_monitors_and_transitions(exported):
    task, result = exported
    call = api_caller(result)
    text = ctypes.c_char_p
    assert call("num_phases")() == len(task.phases)
    assert [call("phase_name", text)(k).decode() for k in range(len(task.phases))] == [p.name for p in task.phases]
    assert call("phase_name", text)(len(task.phases)) == b"" and call("phase_name", text)(-1) == b""
    ordered = sorted(task.transitions, key=lambda tr: tr.order)
    assert [call("transition_guard", text)(k).decode() for k in range(len(ordered))] == [tr.text for tr in ordered]
    phases = [p.name for p in task.phases]
    assert [call("transition_source")(k) for k in range(len(ordered))] == [
        -1 if tr.source is None else phases.index(tr.source) for tr in ordered]
    assert {call("monitor_name", text)(k).decode() for k in range(call("num_monitors")())} == {
        m.name for m in task.monitors}
    ctrl = call("new", ctypes.c_void_p)()
    try:
        assert call("phase", ctypes.c_int, ctypes.c_void_p)(ctrl) == [p.initial for p in task.phases].index(True)
        assert call("transition", ctypes.c_int, ctypes.c_void_p)(ctrl) == -1
        monitor = call("monitor", ctypes.c_int, ctypes.c_void_p, ctypes.c_int)
        assert monitor(ctrl, 0) == 0 and monitor(ctrl, 10_000) == -1 and monitor(ctrl, -1) == -1
        assert call("phase", ctypes.c_int, ctypes.c_void_p)(None) < 0
    finally:
        call("free", None, ctypes.c_void_p)(ctrl)


class _Line:
    """A recorded tick as export_contract.c reads it."""

    def __init__(self, line: str):
        self.text = line
        self.dt = DT

    def line(self) -> str:
        return self.text


def test_no_heap_call_after_new_across_transitions(exported, recorded, tmp_path):
    at_new, ticked, later = heap_calls(exported[1], [t[0] for t in recorded.ticks], DT, tmp_path)
    assert at_new > 0 and ticked == 0 and later == 0


def test_two_controllers_in_two_threads_answer_as_alone(exported, recorded, tmp_path):
    _, result = exported
    exe = _contract(type("Exported", (), {"directory": result.directory, "result": result}), tmp_path, [])
    assert _run_contract(exe, "threads", [_Line(t[0]) for t in recorded.ticks]) == "0"


def test_a_phase_s_derived_direction_is_checked_from_the_first_phase(exported):
    """needle_procedure's `align` phase keeps the needle along normalize(target - entry): an entry moved onto the
    target is refused in `approach` already (VF_ERR_PARAM, the derived vector's check), as in a task without phases;
    before, it was accepted and the fixture was off when `align` came."""
    task, result = exported
    call = api_caller(result)
    names = [call("param_name", ctypes.c_char_p, ctypes.c_int)(k).decode() for k in range(call("num_params")())]
    set_param = call("set_param", ctypes.c_int, ctypes.c_void_p, ctypes.c_int, ctypes.POINTER(ctypes.c_double))
    point = (ctypes.c_double * 3)(0.010, 0.005, 0.300)
    ctrl = call("new", ctypes.c_void_p)()
    try:
        assert set_param(ctrl, names.index("target"), point) == 0
        assert set_param(ctrl, names.index("entry"), point) == -7             # VF_ERR_PARAM
        check = call("error_check", ctypes.c_int, ctypes.c_void_p)(ctrl)
        assert "must not be zero" in call("check_meaning", ctypes.c_char_p, ctypes.c_int)(check).decode()
    finally:
        call("free", None, ctypes.c_void_p)(ctrl)


def test_set_params_reads_the_params_not_the_captured_slots_after_them(exported):
    """_set_params with the defaults and NaN in the captured slots (_param_length() counts them; setting them does
    nothing) is accepted and changes nothing; before, it was refused as a NaN in the last param, 'target', which held
    none. A NaN in a param is still refused, naming it."""
    _, result = exported
    call = api_caller(result)
    n_params, length = call("num_params")(), call("param_length")()
    size = call("param_size", ctypes.c_int, ctypes.c_int)
    default = call("param_default", ctypes.POINTER(ctypes.c_double), ctypes.c_int)
    values = [default(k)[i] for k in range(n_params) for i in range(size(k))]
    assert 0 < len(values) < length
    set_params = call("set_params", ctypes.c_int, ctypes.c_void_p, ctypes.POINTER(ctypes.c_double))
    error_index = call("error_index", ctypes.c_int, ctypes.c_void_p)
    ctrl = call("new", ctypes.c_void_p)()
    try:
        assert set_params(ctrl, (ctypes.c_double * length)(*values, *[np.nan] * (length - len(values)))) == 0
        assert error_index(ctrl) == -1
        values[-1] = np.nan
        assert set_params(ctrl, (ctypes.c_double * length)(*values, *[0.0] * (length - len(values)))) == -7
        assert error_index(ctrl) == n_params - 1
    finally:
        call("free", None, ctypes.c_void_p)(ctrl)
