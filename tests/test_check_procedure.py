"""``vfdsl check`` of a procedure (issue 33, item 4): the analyses the IR decides (docs/check.md, VF950-VF960).

Variants of the example are its text with one change (str.replace), loaded beside a copy of its scene and the
library it imports; each finding is asserted at its line, with its code."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli

import vfdsl
from vfdsl.check import monitors
from vfdsl.check.report import Severity
from vfdsl.ir import model as ir

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = REPO / "tasks" / "procedures" / "needle_procedure.vf"
TEXT = EXAMPLE.read_text()


def line(text: str, fragment: str) -> int:
    """The line of the one occurrence of ``fragment``."""
    assert text.count(fragment) == 1, fragment
    return text[:text.index(fragment)].count("\n") + 1


@pytest.fixture
def variant(tmp_path):
    """variant(old, new, ...) -> (task, text): the example with each ``old`` replaced by ``new``."""
    (tmp_path / "procedures").mkdir()
    (tmp_path / "library").symlink_to(REPO / "tasks" / "library")
    (tmp_path / "procedures" / "needle_procedure.yaml").write_text(EXAMPLE.with_suffix(".yaml").read_text())

    def make(*changes: str):
        text = TEXT
        for old, new in zip(changes[::2], changes[1::2]):
            assert old in text, old
            text = text.replace(old, new)
        path = tmp_path / "procedures" / "needle_procedure.vf"
        path.write_text(text)
        return vfdsl.load(path), text
    return make


def quick(task: ir.Task):
    """``vfdsl check`` of a variant, its compiled analyses run interpreted and without the random walk (these tests
    are about what the IR decides; the example's full check is test_the_example_passes_...)."""
    return vfdsl.check(task, samples=0, backend="interpreted")


def found(task: ir.Task, code: str):
    return [f for f in quick(task).findings if f.code == code]


def at(findings) -> list[tuple[str, int]]:
    return sorted((f.severity.value, f.span.line) for f in findings)


# ------------------------------------------------------------------------------------------------ the example
def test_the_example_is_sound_and_its_findings_are_the_procedures():
    report_task = vfdsl.load(EXAMPLE)
    report = vfdsl.check(report_task)
    assert report.exit_status() == 0 and report.count(Severity.ERROR) == 0
    by_code = {}
    for f in report.findings:
        by_code.setdefault(f.code, []).append(f)
    # the stale watchdog (first) overlaps every other transition: notes at the later ones
    watchdog = line(TEXT, "transition * -> hold")
    later = [line(TEXT, f"transition {t}") for t in ("approach ->", "align ->", "insert ->", "retract ->")]
    assert at(by_code["VF953"]) == [("note", n) for n in later] and later[0] == watchdog + 1
    assert all(f"line {watchdog}, wins" in f.message for f in by_code["VF953"])
    # approach -> align: near_entry is latched up to 1.5 mm, align holds 0.5 mm: the 200 ms blend funnels it
    [distance, angle] = sorted(by_code["VF956"], key=lambda f: f.data["constraint"], reverse=True)
    assert (distance.severity, distance.span.line, distance.data["where"]) == (
        Severity.NOTE, later[0], f"needle_procedure.vf:{line(TEXT, 'require tip stays_at(entry)')}")
    assert "violated by up to 1 mm" in distance.message and "200 ms" in distance.message
    assert math.isclose(distance.data["worst"], 1.5e-3) and angle.severity == Severity.NOTE
    # nothing states how far approach turns the needle: the note says from how far the funnel can bring it in
    # (0.29 deg a tick at the speed limits, 20 ticks), not that it brings in any angle in 200 ms
    assert "violated by up to 179 deg" in angle.message and "beyond it (at the speed limits)" in angle.message
    # insert and retract fix lines through points captured on entry: no entry finding for them
    captured = [f":{line(TEXT, r)}" for r in ("along(line(start", "keeps_direction(axis0)", "along(line(stop")]
    assert not any(f.data["where"].endswith(tuple(captured)) for f in by_code["VF956"])
    [every] = by_code["VF958"]
    assert "joint_limits()" in every.message and "joint_speed()" in every.message
    # the compiled controller's analyses ran on each phase alone, their findings saying where they hold
    assert "VF950" not in by_code and set(report.figures["phases"]) == {p.name for p in report_task.phases}
    sampled = {tuple(f.data["phases"]) for f in by_code["VF700"]}
    assert ("insert",) in sampled and ("done", "hold") in sampled
    assert all(f.message.startswith(f"in phase{'s' if len(f.data['phases']) > 1 else ''} ") for f in by_code["VF700"])
    # warnings, each justified: the library's 4x4 stays_at polytope (VF102); `done` holds the point it captures
    # on entry, so entering it violates nothing
    assert {f.code for f in report.findings if f.severity == Severity.WARNING} <= {"VF102"}


def test_a_final_phase_holding_an_earlier_capture_is_entered_violated(variant):
    """`done` holding the tip at `stop`, captured where the retraction began, while `out` fires only 10 mm from
    `stop`: every entry is at least 9.9 mm off, and the funnel would drive the needle back in (VF957)."""
    task, text = variant("    capture rest = tip.position          # where the retraction ended: held there\n", "",
                         "stays_at(rest) within 0.1 mm", "stays_at(stop) within 0.1 mm")
    [found] = [f for f in quick(task).findings if f.code == "VF957"]
    assert found.span.line == line(text, "transition retract -> done") and "at least 9.9 mm" in found.message


# ------------------------------------------------------------------------------------------------ the graph
def test_unreachable_phase(variant):
    task, text = variant("transition align -> insert when aligned", "transition align -> retract when aligned")
    [f] = found(task, "VF951")
    assert (f.severity, f.span.line) == (Severity.ERROR, line(text, "phase insert {"))
    assert "no transition leads to it" in f.message
    assert quick(task).exit_status() == 1


def test_a_transition_that_never_fires_leaves_its_targets_unreachable(variant):
    task, text = variant("< 2 deg for 100 ms", "> 190 deg for 100 ms")
    [monitor] = found(task, "VF954")                    # at the monitor; the guard naming it is not repeated
    assert monitor.span.line == line(text, "monitor aligned") and "180" in monitor.message
    unreachable = {f.span.line: f.message for f in found(task, "VF951")}
    assert set(unreachable) == {line(text, f"phase {p}") for p in ("insert {", "retract {", "done final")}
    assert "can never fire" in unreachable[line(text, "phase insert {")]
    assert "never reached: insert" in unreachable[line(text, "phase retract {")]


def test_dead_end(variant):
    task, text = variant("transition retract -> done when out\n", "",
                         "transition * -> hold when stale", "transition approach -> hold when stale")
    [dead] = found(task, "VF952")
    assert (dead.severity, dead.span.line) == (Severity.WARNING, line(text, "phase retract {"))
    assert "no transition leaves it" in dead.message
    assert [f.span.line for f in found(task, "VF951")] == [line(text, "phase done final")]


def test_a_phase_whose_only_way_out_never_fires_is_a_dead_end(variant):
    task, text = variant("monitor out = distance(tip, stop) > 10 mm", "monitor out = distance(tip, stop) < -1 mm",
                         "transition * -> hold when stale", "transition approach -> hold when stale")
    [dead] = found(task, "VF952")
    assert dead.span.line == line(text, "phase retract {") and "can never fire: retract -> done" in dead.message


# ------------------------------------------------------------------------------------------------ the guards
def test_a_guard_implied_by_an_earlier_one_never_fires(variant):
    task, text = variant("transition retract -> done when out\n",
                         "transition retract -> done when out\ntransition retract -> hold when "
                         "distance(tip, stop) > 20 mm\n")
    [f] = [f for f in found(task, "VF953") if f.span.line == line(text, "retract -> hold")
           and f.data["first"] == line(text, "retract -> done")]
    assert f.severity == Severity.WARNING and "never fires from 'retract'" in f.message


def test_overlapping_guards_and_exclusive_ones(variant):
    task, text = variant("transition retract -> done when out\n",
                         "transition retract -> done when out\n"
                         "transition retract -> hold when distance(tip, stop) < 5 mm\n"
                         "transition retract -> hold when elapsed > 5 s\n")
    first = line(text, "retract -> done")                                   # the stale watchdog's aside
    lines = {f.span.line: f for f in found(task, "VF953") if f.data["first"] == first}
    assert line(text, "hold when distance(tip, stop) < 5 mm") not in lines     # < 5 mm and > 10 mm: exclusive
    overlap = lines[line(text, "hold when elapsed > 5 s")]                        # a time and a distance can
    assert overlap.severity == Severity.NOTE and f"line {line(text, 'retract -> done')}, wins" in overlap.message


def test_latched_monitor_overlaps_where_its_latch_may_still_be_on(tmp_path):
    task = vfdsl.load(EXAMPLE)
    near = next(m for m in task.monitors if m.name == "near_entry").expr      # < 1 mm release 1.5 mm
    at_12 = near.model_copy(update={"op": ">=", "threshold": 1.2e-3, "release": None})
    at_20 = near.model_copy(update={"op": ">=", "threshold": 2e-3, "release": None})
    unlatched = near.model_copy(update={"release": None})
    assert monitors.hold_together(task, ir.MonitorRef(name="near_entry"), at_12)
    assert not monitors.hold_together(task, ir.MonitorRef(name="near_entry"), at_20)
    assert not monitors.hold_together(task, unlatched, at_12)
    ref = ir.MonitorRef(name="pushed")                                         # held: `m` and `not m` never
    assert not monitors.hold_together(task, ref, ir.Not(items=[ref]))
    condition = next(m for m in task.monitors if m.name == "pushed").expr      # norm(hand) > 5 N
    assert not monitors.hold_together(task, ref, ir.Not(items=[condition]))   # true: its condition holds now
    assert monitors.hold_together(task, ir.Not(items=[ref]), condition)       # still counting its 50 ms


def test_a_huge_guard_is_taken_to_hold_anywhere():
    task = vfdsl.load(EXAMPLE)
    near = next(m for m in task.monitors if m.name == "near_entry").expr
    factor = ir.Or(items=[near, ir.MonitorRef(name="pressed")])
    guard = ir.And(items=[factor] * 12)                                        # 4096 terms
    assert monitors.can_hold(task, guard) and not monitors.always_holds(task, guard)
    assert monitors.bounds(task, guard, near.measure).hi == math.inf


# ------------------------------------------------------------------------------------------------ the monitors
@pytest.mark.parametrize("old, new, what", [
    ("distance(tip, start) > 30 mm", "distance(tip, start) < -1 mm", "a distance to a point is at least 0"),
    ("distance(tip, start) > 30 mm", "distance(tip, start) < 0 mm", "a distance to a point is at least 0"),
    ("norm(hand) > 5 N", "norm(hand) < 0 N", "a norm is at least 0"),
    ("angle(needle, normalize(target - entry)) < 2 deg", "angle(needle, normalize(target - entry)) > 181 deg",
     "[0, 180] deg"),
    ("unchanged(hand) for 20 ms", "unchanged(hand) < -1 ms", "a time is at least 0"),
    ("distance(tip, stop) > 10 mm", "elapsed <= -1 ms", "a time is at least 0"),
])
def test_a_monitor_that_can_never_become_true(variant, old, new, what):
    task, text = variant(old, new)
    [f] = found(task, "VF954")
    assert (f.severity, f.span.line) == (Severity.ERROR, line(text, new)) and what in f.message
    assert quick(task).exit_status() == 1


def test_a_monitor_whose_thresholds_exclude_each_other(variant):
    task, text = variant("monitor out = distance(tip, stop) > 10 mm",
                         "monitor out = distance(tip, stop) > 10 mm and distance(tip, stop) < 5 mm")
    [f] = found(task, "VF954")
    assert f.span.line == line(text, "monitor out") and "can never become true" in f.message


def test_a_distance_to_a_plane_is_signed(variant):
    task, _ = variant("monitor deep = distance(tip, start) > 30 mm",
                      "monitor deep = distance(tip, plane(start, axis0)) < -30 mm")
    assert not found(task, "VF954")


def test_a_monitor_that_always_holds_and_a_latch_that_never_switches_off(variant):
    task, text = variant("distance(tip, start) > 30 mm", "distance(tip, start) >= 0 mm",
                         "< 2 deg for 100 ms", "< 2 deg release 200 deg for 100 ms")
    always = {f.span.line: f for f in found(task, "VF955")}
    assert always[line(text, "monitor deep")].severity == Severity.WARNING
    assert "never switches off" in always[line(text, "monitor aligned")].message
    # the guard `pushed or deep` always holds too: insert is left at once
    assert "always holds" in always[line(text, "transition insert -> retract")].message


def test_a_for_beyond_the_limit_and_a_nan_threshold_in_a_task_built_in_python():
    task = vfdsl.load(EXAMPLE)
    pushed = next(m for m in task.monitors if m.name == "pushed")
    long = pushed.model_copy(update={"hold": 7200.0})
    nan = pushed.model_copy(update={"name": "nan", "expr": pushed.expr.model_copy(update={"threshold": math.nan})})
    task = task.model_copy(update={"monitors": [*task.monitors, long, nan]})
    findings = [f for f in monitors.analyse(task) if f.code == "VF954"]
    assert any("7200 s" in f.message and "3600 s" in f.message for f in findings)
    assert any("monitor 'nan'" in f.message for f in findings)


# ------------------------------------------------------------------------------------------------ entering a phase
def test_an_unfunnelled_transition(variant):
    task, text = variant("blend 200 ms\n", "")
    entries = [f for f in found(task, "VF956") if f.data["where"].endswith(":37")]
    [f] = entries
    assert (f.severity, f.span.line) == (Severity.WARNING, line(text, "transition approach -> align"))
    assert "violated by up to 1 mm" in f.message and "no blend" in f.message and "add a blend" in f.suggestion
    assert quick(task).exit_status(strict=True) == 1


def test_a_guard_within_the_fixture_needs_no_funnel(variant):
    task, _ = variant("blend 200 ms\n", "", "stays_at(entry) within 0.5 mm", "stays_at(entry) within 2 mm")
    assert not [f for f in found(task, "VF956") if f.data["where"].endswith(":37")]


def test_a_per_transition_blend_funnels_only_its_transition(variant):
    task, text = variant("blend 200 ms\n", "", "when near_entry and pressed", "when near_entry and pressed blend 50 ms")
    [f] = [f for f in found(task, "VF956") if f.data["where"].endswith(":37")]
    assert f.severity == Severity.NOTE and "50 ms" in f.message


def test_a_funnel_faster_than_the_speed_limits_is_a_warning(variant):
    """near_entry up to 10 mm into align's 0.5 mm: the 200 ms funnel asks for 47.5 mm/s, the joints move the tip at
    most 26.4 mm/s along the worst facet (VF204's reach): check said "its blend's funnel brings it within 500 um in
    200 ms" while the run entered at 9.8 mm was 4.8 mm off at 200 ms, least violation for 39 ticks."""
    task, text = variant("distance(tip, entry) < 1 mm release 1.5 mm", "distance(tip, entry) < 10 mm",
                         "< 2 deg for 100 ms", "< 2 deg for 2 s")         # (the run stays in align)
    [f] = [f for f in found(task, "VF956") if f.data["where"].endswith(":37")]
    assert (f.severity, f.span.line) == (Severity.WARNING, line(text, "transition approach -> align"))
    assert "cannot bring it in" in f.message and "200 ms" in f.message
    reach = f.data["reach_per_tick"]
    assert 2e-4 < reach < 3e-4 and f.data["ticks"] == math.ceil(9.5e-3 / reach)
    # the run: pushed to 9.8 mm, then the button: the tool lags its funnel (least violation) for about that long (the
    # hand's force changes every tick: an unchanged one would be the stale sensor)
    controller = vfdsl.compile(task)
    entry = np.array([10, 5, 285]) * 1e-3
    q = np.array(task.start, dtype=float)
    for k in range(200):
        if np.linalg.norm(controller.frames(q)["tip"].position - entry) >= 9.8e-3:
            break
        q = q + controller.step(q, {"hand": np.array([5.0 + 0.01 * (k % 2), 0, 0]), "go": np.zeros(1)})
    assert controller.phase == "approach"
    late = []
    for k in range(60):
        q = q + controller.step(q, {"hand": np.array([0.01 * (k % 2), 0, 0]), "go": np.ones(1)})
        late += [k + 1] if controller.status & 1 else []
    assert controller.phase == "align" and 20 < len(late) and abs(max(late) - f.data["ticks"]) <= 0.2 * f.data["ticks"]


def test_a_funnel_within_the_speed_limits_stays_a_note(variant):
    task, text = variant("distance(tip, entry) < 1 mm release 1.5 mm", "distance(tip, entry) < 10 mm",
                         "blend 200 ms\n", "blend 500 ms\n")
    [f] = [f for f in found(task, "VF956") if f.data["where"].endswith(":37")]
    assert f.severity == Severity.NOTE and "brings it within 500 um in 500 ms" in f.message


def test_the_source_phase_fixture_bounds_the_entry(variant):
    task, _ = variant("blend 200 ms\n", "",
                      "    minimize track(tip, hand, gain = 2 mm/s/N)\n}",
                      "    minimize track(tip, hand, gain = 2 mm/s/N)\n    require tip within_distance(entry, 0.4 mm)\n}")
    assert not [f for f in found(task, "VF956") if f.data["where"].endswith(":37")]


# ------------------------------------------------------------------------------------------------ every phase
def test_a_phase_cannot_loosen_a_fixture_of_every_phase(variant):
    task, text = variant("use joint_safety()\n", "use joint_safety()\nrequire tip stays_at(entry) within 0.2 mm\n")
    [f] = found(task, "VF959")
    assert (f.severity, f.span.line) == (Severity.ERROR, line(text, "stays_at(entry) within 0.5 mm"))
    assert f"needle_procedure.vf:{line(text, 'stays_at(entry) within 0.2 mm')}" in f.message
    [every] = found(task, "VF958")
    assert "3 constraints" in every.message and "stays_at(tip)" in every.message
    tighter, _ = variant("use joint_safety()\n", "use joint_safety()\nrequire tip stays_at(entry) within 1 mm\n")
    assert not found(tighter, "VF959")


# ------------------------------------------------------------------------------------------------ JSON and the CLI
def test_cli_prints_the_procedure_findings_and_exits_0():
    proc = run_cli("check", str(EXAMPLE))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for code in ("note VF953 guards-overlap", "note VF956 entry-unfunnelled", "note VF700 sampled-summary: in phase "
                 "insert: 200 states"):
        assert code in proc.stdout
    assert proc.stdout.rstrip().splitlines()[-1].startswith("needle_procedure: sound")


def test_cli_json_carries_the_findings_and_an_error_exits_1(variant, tmp_path):
    _, text = variant("transition align -> insert when aligned", "transition align -> retract when aligned",
                      "blend 200 ms\n", "")
    proc = run_cli("check", str(tmp_path / "procedures" / "needle_procedure.vf"), "--json", "--samples", "0")
    data = json.loads(proc.stdout)
    assert proc.returncode == 1 and data["exit_status"] == 1 and not data["sound"]
    codes = {(f["code"], f["severity"], f["location"]["line"]) for f in data["findings"] if f["location"]}
    assert ("VF951", "error", line(text, "phase insert {")) in codes
    assert ("VF956", "warning", line(text, "transition approach -> align")) in codes
    json.dumps(data, allow_nan=False)


def test_monitors_without_phases_are_checked_and_the_task_analysed_as_one_moment(tmp_path):
    path = tmp_path / "t.vf"
    path.write_text('task t\nunits mm, deg\nrobot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\n'
                    "param entry : point = [10, 5, 285]\nmonitor never = distance(tip, entry) <= -1 mm\n"
                    "require tip stays_at(entry) within 1 mm\n")
    report = quick(vfdsl.load(path))
    assert [(f.code, f.span.line) for f in report.findings if f.code >= "VF950"] == [("VF954", 6)]
    assert "no-start" in {f.name for f in report.findings}         # no scene: the compiled analyses need a start


SCALAR_CAPTURE = """\
task t
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
input go : button
param entry : point = [10, 5, 285]
param r : length = 2 mm
monitor pressed = go
phase a initial { minimize track(tip, f, gain = 1 mm/s/N) }
phase b final {
    capture r0 = r
    require tip within_distance(entry, r0)
}
transition a -> b when pressed
"""


def test_a_phase_reading_a_captured_scalar_is_not_analysed_alone_the_others_are(tmp_path):
    path = tmp_path / "t.vf"
    path.write_text(SCALAR_CAPTURE)
    (tmp_path / "t.yaml").write_text("start: [0, 0, 0, 0, 0, 0, 0]\nperiod: 1 ms\n")
    report = quick(vfdsl.load(path))
    [skipped] = [f for f in report.findings if f.code == "VF950"]
    assert skipped.span.line == line(SCALAR_CAPTURE, "phase b final") and skipped.data["phase"] == "b"
    assert "'b' reads a captured input or scalar" in skipped.message
    assert set(report.figures["phases"]) == {"a", "b"} and "start_margin" in report.figures["phases"]["a"]
    assert report.figures["phases"]["b"] == {} and not any(
        "b" in f.data.get("phases", ()) for f in report.findings if f.code != "VF950")


def test_a_button_input_is_left_released_by_the_random_walk(tmp_path):
    """The sampled analysis pushes every motion input at random and leaves a button (which moves nothing) at 0."""
    from vfdsl.check.sampling import random_inputs
    path = tmp_path / "t.vf"
    path.write_text('task t\nunits mm, deg\nrobot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\n'
                    "input f : force\ninput go : button\nminimize track(tip, f, gain = 1 mm/s/N)\n")
    (tmp_path / "t.yaml").write_text("start: [0, 0, 0, 0, 0, 0, 0]\nperiod: 1 ms\n")
    task = vfdsl.load(path)
    inputs = random_inputs(task, 60, 0)
    assert all(i["go"].shape == (1,) and i["go"][0] == 0.0 for i in inputs)
    assert max(np.linalg.norm(i["f"]) for i in inputs) > 0
    report = vfdsl.check(task)
    assert report.count(Severity.ERROR) == 0 and any(f.code == "VF700" for f in report.findings)


def test_a_direction_from_two_captured_points_is_noted(variant):
    """VF960 at the expression: a line through the points captured on entry to insert and to retract; none for the
    example's line through one captured point along a captured axis."""
    assert not found(variant()[0], "VF960")
    task, text = variant("require needle along(line(stop, axis0)) within 0.5 mm",
                         "require needle along(line(start, stop)) within 0.5 mm")
    [finding] = found(task, "VF960")
    assert finding.severity == Severity.NOTE and finding.data["captures"] == ["start", "stop"]
    assert finding.span.line == line(text, "line(start, stop)")
