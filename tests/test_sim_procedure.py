"""`vfdsl simulate` of a procedure: the example needle procedure driven by its simulation scene (scripted pushes, a
button press, sensor noise) end to end at dt 1 ms, every transition checked against the tick computed here from the
recorded trace; the stale watchdog on a frozen sensor; the trace's phase and monitor columns, the per-phase report;
the scene's new fields refused at their lines."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pytest

import vfdsl
from vfdsl.errors import VfError
from vfdsl.kinematics.robot import Robot
from vfdsl.sim import report
from vfdsl.sim.command import _events_after_the_end
from vfdsl.sim.runner import make_jobs, simulate_with
from vfdsl.sim.scene_file import load_settings

REPO = Path(__file__).resolve().parent.parent
TASK = REPO / "tasks" / "procedures" / "needle_procedure.vf"
SCENE = REPO / "tasks" / "procedures" / "needle_procedure.sim.yaml"
DT = 1e-3


class Run:
    """One trial of the example with its own controller (its captures readable), its trace and its report."""

    def __init__(self, settings):
        self.task = vfdsl.load(TASK)
        self.ctrl = vfdsl.compile(self.task, backend="interpreted")
        robot = Robot.load(self.task.robots[0].urdf, TASK.parent)
        job = make_jobs(str(TASK), settings, keep_trace=True)[0]
        self.result = simulate_with(job, self.task, self.ctrl, robot, None)
        self.trace = self.result.trace
        joints = [c for c in self.trace if c.startswith("q.")]
        self.q = np.column_stack([self.trace[c] for c in joints])
        self.events = self.result.procedure["transitions"]

    def column(self, prefix: str) -> np.ndarray:
        return np.column_stack([v for c, v in self.trace.items() if c.startswith(prefix)])

    def frame(self, name: str, k: int):
        return self.ctrl.frames(self.q[k])[name]

    def capture(self, name: str) -> np.ndarray:
        return self.ctrl.captures[name]

    def event(self, target: str) -> dict:
        return next(e for e in self.events if e["target"] == target)


def held_from(condition: np.ndarray, start: int, ticks: int) -> int:
    """The first tick k >= start at which ``condition`` has been true on the ``ticks`` ticks ending at k."""
    run = 0
    for k, c in enumerate(condition):
        run = run + 1 if c else 0
        if k >= start and run >= ticks:
            return k
    raise AssertionError("never held that long")


@pytest.fixture(scope="module")
def settings():
    return load_settings(vfdsl.load(TASK), SCENE)


@pytest.fixture(scope="module")
def run(settings):
    return Run(settings)


def test_the_scene_runs_at_one_millisecond(settings):
    assert settings.period == DT and settings.sensors[0].linear == pytest.approx(0.02)


def test_every_phase_is_entered_in_order(run):
    assert [(e["source"], e["target"]) for e in run.events] == [
        ("approach", "align"), ("align", "insert"), ("insert", "retract"), ("retract", "done")]
    phase = run.trace["phase"]
    for e in run.events:                      # the new phase is solved from the transition's own tick on
        assert phase[e["tick"]] == e["target"] and phase[e["tick"] - 1] == e["source"]
    assert phase[-1] == "done" and "hold" not in phase
    assert [e["guard"] for e in run.events] == ["near_entry and pressed", "aligned", "pushed or deep", "out"]


def test_the_approach_ends_at_the_press_near_the_entry(run):
    entry = run.column("param.entry")
    distance = [np.linalg.norm(run.frame("tip", k).position - entry[k]) for k in range(len(run.q))]
    latch, near = False, []
    for d in distance:                               # on below 1 mm, off above 1.5 mm
        latch = d < 1e-3 if not latch else d <= 1.5e-3
        near.append(latch)
    go = run.trace["input.go.pressed_1"]
    expected = next(k for k in range(len(go)) if near[k] and go[k] == 1.0)
    assert run.event("align")["tick"] == expected == np.flatnonzero(go == 1.0)[0]
    assert distance[0] > 3.9e-3 and 0 < near.index(True) < expected     # 4 mm off at first, near before the press


def test_the_alignment_ends_when_the_angle_held_100_ms(run):
    start = run.event("align")["tick"]
    entry = run.column("param.entry")
    target = run.column("param.target")
    planned = (target - entry) / np.linalg.norm(target - entry, axis=1, keepdims=True)
    axis = np.array([run.frame("needle", k).tool_axis for k in range(len(run.q))])
    angle = np.arccos(np.clip(np.sum(axis * planned, axis=1), -1, 1))
    assert angle[start] > np.radians(2)              # the re-registered target: the alignment had work to do
    assert run.event("insert")["tick"] == held_from(angle < np.radians(2), start, 100)


def test_the_force_monitor_retracts_at_its_tick(run):
    force = np.linalg.norm(run.column("input.hand."), axis=1)
    start = run.event("insert")["tick"]
    k = run.event("retract")["tick"]
    assert k == held_from(force > 5.0, start, 50)
    first_over = k - 49
    assert force[first_over - 1] <= 5.0 < force[first_over]
    assert (k - first_over) * DT <= 0.050 + DT       # within 50 ms + one tick of the limit
    tip_start = run.frame("tip", start).position
    assert np.linalg.norm(run.frame("tip", k).position - tip_start) < 0.03      # not `deep`: the push did it


def test_the_retract_starts_where_the_insertion_stopped(run):
    k = run.event("retract")["tick"]
    stop = run.capture("stop")
    assert np.allclose(stop, run.frame("tip", k).position, rtol=0, atol=1e-12)
    assert np.linalg.norm(stop - run.frame("tip", k - 1).position) > 1e-6      # not the tick before
    out = np.array([np.linalg.norm(run.frame("tip", j).position - stop) for j in range(len(run.q))])
    assert run.event("done")["tick"] == k + int(np.argmax(out[k:] > 0.010))


def test_the_trace_has_the_phase_and_a_column_per_monitor(run):
    names = [m.name for m in run.task.monitors]
    columns = list(run.trace)
    assert [c for c in columns if c.startswith("monitor.")] == [f"monitor.{n}" for n in names]
    assert columns.index("phase") > columns.index("violations")
    k = run.event("retract")["tick"]
    assert run.trace["monitor.pushed"][k] == 1 and run.trace["monitor.pushed"][k - 1] == 0
    assert set(np.unique(run.trace["monitor.stale"])) == {0}
    assert all(set(np.unique(run.trace[f"monitor.{n}"])) <= {0, 1} for n in names)


def test_the_report_gives_each_phase(run, settings):
    doc = report.document(run.task.name, str(TASK), settings, [run.result], None)
    phases = {p["name"]: p for p in doc["procedure"]["phases"]}
    assert list(phases) == ["approach", "align", "insert", "retract", "done", "hold"]
    ticks = [e["tick"] for e in run.events]
    assert phases["insert"]["visits"] == [{"trial": 0, "entry_tick": ticks[1], "entry_s": ticks[1] * DT,
                                           "exit_tick": ticks[2], "exit_s": ticks[2] * DT}]
    assert phases["insert"]["time_s"] == pytest.approx((ticks[2] - ticks[1]) * DT)
    assert phases["done"]["visits"][0]["exit_tick"] is None and phases["hold"]["visits"] == []
    assert sum(p["time_s"] for p in phases.values()) == pytest.approx(len(run.q) * DT)
    metric = next(iter(doc["metrics"]))
    assert sum(p["metrics"][metric]["samples"] for p in phases.values()) == doc["metrics"][metric]["samples"]
    text = report.phase_table(doc)
    assert re.search(rf"insert\s+{(ticks[2] - ticks[1]) * DT:.3f}\s+{ticks[1]} \(", text)
    assert f"{ticks[2]} ({ticks[2] * DT:.3f} s)  insert -> retract  when pushed or deep" in text


def test_each_phase_fixture_is_measured_in_its_phase_against_what_it_captured(run, settings):
    k_insert, k_retract = run.event("insert")["tick"], run.event("retract")["tick"]
    along = run.trace["metric.insert_needle_along_error_m"]
    assert np.all(np.isnan(along[:k_insert])) and np.all(np.isnan(along[k_retract:]))
    assert np.all(np.isfinite(along[k_insert:k_retract]))
    assert along[k_insert] < 1e-12                       # the line through the tip along its axis, taken this tick
    stop, axis = run.capture("stop"), run.capture("axis0")         # an independent measure: |(I - a a')(x - stop)|
    retract = run.trace["metric.retract_needle_along_error_m"]
    for j in range(k_retract, run.event("done")["tick"], 97):
        d = run.frame("needle", j).position - stop
        assert retract[j] == pytest.approx(np.linalg.norm(d - (d @ axis) * axis), abs=1e-12)
    doc = report.document(run.task.name, str(TASK), settings, [run.result], None)
    phases = {p["name"]: p for p in doc["procedure"]["phases"]}
    assert "insert_needle_along_error_mm" in phases["insert"]["metrics"]
    assert not any(name.startswith(("retract_", "align_")) for name in phases["insert"]["metrics"])
    assert doc["metrics"]["insert_needle_along_error_mm"]["samples"] == k_retract - k_insert
    assert doc["metrics"]["hold_tip_stays_at_error_mm"]["samples"] == 0      # never entered: shown as -
    assert re.search(r"hold_tip_stays_at_error_mm\s+mm(\s+-){4}\s+0.1", report.table(doc, {"hold_tip_stays_at_error_mm": 0.1}))


def test_a_frozen_force_sensor_ends_in_hold_after_20_ms(settings):
    frozen = Run(dataclasses.replace(settings, sensors=(), duration=0.3))
    force = frozen.column("input.hand.")
    same = np.r_[False, np.all(force[1:] == force[:-1], axis=1)]    # the first tick counts as a change
    k = held_from(same, 0, 20)
    assert [(e["source"], e["target"], e["tick"]) for e in frozen.events] == [("approach", "hold", k)]
    last_change = np.flatnonzero(~same[:k + 1])[-1]
    assert (k - last_change) * DT == pytest.approx(0.020)
    assert set(frozen.trace["phase"][k:]) == {"hold"}


def test_a_task_without_phases_has_no_phase_columns():
    task_file = REPO / "tasks" / "lecture_follow_path.vf"
    task = vfdsl.load(task_file)
    settings = load_settings(task, None).replace(duration=0.05)
    ctrl = vfdsl.compile(task)
    result = simulate_with(make_jobs(str(task_file), settings, keep_trace=True)[0], task, ctrl,
                           Robot.load(task.robots[0].urdf, task_file.parent), None)
    assert result.procedure is None and "phase" not in result.trace
    assert not any(c.startswith("monitor.") for c in result.trace)


BAD = [   # (scene lines after the header, message, line of the mistake)
    ("pushes:\n  - {input: hand, magnitude: 1 N}", "a push needs 'direction'", 5),
    ("pushes:\n  - {input: fist, magnitude: 1 N, direction: [1, 0, 0]}", "declares no input 'fist'", 5),
    ("pushes:\n  - {input: go, magnitude: 1 N, direction: [1, 0, 0]}", "a push needs a .* input; 'go' is a button", 5),
    ("pushes:\n  - {input: hand, magnitude: -1 N, direction: [1, 0, 0]}", "zero or positive", 5),
    ("pushes:\n  - {input: hand, magnitude: 1e308 N, direction: [1, 0, 0]}", "beyond the 1000 N", 5),
    ("pushes:\n  - {input: hand, magnitude: 1 N, direction: [0, 0, 0]}", "must not be zero", 5),
    ("pushes:\n  - {input: hand, kind: shove, magnitude: 1 N, direction: [1, 0, 0]}", "unknown push kind", 5),
    ("pushes:\n  - {input: hand, kind: turn, magnitude: 1 N, direction: [1, 0, 0]}", "a turn needs", 5),
    ("pushes:\n  - {input: hand, magnitude: 1 N, direction: [1, 0, 0],\n     from: 3 s, to: 2 s}",
     r"end \(2 s\) must come after its start \(3 s\)", 6),
    ("pushes:\n  - {input: hand, magnitude: 1 ms, direction: [1, 0, 0]}", "expected a force", 5),
    ("pushes:\n  - {input: hand, magnitude: 1 N, direction: [1, 0, 0], at: 2 s}", "unknown key 'at'", 5),
    ("pushes: {input: hand}", "pushes is a list", 4),
    ("buttons:\n  hand: 2 s", "input 'hand' is a force, not a button", 5),
    ("buttons:\n  go: [2 s, 2.05 s]", r"this press of 'go' \(2.05 s\) starts before", 5),
    ("buttons:\n  go: {from: 2 s}", "a press needs 'from' and 'to'", 5),
    ("buttons:\n  go: -1 s", "zero or positive", 5),
    ("buttons:\n  go: []", "has no press", 5),
    ("buttons:\n  go: {from: 2 s, to: 3 s, for: 1 s}", "unknown key 'for'", 5),
    ("buttons: [go]", "buttons is a mapping", 4),
    ("sensors:\n  hand: {noise: -0.1 N}", "zero or positive", 5),
    ("sensors:\n  hand: {angular_noise: 0.1 Nmm}", "no angular part", 5),
    ("sensors:\n  go: {noise: 0.1}", "no linear part", 5),
    ("sensors:\n  hand: {nosie: 0.1 N}", "unknown key 'nosie'", 5),
    ("sensors:\n  hand: {noise: 2 mm}", "expected a force", 5),
]


@pytest.mark.parametrize("body, message, line", BAD, ids=[b[1] for b in BAD])
def test_bad_scene_fields_are_refused_at_their_lines(tmp_path, body, message, line):
    scene = tmp_path / "bad.sim.yaml"
    scene.write_text("# a bad scene\nunits: mm, deg\nperiod: 1 ms\n" + body + "\n")
    with pytest.raises(VfError) as err:
        load_settings(vfdsl.load(TASK), scene)
    assert re.search(message, err.value.message), err.value.message
    assert err.value.line == line
    assert err.value.code == ("E302" if "expected a" in message else "E602")     # a unit's mistake: E302


def test_pushes_and_presses_after_the_end_are_warned_of(tmp_path, settings):
    late = dataclasses.replace(settings, duration=2.2)
    warnings = [w.message for w in _events_after_the_end(late, [])]
    assert any("the press of 'go' at 2.3 s" in w for w in warnings)
    assert any("the push on 'hand' from 3 s" in w for w in warnings)
    assert not any("from 0 s" in w for w in warnings)


def test_the_command_prints_and_writes_the_procedure(tmp_path, capsys):
    """`vfdsl simulate` (its default backend) prints the per-phase table and writes the phases and transitions."""
    from vfdsl.cli import main

    out = tmp_path / "run.json"
    assert main(["simulate", str(TASK), "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    doc = json.loads(out.read_text())
    assert [(e["source"], e["target"]) for e in doc["procedure"]["transitions"]] == [
        ("approach", "align"), ("align", "insert"), ("insert", "retract"), ("retract", "done")]
    assert [p["name"] for p in doc["procedure"]["phases"]] == [p.name for p in vfdsl.load(TASK).phases]
    assert "transitions: tick (s), from -> to, the guard that held" in printed
    assert re.search(r"^retract\s+\d+\.\d{3}\s+\d+ \(", printed, re.M)


def test_every_trial_starts_the_procedure_afresh(tmp_path):
    """The simulator's controller is cached per process: each trial starts in the initial phase with its captures
    taken again, not where the last trial ended (trial 2 of the needle procedure once began in 'done')."""
    from vfdsl.cli import main
    out = tmp_path / "trace.csv"
    assert main(["simulate", str(TASK), "--trials", "2", "--duration", "1 s", "--trace", str(out), "--quiet"]) == 0
    import csv
    rows = list(csv.DictReader(out.open()))
    firsts = [next(r for r in rows if r["trial"] == t) for t in ("0", "1")]
    assert [r["phase"] for r in firsts] == ["approach", "approach"]
    assert [r["phase"] for r in rows if r["trial"] == "0"] == [r["phase"] for r in rows if r["trial"] == "1"]
