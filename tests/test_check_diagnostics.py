"""``vfdsl check`` findings found wanting by new users: frames used only as the base of another frame,
redundancy judged at one degenerate point, implausible speed limits, soft constraints that cannot be met
at the start, and which objective term a hands-off turn is blamed on. Each with a task that triggers the
finding and one that must not."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import TASKS_DIR
from test_check import PROBE, SCENE, codes, probe

import vfdsl
from vfdsl.check import check, hygiene
from vfdsl.check.linearized import ConstraintRows, Linearization
from vfdsl.check.report import Severity
from vfdsl.errors import Span
from vfdsl.ir import model as ir

# ------------------------------------------------------------------------------ D: frames built on frames

BASE_ONLY = PROBE.replace('frame tip = shr.link("tool_tip")',
                          'frame tip = shr.link("tool_tip")\nframe bur = tip axis [0, 0, -1]').replace(
    "track(tip,", "track(bur,").replace("require tip stays_at", "require bur stays_at")


def test_a_frame_used_only_as_the_base_of_another_is_used(tmp_path):
    task = probe(tmp_path, BASE_ONLY)
    assert "tip" not in str(task.constraints) + str(task.objectives)
    assert [f.base for f in task.frames] == [None, "tip"]
    assert hygiene.unused(task) == []


def test_an_unused_frame_built_on_another_is_reported_and_its_base_is_not(tmp_path):
    text = BASE_ONLY.replace("frame bur = tip axis [0, 0, -1]",
                             "frame bur = tip axis [0, 0, -1]\nframe spare = tip offset [0, 0, 5]")
    [finding] = hygiene.unused(probe(tmp_path, text))
    assert finding.data == {"kind": "frame", "name": "spare"} and finding.span.line == 6


# ------------------------------------------------------------------ E: redundancy over the reached region

ORBIT_ON_AXIS = """units: mm, deg
period: 10 ms
start: [0, -45, 0, -135, 0, 90, 45]              # the scope points straight down: on the tilt limit's axis
params:
  target: [306.890567, 0, 286.882052]             # on the optical axis, 200 mm below the scope
"""


def _orbit_on_axis(tmp_path):
    (tmp_path / "orbit.vf").write_text((TASKS_DIR / "tilt_limited_orbit.vf").read_text())
    (tmp_path / "orbit.yaml").write_text(ORBIT_ON_AXIS)
    return vfdsl.load(tmp_path / "orbit.vf")


@pytest.mark.parametrize("samples", [0, 40])
def test_tilt_at_most_on_its_axis_is_not_redundant(tmp_path, samples):
    """On the axis the tilt row's gradient l x a is zero: it holds trivially at that one point, and was
    called redundant; it is the task's only tilt limit."""
    task = _orbit_on_axis(tmp_path)
    found = codes(task, samples=samples)
    assert "redundant-constraint" not in found
    # the row is indeed degenerate at the start
    ctrl = vfdsl.compile(task, backend="interpreted")
    [tilt] = [r for r in Linearization(task, ctrl.assembled.context).rows(task.start)
              if r.constraint.primitive == "tilt_at_most"]
    assert np.linalg.norm(tilt.A) < 1e-12 and tilt.lb[0] < 0


def _rows(index: int, lb: float, line: int) -> ConstraintRows:
    span = Span(file="t.vf", line=line, column=1, end_line=line, end_column=10)
    c = ir.Constraint(primitive="above", frame="tip", args={}, span=span)
    return ConstraintRows(index, c, np.array([[1.0]]), np.array([lb]), np.array([np.inf]), ["half-space"], False)


def test_redundancy_is_judged_at_every_reached_state():
    """dq >= -1 is implied by dq >= 0 at the start; at a reached state it reads dq >= 0.5, which is not."""
    start = [_rows(0, 0.0, 1), _rows(1, -1.0, 2)]
    [finding] = hygiene.redundant(start, 1)
    assert finding.span.line == 2 and finding.data["states"] == 1
    later = {"q1": [_rows(0, 0.0, 1), _rows(1, 0.5, 2)], "q2": start}
    assert hygiene.redundant(start, 1, ["q1"], later.__getitem__) == []
    [finding] = hygiene.redundant(start, 1, ["q2", "q2"], later.__getitem__)
    assert finding.data["states"] == 3 and "and at 2 states the task reaches" in finding.message


def test_a_degenerate_row_is_never_redundant():
    zero = ConstraintRows(1, _rows(1, 0, 2).constraint, np.array([[0.0]]), np.array([-0.1]), np.array([np.inf]),
                          ["tilt"], False)
    assert hygiene.redundant([_rows(0, 0.0, 1), zero], 1) == []


def _inactive(index: int, line: int) -> ConstraintRows:
    """A row that always holds, 0 >= -inf: a mesh feature beyond reach."""
    return ConstraintRows(index, _rows(index, 0.0, line).constraint, np.zeros((1, 1)), np.array([-np.inf]),
                          np.array([np.inf]), ["feature 1/8"], False)


