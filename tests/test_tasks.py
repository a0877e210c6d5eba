"""The example tasks in ``tasks/``: they load, their IR round-trips through ``vfdsl show``, the IR says what
the paper and the lecture say, and each scene's start configuration puts the robot where the task needs it.

Expected values are computed here from the task text and the papers (not read back from the front end), and
the start poses are checked with the robot's own forward kinematics.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import TASKS_DIR, run_cli
from scipy.spatial.transform import Rotation

import vfdsl
from vfdsl import Task
from vfdsl.cli import main as cli_main
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import ROBOTS_DIR, Robot

TASK_FILES = sorted(TASKS_DIR.glob("*.vf"))
TASK_IDS = [p.stem for p in TASK_FILES]
LIBRARY = TASKS_DIR / "library" / "fixtures.vf"

MM = 1e-3
DEG = math.pi / 180.0


# ----------------------------------------------------------------------------------------------- helpers

def line_of(path: Path, prefix: str) -> int:
    """1-based number of the first line of ``path`` whose text (indentation stripped) starts with ``prefix``."""
    for number, text in enumerate(path.read_text().splitlines(), start=1):
        if text.strip().startswith(prefix):
            return number
    raise AssertionError(f"no line starting with {prefix!r} in {path}")


def only(items: list, what: str):
    assert len(items) == 1, f"expected exactly one {what}, got {len(items)}"
    return items[0]


def constraints_of(task: Task, primitive: str, frame: str | None = None) -> list[ir.Constraint]:
    return [c for c in task.constraints if c.primitive == primitive and (frame is None or c.frame == frame)]


def const(arg: ir.Arg) -> ir.Value:
    assert isinstance(arg, ir.Const), f"expected a compile-time constant, got {arg!r}"
    return arg.value


def unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def same_file(a: str, b: Path) -> bool:
    return Path(a).resolve() == b.resolve()


@pytest.fixture(scope="module")
def loaded() -> dict[str, Task]:
    return {p.stem: vfdsl.load(p) for p in TASK_FILES}


def start_pose(task: Task, frame: str = "tip") -> tuple[Robot, np.ndarray, np.ndarray]:
    """(robot, p, R) of a task frame at the scene's start configuration, by the robot's own FK."""
    robot = Robot.load(task.robots[0].urdf)
    decl = task.frame(frame)
    offset = np.eye(4)
    offset[:3, :3] = Rotation.from_euler("xyz", decl.rpy).as_matrix()
    offset[:3, 3] = decl.offset
    assert task.start is not None, f"{task.name}: the scene gives no start configuration"
    p, R = robot.frame_pose(task.start, decl.link, offset)
    return robot, p, R


# --------------------------------------------------------------------------------- every task, generically

def test_there_are_example_tasks():
    assert {"paper_a_follow_curve", "paper_b_virtual_rcm"} <= set(TASK_IDS)
    assert len(TASK_FILES) >= 7


@pytest.mark.parametrize("path", TASK_FILES, ids=TASK_IDS)
def test_task_loads(path: Path):
    task = vfdsl.load(path)
    assert task.name == path.stem
    assert len(task.robots) == 1
    assert task.constraints, "every example task has at least one constraint"
    assert task.objectives, "every example task has at least one objective term"


@pytest.mark.parametrize("path", TASK_FILES, ids=TASK_IDS)
def test_json_from_cli_round_trips(path: Path):
    """`vfdsl show --format json` gives back exactly the task vfdsl.load builds (the command as a separate process:
    tests/test_cli.py)."""
    proc = run_cli("show", str(path), "--format", "json")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert Task.model_validate_json(proc.stdout) == vfdsl.load(path)


@pytest.mark.parametrize("path", TASK_FILES, ids=TASK_IDS)
def test_yaml_from_cli_round_trips(path: Path, capsys):
    assert cli_main(["show", str(path), "--format", "yaml"]) == 0
    out = capsys.readouterr().out
    assert Task.model_validate(yaml.safe_load(out)) == vfdsl.load(path)


@pytest.mark.parametrize("path", TASK_FILES, ids=TASK_IDS)
def test_default_format_is_yaml(path: Path, capsys):
    assert cli_main(["show", str(path)]) == 0
    out = capsys.readouterr().out
    assert not out.lstrip().startswith("{")
    assert yaml.safe_load(out)["name"] == path.stem


@pytest.mark.parametrize("path", TASK_FILES, ids=TASK_IDS)
def test_every_statement_keeps_its_source(path: Path):
    """Each constraint/objective points at its own `require`/`minimize` line; one that comes from a fixture
    also lists the `use` lines it was expanded through, outermost (in the task file) first."""
    task = vfdsl.load(path)
    for stmt in [*task.constraints, *task.objectives]:
        keyword = "require" if isinstance(stmt, ir.Constraint) else "minimize"
        src = Path(stmt.span.file).read_text().splitlines()[stmt.span.line - 1]
        assert src[stmt.span.column - 1:].startswith(keyword), (stmt, src)
        if same_file(stmt.span.file, path):
            assert stmt.via == []
            continue
        assert stmt.via, f"{stmt} comes from another file but has no `via`"
        assert same_file(stmt.via[0].file, path)
        for site in stmt.via:
            text = Path(site.file).read_text().splitlines()[site.line - 1]
            assert text[site.column - 1:].startswith("use "), (site, text)


@pytest.mark.parametrize("path", TASK_FILES, ids=TASK_IDS)
def test_start_is_inside_the_joint_limits(path: Path):
    task = vfdsl.load(path)
    robot = Robot.load(task.robots[0].urdf)
    q = task.start
    assert q is not None and q.shape == (robot.nq,)
    assert np.all(q >= robot.lower) and np.all(q <= robot.upper)
    assert task.scene.period is not None and task.scene.period > 0


# ------------------------------------------------------------------------------- paper, experiment B

class TestPaperB:
    path = TASKS_DIR / "paper_b_virtual_rcm.vf"

    @pytest.fixture
    def task(self, loaded) -> Task:
        return loaded[self.path.stem]

    def test_stays_at_pivot(self, task):
        c = only(constraints_of(task, "stays_at"), "stays_at")
        assert c.frame == "tip"
        assert c.tolerance == pytest.approx(1e-6, rel=1e-12)      # eps_p = 0.001 in the library's mm
        assert c.resolution == [4, 4]
        assert not c.soft and c.weight is None
        target = c.args["target"]
        assert isinstance(target, ir.ParamRef) and target.name == "pivot"
        pivot = task.param("pivot")
        assert pivot.type == "point" and pivot.frame is None
        np.testing.assert_allclose(pivot.value.xyz, [0.0, 0.0, 0.29], atol=1e-15)

    def test_cone(self, task):
        c = only(constraints_of(task, "cone"), "cone")
        assert c.frame == "tip"
        angle = const(c.args["angle"])
        assert isinstance(angle, ir.ScalarValue) and angle.dimension == "angle"
        assert angle.value == pytest.approx(math.radians(15), rel=1e-12)
        assert angle.value == pytest.approx(0.2618, abs=1e-4)
        assert c.tolerance == pytest.approx(1e-3, rel=1e-12)      # eps_r = 0.001 rad
        assert c.resolution == [8]
        axis = c.args["axis"]
        assert isinstance(axis, ir.ParamRef) and axis.name == "axis"
        value = task.param("axis").value
        assert isinstance(value, ir.DirectionValue)
        np.testing.assert_allclose(value.xyz, unit([0, -0.2, 1]), atol=1e-15)
        np.testing.assert_allclose(value.xyz, [0, -0.2 / math.sqrt(1.04), 1 / math.sqrt(1.04)], atol=1e-15)

    def test_track_torque(self, task):
        track = only([o for o in task.objectives if o.term == "track"], "track")
        assert track.args["frame"] == ir.FrameRef(name="tip")
        assert track.args["input"] == ir.InputRef(name="tau")
        assert task.input("tau").type == "torque"
        assert "gain" not in track.args                          # a torque has no linear part
        # 20 deg/s per N mm = 20 * (pi/180) rad/s per 1e-3 N m
        assert const(track.args["angular_gain"]).value == pytest.approx(20 * DEG / 1e-3, rel=1e-12)

    def test_fixture_constraints_point_at_the_use_line(self, task):
        use_line = line_of(self.path, "use virtual_rcm")
        for primitive, body_line in (("stays_at", "require f stays_at"), ("cone", "require f cone")):
            c = only(constraints_of(task, primitive), primitive)
            assert len(c.via) == 1
            assert same_file(c.via[0].file, self.path)
            assert (c.via[0].line, c.via[0].column) == (use_line, 1)
            assert same_file(c.span.file, LIBRARY)
            assert c.span.line == line_of(LIBRARY, body_line)

    def test_start_tip_at_pivot_on_the_cone(self, task):
        _, p, R = start_pose(task)
        np.testing.assert_allclose(p, [0.0, 0.0, 0.29], atol=1e-6)
        tool_axis = R[:, 2]
        angle = math.acos(np.clip(tool_axis @ unit([0, -0.2, 1]), -1, 1))
        assert abs(angle - math.radians(15)) < 1e-5


# ------------------------------------------------------------------------------- paper, experiment A

class TestPaperA:
    path = TASKS_DIR / "paper_a_follow_curve.vf"

    @pytest.fixture
    def task(self, loaded) -> Task:
        return loaded[self.path.stem]

    def test_two_follows_constraints(self, task):
        follows = constraints_of(task, "follows")
        assert sorted(c.frame for c in follows) == ["shaft", "tip"]
        tip = only(constraints_of(task, "follows", "tip"), "follows on tip")
        shaft = only(constraints_of(task, "follows", "shaft"), "follows on shaft")
        for c in (tip, shaft):
            assert c.args["curve"] == ir.ParamRef(name="path")
            assert c.args["anchor"] == ir.FrameRef(name="tip")
            assert c.tolerance == pytest.approx(1e-6, rel=1e-12)
            assert c.resolution == [8]
        np.testing.assert_allclose(const(shaft.args["shift"]).xyz, [0.0, 0.0, 0.1], atol=1e-15)
        np.testing.assert_allclose(const(tip.args["shift"]).xyz, [0.0, 0.0, 0.0], atol=0)

    def test_frames(self, task):
        np.testing.assert_allclose(task.frame("tip").offset, [0, 0, 0])
        np.testing.assert_allclose(task.frame("shaft").offset, [0, 0, 0.1], atol=1e-15)
        assert task.frame("shaft").link == task.frame("tip").link == "tool_tip"

    def test_curve_param(self, task):
        path = task.param("path")
        assert path.type == "curve" and path.frame == "plate"
        assert isinstance(path.value, ir.CurveValue)
        assert path.value.degree == 5
        assert len(path.value.points) == 11
        np.testing.assert_allclose(path.value.points[0], [-0.040, -0.008, 0.0], atol=1e-15)
        np.testing.assert_allclose(path.value.points[-1], [0.040, -0.002, 0.0], atol=1e-15)
        plate = task.param("plate")
        assert plate.type == "pose"
        np.testing.assert_allclose(plate.value.translation, [0, 0, 0.25], atol=1e-15)
        np.testing.assert_allclose(plate.value.rpy, np.radians([4, -3, 20]), atol=1e-15)

    def test_track_force(self, task):
        track = only([o for o in task.objectives if o.term == "track"], "track")
        assert task.input("f").type == "force"
        assert const(track.args["gain"]).value == pytest.approx(1e-3, rel=1e-12)   # 1 mm/s/N
        assert "angular_gain" not in track.args

    def test_fixture_constraints_point_at_the_use_line(self, task):
        use_line = line_of(self.path, "use perpendicular_follow")
        for c in constraints_of(task, "follows"):
            assert [(Path(v.file).resolve(), v.line) for v in c.via] == [(self.path.resolve(), use_line)]
            assert same_file(c.span.file, LIBRARY)
        safety = line_of(self.path, "use joint_safety")
        for primitive in ("joint_limits", "joint_speed"):
            c = only(constraints_of(task, primitive), primitive)
            assert c.frame is None and c.via[0].line == safety

    def test_start_tip_on_first_curve_point_tool_along_plate_normal(self, task):
        _, p, R = start_pose(task)
        plate = task.param("plate").value
        R_plate = Rotation.from_euler("xyz", plate.rpy).as_matrix()     # URDF fixed-axis roll-pitch-yaw
        first = np.array(plate.translation) + R_plate @ np.array(task.param("path").value.points[0])
        np.testing.assert_allclose(p, first, atol=1e-6)
        np.testing.assert_allclose(R[:, 2], R_plate[:, 2], atol=1e-6)

    def test_start_shaft_on_the_shifted_curve(self, task):
        _, p, _ = start_pose(task, "shaft")
        plate = task.param("plate").value
        R_plate = Rotation.from_euler("xyz", plate.rpy).as_matrix()
        first = np.array(task.param("path").value.points[0]) + [0, 0, 0.1]
        np.testing.assert_allclose(p, np.array(plate.translation) + R_plate @ first, atol=1e-6)


# ---------------------------------------------------------------------------------------- lecture tasks

@pytest.mark.parametrize("name", ["lecture_stay_near_goal", "lecture_steady_direction"])
def test_lecture_goal_within_3mm_of_start(name, loaded):
    task = loaded[name]
    _, p, _ = start_pose(task)
    goal = np.array(task.param("goal").value.xyz)
    assert np.linalg.norm(goal - p) < 3 * MM
    c = only(constraints_of(task, "within_distance", "tip"), "within_distance")
    assert c.args["center"] == ir.ParamRef(name="goal")
    assert const(c.args["distance"]).value == pytest.approx(3 * MM, rel=1e-12)
    assert c.resolution == [8, 8]
    distance = only([o for o in task.objectives if o.term == "distance"], "distance term")
    assert distance.args == {"frame": ir.FrameRef(name="tip"), "target": ir.ParamRef(name="goal"),
                             "time_constant": ir.Const(value=ir.ScalarValue(dimension="time", value=1.0))}


def test_lecture_steady_direction_eta(loaded):
    task = loaded["lecture_steady_direction"]
    eta = only([o for o in task.objectives if o.term == "direction_change"], "direction_change")
    assert eta.weight == 10.0 and eta.args == {"frame": ir.FrameRef(name="tip")}
    assert task.scene.file is not None and Path(task.scene.file).name == "lecture_stay_near_goal.yaml"


def test_lecture_remote_center_port_on_start_tool_axis(loaded):
    task = loaded["lecture_remote_center"]
    _, p, R = start_pose(task)
    port = np.array(task.param("port").value.xyz)
    axis = R[:, 2]
    off_axis = (port - p) - ((port - p) @ axis) * axis
    assert abs((port - p) @ axis) == pytest.approx(60 * MM, abs=0.1 * MM)      # "60 mm above the tip"
    assert np.linalg.norm(off_axis) < 1e-6, (
        f"the port is {np.linalg.norm(off_axis) * 1e3:.4f} mm off the start tool axis; "
        f"a port on the axis 60 mm from the tip is {np.round((p - 0.06 * axis) * 1e3, 6).tolist()} mm")
    c = only(constraints_of(task, "passes_through", "tip"), "passes_through")
    assert c.args["port"] == ir.ParamRef(name="port")
    assert c.tolerance == pytest.approx(0.5 * MM, rel=1e-12)


def test_lecture_follow_path_start_on_the_line(loaded):
    task = loaded["lecture_follow_path"]
    _, p, R = start_pose(task)
    line = task.param("path").value
    assert isinstance(line, ir.LineValue)
    np.testing.assert_allclose(line.direction, unit([1, 1, 0]), atol=1e-15)
    d = np.array(line.direction)
    rel = p - np.array(line.point)
    assert np.linalg.norm(rel - (rel @ d) * d) < 1e-9
    keeps = only(constraints_of(task, "keeps_direction", "tip"), "keeps_direction")
    direction = const(keeps.args["direction"]).xyz
    np.testing.assert_allclose(R[:, 2], direction, atol=1e-9)           # tool already along [0, 0, 1]
    along = only(constraints_of(task, "along", "tip"), "along")
    assert along.tolerance == pytest.approx(0.5 * MM) and along.resolution == [8]
    assert keeps.tolerance == pytest.approx(0.01, rel=1e-12)


def test_lecture_forbidden_half_space_start_above_the_wall(loaded):
    task = loaded["lecture_forbidden_half_space"]
    _, p, _ = start_pose(task)
    wall = task.param("wall").value
    assert isinstance(wall, ir.PlaneValue)
    np.testing.assert_allclose(wall.point, [0, 0, 0.27], atol=1e-15)
    height = (p - np.array(wall.point)) @ np.array(wall.normal)
    assert height > 1 * MM                                              # strictly on the free side
    c = only(constraints_of(task, "above", "tip"), "above")
    assert c.args["plane"] == ir.ParamRef(name="wall") and c.tolerance is None and c.resolution is None


# ------------------------------------------------------------------------------------ docs/language.md

DOC = TASKS_DIR.parent / "docs" / "language.md"
PRELUDE = 'task example\nunits mm, deg\nrobot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\n'
BLOCK = re.compile(r"(?:<!-- file: (?P<name>[\w.]+) -->\n)?```(?P<lang>\w*)\n(?P<body>.*?)```", re.DOTALL)


def doc_blocks() -> list[tuple[str | None, str, str]]:
    """(file name or None, language, text) of every fenced block of docs/language.md."""
    return [(m["name"], m["lang"], m["body"]) for m in BLOCK.finditer(DOC.read_text())]


VF_BLOCKS = [(i, name, body) for i, (name, lang, body) in enumerate(doc_blocks()) if lang == "vf"]


def test_docs_prelude_is_the_fragment_header():
    untagged = [body for _, lang, body in doc_blocks() if lang == "" and body.startswith("task ")]
    assert untagged[0] == PRELUDE


@pytest.mark.parametrize("index, name, body", VF_BLOCKS, ids=[f"block{i}" for i, _, _ in VF_BLOCKS])
def test_docs_vf_example_loads(tasks_copy, index, name, body):
    """Every ```vf block of the language reference is valid: a task loads, a library loads when imported,
    and a fragment loads after the prelude. Blocks named with <!-- file: NAME --> are written first."""
    for other_name, _, other_body in doc_blocks():
        if other_name:
            (tasks_copy / other_name).write_text(other_body)
    if body.startswith("task "):
        shipped = TASKS_DIR / f"{body.split()[1]}.vf"
        if shipped.is_file():                                 # quoted from tasks/: must be verbatim
            assert body == shipped.read_text()
        path = tasks_copy / (name or f"doc_block{index}.vf")
        path.write_text(body)
        task = vfdsl.load(path)
        assert task.name == body.split()[1]
    elif body.startswith("library "):
        (tasks_copy / f"doc_block{index}.vf").write_text(body)
        (tasks_copy / "doc_main.vf").write_text(PRELUDE + f'import "doc_block{index}.vf"\n')
        vfdsl.load(tasks_copy / "doc_main.vf")
    else:
        (tasks_copy / "doc_main.vf").write_text(PRELUDE + body)
        vfdsl.load(tasks_copy / "doc_main.vf")


def test_docs_yaml_blocks(monkeypatch, capsys):
    """YAML blocks are a shipped scene (verbatim), a named scene (loaded with its task above) or an excerpt
    of real `vfdsl show` output."""
    monkeypatch.chdir(TASKS_DIR.parent)
    assert cli_main(["show", "tasks/paper_b_virtual_rcm.vf"]) == 0
    shown = capsys.readouterr().out
    scenes = [p.read_text() for p in TASKS_DIR.glob("*.yaml")]
    yaml_blocks = [(name, body) for name, lang, body in doc_blocks() if lang == "yaml"]
    assert yaml_blocks
    for name, body in yaml_blocks:
        yaml.safe_load(body)
        assert name or body in scenes or body in shown, body


def doc_text_blocks() -> set[str]:
    return {body for _, lang, body in doc_blocks() if lang == "text"}


TYPOS = [   # (file of lecture_follow_path to edit, old, new): the diagnostics quoted in docs/language.md
    ("vf", "require tip along(path)", "require tpi along(path)"),
    ("vf", "within 0.01 rad", "within 0.01 mm"),
    ("yaml", "rcm_a: 0,", "rcm_a: 0, rcm_c: 0,"),
    ("vf", "minimize damping", "minimise damping"),
]


@pytest.mark.parametrize("suffix, old, new", TYPOS)
def test_docs_error_examples_are_real(tasks_copy, monkeypatch, suffix, old, new):
    for ext in ("vf", "yaml"):
        text = (tasks_copy / f"lecture_follow_path.{ext}").read_text()
        if ext == suffix:
            assert text.count(old) == 1
            text = text.replace(old, new)
        (tasks_copy / f"typo.{ext}").write_text(text)
    monkeypatch.chdir(tasks_copy.parent)
    with pytest.raises(vfdsl.VfError) as info:
        vfdsl.load("tasks/typo.vf")
    assert info.value.render() + "\n" in doc_text_blocks()


def _default(value) -> str:
    if value == "subject":
        return "the constrained frame"
    if isinstance(value, ir.VectorValue):
        return "[" + ", ".join(f"{x:g}" for x in value.xyz) + "]"
    if isinstance(value, ir.FlagValue):
        return "true" if value.value else "false"
    if isinstance(value, ir.ScalarValue):
        return f"{value.value:g}"
    if isinstance(value, ir.ChoiceValue):
        return value.value
    if isinstance(value, ir.PoseValue) and not any(value.translation + value.rpy):
        return "identity"
    raise AssertionError(f"no doc form for default {value!r}")


def _signature(spec) -> str:
    args = []
    for a in spec.args:
        if a.required:
            args.append(f"{a.name}: {a.kind}")
        elif a.default is None:
            args.append(f"{a.name}: {a.kind} (optional)")
        else:
            args.append(f"{a.name}: {a.kind} = {_default(a.default)}")
    return f"{spec.name}({', '.join(args)})"


def _tolerance(spec) -> str:
    if spec.tolerance is None:
        return "—"
    v = spec.default_tolerance
    return f"{spec.tolerance}, default " + (f"{v * 1e6:g} um" if spec.tolerance == "length" else f"{v * 1e3:g} mrad")


def _resolution(spec) -> str:
    if spec.resolution is None:
        return "—"
    if callable(spec.resolution):
        assert spec.resolution({}) == "polygon"
        return "n (polygon), default 8; n x m (sphere), default 4x4, when pin_roll = true"
    return {"sphere": "n x m (sphere), default 4x4", "polygon": "n (polygon), default 8"}[spec.resolution]


def _arguments(spec) -> str:
    args = "; ".join(f"`{a.name}` ({a.kind}{', allowed ' + a.range.describe() if a.range else ''}) {a.doc}"
                     for a in spec.args) or "no arguments"
    return f"- `{spec.name}`: {args}." + (f" Source: {spec.source}." if spec.source else "")


def _section(marker: str) -> str:
    text = DOC.read_text()
    return text[text.index(f"<!-- {marker}:begin -->\n") + len(f"<!-- {marker}:begin -->\n"):
                text.index(f"<!-- {marker}:end -->")]


def test_docs_tables_match_the_specs():
    """The primitive and objective tables of docs/language.md are generated from the SPECs (regenerate them
    with these functions when a SPEC changes)."""
    from vfdsl.objectives import OBJECTIVES
    from vfdsl.primitives import CONSTRAINTS
    constraint_rows = ["| primitive | `require` form | `within` | `resolution` | what it does |",
                       "|---|---|---|---|---|"]
    for name, s in CONSTRAINTS.items():
        form = f"`require FRAME {_signature(s)}`" if s.subject else f"`require {_signature(s)}`"
        constraint_rows.append(f"| `{name}` | {form} | {_tolerance(s)} | {_resolution(s)} | {s.summary} |")
    objective_rows = ["| term | `minimize` form | what it does |", "|---|---|---|"]
    for name, s in OBJECTIVES.items():
        objective_rows.append(f"| `{name}` | `minimize {_signature(s)}` | {s.summary} |")
    assert _section("constraint-table").splitlines() == constraint_rows
    assert _section("objective-table").splitlines() == objective_rows
    assert _section("constraint-args").splitlines() == [_arguments(s) for s in CONSTRAINTS.values()]
    assert _section("objective-args").splitlines() == [_arguments(s) for s in OBJECTIVES.values()]


def test_ir_names_shipped_robots_portably(tmp_path):
    """A shipped robot is recorded by name (the IR is the same wherever vfdsl is installed); a URDF file of
    the user's by its absolute path."""
    assert vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf").robots[0].urdf == "shr7"
    urdf = (ROBOTS_DIR / "panda7.urdf").read_text()
    (tmp_path / "my_arm.urdf").write_text(urdf)
    (tmp_path / "t.vf").write_text('task t\nrobot arm = urdf "my_arm.urdf"\n')
    assert vfdsl.load(tmp_path / "t.vf").robots[0].urdf == str((tmp_path / "my_arm.urdf").resolve())
