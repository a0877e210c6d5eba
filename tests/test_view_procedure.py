"""`vfdsl view` of a procedure (issue 33): the panel's phase, monitors and last transition, the button inputs pressed
from the panel, the procedure's reset, and a procedure's trace replayed with its phases. Driven without a browser,
as tests/test_view.py drives the Viewer; the controllers are interpreted (no C build)."""

from __future__ import annotations

import contextlib
import time

import numpy as np
import pytest

import vfdsl
from vfdsl.errors import VfError
from vfdsl.view import replay
from vfdsl.view.app import Viewer
from vfdsl.view.browser import Browser
from vfdsl.view.live import hand_model
from vfdsl.view.options import free_port

from conftest import TASKS_DIR
from test_view import chromium  # noqa: F401  (the fixture: skips where no Chromium is installed)

NEEDLE = TASKS_DIR / "procedures" / "needle_procedure.vf"


@contextlib.contextmanager
def opened(task, ctrl, replay=None):
    """A Viewer of ``task`` on a free port, closed after the block."""
    v = Viewer(task, ctrl, port=free_port(), replay=replay)
    try:
        yield v
    finally:
        v.close()


@pytest.fixture(scope="module")
def needle():
    task = vfdsl.load(NEEDLE)
    return task, vfdsl.compile(task, backend="interpreted")


@pytest.fixture
def viewer(needle):
    task, ctrl = needle
    ctrl.reset()
    with opened(task, ctrl) as v:
        yield v


def _record_buttons(viewer) -> list[float]:
    """Wrap the controller's step: the value of `go` it is given at each tick."""
    seen, step = [], viewer.ctrl.step

    def recording(q, inputs, **kw):
        seen.append(float(inputs["go"][0]))
        return step(q, inputs, **kw)
    viewer.ctrl.step = recording
    return seen


def test_the_panel_shows_the_phase_and_changes_it_at_the_tick_of_the_transition(viewer):
    state = viewer.state()
    assert state["phase"] == "approach" and state["transition"] is None
    assert "phase **approach**" in viewer.procedure_md.content and "no transition yet" in viewer.procedure_md.content
    assert set(state["monitors"]) == {m.name for m in viewer.task.monitors}
    for _ in range(5):                         # the tip starts at the entry: near_entry, but no press yet
        viewer.tick()
    assert viewer.state()["phase"] == "approach" and viewer.state()["monitors"]["near_entry"]
    viewer.press("go")
    viewer.tick()                              # the press's first tick: the guard holds, the transition fires
    state = viewer.state()
    assert state["phase"] == "align" and state["monitors"]["pressed"]
    assert state["transition"] == ("approach", "align", "near_entry and pressed", pytest.approx(0.06))
    text = viewer.procedure_md.content
    assert "phase **align**" in text and "approach -> align when near_entry and pressed at 0.060 s" in text
    assert "pressed: **on**" in text
    while viewer.state()["phase"] == "align" and viewer.ticks < 40:
        viewer.tick()
    # `aligned for 100 ms`: the needle starts on the line and a held timer is the task's, not the phase's, so it
    # has run since the first tick and fires at the 10th (10 ms period)
    assert viewer.state()["phase"] == "insert" and viewer.ticks == 10
    assert "align -> insert when aligned at 0.100 s" in viewer.procedure_md.content
    assert viewer.hand.gain == pytest.approx(1e-3)             # the hand now follows insert's track (1 mm/s/N)


def test_a_click_presses_the_button_for_100_ms_and_a_held_box_as_long_as_it_is_ticked(viewer):
    seen = _record_buttons(viewer)
    try:
        viewer.tick()
        viewer.press("go")
        assert viewer.state()["pressed"] == ["go"]
        for _ in range(14):
            viewer.tick()
        assert seen == [0.0] + [1.0] * 10 + [0.0] * 4          # 10 ticks of the 10 ms period: 100 ms
        assert viewer.state()["pressed"] == []
        viewer.press("go")
        viewer.tick()
        viewer.press("go", seconds=0.03)                       # a shorter press never cuts a running one
        for _ in range(10):
            viewer.tick()
        assert seen[15:] == [1.0] * 10 + [0.0]
        viewer._hold_boxes["go"].value = True
        for _ in range(30):
            viewer.tick()
        assert seen[26:] == [1.0] * 30
        viewer._hold_boxes["go"].value = False
        viewer.tick()
        assert seen[-1] == 0.0
    finally:
        del viewer.ctrl.step


def test_a_press_shorter_than_a_tick_is_one_tick_and_an_unknown_button_is_refused(viewer):
    seen = _record_buttons(viewer)
    try:
        viewer.press("go", seconds=1e-6)
        viewer.tick(), viewer.tick()
        assert seen == [1.0, 0.0]
    finally:
        del viewer.ctrl.step
    with pytest.raises(VfError, match="no button input 'hand'"):
        viewer.press("hand")                                   # the force input is the hand's, not a button
    with pytest.raises(VfError, match="its buttons: go"):
        viewer.press("nosuch")


