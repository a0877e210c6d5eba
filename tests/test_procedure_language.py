"""Procedures in the language (issue 33): phases, captures, monitors, transitions and blend are parsed and
checked into the IR; every mistake is an error at its line and column with its code; the example procedure
loads and prints its statechart; compiling a procedure is refused until the compiler supports it."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import vfdsl
from vfdsl.cli import main as cli_main
from vfdsl.errors import VfError, VfErrors
from vfdsl.ir import model as ir
from vfdsl.ir import statechart

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = REPO / "tasks" / "procedures" / "needle_procedure.vf"
CHANNEL = REPO / "tasks" / "anatomy" / "channel.stl"

PRELUDE = """\
task t
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
input w : wrench
input go : button
param entry : point = [10, 5, 285]
"""
FIRST = PRELUDE.count("\n") + 1          # the line of the first statement after the prelude


def load(tmp_path: Path, body: str) -> ir.Task:
    path = tmp_path / "t.vf"
    path.write_text(PRELUDE + body)
    return vfdsl.load(path)


def error(tmp_path: Path, body: str) -> VfError:
    with pytest.raises(VfError) as info:
        load(tmp_path, body)
    return info.value


# ------------------------------------------------------------------------------------------- the example

@pytest.fixture(scope="module")
def example() -> ir.Task:
    return vfdsl.load(EXAMPLE)


def test_the_example_has_its_phases_captures_and_statements(example):
    assert [(p.name, p.initial, p.final) for p in example.phases] == [
        ("approach", True, False), ("align", False, False), ("insert", False, False), ("retract", False, False),
        ("done", False, True), ("hold", False, True)]
    phases = {p.name: p for p in example.phases}
    assert [(c.name, c.kind, c.source) for c in phases["insert"].captures] == [
        ("start", "point", ir.FrameMeasure(frame="tip", part="position")),
        ("axis0", "direction", ir.FrameMeasure(frame="needle", part="axis"))]
    along = phases["insert"].constraints[0]
    assert along.primitive == "along" and along.args["line"].operands == [ir.CaptureRef(name="start"),
                                                                           ir.CaptureRef(name="axis0")]
    assert math.isclose(along.tolerance, 0.2e-3)
    # retract reads a capture of insert (axis0) and its own (stop)
    assert phases["retract"].constraints[0].args["line"].operands == [ir.CaptureRef(name="stop"),
                                                                        ir.CaptureRef(name="axis0")]
    assert [o.term for o in phases["approach"].objectives] == ["track"]
    # the statements outside the phases stay the task's (every phase)
    assert [o.term for o in example.objectives] == ["damping"]
    assert {c.primitive for c in example.constraints} == {"joint_limits", "joint_speed"}


def test_the_example_monitors_are_in_si_with_their_holds(example):
    monitors = {m.name: m for m in example.monitors}
    near = monitors["near_entry"].expr
    assert (near.op, near.threshold, near.release, near.dimension) == ("<", pytest.approx(1e-3),
                                                                      pytest.approx(1.5e-3), "length")
    assert near.measure == ir.Distance(frame="tip", to=ir.ParamRef(name="entry"))
    pushed = monitors["pushed"]
    assert (pushed.expr.measure, pushed.expr.op, pushed.expr.threshold, pushed.hold) == (
        ir.Norm(input="hand"), ">", 5.0, pytest.approx(0.05))
    assert monitors["aligned"].expr.dimension == "angle"
    assert monitors["aligned"].expr.threshold == pytest.approx(math.radians(2))
    assert monitors["deep"].expr.measure.to == ir.CaptureRef(name="start")
    assert monitors["stale"].expr == ir.Flag(measure=ir.Unchanged(input="hand"), span=monitors["stale"].expr.span)
    assert monitors["stale"].hold == pytest.approx(0.02)
    assert monitors["pressed"].expr.measure == ir.Button(input="go")
    assert monitors["near_entry"].text == "distance(tip, entry) < 1 mm release 1.5 mm"


def test_the_example_transitions_keep_file_order_and_blend(example):
    assert [(t.source, t.target, t.order, t.text) for t in example.transitions] == [
        (None, "hold", 0, "stale"),
        ("approach", "align", 1, "near_entry and pressed"),
        ("align", "insert", 2, "aligned"),
        ("insert", "retract", 3, "pushed or deep"),
        ("retract", "done", 4, "out")]
    assert example.blend == pytest.approx(0.2)
    assert all(t.blend == pytest.approx(0.2) for t in example.transitions)
    guard = example.transitions[1].guard
    assert guard == ir.And(items=[ir.MonitorRef(name="near_entry"), ir.MonitorRef(name="pressed")])


def test_the_example_round_trips_through_json(example):
    assert ir.Task.model_validate_json(example.model_dump_json()) == example


def test_a_task_without_phases_serializes_as_before(tmp_path):
    task = load(tmp_path, "minimize track(tip, f, gain = 1 mm/s/N)\n")
    data = task.model_dump(mode="json")
    assert not {"phases", "monitors", "transitions", "blend"} & set(data)
    assert ir.Task.model_validate_json(task.model_dump_json()) == task


def test_the_statechart_of_the_example(example, capsys):
    assert cli_main(["show", str(EXAMPLE), "--statechart", "dot"]) == 0
    dot = capsys.readouterr().out
    assert dot == statechart.dot(example) and dot.startswith('digraph "needle_procedure" {')
    assert '"__start" -> "approach";' in dot
    assert '"done" [label="done", peripheries=2];' in dot and '"approach" [label="approach"];' in dot
    assert '"approach" -> "align" [label="2: near_entry and pressed (blend 200 ms)"];' in dot
    # `*` is drawn from every phase but the final ones and the target
    assert [line for line in dot.splitlines() if '-> "hold"' in line] == [
        f'  "{p}" -> "hold" [label="1: stale (blend 200 ms)"];' for p in ("approach", "align", "insert", "retract")]
    assert cli_main(["show", str(EXAMPLE), "--statechart", "mermaid"]) == 0
    mermaid = capsys.readouterr().out.splitlines()
    assert mermaid[:2] == ["stateDiagram-v2", "  [*] --> approach"]
    assert "  insert --> retract : 4: pushed or deep (blend 200 ms)" in mermaid
    assert mermaid[-2:] == ["  done --> [*]", "  hold --> [*]"]


def test_the_statechart_escapes_the_guard_text(tmp_path):
    task = load(tmp_path, 'phase a initial {}\nphase b {}\ntransition a -> b when norm(f) > 2 N\n')
    assert '[label="1: norm(f) > 2 N"]' in statechart.dot(task)
    assert "a --> b : 1: norm(f) #gt; 2 N" in statechart.mermaid(task)


def test_show_prints_the_procedure_and_refuses_a_statechart_without_phases(tmp_path, capsys):
    assert cli_main(["show", str(EXAMPLE)]) == 0
    shown = capsys.readouterr().out
    assert "\nphases:\n" in shown and "\nmonitors:\n" in shown and "\ntransitions:\n" in shown
    (tmp_path / "t.vf").write_text(PRELUDE)
    assert cli_main(["show", str(tmp_path / "t.vf"), "--statechart", "dot"]) == 2
    assert "has no phases" in capsys.readouterr().err


def test_a_procedure_compiles_and_starts_in_its_initial_phase(example):
    ctrl = vfdsl.compile(example, backend="interpreted")
    assert ctrl.phase == "approach" and ctrl.events == ()


# ------------------------------------------------------------------------------------------- the checks

TWO_PHASES = "phase a initial {}\nphase b {}\n"
CASES = [   # id, body after the prelude, (line after the prelude, column), code, message (a substring)
    ("unknown target", TWO_PHASES + "transition a -> c when go\n", (2, 17), "E801", "unknown phase 'c'"),
    ("unknown source", TWO_PHASES + "transition x -> b when go\n", (2, 12), "E801", "unknown phase 'x'"),
    ("a monitor as a phase", TWO_PHASES + "monitor m = go\ntransition a -> m when go\n", (3, 17), "E801",
     "unknown phase 'm'"),
    ("no initial", "phase a {}\nphase b {}\n", (0, 7), "E802", "no initial phase"),
    ("two initials", "phase a initial {}\nphase b initial {}\n", (1, 9), "E802", "two initial phases"),
    ("out of a final", "phase a initial {}\nphase b final {}\ntransition b -> a when go\n", (2, 12), "E803",
     "a transition out of final phase 'b'"),
    ("to itself", TWO_PHASES + "transition a -> a when go\n", (2, 17), "E804", "from phase 'a' to itself"),
    ("phase twice", "phase a initial {}\nphase a {}\n", (1, 7), "E805", "phase 'a' is declared twice"),
    ("monitor named like a param", "monitor entry = go\n", (0, 9), "E805", "monitor 'entry' is declared twice"),
    ("phase named like a frame", "phase tip initial {}\n", (0, 7), "E805", "phase 'tip' is declared twice"),
    ("capture named like an input", "phase a initial { capture f = tip.position }\n", (0, 27), "E805",
     "capture 'f' is declared twice"),
    ("capture twice", "phase a initial { capture s = tip.position }\nphase b { capture s = tip.axis }\n",
     (1, 19), "E805", "capture 's' is declared twice"),
    ("monitor named like a measure", "monitor elapsed = go\n", (0, 9), "E805", "'elapsed' is a measure"),
    ("a second blend", "blend 1 s\nblend 2 s\n", (1, 1), "E805", "a second `blend` statement"),
    ("distance to an angle", "monitor m = distance(tip, entry) < 2 deg\n", (0, 36), "E806",
     "distance(...) (length) is a length, but 2 deg is an angle"),
    ("a millimetre to a force", "monitor m = norm(f) > 1 mm\n", (0, 23), "E806",
     "norm(...) (force) is a force, but 1 mm is a length"),
    ("for not a time", "monitor m = go for 3 mm\n", (0, 20), "E806", "a `for` is a time, but 3 mm is a length"),
    ("release below a <", "monitor m = distance(tip, entry) < 1 mm release 0.5 mm\n", (0, 49), "E806",
     "must lie above its threshold"),
    ("release equal to the threshold", "monitor m = norm(f) > 5 N release 5 N\n", (0, 35), "E806",
     "must lie below its threshold"),
    ("release of another dimension", "monitor m = distance(tip, entry) < 1 mm release 1 deg\n", (0, 49),
     "E806", "the release of distance(...) (length) is a length, but 1 deg is an angle"),
    ("unknown monitor", "monitor m = pressd\n", (0, 13), "E807", "unknown monitor or measure 'pressd'"),
    ("unknown measure", "monitor m = speed(tip) > 1 mm/s\n", (0, 13), "E807", "unknown measure 'speed(...)'"),
    ("unknown monitor in a guard", TWO_PHASES + "transition a -> b when nothere\n", (2, 24), "E807",
     "unknown monitor or measure 'nothere'"),
    ("a cycle", "monitor m1 = m2 and go\nmonitor m2 = not m3\nmonitor m3 = m1\n", (0, 1), "E808",
     "monitors name each other in a cycle: m1 -> m2 -> m3 -> m1"),
    ("a monitor naming itself", "monitor m = m or go\n", (0, 1), "E808", "cycle: m -> m"),
    ("capture of an unknown frame", "phase a initial { capture s = tpi.position }\n", (0, 31), "E809",
     "cannot capture 'tpi'"),
    ("capture of a frame without a part", "phase a initial { capture s = tip }\n", (0, 31), "E809",
     "reads its position, its axis or its pose"),
    ("capture of a frame's unknown part", "phase a initial { capture s = tip.speed }\n", (0, 35), "E809",
     "reads its position, its axis or its pose"),
    ("capture of an input's part", "phase a initial { capture s = f.linear }\n", (0, 33), "E809",
     "'f' has no part 'linear' to capture"),
    ("capture of the robot", "phase a initial { capture s = shr }\n", (0, 31), "E809", "cannot capture 'shr'"),
    ("capture of a curve param", "param c : curve(degree = 1) = [[0, 0, 280], [10, 0, 280]]\n"
     "phase a initial { capture k = c }\n", (1, 31), "E809", "a curve param cannot be captured"),
    ("capture of a mesh param", f"param m : mesh(unit = 1 mm) = \"{CHANNEL}\"\nphase a initial {{ capture k = m }}\n",
     (1, 31), "E809", "a mesh param cannot be captured"),
    ("capture outside the phases", "phase a initial { capture s = tip.position }\n"
     "require tip stays_at(s) within 1 mm\n", (1, 22), "E810", "'s' is captured on entry to a phase"),
    ("capture outside the phases through a fixture",
     "fixture hold(at: frame, p: point) { require at stays_at(p) within 1 mm }\n"
     "phase a initial { capture s = tip.position }\nuse hold(tip, s)\n", (2, 15), "E810", "captured"),
    ("a button compared", "monitor m = go > 0.5\n", (0, 13), "E811", "go is a condition, not a quantity"),
    ("a monitor compared", "monitor m1 = go\nmonitor m2 = m1 < 1\n", (1, 14), "E811", "m1 is a condition"),
    ("a force as a condition", "monitor m = f\n", (0, 13), "E811", "input 'f' is a force, not a condition"),
    ("elapsed as a condition", "monitor m = elapsed\n", (0, 13), "E811", "elapsed is a time, not a condition"),
    ("a distance as a condition", "monitor m = distance(tip, entry)\n", (0, 13), "E811",
     "distance(...) is a length, not a condition"),
    ("a wrench's norm", "monitor m = norm(w) > 1 N\n", (0, 18), "E811", "its parts have different units"),
    ("a force's angular part", "monitor m = norm(f.angular) > 1 N\n", (0, 20), "E811",
     "a force input has no part 'angular'"),
    ("a part outside norm", "monitor m = unchanged(w.linear) for 1 s\n", (0, 23), "E811",
     "`.linear` is read only by norm(...)"),
    ("too many arguments", "monitor m = norm(f, w) > 1 N\n", (0, 13), "E501", "norm(...) takes 1 argument, got 2"),
    ("a frame where an input is read", "monitor m = norm(tip) > 1 N\n", (0, 18), "E203", "expected"),
    ("distance to a direction", "monitor m = distance(tip, [0, 0, 1] * 1) < 1 mm\n", (0, 27), "E403", ""),
    ("a param as a threshold", "param d : length = 1 mm\nmonitor m = distance(tip, entry) < d\n", (1, 36),
     "E206", "a name ('d') cannot stand here"),
    ("a zero for", "monitor m = go for 0 s\n", (0, 20), "E402", "a `for` duration must be above 0"),
    ("a negative for", "monitor m = go for -5 ms\n", (0, 20), "E402", "got -0.005 s"),
    ("a huge for", "monitor m = go for 1e9 s\n", (0, 20), "E402", "at most 3600 s"),
    ("an overflowing for", "monitor m = go for 1e400 s\n", (0, 20), "E304", ""),
    ("a negative blend", "blend -1 s\n", (0, 7), "E402", "a blend duration must be at least 0"),
    ("a huge transition blend", TWO_PHASES + "transition a -> b when go blend 7200 s\n", (2, 33), "E402", "a blend"),
    ("a blend in metres", "blend 3 mm\n", (0, 7), "E806", "a blend is a time, but 3 mm is a length"),
    ("initial twice on a phase", "phase a initial initial {}\n", (0, 17), "E104", "marked `initial` twice"),
    ("a star as a target", TWO_PHASES + "transition a -> * when go\n", (2, 17), "E101", "unexpected '*'"),
    ("a for in a guard", TWO_PHASES + "transition a -> b when go for 1 s\n", (2, 27), "E101", "unexpected"),
    ("a capture outside a phase", "capture s = tip.position\n", (0, 1), "E101", "unexpected"),
    ("nan as a threshold", "monitor m = norm(f) > nan N\n", (0, 23), "E304", "'nan' is not a number"),
]


@pytest.mark.parametrize("body, where, code, message", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_each_mistake_has_its_code_line_and_column(tmp_path, body, where, code, message):
    err = error(tmp_path, body)
    assert len(err.errors) == 1, err.render()
    assert (err.code, err.line, err.column) == (code, FIRST + where[0], where[1]), err.render()
    assert message in err.message


@pytest.mark.parametrize("body", ["capture s = tip.position\n",
                                  "fixture hold(at: frame) { capture s = at.position }\n"])
def test_a_capture_outside_a_phase_says_where_it_belongs(tmp_path, body):
    """The hint was "did you mean 'capture'?" for the word as written."""
    err = error(tmp_path, body)
    assert err.code == "E101" and err.errors[0].hint.startswith("a capture is taken on entry to a phase"), err.render()


def test_a_hint_says_e_g_once(tmp_path):
    """The hint of a value in the wrong unit (E806) read "e.g. a number with a unit, e.g. 5 N"."""
    err = error(tmp_path, "monitor m = norm(f) > 1 mm\n")
    assert err.errors[0].hint == "write a number with a unit, e.g. 5 N", err.render()


def test_independent_mistakes_are_reported_together(tmp_path):
    """Three independent mistakes, each at its place; a transition naming a failed monitor is not an echo."""
    err = error(tmp_path, "monitor bad = norm(f) > 1 mm\n"
                          "phase a initial { capture s = tpi.position }\nphase b {}\n"
                          "transition a -> c when bad\ntransition a -> b when bad\n")
    assert isinstance(err, VfErrors)
    assert [(e.code, e.line) for e in err.errors] == [("E806", FIRST), ("E809", FIRST + 1), ("E801", FIRST + 3)]


def test_a_failed_capture_is_not_reported_again_where_it_is_read(tmp_path):
    err = error(tmp_path, "phase a initial { capture s = tpi.position\n require tip stays_at(s) within 1 mm }\n"
                          "monitor m = distance(tip, s) < 1 mm\n")
    assert [(e.code, e.line) for e in err.errors] == [("E809", FIRST)]


# ------------------------------------------------------------------------------------- what is accepted

def test_an_empty_phase_and_a_capture_read_before_it_is_taken(tmp_path):
    """A phase may be empty; a capture taken in a later phase may be read earlier (it holds its start value)."""
    task = load(tmp_path, "phase a initial { require tip stays_at(s) within 1 mm }\n"
                          "phase b { capture s = tip.position }\nphase c final {}\n"
                          "monitor blocked = least_violation for 100 ms\n"
                          "transition a -> b when elapsed > 2 s\ntransition b -> c when blocked or least_violation\n")
    assert task.phases[0].constraints[0].args["target"] == ir.CaptureRef(name="s")
    assert task.phases[2].constraints == task.phases[2].objectives == task.phases[2].captures == []
    assert task.transitions[0].guard.measure == ir.Elapsed() and task.transitions[0].guard.threshold == 2
    assert task.monitors[0].expr.measure == ir.LeastViolation() and task.monitors[0].hold == pytest.approx(0.1)
    assert task.transitions[1].guard.items[1].measure == ir.LeastViolation()


def test_captures_of_an_input_a_param_and_an_axis_are_typed(tmp_path):
    task = load(tmp_path, "param d : direction = [0, 0, 1]\n"
                          "phase a initial { capture f0 = f\n capture d0 = d\n capture ax = tip.axis\n"
                          " require tip keeps_direction(ax) within 1 deg\n"
                          " require tip along(line(entry, d0)) within 1 mm }\n")
    assert [(c.name, c.kind, c.source) for c in task.phases[0].captures] == [
        ("f0", "force", ir.InputRef(name="f")), ("d0", "direction", ir.ParamRef(name="d")),
        ("ax", "direction", ir.FrameMeasure(frame="tip", part="axis"))]


@pytest.mark.parametrize("backend", ["interpreted", "native"])
def test_a_param_captured_into_an_argument_meets_the_arguments_range(tmp_path, backend):
    """`capture k = r`, then `time_constant = k`: a default of -1 s is refused at the value, naming the capture; a
    run-time -1 s is refused by step() before anything moves, on both paths, as it is without the capture."""
    body = ("param r : time = {}\ninput tau : torque\nminimize track(tip, tau, angular_gain = 20 deg/s/Nmm)\n"
            "phase a initial {{ capture k = r }}\nphase b final {{ minimize centering(time_constant = k) }}\n"
            "transition a -> b when go\n")
    err = error(tmp_path, body.format(-1))
    assert (err.code, err.line, err.column) == ("E402", FIRST, 18), err.render()
    assert "must be > 0, as the argument 'time_constant' of centering through the capture 'k'" in err.message
    (tmp_path / "t.yaml").write_text("units: mm, deg\nperiod: 10 ms\n"
                                      "start: {x: 0, y: 0, z: 0, rcm_a: 0, rcm_b: 0, roll: 0, insert: 20}\n")
    task = load(tmp_path, body.format(1))
    ctrl = vfdsl.compile(task, backend=backend)
    q = np.array(task.start, dtype=float)
    u = {"f": np.zeros(3), "w": np.zeros(6), "go": [1.0], "tau": np.zeros(3)}
    with pytest.raises(VfError, match="param 'r' = -1 \\(SI\\) must be > 0"):
        ctrl.step(q, u, params={"r": -1.0}, dt=0.01)
    assert np.all(np.isfinite(ctrl.step(q, u, params={"r": 2.0}, dt=0.01))) and ctrl.phase == "b"


def test_a_capture_passed_to_a_fixture_inside_a_phase(tmp_path):
    task = load(tmp_path, "fixture hold(at: frame, p: point) { require at stays_at(p) within 1 mm }\n"
                          "phase a initial { capture s = tip.position\n use hold(tip, s) }\n")
    assert task.phases[0].constraints[0].args["target"] == ir.CaptureRef(name="s")
    assert task.phases[0].constraints[0].via


def test_conditions_nest_with_precedence_and_flatten_chains(tmp_path):
    """not binds tightest, then and, then or; a chain of one operator is one node."""
    task = load(tmp_path, "monitor a = go\nmonitor b = go\nmonitor c = go\n"
                          "monitor m = not a and b or c or (a and not (b or c))\n")
    m = task.monitors[-1].expr
    ref = {n: ir.MonitorRef(name=n) for n in "abc"}
    assert m == ir.Or(items=[ir.And(items=[ir.Not(items=[ref["a"]]), ref["b"]]), ref["c"],
                             ir.And(items=[ref["a"], ir.Not(items=[ir.Or(items=[ref["b"], ref["c"]])])])])


def test_monitors_may_name_later_monitors_without_a_cycle(tmp_path):
    task = load(tmp_path, "monitor m1 = m2 and m3\nmonitor m2 = m3\nmonitor m3 = go\n")
    assert task.monitors[0].expr == ir.And(items=[ir.MonitorRef(name="m2"), ir.MonitorRef(name="m3")])


def test_measures_and_their_units(tmp_path):
    task = load(tmp_path, "param pl : plane = plane([0, 0, 200], [0, 0, 1])\n"
                          "monitor a = angle(tip, [0, 0, 1]) >= 10 deg\n"
                          "monitor b = distance(tip, pl) <= 5\n"                 # bare numbers: the file's mm
                          "monitor c = norm(w.angular) > 0.2 Nm\n"
                          "monitor d = unchanged(f) > 30 ms\n"
                          "monitor e = distance(tip, line(entry, [1, 0, 0])) < 2 mm release 3 mm\n"
                          "monitor g = distance(tip, entry + [0, 0, 5]) > 1 mm release 0.5 mm\n")
    m = {x.name: x.expr for x in task.monitors}
    assert (m["a"].op, m["a"].threshold, m["a"].dimension) == (">=", pytest.approx(math.radians(10)), "angle")
    assert (m["b"].threshold, m["b"].measure.to) == (pytest.approx(5e-3), ir.ParamRef(name="pl"))
    assert (m["c"].measure, m["c"].threshold) == (ir.Norm(input="w", part="angular"), pytest.approx(0.2))
    assert (m["d"].measure, m["d"].threshold, m["d"].dimension) == (ir.Unchanged(input="f"), pytest.approx(0.03),
                                                                    "time")
    assert m["e"].measure.to.kind == "line" and m["e"].release == pytest.approx(3e-3)
    assert (m["g"].measure.to.op, m["g"].measure.to.kind) == ("add", "point")     # entry is a run-time param
    assert m["g"].release == pytest.approx(0.5e-3)


def test_a_transition_blend_on_its_line_overrides_and_one_on_its_own_line_is_the_tasks(tmp_path):
    task = load(tmp_path, TWO_PHASES + "phase c {}\n"
                          "transition a -> b when go blend 50 ms\n"
                          "transition b -> c when go\n"
                          "blend 300 ms\n"
                          "transition c -> a when go and # a comment inside the guard\n  elapsed > 1 s blend 0 s\n")
    assert task.blend == pytest.approx(0.3)
    assert [t.blend for t in task.transitions] == [pytest.approx(0.05), pytest.approx(0.3), 0.0]
    assert task.transitions[2].text == "go and elapsed > 1 s"


def test_a_blend_on_the_line_after_a_guard_is_the_tasks(tmp_path):
    """Newlines are insignificant but for this: a `blend` starting its own line is the task's statement."""
    err = error(tmp_path, TWO_PHASES + "blend 1 s\ntransition a -> b when go\nblend 0 s\n")
    assert (err.code, err.line) == ("E805", FIRST + 4)


def test_a_zero_task_blend_and_a_transition_without_phases_are_plain(tmp_path):
    task = load(tmp_path, "monitor m = go\n")
    assert task.phases == task.transitions == [] and task.blend == 0
    assert [m.name for m in task.monitors] == ["m"]


def test_deeply_nested_conditions_stop_at_the_nesting_limit(tmp_path):
    err = error(tmp_path, "monitor m = " + "not " * 5000 + "go\n")
    assert err.code == "E701" and "nested too deeply" in err.message


def test_a_star_transition_reads_from_every_phase(tmp_path):
    task = load(tmp_path, TWO_PHASES + "phase z final {}\ntransition * -> z when elapsed > 1 s\n"
                          "transition * -> a when go\n")
    assert [t.source for t in task.transitions] == [None, None]
    assert statechart.edges(task) == [("a", "z", "1: elapsed > 1 s"), ("b", "z", "1: elapsed > 1 s"),
                                      ("b", "a", "2: go")]


def test_procedures_do_not_belong_in_a_library(tmp_path):
    (tmp_path / "lib.vf").write_text("library lib\nmonitor m = go\n")
    err = error(tmp_path, 'import "lib.vf"\n')
    assert err.code == "E601" and "this monitor statement" in err.message