@pytest.mark.parametrize("reached", [0, 3])
def test_a_constraint_inactive_at_every_state_is_a_note_never_redundant(reached):
    start = [_rows(0, 0.0, 1), _inactive(1, 2)]
    [note] = hygiene.redundant(start, 1, ["q"] * reached, {"q": start}.__getitem__)
    assert note.name == "inactive-constraint" and note.severity == Severity.NOTE and note.span.line == 2
    assert note.data == {"states": 1 + reached} and note.message.startswith("inactive at the start")
    assert "remove" not in note.message + note.suggestion


def test_redundancy_is_judged_only_where_the_constraint_has_bounded_rows():
    """Inactive at the start; at the reached state dq >= -1, implied by dq >= 0: redundant, from that one state,
    and said so. dq >= 0.5 there: not redundant (the inactive start proves nothing either way)."""
    start = [_rows(0, 0.0, 1), _inactive(1, 2)]
    implied = {"q": [_rows(0, 0.0, 1), _rows(1, -1.0, 2)]}
    [finding] = hygiene.redundant(start, 1, ["q"], implied.__getitem__)
    assert finding.name == "redundant-constraint" and finding.data["acting_states"] == 1
    assert finding.data["states"] == 2 and "at the 1 of these 2 where it has a bounded row" in finding.message
    assert "before removing it" in finding.suggestion
    not_implied = {"q": [_rows(0, 0.0, 1), _rows(1, 0.5, 2)]}
    assert hygiene.redundant(start, 1, ["q"], not_implied.__getitem__) == []


def test_inactive_rows_of_a_constraint_with_bounded_ones_are_not_tested():
    """One bounded row implied by the others and one row 0 >= -inf: redundant at every state, as before."""
    both = ConstraintRows(1, _rows(1, 0, 2).constraint, np.array([[1.0], [0.0]]), np.array([-1.0, -np.inf]),
                          np.array([np.inf, np.inf]), ["feature 1/8", "feature 2/8"], False)
    [finding] = hygiene.redundant([_rows(0, 0.0, 1), both], 1)
    assert finding.data["acting_states"] == finding.data["states"] == 1
    assert finding.suggestion.startswith("remove it")


# --------------------------------------------------------------------------- F: implausible speed limits

@pytest.mark.parametrize("statement, severity, message", [
    ("require tip speed(0.001 mm/s)", Severity.ERROR,
     "a limit of 1 um/s is below the plausible range [10 um/s, 5 m/s]: at it a correction of 1 mm takes 1e+03 s"),
    ("require tip speed(0.001)", Severity.ERROR, "a limit of 1 um/s is below"),          # `units mm`: 1 um/s
    ("require tip angular_speed(0.001 deg/s)", Severity.ERROR, "a limit of 0.01745 mrad/s is below"),
    ("require tip speed(0.001 mm/s) soft weight 1", Severity.WARNING, "a limit of 1 um/s is below"),
    ("require tip speed(50 m/s)", Severity.WARNING, "a limit of 50 m/s is above the plausible range"),
])
def test_implausible_cartesian_speed_limits_are_named(tmp_path, statement, severity, message):
    [finding] = codes(probe(tmp_path, PROBE + statement + "\n"), samples=0)["speed-implausible"]
    assert finding.severity == severity and message in finding.message and finding.span.line == 12


def test_a_tiny_joint_speed_fraction_is_an_error_and_slow_corrections_name_it(tmp_path):
    text = PROBE.replace("require joint_speed()", "require joint_speed(fraction = 0.00001)")
    found = codes(probe(tmp_path, text), samples=0)
    [finding] = found["speed-implausible"]
    assert finding.severity == Severity.ERROR and finding.span.line == 11
    assert "fraction = 1e-05 of the URDF velocity limits is below the plausible range [0.001, 1]" in finding.message
    [slow] = found["tolerance-restore-ticks"]
    assert slow.span.line == 9 and "the limit: joint_speed(fraction = 1e-05) at probe.vf:11" in slow.message
    assert slow.data["limited_by"] == ["probe.vf:11"]


def test_slow_corrections_name_the_speed_limit_that_causes_them(tmp_path):
    found = codes(probe(tmp_path, PROBE + "require tip speed(0.001 mm/s)\n"), samples=0)
    [slow] = found["tolerance-restore-ticks"]
    assert slow.span.line == 9 and "the limit: speed(tip) of 1 um/s at probe.vf:12" in slow.message
    assert slow.data["limited_by"] == ["probe.vf:12"]


def test_plausible_speed_limits_pass(tmp_path):
    text = PROBE + "require tip speed(5 mm/s)\nrequire tip angular_speed(10 deg/s)\n"
    text = text.replace("require joint_speed()", "require joint_speed(fraction = 0.5)")
    assert "speed-implausible" not in codes(probe(tmp_path, text), samples=0)


# ------------------------------------------------------------------- G: soft constraints unmet at the start

SOFT_ONLY = PROBE.replace("require tip stays_at(target) within 0.05 resolution 12x12",
                          "require tip stays_at(target) within 0.5 soft weight 1 priority 1")