def test_a_still_hand_is_no_frozen_sensor_and_the_buttons_are_not_the_hand_s(viewer):
    """The hand held still for 0.5 s: `unchanged(hand) for 20 ms` must not fire (the hand's reading ripples by
    1e-6 N), and the hand drives `hand`, never the button `go`."""
    seen = _record_buttons(viewer)
    try:
        viewer.push([0.0, 0.0, 0.0])
        for _ in range(50):
            viewer.tick()
    finally:
        del viewer.ctrl.step
    assert viewer.state()["phase"] == "approach" and not viewer.state()["monitors"]["stale"]
    assert seen == [0.0] * 50 and viewer.hand.input.name == "hand"


def test_reset_procedure_goes_back_to_the_initial_phase_and_keeps_the_robot(viewer):
    viewer.press("go")
    for _ in range(3):
        viewer.tick()
    assert viewer.state()["phase"] == "align"
    q = list(viewer.q)
    viewer.press("go")
    viewer.reset_procedure()
    state = viewer.state()
    assert state["phase"] == "approach" and state["transition"] is None and state["pressed"] == []
    assert state["q"] == q and "no transition yet" in viewer.procedure_md.content
    viewer.tick()
    assert viewer.state()["phase"] == "approach"               # the press was dropped with the reset


def test_the_hand_follows_the_phase_s_track_gain(needle):
    task, _ = needle
    assert hand_model(task, "approach").gain == pytest.approx(2e-3)      # 2 mm/s/N
    assert hand_model(task, "insert").gain == pytest.approx(1e-3)
    assert hand_model(task, "done") is None                              # no track term: the viewer keeps its hand
    buttons_first = task.model_copy(update={"inputs": list(reversed(task.inputs))})
    assert hand_model(buttons_first).input.name == "hand"                # a button is never the hand's input
    only_buttons = task.model_copy(update={"inputs": [d for d in task.inputs if d.type == "button"]})
    assert hand_model(only_buttons) is None


def test_a_procedure_trace_replays_its_phases(needle, tmp_path):
    task, ctrl = needle
    joints = ctrl.assembled.context.robot.joint_names
    names = ["approach"] * 4 + ["align"] * 3 + ["insert"] * 3
    lines = ["t_s," + ",".join(f"q.{j}" for j in joints) + ",status,violations,phase,monitor.pressed,monitor.aligned"]
    for k, name in enumerate(names):
        lines.append(f"{0.01 * k}," + ",".join(map(str, task.start)) + f",0,,{name},{int(k == 4)},{int(k >= 6)}")
    (tmp_path / "run.csv").write_text("\n".join(lines) + "\n")
    trace = replay.read(tmp_path / "run.csv", joints)
    assert list(trace.phase) == names and np.allclose(trace.monitors["pressed"], [k == 4 for k in range(10)])
    with opened(task, ctrl, replay=trace) as v:
        v.show_time(0.0)
        assert v.state()["phase"] == "approach" and v.state()["transition"] is None
        v.show_time(0.045)
        state = v.state()
        assert state["phase"] == "align" and state["monitors"] == {"pressed": True, "aligned": False}
        assert state["transition"] == ("approach", "align", None, pytest.approx(0.04))
        v.show_time(0.09)
        assert v.state()["transition"][:2] == ("align", "insert")
        assert "phase **insert**" in v.procedure_md.content and "align -> insert at 0.070 s" in v.procedure_md.content
        assert v._hold_boxes == {}                             # a replay has no buttons to press


def test_a_trace_without_phases_or_with_empty_cells_shows_no_procedure(needle, tmp_path):
    task, ctrl = needle
    joints = ctrl.assembled.context.robot.joint_names
    head = "t," + ",".join(f"q[{i}]" for i in range(len(joints)))
    row = lambda k: f"{0.01 * k}," + ",".join(map(str, task.start))
    (tmp_path / "plain.csv").write_text("\n".join([head] + [row(k) for k in range(3)]) + "\n")
    (tmp_path / "empty.csv").write_text("\n".join([head + ",phase"] + [row(k) + "," for k in range(3)]) + "\n")
    for name in ("plain.csv", "empty.csv"):
        trace = replay.read(tmp_path / name, joints)
        assert trace.phase is None
        with opened(task, ctrl, replay=trace) as v:
            v.show_time(0.02)
            assert v.state()["phase"] is None and not hasattr(v, "procedure_md")


