"""Mesh fixtures: the C proximity query against brute force over all triangles (NumPy), the rows against finite
differences of the frames' kinematics (Pinocchio), the mesh param's errors, and both runtime paths."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import vfdsl
from vfdsl.check.kinematics import frame_pose
from vfdsl.compiler.mesh_rows import K, REACH
from vfdsl.errors import VfError
from vfdsl.kinematics.robot import Robot
from vfdsl.mesh import brute
from vfdsl.mesh.external import mesh_query
from vfdsl.mesh.load import read_mesh

TASKS = Path(__file__).resolve().parent.parent / "tasks"
CHANNEL = TASKS / "anatomy" / "channel.stl"


@pytest.fixture(scope="module")
def channel():
    mesh = read_mesh(CHANNEL, 1e-3)
    return mesh, mesh_query(mesh, K)


def _samples(rng, n, segment):
    centre = np.array([0.004, 0.0, 0.27])
    a = centre + rng.uniform(-1, 1, (n, 3)) * [0.012, 0.008, 0.045]
    b = a + (rng.normal(size=(n, 3)) * 0.015 if segment else 0)
    return a, b


@pytest.mark.parametrize("segment", [False, True], ids=["point", "capsule"])
def test_query_matches_brute_force(channel, segment):
    """The nearest feature is at the brute-force distance of the segment; every feature's |d| is the distance from
    its point x = a + s (b - a) of the segment to some triangle, and its direction is unit."""
    mesh, query = channel
    rng = np.random.default_rng(1)
    for a, b in zip(*_samples(rng, 25, segment)):
        d, s, u = (np.array(x) for x in query.function(a, b, [1.0, -1.0]))
        d, s, u = d.ravel(), s.ravel(), u.reshape(3, K, order="F")
        each = brute.segment_distances(a, b, mesh.vertices, mesh.triangles)
        assert abs(np.abs(d[0]) - each.min()) < 1e-12
        active = np.isfinite(d)
        assert np.all(np.diff(np.abs(d[active])) >= 0)
        for i in np.flatnonzero(active):
            x = a + s[i] * (b - a)
            at_x = brute.segment_distances(x, x, mesh.vertices, mesh.triangles)
            assert np.min(np.abs(at_x - abs(d[i]))) < 1e-10          # x's distance to one triangle
            assert abs(d[i]) >= each.min() - 1e-12
            assert abs(np.linalg.norm(u[:, i]) - 1) < 1e-12


def test_query_sign_is_the_side(channel):
    """inside_mesh (side -1): d > 0 exactly where the point is inside the closed channel (winding number)."""
    mesh, query = channel
    rng = np.random.default_rng(2)
    for a, _ in zip(*_samples(rng, 80, False)):
        d = float(np.array(query.function(a, a, [1.0, -1.0])[0]).ravel()[0])
        inside = brute.winding_number(a, mesh.vertices, mesh.triangles) > 0.5
        assert (d > 0) == inside, (a, d)


def test_cutoff_relaxes_rows(channel):
    """Features farther than the cutoff give d = +inf, s = 0, u = 0: rows 0 >= -inf."""
    _, query = channel
    d, s, u = (np.array(x) for x in query.function([0.0, 0.0, 0.27], [0.0, 0.0, 0.27], [0.0037, -1.0]))
    assert np.all(np.isinf(d[1:]) | (np.abs(d[1:]) <= 0.0037))
    assert np.isinf(d).any() and np.all(u.reshape(3, K, order="F")[:, np.isinf(d.ravel())] == 0)


def _rows(ctrl, q):
    qp = ctrl.problem(q, {"f": [0, 0, 0]}, dt=0.01)
    idx = [i for i, label in enumerate(qp.labels) if "inside_mesh" in label or "outside_mesh" in label]
    return qp.A[idx, :qp.nq], qp.lb[idx]


def test_rows_against_finite_differences_and_brute_force(tmp_path):
    """Row i is u_i' dx_i with dx_i the motion of the capsule's point x_i = (1 - s_i) a + s_i b: the same numbers
    as finite differences of u_i . x_i(q) (u_i, s_i held); the first row's bound is r + margin - d with d the
    brute-force distance of the capsule's axis to the channel."""
    task = vfdsl.load(TASKS / "sinus_channel.vf")
    robot = Robot.load(task.robots[0].urdf)
    ctrl = vfdsl.compile(task, backend="interpreted")
    mesh, query = read_mesh(CHANNEL, 1e-3), mesh_query(read_mesh(CHANNEL, 1e-3), K)
    tip, shaft = task.frame("tip"), task.frame("shaft")
    rng = np.random.default_rng(3)
    for _ in range(4):
        q = task.start + rng.normal(size=7) * [0.001, 0.001, 0.002, 0.03, 0.03, 0.2, 0.005]
        A, lb = _rows(ctrl, q)
        a, b = frame_pose(robot, tip, q)[0], frame_pose(robot, shaft, q)[0]
        d, s, u = (np.array(x) for x in query.function(a, b, [0.0015 + REACH, -1.0]))
        d, s, u = d.ravel(), s.ravel(), u.reshape(3, K, order="F")
        assert abs(lb[0] - (0.0015 - brute.segment_distances(a, b, mesh.vertices, mesh.triangles).min())) < 1e-12
        for i in np.flatnonzero(np.isfinite(lb)):
            def phi(q):
                x = (1 - s[i]) * frame_pose(robot, tip, q)[0] + s[i] * frame_pose(robot, shaft, q)[0]
                return u[:, i] @ x
            h = 1e-7
            fd = np.array([(phi(q + h * e) - phi(q - h * e)) / (2 * h) for e in np.eye(7)])
            assert np.allclose(A[i], fd, atol=1e-7), (i, A[i], fd)
            assert abs(lb[i] - (0.0015 - d[i])) < 1e-12


