"""Classes of bad input, each with a case that must fail cleanly (VfError at a known place) and a near miss
that must still load: curves, URDF semantics, resource limits, semantics that used to be silently wrong,
and diagnostics."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tracemalloc

import casadi as ca
import numpy as np
import pytest

import vfdsl
from vfdsl import VfError
from vfdsl.compiler.curve import SplineCurve
from vfdsl.kinematics.robot import ROBOTS_DIR
from vfdsl import limits

HEAD = 'task t\nunits mm, deg\nrobot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\n'
# Appended lines start at line 5.


def write(tmp_path, body: str, files: dict[str, str | bytes] | None = None):
    for name, text in (files or {}).items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(text) if isinstance(text, bytes) else path.write_text(text)
    (tmp_path / "t.vf").write_text(body if body.startswith("task") else HEAD + body)
    return tmp_path / "t.vf"


def load(tmp_path, body: str, files=None):
    return vfdsl.load(write(tmp_path, body, files))


def fails(tmp_path, body, message, line=None, column=None, files=None, file="t.vf") -> VfError:
    with pytest.raises(VfError) as info:
        load(tmp_path, body, files)
    err = info.value
    assert message in err.message, err.render()
    if line is not None:
        assert err.pos is not None and err.pos.file.endswith(file), err.render()
        assert (err.line, err.column if column else None) == (line, column), err.render()
    err.render()
    return err


# ------------------------------------------------------------------------------------------------- curves

def test_degree_one_curve_builds_and_finds_brute_force_closest_points(tmp_path):
    task = load(tmp_path, "param c : curve(degree = 1) = [[0, 0, 280], [10, 0, 280], [10, 10, 285]]\n"
                          "require tip follows(c)\n")
    ctrl = vfdsl.compile(task, backend="interpreted")
    assert ctrl.problem(np.zeros(7), {}, dt=0.01) is not None
    points = np.array(task.param("c").value.points)
    curve = SplineCurve.interpolate(points, 1)
    x = ca.SX.sym("x", 3)
    closest = ca.Function("closest", [x], list(curve.closest(x)))
    dense = np.concatenate([np.linspace(a, b, 4001) for a, b in zip(points, points[1:])])
    rng = np.random.default_rng(1)
    for query in rng.uniform([-0.005, -0.005, 0.275], [0.015, 0.015, 0.29], size=(40, 3)):
        point, tangent = (np.asarray(v).ravel() for v in closest(query))
        brute = dense[np.argmin(np.linalg.norm(dense - query, axis=1))]
        assert np.linalg.norm(point - query) <= np.linalg.norm(brute - query) + 1e-9
        assert np.isclose(np.linalg.norm(tangent), 1.0)


@pytest.mark.parametrize("curve, message, column", [
    ("[[0, 0, 280], [0, 0, 280], [10, 0, 280], [10, 10, 280]]", "curve points 1 and 2 are the same point", 33),
    ("curve(degree = 3) = [[0, 0, 280], [10, 0, 280], [10, 10, 280]]", "needs at least 4 points, got 3", 31),
    ("curve(degree = 12) = [[0, 0, 280], [10, 0, 280], [10, 10, 280]]", "a degree-12 curve: the limit is 9", 32),
    ("[[0, 0, 0], [3000, 0, 0], [3000, 3000, 0], [0, 3000, 0]]", "this curve is too long", 19),
    ("[[0, 0, 280], [10, 0, 280], [10, 0.1, 280], [0, 100, 280]]", "too close for the curve's closest-point", 47),
])
def test_bad_curves_fail_at_the_curve(tmp_path, curve, message, column):
    decl = f"param c : {curve}" if curve.startswith("curve(") else f"param c : curve = {curve}"
    fails(tmp_path, decl + "\nrequire tip follows(c)\n", message, 5, column)


def test_near_miss_curves_load(tmp_path):
    load(tmp_path, "param c : curve = [[0, 0, 280], [10, 0, 280], [10, 2, 280], [0, 100, 280]]\n"
                   "require tip follows(c)\n")
    load(tmp_path, "param c : curve(degree = 3) = [[0, 0, 280], [10, 0, 280], [10, 10, 280], [0, 10, 280]]\n")


# --------------------------------------------------------------------------------------------------- URDF

def urdf_variant(old: str, new: str) -> str:
    text = (ROBOTS_DIR / "shr7.urdf").read_text()
    assert text.count(old) == 1, old
    return text.replace(old, new)


def joint_line(text: str, name: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if f'<joint name="{name}"' in line)


SHR_X_LIMIT = '<limit lower="-0.05" upper="0.05"'


@pytest.mark.parametrize("old, new, joint, message", [
    ('<joint name="insert" type="prismatic">', '<joint name="insert" type="prismatic"><mimic joint="roll"/>',
     "insert", "mimics joint 'roll'"),
    ('<joint name="roll" type="revolute">', '<joint name="roll" type="revolute"><axis xyz="0 0 0"/>', "roll",
     "has a zero axis"),
])
def test_bad_urdf_joint_fails_at_the_robot_line_with_the_urdf_line(tmp_path, old, new, joint, message):
    text = urdf_variant(old, new)
    err = fails(tmp_path, HEAD.replace('"shr7"', '"arm.urdf"'), message, 3, 1, {"arm.urdf": text})
    assert f"arm.urdf:{joint_line(text, joint)}:" in err.message


def test_urdf_lower_above_upper(tmp_path):
    text = (ROBOTS_DIR / "shr7.urdf").read_text()
    start = text.index('<joint name="x"')
    limit = text.index("<limit", start)
    end = text.index("/>", limit)
    bad = text[:limit] + '<limit lower="0.05" upper="-0.05" effort="1" velocity="0.1"' + text[end:]
    err = fails(tmp_path, HEAD.replace('"shr7"', '"arm.urdf"'), "lower limit 0.05 above its upper limit -0.05",
                3, 1, {"arm.urdf": bad})
    assert f"arm.urdf:{joint_line(bad, 'x')}:" in err.message


def test_robot_without_actuated_joint(tmp_path):
    urdf = '<robot name="rock"><link name="a"/><link name="b"/><joint name="j" type="fixed"><parent link="a"/>' \
           '<child link="b"/></joint></robot>'
    fails(tmp_path, 'task t\nrobot r = urdf "rock.urdf"\n', "has no actuated joint", 2, 1, {"rock.urdf": urdf})


@pytest.mark.parametrize("sidecar, message", [
    ("resolution: {x: [1], y: 1, z: 1, rcm_a: 1, rcm_b: 1, roll: 1, insert: 1}\n", "joint 'x' must be a positive"),
    ("resolution: {x: -1, y: 1, z: 1, rcm_a: 1, rcm_b: 1, roll: 1, insert: 1}\n", "joint 'x' must be a positive"),
    ("tool_axis: [z]\n", "tool_axis maps link names"),
    ("tool_axis: {tool_tip: {a: 1}}\n", "tool_axis maps link names"),
    ("description: {a: 1}\n", "description must be one line"),
    ("description: " + "[" * 50 + "]" * 50 + "\n", "nested more than"),
])
def test_bad_sidecar(tmp_path, sidecar, message):
    files = {"arm.urdf": (ROBOTS_DIR / "shr7.urdf").read_text(), "arm.yaml": sidecar}
    fails(tmp_path, HEAD.replace('"shr7"', '"arm.urdf"'), message, 3, 1, files)


def test_near_miss_urdf_and_sidecar_load(tmp_path):
    files = {"arm.urdf": (ROBOTS_DIR / "shr7.urdf").read_text(),
             "arm.yaml": "description: fine\nresolution: {x: 1, y: 1.0e-5, z: 1, rcm_a: 1, rcm_b: 1, roll: 1, "
                         "insert: 1}\ntool_axis: {tool_tip: z}\n"}
    task = load(tmp_path, HEAD.replace('"shr7"', '"arm.urdf"'), files)
    assert task.robots[0].urdf == str((tmp_path / "arm.urdf").resolve())


def test_urdf_path_is_relative_to_the_task_not_the_working_directory(tmp_path, monkeypatch):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "arm.urdf").write_text((ROBOTS_DIR / "shr7.urdf").read_text())
    (tmp_path / "sub" / "t.vf").write_text('task t\nrobot r = urdf "arm.urdf"\n')
    monkeypatch.chdir(tmp_path)
    task = vfdsl.load("sub/t.vf")
    assert task.robots[0].urdf == str(tmp_path / "sub" / "arm.urdf")
    monkeypatch.chdir(tmp_path / "sub")
    assert vfdsl.compile(task, backend="interpreted").assembled.nq == 7     # compiles from another directory


# -------------------------------------------------------------------------------------------- resources

@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_import_and_scene_are_refused_without_blocking(tmp_path):
    os.mkfifo(tmp_path / "lib.vf")
    os.mkfifo(tmp_path / "s.yaml")
    os.mkfifo(tmp_path / "arm.urdf")
    fails(tmp_path, 'import "lib.vf"\n', "not a regular file", 5, 1)
    fails(tmp_path, 'scene "s.yaml"\n', "not a regular file", 5, 1)
    fails(tmp_path, HEAD.replace('"shr7"', '"arm.urdf"'), "not a regular file", 3, 1)
    (tmp_path / "lib2.vf").mkdir()
    fails(tmp_path, 'import "lib2.vf"\n', "not a regular file", 5, 1)


def test_oversized_files_are_refused(tmp_path):
    big = "library lib\n" + "#" * limits.FILE_BYTES + "\n"
    fails(tmp_path, 'import "lib.vf"\n', "is too large: the limit is 1,000,000", 5, 1, {"lib.vf": big})
    load(tmp_path, 'import "lib.vf"\n', {"lib.vf": "library lib\n" + "#" * (limits.FILE_BYTES // 2) + "\n"})


def test_yaml_alias_bomb_is_bounded(tmp_path):
    """A 600-byte scene whose aliases would expand to 10^9 values fails fast, in little memory."""
    levels = "".join(f"  - &l{i} [{', '.join([f'*l{i - 1}'] * 10)}]\n" for i in range(1, 10))
    scene = f"params:\n  p:\n  - &l0 [0, 0, 0]\n{levels}"
    assert len(scene) < 700
    tracemalloc.start()
    err = fails(tmp_path, 'param p : point\nscene "s.yaml"\n', "too large (YAML aliases expand them)",
                files={"s.yaml": scene})
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert err.pos.file.endswith("s.yaml") and peak < 200e6
    load(tmp_path, 'param p : point\nparam q : point\nscene "s.yaml"\n',
         {"s.yaml": "params: {p: &a [1, 2, 3], q: *a}\n"})


def test_yaml_alias_expansion_limit(tmp_path):
    levels = "".join(f"  l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 10)}]\n" for i in range(1, 7))
    scene = "params:\n  l0: &l0 [0, 0, 0]\n" + levels + "  p: *l6\n"
    body = "".join(f"param l{i} : point = [0, 0, 0]\n" for i in range(7)) + 'param p : point\nscene "s.yaml"\n'
    err = fails(tmp_path, body, "too large (YAML aliases expand them): the limit is 100,000", files={"s.yaml": scene})
    assert err.pos.file.endswith("s.yaml")


def test_deep_nesting_never_reaches_pythons_recursion_limit(tmp_path):
    depth = sys.getrecursionlimit() * 3
    fails(tmp_path, "param p : point = " + "[" * depth + "]" * depth + "\n", "values nested too deeply", 5, 35)
    fails(tmp_path, 'param p : point\nscene "s.yaml"\n', "nested more than", 1, files={"s.yaml": "params: {p: " + "[" * depth + "]" * depth + "}\n"}, file="s.yaml")
    nested = "bspline(points = [[0, 0, 0], [0, 0, 10], [0, 10, 10], [10, 10, 10]])"
    load(tmp_path, f"param c : curve = {nested}\n")


def test_number_and_name_length(tmp_path):
    fails(tmp_path, "require tip stays_at([0, 0, 0]) resolution " + "9" * 5000 + "\n",
          "this number is 5,000 characters long: the limit is 40", 5, 44)
    fails(tmp_path, "param " + "a" * 500 + " : point = [0, 0, 0]\n", "this name is 500 characters long", 5, 7)
    load(tmp_path, "param " + "a" * 100 + " : length = 1.00000000000000000000000000000000000000\n")


def test_resolution_rows_and_constraint_limits(tmp_path):
    fails(tmp_path, "require tip stays_at([0, 0, 290]) resolution 65x4\n", "resolution 65 is too fine", 5, 46)
    load(tmp_path, "require tip stays_at([0, 0, 290]) resolution 64x4\n")
    many = "require tip stays_at([0, 0, 290]) resolution 64x64\n" * 3
    fails(tmp_path, many, "too many constraint rows", 7, 1)
    fails(tmp_path, "require tip above(plane([0, 0, 0], [0, 0, 1]))\n" * (limits.CONSTRAINTS + 1), "too many constraints",
          5 + limits.CONSTRAINTS, 1)


def test_fixture_expansion_and_import_depth(tmp_path):
    lib = "library lib\nfixture f0(x: frame) {\n    require x speed(5)\n}\n" + "".join(
        f"fixture f{i}(x: frame) {{\n    use f{i - 1}(x)\n    use f{i - 1}(x)\n}}\n" for i in range(1, 15))
    fails(tmp_path, 'import "lib.vf"\nuse f14(tip)\n', "too many statements after expanding fixtures",
          files={"lib.vf": lib})
    assert len(load(tmp_path, 'import "lib.vf"\nuse f9(tip)\n', {"lib.vf": lib}).constraints) == 512
    chain = {f"l{i}.vf": f'library l{i}\nimport "l{i + 1}.vf"\n' for i in range(40)}
    chain["l40.vf"] = "library l40\n"
    fails(tmp_path, 'import "l0.vf"\n', "imports nested too deeply", files=chain)


# ------------------------------------------------------------------------------------------- semantics

def test_pose_in_a_pose_is_refused(tmp_path):
    body = ("param plate : pose = pose(translation = [0, 0, 250])\n"
            "param tool : pose in plate = pose(translation = [0, 0, 10])\n")
    fails(tmp_path, body, "a pose cannot be expressed `in` another pose", 6, 22)
    fails(tmp_path, "param a : pose in a = pose(translation = [0, 0, 10])\n", "another pose", 5, 19)
    load(tmp_path, "param plate : pose = pose(translation = [0, 0, 250])\n"
                   "param p : point in plate = [0, 0, 10]\n")


def test_scene_units_with_two_length_units(tmp_path):
    fails(tmp_path, 'scene "s.yaml"\n', "two units for a length: 'mm' and 'cm'", 1, 8, {"s.yaml": "units: mm, cm\n"},
          file="s.yaml")
    load(tmp_path, 'scene "s.yaml"\n', {"s.yaml": "units: cm, deg\n"})


@pytest.mark.parametrize("value, shown", [("null", "got the text 'null'"), ("nowhere", "got the text 'nowhere'"),
                                          ("{x: 0, y: 0, z: 290}", "got a mapping of x, y, z")])
def test_a_scene_value_of_the_wrong_shape_is_shown_as_written(tmp_path, value, shown):
    """A point set to YAML null, a word, or a mapping of x, y, z (not [x, y, z]) was 'got a string' or, for the
    mapping, 'got point(...)': a call the user never wrote."""
    fails(tmp_path, 'scene "s.yaml"\nparam p : point = [0, 0, 290]\n', f"expected a point, {shown}", 2, 6,
          {"s.yaml": f"params:\n  p: {value}\n"}, file="s.yaml")


# -------------------------------------------------------------------------------------------- diagnostics

def test_source_line_is_the_line_the_parser_counted(tmp_path):
    err = fails(tmp_path, "param q : point = [0, 0, 0]\f # x\f\nrequire tpi speed(5)\n", "unknown frame 'tpi'", 6, 9)
    shown = err.render().splitlines()
    assert shown[1] == " 6 | require tpi speed(5)"
    assert shown[2].index("^") == shown[1].index("tpi")


@pytest.mark.parametrize("separator", ["\u2028", "\x85", "\u2029", "\x0b", "\x1b"])
def test_line_separators_stay_inside_the_line_and_are_shown_as_one_character(tmp_path, separator):
    err = fails(tmp_path, f"# a\x1bb\nparam q : point = [0, 0, 0]{separator} # x\n", "unexpected character", 6, 28)
    shown = err.render().splitlines()
    assert shown[1] == " 6 | param q : point = [0, 0, 0]? # x"
    assert shown[2].index("^") == shown[1].index("?")


@pytest.mark.parametrize("separator", ["\u2028", "\x85", "\u2029", "\x0b", "\x1c"])
def test_a_line_separator_ends_a_comment_so_no_statement_hides_in_it(tmp_path, separator):
    # An editor may show the text after the separator on a line of its own: it is refused, not commented out.
    fails(tmp_path, f"param q : point = [0, 0, 0]  # see{separator}require tip stays_at(q)\n", "unexpected character",
          5, 35)


def test_text_after_a_form_feed_in_a_comment_is_read(tmp_path):
    task = load(tmp_path, "param q : point = [0, 0, 290]  # see\frequire tip stays_at(q)\n")
    assert [c.primitive for c in task.constraints] == ["stays_at"]


def test_carriage_returns_alone_are_refused_not_read_as_one_commented_line(tmp_path):
    body = (HEAD + "param q : point = [0, 0, 290]   # the pivot\nrequire tip stays_at(q)\n").replace("\n", "\r")
    err = fails(tmp_path, body, "a carriage return without a newline", 1, 7)
    assert err.code == "E101" and " 1 | task t?units" in err.render()
    crlf = load(tmp_path, body.replace("\r", "\r\n"))
    assert [c.primitive for c in crlf.constraints] == ["stays_at"]


def test_end_of_file_is_reported_on_the_line_the_parser_counted(tmp_path):
    err = fails(tmp_path, "param q : point = [0, 0, 290]\f\f\nrequire tip stays_at(", "unexpected end of file", 6, 22)
    assert " 6 | require tip stays_at(" in err.render()


@pytest.mark.parametrize("separator", ["\u2028", "\x85", "\u2029", "\r"])
def test_a_scene_line_is_shown_as_yaml_counted_it(tmp_path, separator):
    # YAML ends a line (and a comment) at these too: the line shown was another one than the error's.
    scene = f"units: mm   # a{separator}period: 20 ms\nperiod: 10 ms\n"
    err = fails(tmp_path, 'scene "s.yaml"\n', "key 'period' appears twice", 3, 1, {"s.yaml": scene.encode()},
                file="s.yaml")
    assert " 3 | period: 10 ms" in err.render()


def test_caret_lines_up_under_tabs(tmp_path):
    err = fails(tmp_path, "\t\trequire tpi speed(5)\n", "unknown frame", 5, 11)
    source, caret = err.render().splitlines()[1:3]
    assert caret.startswith(" " * 2 + " | \t\t" + " " * 8 + "^^^")
    assert source.expandtabs(8).index("tpi") == caret.expandtabs(8).index("^")


def test_error_inside_a_fixture_names_the_use_site(tmp_path):
    lib = "library lib\nunits mm\nfixture bad(f: frame) {\n    require f stays_at([0, 0])\n}\n"
    err = fails(tmp_path, 'import "lib.vf"\nuse bad(tip)\n', "a point needs 3 numbers", 4, 24, {"lib.vf": lib},
                file="lib.vf")
    assert err.notes == (f"in a fixture used at {tmp_path / 't.vf'}:6:1",)
    assert "note: in a fixture used at" in err.render()


def test_files_that_are_not_task_files_are_not_echoed(tmp_path):
    secret = "root:$6$very-secret-hash:19000:0:99999:7:::\n"
    err = fails(tmp_path, 'import "shadow.vf"\n', "is not a .vf file", files={"shadow.vf": secret})
    assert "very-secret" not in err.render()
    err = fails(tmp_path, 'import "/etc/passwd"\n', "is not a .vf file", 5, 1)
    assert "root:" not in err.render()
    err = fails(tmp_path, 'scene "shadow"\n', "a scene file is YAML", 5, 1, {"shadow": secret})
    assert "very-secret" not in err.render()


def test_hints_fit_the_mistake(tmp_path):
    assert "um" in fails(tmp_path, "param d : length = 5 \u00b5m\n", "unexpected character").hint
    assert "5 mm + 3 mm" in fails(tmp_path, "param d : length = 5 + 3\n", "expected a length, got a plain number").hint
    assert "plain number" in fails(tmp_path, "minimize damping() weight 2 mm\n", "expected a plain number").hint
    for name in ("spitze_\u00e4", "\u00e9cart", "\u5c16\u7aef", "tip\u0661"):   # a letter or digit not ASCII
        assert "names are ASCII" in fails(tmp_path, f"param {name} : length = 5 mm\n", "unexpected character").hint
    assert fails(tmp_path, "param d : length = 5 mm \u2014 five\n", "unexpected character").hint is None


def test_cli_exits_2_on_a_resource_limit(tmp_path):
    path = write(tmp_path, "param p : point = " + "[" * 5000 + "]" * 5000 + "\n")
    proc = subprocess.run([sys.executable, "-m", "vfdsl.cli", "show", str(path)], capture_output=True, text=True,
                          preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30)))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "values nested too deeply: the limit is 16" in proc.stderr