def test_a_task_without_phases_shows_nothing_new():
    task = vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf")
    with opened(task, vfdsl.compile(task, backend="interpreted")) as v:
        v.push([0.0, 0.005, 0.0])
        for _ in range(3):
            v.tick()
        state = v.state()
        assert state["phase"] is None and state["monitors"] == {} and state["transition"] is None
        assert not hasattr(v, "procedure_md") and v.buttons == []
        with pytest.raises(VfError, match="its buttons: none"):
            v.press("go")


# ------------------------------------------------------------------------------------ in a real browser
def _click(browser, label: str) -> bool:
    return browser.evaluate("(() => { for (const b of document.querySelectorAll('button')) "
                            f"if (b.textContent.trim() == {label!r}) {{ b.click(); return true; }} return false; }})()")


def _until(viewer, check, timeout: float = 10.0) -> dict:
    deadline = time.monotonic() + timeout
    state = viewer.command(cmd="state")
    while not check(state) and time.monotonic() < deadline:
        time.sleep(0.2)
        state = viewer.command(cmd="state")
    return state


def test_the_page_shows_the_phase_and_its_press_button_moves_the_procedure(chromium):
    """`vfdsl view` of the needle procedure in headless Chromium: the panel reads `phase approach`; a click on
    `press go` in the page fires approach -> align (the tip starts at the entry), and the page then reads
    `phase align` and the transition; `Reset procedure` goes back to approach."""
    from test_view import ViewerProcess
    port = free_port()
    viewer = ViewerProcess(NEEDLE, port)
    try:
        viewer.wait_for("vfdsl view:", timeout=120)
        with Browser(960, 640, timeout=40) as browser:
            browser.open(f"http://127.0.0.1:{port}/")
            state = viewer.connected()
            assert state["phase"] == "approach"
            page = lambda text: browser.evaluate(f"document.body.innerText.includes({text!r})")
            deadline = time.monotonic() + 10
            while not page("phase approach") and time.monotonic() < deadline:
                time.sleep(0.2)
            assert page("phase approach") and page("near_entry")
            time.sleep(0.5)                                        # the still hand is no stale sensor
            assert viewer.command(cmd="state")["phase"] == "approach"
            assert _click(browser, "press go")
            state = _until(viewer, lambda s: s["phase"] != "approach")
            assert state["phase"] in ("align", "insert")           # align, then insert once aligned for 100 ms
            assert state["transition"] is not None and state["message"] == ""
            deadline = time.monotonic() + 10
            while not page("approach -> align when near_entry and pressed") and time.monotonic() < deadline:
                time.sleep(0.2)
            assert page("approach -> align when near_entry and pressed") or page("align -> insert when aligned")
            assert _click(browser, "Reset procedure")
            state = _until(viewer, lambda s: s["phase"] == "approach" and s["transition"] is None)
            assert state["phase"] == "approach" and state["transition"] is None
            state = viewer.command(cmd="press", name="go")          # the control channel presses too
            assert state["pressed"] == ["go"] or state["phase"] != "approach"
    finally:
        viewer.stop()


def test_a_trace_written_by_simulate_replays_its_phases(needle, tmp_path):
    """The example's scene without its sensor noise, 0.1 s: the frozen force sensor's watchdog ends the approach
    in `hold`; the trace `vfdsl simulate` writes replays with the phase of each row and the transition."""
    import dataclasses
    from vfdsl.kinematics.robot import Robot
    from vfdsl.sim import trace as sim_trace
    from vfdsl.sim.runner import make_jobs, simulate_with
    from vfdsl.sim.scene_file import load_settings
    task, ctrl = needle
    ctrl.reset()
    settings = dataclasses.replace(load_settings(task, NEEDLE.with_suffix(".sim.yaml")), sensors=(), duration=0.1)
    result = simulate_with(make_jobs(str(NEEDLE), settings, keep_trace=True)[0], task, ctrl,
                           Robot.load(task.robots[0].urdf, NEEDLE.parent), None)
    (event,) = result.procedure["transitions"]
    assert (event["source"], event["target"]) == ("approach", "hold")
    sim_trace.write(tmp_path / "run.csv", [result], task.name, str(NEEDLE))
    trace = replay.read(tmp_path / "run.csv", ctrl.assembled.context.robot.joint_names, trial="0")
    assert list(trace.phase) == list(result.trace["phase"]) and set(trace.monitors) == {m.name for m in task.monitors}
    ctrl.reset()
    with opened(task, ctrl, replay=trace) as v:
        v.show_time(event["time_s"] - 0.0005)
        assert v.state()["phase"] == "approach" and not v.state()["monitors"]["stale"]
        v.show_time(event["time_s"])
        state = v.state()
        assert state["phase"] == "hold" and state["monitors"]["stale"]
        assert state["transition"] == ("approach", "hold", None, pytest.approx(event["time_s"]))