def test_native_and_interpreted_agree():
    task = vfdsl.load(TASKS / "bone_nerve.vf")
    paths = [vfdsl.compile(task, backend=b) for b in ("interpreted", "native")]
    q = task.start.copy()
    for _ in range(40):
        steps = [c.step(q, {"f": [8, 0, -8]}) for c in paths]
        assert np.allclose(steps[0], steps[1], atol=1e-12, rtol=0)
        q = q + steps[0]


def test_registration_moves_the_mesh():
    """A mesh `in` a pose param moves with it: the nerve registered 18 mm higher and 6 mm toward the tool is
    within reach of the tool, and its row's bound is the brute-force distance of the moved nerve."""
    task = vfdsl.load(TASKS / "bone_nerve.vf")
    robot = Robot.load(task.robots[0].urdf)
    ctrl = vfdsl.compile(task, backend="interpreted")
    q, shift = task.start, np.array([-0.006, 0, 0.018])
    rows = [i for i, label in enumerate(ctrl.problem(q, {"f": [0, 0, 0]}).labels) if "outside_mesh(tip)" in label]
    assert np.all(np.isinf(ctrl.problem(q, {"f": [0, 0, 0]}).lb[rows]))        # 20 mm away: beyond reach
    moved = ctrl.problem(q, {"f": [0, 0, 0]}, params={"patient": [*shift, 0, 0, 0]})
    nerve = read_mesh(TASKS / "anatomy" / "nerve.stl", 1e-3)
    a, b = frame_pose(robot, task.frame("tip"), q)[0], frame_pose(robot, task.frame("shaft"), q)[0]
    d = brute.segment_distances(a, b, nerve.vertices + shift, nerve.triangles).min()
    assert moved.lb[rows[0]] == pytest.approx(0.001 + 0.002 - d, abs=1e-12)


def _task(folder: Path, mesh_line: str, stl: str = "ball.stl") -> Path:
    import trimesh
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=6.0)
    sphere.apply_translation([12, 0, 262])
    sphere.export(folder / stl)
    path = folder / "t.vf"
    path.write_text("task t\nunits mm, deg\nrobot shr = urdf \"shr7\"\nframe tip = shr.link(\"tool_tip\")\n"
                    f"{mesh_line}\nrequire tip outside_mesh(ball, 1 mm)\n")
    return path


@pytest.mark.parametrize("line, message, column", [
    ('param ball : mesh(unit = 1 m) = "ball.stl"', "larger than a patient", 33),
    ('param ball : mesh(unit = 1 um) = "ball.stl"', "too small for anatomy", 34),
    ('param ball : mesh = "nothing.stl"', "not found", 21),
    ('param ball : mesh(scale = 2) = "ball.stl"', "mesh has no type argument 'scale'", 19),
    ('param ball : mesh = [1, 2, 3] mm', "a mesh is given by its file name", 21),
])
def test_mesh_param_errors(tmp_path, line, message, column):
    with pytest.raises(VfError) as err:
        vfdsl.load(_task(tmp_path, line))
    assert message in err.value.message
    assert (err.value.pos.line, err.value.pos.column) == (5, column)


def test_units_follow_the_task_default(tmp_path):
    """Without mesh(unit = ...), a file unit is the task's length unit (mm here): the ball is 6 mm."""
    task = vfdsl.load(_task(tmp_path, 'param ball : mesh = "ball.stl"'))
    mesh = read_mesh(task.param("ball").value.file, task.param("ball").value.unit)
    assert mesh.extent == pytest.approx(0.012, rel=1e-6)


def test_no_compiler_is_a_clear_error(tmp_path, monkeypatch):
    path = _task(tmp_path, 'param ball : mesh = "ball.stl"')
    monkeypatch.setenv("VFDSL_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    with pytest.raises(VfError) as err:
        vfdsl.compile(vfdsl.load(path), backend="interpreted")
    assert "mesh 'ball'" in err.value.message and "C compiler" in err.value.message
    assert err.value.pos.line == 5
