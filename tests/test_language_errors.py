"""Malformed task files: each one must raise VfError at the exact line and column of the mistake, with a
message (and, where there is something to suggest, a hint) that tells the user what to write instead.

Most cases edit one line of BASE (below) or append to it; line and column numbers are 1-based and were read
off the text by hand. Files are written to ``tmp_path`` and use the shipped robot (``urdf "shr7"``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import pytest

import vfdsl
from vfdsl import VfError

BASE = """\
task t
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
param p : point = [0, 0, 290]
minimize track(tip, f, gain = 1 mm/s/N)
require tip stays_at(p) within 1 um resolution 4x4
"""
# Line 9 is the first line of anything appended to BASE.

BASE_WITH_AXIS = BASE + "param ax : direction = [0, 0, 1]\n"      # line 9; appended lines start at 10

START_OK = "{x: 0, y: 0, z: 0, rcm_a: 0, rcm_b: 0, roll: 0, insert: 10}"


def edit(old: str, new: str, text: str = BASE) -> str:
    assert text.count(old) == 1, f"{old!r} must occur exactly once"
    return text.replace(old, new)


def with_import(path: str, text: str = BASE) -> str:
    """BASE with `import PATH` as line 3 (so every later BASE line moves down by one)."""
    return edit("units mm, deg\n", f'units mm, deg\nimport "{path}"\n', text)


@dataclass
class Case:
    id: str
    text: str                                  # the task file, task.vf
    line: int
    column: int
    message: str                               # a substring of err.message
    hint: str | None = None                    # a substring of err.hint (None: no check)
    files: dict[str, str] = field(default_factory=dict)   # other files next to task.vf
    where: str = "task.vf"                     # the file the error points into


CASES = [
    # ------------------------------------------------------------------------------------------- syntax
    Case("missing-paren", edit("gain = 1 mm/s/N)", "gain = 1 mm/s/N"), 8, 1,
         "unexpected 'require'; expected ')'"),
    # a call left open before its clause (the hint said "'port' was read as a unit; did you mean 'import'?")
    Case("unclosed-call-before-clause", edit("stays_at(p) within", "stays_at(port within",
                                             edit("param p :", "param port :")), 8, 27,
         "unexpected 'within'", hint="is a ')' missing before 'within'?"),
    Case("misspelt-keyword-require", edit("require tip", "requir tip"), 8, 1,
         "unexpected name 'requir'", hint="did you mean 'require'?"),
    Case("misspelt-keyword-param", edit("input f : force\n", "input f : force\nparm q : point = [0, 0, 0]\n"),
         6, 1, "unexpected name 'parm'", hint="did you mean 'param'?"),
    Case("misspelt-header", edit("task t", "tsk t"), 1, 1,
         "expected 'library' or 'task'", hint="did you mean 'task'?"),
    Case("unterminated-vector", edit("[0, 0, 290]", "[0, 0, 290"), 7, 1,
         "unexpected 'minimize'; expected ',' or ']'"),
    Case("stray-character", edit("input f : force", "input f : force $"), 5, 17,
         "unexpected character '$'"),
    Case("bad-resolution", edit("resolution 4x4", "resolution x"), 8, 48,
         "expected a resolution such as 8 or 4x4"),
    Case("negative-resolution", edit("resolution 4x4", "resolution -4"), 8, 48,
         "unexpected number -4; expected a resolution such as 8 or 4x4"),
    Case("end-of-file-inside-call", BASE + "require tip stays_at(p", 9, 23, "unexpected end of file"),
    Case("clause-twice", edit("resolution 4x4", "resolution 4x4 soft within 2 um"), 8, 57,
         "the 'within' clause is given twice"),
    # ------------------------------------------------------------------------------------ unknown names
    Case("unknown-frame", BASE + 'frame shaft = shr.link("tool_holder")\nrequire tpi speed(10 mm/s)\n',
         10, 9, "unknown frame 'tpi'", hint="did you mean 'tip'? known frames: shaft, tip"),
    Case("unknown-param", edit("stays_at(p)", "stays_at(pp)"), 8, 22,
         "unknown point 'pp'", hint="did you mean 'p'? known points: p"),
    Case("unknown-input", edit("track(tip, f,", "track(tip, ff,"), 7, 21,
         "unknown input 'ff'", hint="did you mean 'f'?"),
    Case("unknown-robot-urdf", edit('urdf "shr7"', 'urdf "shr8"'), 3, 1,
         "no robot 'shr8'", hint="did you mean 'shr7'?"),
    Case("unknown-robot-name", edit("shr.link", "sh.link"), 4, 13,
         "unknown robot 'sh'", hint="did you mean 'shr'?"),
    Case("unknown-link", edit('"tool_tip"', '"tool_tp"'), 4, 22,
         "robot 'shr' has no link 'tool_tp'", hint="did you mean 'tool_tip'?"),
    Case("unknown-primitive", edit("stays_at(p)", "stay_at(p)"), 8, 13,
         "unknown primitive 'stay_at'", hint="did you mean 'stays_at'?"),
    Case("objective-used-as-constraint", BASE + "require tip damping()\n", 9, 13,
         "unknown primitive 'damping'", hint="is an objective term: write `minimize damping(...)`"),
    Case("constraint-used-as-objective", edit("track(tip, f, gain = 1 mm/s/N)", "stays_at(p)"), 7, 10,
         "unknown objective term 'stays_at'", hint="is a constraint: write `require <frame> stays_at(...)`"),
    Case("unknown-fixture",
         with_import("lib.vf") + "use stay_neer(tip, p, 3 mm)\n", 10, 5,
         "unknown fixture 'stay_neer'", hint="did you mean 'stay_near'?",
         files={"lib.vf": "library lib\nunits mm\n"
                          "fixture stay_near(f: frame, goal: point, radius: length) {\n"
                          "    require f within_distance(goal, radius)\n}\n"}),
    Case("unknown-kwarg", edit("gain = 1", "gian = 1"), 7, 24,
         "track(...) has no argument 'gian'", hint="did you mean 'gain'?"),
    Case("unknown-input-type", edit("input f : force", "input f : forse"), 5, 11,
         "unknown input type 'forse'", hint="did you mean 'force' or 'pose'?"),
    Case("unknown-param-type", edit("param p : point", "param p : pointt"), 6, 11,
         "unknown param type 'pointt'", hint="did you mean 'point'?"),
    Case("wrong-kind-of-name", BASE + "require tip stays_at(f)\n", 9, 22,
         "expected a point, but 'f' is an input"),
    Case("too-many-arguments", edit("stays_at(p)", "stays_at(p, p)"), 8, 25,
         "stays_at(...) takes 1 argument, got 2", hint="its arguments are: target"),
    # -------------------------------------------------------------------------------------------- units
    Case("length-where-angle-expected", BASE_WITH_AXIS + "require tip cone(ax, 15 mm)\n", 10, 22,
         "expected an angle, but 'mm' is a length", hint="5 deg"),
    Case("angle-where-length-expected", edit("within 1 um", "within 1 deg"), 8, 32,
         "expected a length, but 'deg' is an angle", hint="5 mm"),
    Case("unknown-unit", edit("within 1 um", "within 1 umm"), 8, 32,
         "unknown unit 'umm'", hint="did you mean 'um'?"),
    Case("unit-on-direction", edit("[0, 0, 1]", "[0, 0, 1 mm]", BASE_WITH_AXIS), 9, 31,
         "expected a plain number, but 'mm' is a length", hint="without a unit"),
    Case("gain-wrong-dimension", edit("1 mm/s/N", "1 mm/s"), 7, 31,
         "expected a quantity in m/(s*N), but 'mm/s' is a speed"),
    Case("two-length-units", edit("units mm, deg", "units mm, cm"), 2, 11,
         "two units for a length: 'mm' and 'cm'"),
    Case("two-units-statements", edit("units mm, deg", "units mm\nunits deg"), 3, 1,
         "only one `units` statement per file"),
    Case("fixture-argument-wrong-unit", with_import("lib.vf") + "use stay_near(tip, p, 3 deg)\n", 10, 23,
         "expected a length, but 'deg' is an angle",
         files={"lib.vf": "library lib\nfixture stay_near(f: frame, goal: point, radius: length) {\n"
                          "    require f within_distance(goal, radius)\n}\n"}),
    # ------------------------------------------------------------------------------------------- shapes
    Case("point-with-two-numbers", edit("[0, 0, 290]", "[0, 290]"), 6, 19,
         "a point needs 3 numbers, got 2", hint="[x, y, z]"),
    Case("zero-direction", edit("[0, 0, 1]", "[0, 0, 0]", BASE_WITH_AXIS), 9, 24,
         "a direction cannot be zero", hint="non-zero"),
    Case("curve-too-few-points",
         BASE + "param c : curve(degree = 5) = bspline(points = [[0,0,0],[1,0,0],[2,0,0]])\n", 9, 48,
         "a degree-5 b-spline needs at least 6 points, got 3"),
    Case("sphere-resolution-on-polygon", BASE_WITH_AXIS + "require tip cone(ax, 15 deg) resolution 4x4\n",
         10, 41, "cone is bounded by a polygon: give its number of sides", hint="resolution 8"),
    Case("polygon-resolution-on-sphere", edit("resolution 4x4", "resolution 8"), 8, 48,
         "stays_at is bounded by a sphere polytope", hint="resolution 4x4"),
    Case("resolution-below-3", edit("resolution 4x4", "resolution 2x4"), 8, 48,
         "a bounded polytope needs at least 3 directions per angle"),
    Case("non-positive-tolerance", BASE + "require tip stays_at(p) within -1 mm\n", 9, 32,
         "a tolerance must be positive"),
    # ------------------------------------------------------------------------------------------ imports
    Case("import-cycle", with_import("a.vf"), 2, 1, "import cycle: a.vf -> b.vf -> a.vf",
         files={"a.vf": 'library a\nimport "b.vf"\n', "b.vf": 'library b\nimport "a.vf"\n'}, where="b.vf"),
    Case("import-a-task", with_import("other.vf"), 3, 1, "'other.vf' is a task, not a library",
         hint="only files that start with `library NAME` can be imported", files={"other.vf": BASE}),
    Case("import-missing-file", with_import("missing.vf"), 3, 1, "file not found"),
    Case("library-with-a-param", with_import("lib.vf"), 2, 1,
         "a library holds only fixtures, imports and units; this param statement belongs in a task",
         files={"lib.vf": "library lib\nparam x : point = [0, 0, 0]\n"}, where="lib.vf"),
    # --------------------------------------------------------------------------------------- duplicates
    Case("frame-declared-twice", BASE + 'frame tip = shr.link("tool_holder")\n', 9, 7,
         "'tip' is declared twice", hint="first declared at"),
    Case("param-shadows-frame", BASE + "param tip : point = [0, 0, 0]\n", 9, 7, "'tip' is declared twice"),
    Case("fixture-defined-twice",
         BASE + "fixture fx(a: frame) { require a stays_at([0, 0, 0]) }\nfixture fx(b: frame) { }\n", 10, 9,
         "fixture 'fx' is defined twice", hint="first defined at"),
    Case("formal-twice", BASE + "fixture fx(a: frame, a: point) { require a stays_at([0, 0, 0]) }\n", 9, 22,
         "formal 'a' appears twice"),
    # ----------------------------------------------------------------------------------------- fixtures
    Case("fixture-recursion",
         BASE + "fixture fx(a: frame) { use gx(a) }\nfixture gx(b: frame) { use fx(b) }\nuse fx(tip)\n",
         10, 24, "fixture 'fx' uses itself: fx -> gx -> fx"),
    Case("fixture-uses-task-name", BASE + "fixture fx(a: frame) { require a stays_at(p) }\nuse fx(tip)\n", 9, 43,
         "unknown name 'p' in fixture 'fx'", hint="a fixture body sees only its formals"),
    Case("fixture-missing-argument", with_import("lib.vf") + "use stay_near(tip, p)\n", 10, 5,
         "fixture 'stay_near' is missing argument radius", hint="its arguments are: f, goal, radius",
         files={"lib.vf": "library lib\nfixture stay_near(f: frame, goal: point, radius: length) {\n"
                          "    require f within_distance(goal, radius)\n}\n"}),
    Case("use-with-clauses", BASE + "fixture fx(a: frame) { require a stays_at([0, 0, 0]) }\nuse fx(tip) soft\n",
         10, 1, "`use` takes no clauses"),
    # ------------------------------------------------------------------------------------------ clauses
    Case("weight-on-hard-constraint", edit("resolution 4x4", "resolution 4x4 weight 10"), 8, 59,
         "`weight` applies to soft constraints", hint="add `soft`"),
    Case("within-without-tolerance", BASE + "require tip speed(10 mm/s) within 1 mm\n", 9, 35,
         "speed takes no tolerance (`within`)"),
    Case("within-on-objective", BASE + "minimize damping() within 1 mm\n", 9, 27,
         "`within` applies to constraints, not to objective terms"),
    Case("track-without-gain", edit("track(tip, f, gain = 1 mm/s/N)", "track(tip, f)"), 7, 10,
         "track with a force input needs gain", hint="gain = 2 mm/s/N"),
    # ------------------------------------------------------------------------------------------- params
    Case("missing-param-value", BASE + "param g : point\n", 9, 7, "param 'g' has no value",
         hint="set params.g in the scene file"),
    Case("in-frame-not-a-pose", edit("param p : point = [0, 0, 290]", "param p : point in plate = [0, 0, 290]"),
         6, 20, "'plate' is not a pose param"),
    # -------------------------------------------------------------------------------------------- scene
    Case("unknown-scene-key", BASE + 'scene "s.yaml"\n', 2, 1, "unknown scene key 'strat'",
         hint="did you mean 'start'?", files={"s.yaml": "period: 10 ms\nstrat: [0, 0, 0, 0, 0, 0, 0]\n"},
         where="s.yaml"),
    Case("unknown-joint-in-start", BASE + 'scene "s.yaml"\n', 2, 47, "robot 'shr7' has no joint 'rol'",
         hint="did you mean 'roll'?",
         files={"s.yaml": "units: mm, deg\n" + "start: " + START_OK.replace("roll", "rol") + "\n"}, where="s.yaml"),
    Case("start-outside-joint-limits", BASE + 'scene "s.yaml"\n', 2, 18,
         "joint rcm_a starts outside its limits",
         files={"s.yaml": "units: mm, deg\nstart: [0, 0, 0, 90, 0, 0, 10]\n"}, where="s.yaml"),
    Case("start-outside-joint-limits-bare-si", BASE.replace("units mm, deg\n", "") + 'scene "s.yaml"\n', 1, 64,
         "joint insert starts outside its limits", hint="20 mm is within the limits: write `20 mm`",
         files={"s.yaml": "start: {x: 0, y: 0, z: 0, rcm_a: 0, rcm_b: 0, roll: 0, insert: 20}\n"}, where="s.yaml"),
    Case("start-outside-joint-limits-bare-rad", edit("units mm, deg", "units mm") + 'scene "s.yaml"\n', 1, 18,
         "joint rcm_a starts outside its limits", hint="a bare angle here is in rad",
         files={"s.yaml": "start: [0, 0, 0, 30, 0, 0, 10]\n"}, where="s.yaml"),
    Case("start-wrong-length", BASE + 'scene "s.yaml"\n', 2, 8, "the start configuration needs 7 joint values",
         files={"s.yaml": "units: mm, deg\nstart: [0, 0, 0, 0, 0, 10]\n"}, where="s.yaml"),
    Case("malformed-yaml", BASE + 'scene "s.yaml"\n', 3, 7, "malformed YAML",
         files={"s.yaml": "units: mm, deg\nstart: [0, 0, 0, 0, 0, 0, 10\nperiod: 10 ms\n"}, where="s.yaml"),
    Case("scene-sets-unknown-param", BASE + 'scene "s.yaml"\n', 2, 3,
         "the scene sets 'q', which is not a param of this task", hint="known params: p",
         files={"s.yaml": "params:\n  q: [1, 2, 3]\n"}, where="s.yaml"),
    Case("scene-period-wrong-unit", BASE + 'scene "s.yaml"\n', 1, 9, "expected a time, but 'mm' is a length",
         files={"s.yaml": "period: 10 mm\n"}, where="s.yaml"),
    Case("scene-file-missing", BASE + 'scene "nope.yaml"\n', 9, 1, "scene file not found"),
    # ------------------------------------------------------------------------------------ robots, subjects
    Case("two-robots", BASE + 'robot arm = urdf "panda7"\n', 9, 1, "a task drives exactly one robot"),
    Case("frame-primitive-without-subject", BASE + "require stays_at(p)\n", 9, 9,
         "stays_at applies to a task frame", hint="write `require <frame> stays_at(...)`"),
    Case("robot-primitive-with-subject", BASE + "require tip joint_limits()\n", 9, 9,
         "joint_limits applies to the whole robot, not to a frame", hint="write `require joint_limits(...)`"),
    Case("library-loaded-as-task", edit("task t", "library t"), 1, 9, "is a library; load a task file"),
    # ---------------------------------- non-finite numbers spelled as names (were "unknown length 'nan'", E201)
    Case("tolerance-nan", edit("within 1 um", "within nan"), 8, 32, "'nan' is not a number: numbers must be finite",
         hint="write a finite number"),
    Case("weight-inf", BASE + "minimize damping() weight inf\n", 9, 27, "'inf' is not a number"),
    Case("point-item-nan", edit("[0, 0, 290]", "[0, 0, NaN]"), 6, 26, "'NaN' is not a number"),
    Case("param-value-infinity", BASE + "param r : length = Infinity\n", 9, 20, "'Infinity' is not a number"),
    # with a unit after it (was E101 "unexpected name 'um'" at the unit)
    Case("tolerance-nan-unit", edit("within 1 um", "within nan um"), 8, 32, "'nan' is not a number",
         hint="write a finite number"),
    Case("param-value-inf-unit", BASE + "param r : angle = -inf deg\n", 9, 20, "'inf' is not a number"),
    Case("point-item-nan-unit", edit("[0, 0, 290]", "[NaN, 0, 0] mm"), 6, 20, "'NaN' is not a number"),
]


def write_files(root: Path, case: Case) -> Path:
    for name, text in case.files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    task = root / "task.vf"
    task.write_text(case.text)
    return task


def load_error(root: Path, case: Case) -> VfError:
    task = write_files(root, case)
    with pytest.raises(VfError) as info:
        vfdsl.load(task)
    return info.value


def test_there_are_at_least_30_cases():
    assert len(CASES) >= 30
    assert len({c.id for c in CASES}) == len(CASES)


def test_base_task_is_valid(tmp_path):
    (tmp_path / "task.vf").write_text(BASE)
    task = vfdsl.load(tmp_path / "task.vf")
    assert [c.primitive for c in task.constraints] == ["stays_at"]
    (tmp_path / "task.vf").write_text(BASE_WITH_AXIS)
    vfdsl.load(tmp_path / "task.vf")


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_error(tmp_path, case: Case):
    err = load_error(tmp_path, case)
    assert err.pos is not None, f"no position: {err.render()}"
    assert Path(err.pos.file).resolve() == (tmp_path / case.where).resolve(), err.render()
    assert (err.pos.line, err.pos.column) == (case.line, case.column), err.render()
    assert case.message in err.message, err.render()
    if case.hint is not None:
        assert err.hint is not None and case.hint in err.hint, err.render()
    rendered = err.render()                                 # rendering never fails and carries the position
    assert rendered.startswith(f"{err.pos.file}:{case.line}:{case.column}: error: ")


# ------------------------------------------------------------------------------------------------ render

def caret_columns(rendered: str) -> tuple[str, int, int]:
    """(source line as shown, column of the first caret (1-based), number of carets) of a rendered error."""
    lines = rendered.splitlines()
    source, carets = lines[1], lines[2]
    bar = source.index("| ") + 2
    assert carets.index("|") == source.index("|"), "the caret line's gutter lines up with the source line's"
    first = carets.index("^")
    return source[bar:], first - bar + 1, carets.count("^")


def test_render_shows_line_and_caret(tmp_path):
    case = next(c for c in CASES if c.id == "unknown-frame")
    err = load_error(tmp_path, case)
    rendered = err.render()
    lines = rendered.splitlines()
    assert lines[0] == f"{tmp_path / 'task.vf'}:10:9: error: unknown frame 'tpi'"
    assert lines[1] == " 10 | require tpi speed(10 mm/s)"
    assert lines[2] == "    |         ^^^"
    assert lines[3] == "hint: did you mean 'tip'? known frames: shaft, tip"
    source, column, width = caret_columns(rendered)
    assert source[column - 1:column - 1 + width] == "tpi"
    assert str(err) == rendered


@pytest.mark.parametrize("case_id, underlined", [
    ("unknown-unit", "1 umm"),
    ("unknown-link", '"tool_tp"'),
    ("unit-on-direction", "1 mm"),
    ("weight-on-hard-constraint", "10"),
    ("stray-character", "$"),
    ("unknown-joint-in-start", "rol"),
    ("malformed-yaml", ":"),
    ("tolerance-nan-unit", "nan"),
])
def test_caret_underlines_the_mistake(tmp_path, case_id, underlined):
    case = next(c for c in CASES if c.id == case_id)
    err = load_error(tmp_path, case)
    source, column, width = caret_columns(err.render())
    assert column == case.column
    assert source[column - 1:column - 1 + width] == underlined


def test_render_of_scene_error_shows_the_yaml_line(tmp_path):
    case = next(c for c in CASES if c.id == "unknown-scene-key")
    rendered = load_error(tmp_path, case).render()
    assert rendered.splitlines()[0].startswith(f"{tmp_path / 's.yaml'}:2:1: error: unknown scene key 'strat'")
    assert " 2 | strat: [0, 0, 0, 0, 0, 0, 0]" in rendered
    assert "   | ^^^^^" in rendered


def test_render_without_position():
    err = VfError("something is wrong", hint="fix it")
    assert err.render() == "error: something is wrong\nhint: fix it"


def test_error_in_a_library_points_into_the_library(tmp_path):
    lib = "library lib\nunits mm\nfixture bad(f: frame) {\n    require f stays_at([0, 0]) within 1\n}\n"
    case = Case("lib", with_import("lib.vf") + "use bad(tip)\n", 0, 0, "", files={"lib.vf": lib})
    err = load_error(tmp_path, case)
    assert Path(err.pos.file).resolve() == (tmp_path / "lib.vf").resolve()
    assert (err.pos.line, err.pos.column) == (4, 24)
    assert "a point needs 3 numbers, got 2" in err.message