@pytest.mark.parametrize("target, severity", [("[300, 0, 290]", Severity.WARNING), ("[20, 0, 290]", Severity.NOTE)])
def test_a_soft_constraint_unmet_at_the_start_is_reported_with_its_error(tmp_path, target, severity):
    task = probe(tmp_path, SOFT_ONLY.replace("[0, 0, 290]", target))
    report = check(task, backend="interpreted", samples=0)
    [finding] = [f for f in report.findings if f.name == "soft-unmet-at-start"]
    assert finding.severity == severity and finding.span.line == 9 and finding.code == "VF403"
    x = float(target[1:].split(",")[0]) * 1e-3
    assert finding.data["error"] == pytest.approx(x, rel=1e-6)          # the tip starts at (0, 0, 290) mm
    assert f"its error is {x * 1e3:.4g} mm against its 500 um tolerance" in finding.message
    assert report.figures["soft_at_start"]["probe.vf:9"]["error"] == pytest.approx(x, rel=1e-6)
    if severity == Severity.WARNING:
        # x stage +-60 mm plus the tool's first-order swing: about 70 mm of reach toward +x; 229 mm short
        assert "cannot be met at the start" in finding.message and 0.2 < finding.data["short"] < 0.25
    else:
        assert finding.data["meetable"] and finding.data["short"] < 1e-9


def test_a_soft_constraint_met_at_the_start_is_not_reported(tmp_path):
    assert "soft-unmet-at-start" not in codes(probe(tmp_path, SOFT_ONLY), samples=0)


# --------------------------------------------------------------- H: which cost a hands-off turn is blamed on

TURNING = PROBE.replace("minimize damping() weight 1e-6", "minimize centering() weight 1e-3").replace(
    "require tip stays_at(target) within 0.05 resolution 12x12",
    "require tip keeps_direction([0, 0.2, 1]) within 1 deg soft weight 1")


@pytest.mark.parametrize("with_centering", [True, False])
def test_a_turn_made_by_a_soft_constraint_is_blamed_on_it_not_on_centering(tmp_path, with_centering):
    """The tool axis starts 11.3 deg from the soft keeps_direction's direction: the soft constraint turns
    it (level 1); centering (level 2) only gains along the way. Removing centering changes nothing."""
    text = TURNING if with_centering else TURNING.replace("minimize centering() weight 1e-3\n", "")
    [finding] = codes(probe(tmp_path, text), samples=0)["handsoff-drift"]
    assert finding.data["turned"] > 0.17                      # about 10 deg in 0.5 s
    assert finding.data["cause"].startswith("soft `keeps_direction` at probe.vf:")
    assert "centering" not in finding.data["cause"]


def test_centering_alone_is_still_blamed_for_its_own_motion(tmp_path):
    text = PROBE.replace("minimize track(tip, f, gain = 1 mm/s/N)\n", "").replace(
        "minimize damping() weight 1e-6", "minimize centering() weight 1")
    [finding] = codes(probe(tmp_path, text, SCENE.replace("x: 0", "x: 30")), samples=0)["handsoff-drift"]
    assert finding.data["cause"].startswith("`minimize centering` at probe.vf:7 (priority 2")


def test_redundancy_is_confirmed_at_a_bounded_number_of_states():
    start = [_rows(0, 0.0, 1), _rows(1, -1.0, 2)]
    asked = []

    def rows_at(q):
        asked.append(q)
        return start

    [finding] = hygiene.redundant(start, 1, list(range(1000)), rows_at)
    assert finding.data["states"] == 1 + hygiene.REDUNDANCY_STATES and len(asked) == hygiene.REDUNDANCY_STATES
    assert asked[0] == 0 and asked[-1] == 999


def test_a_mistaken_scene_value_names_the_param_and_the_scene_line(tasks_copy):
    """A flipped normal set in the scene: check names the constraint that fails at the start and, in notes,
    the param's declaration and the scene line where its value is written (where the user must edit)."""
    scene = tasks_copy / "lecture_forbidden_half_space.yaml"
    scene.write_text(scene.read_text() + "params:\n  wall: {point: [0, 0, 270], normal: [0, 0, -1]}\n")
    report = vfdsl.check(vfdsl.load(tasks_copy / "lecture_forbidden_half_space.vf"), samples=0)
    serious = [f for f in report.findings if f.severity != Severity.NOTE and "above" in f.subject]
    assert serious, report.render_text()
    for finding in serious:
        assert any("reads param 'wall', declared at" in note and "lecture_forbidden_half_space.vf:12:1" in note
                   and "its value set at" in note and "lecture_forbidden_half_space.yaml:5" in note
                   for note in finding.notes), finding.render()
        assert "lecture_forbidden_half_space.yaml:5" in finding.render()
    default = vfdsl.check(vfdsl.load(TASKS_DIR / "lecture_forbidden_half_space.vf"), samples=0)
    for finding in default.findings:      # a default written at the declaration: no 'value set at' note
        assert not any("its value set at" in note for note in finding.notes)
