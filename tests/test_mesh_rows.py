"""Mesh fixtures: the C proximity query against brute force over all triangles (NumPy), the rows against finite
differences of the frames' kinematics (Pinocchio), the mesh param's errors, and both runtime paths."""
# The query's answer is stated in vfdsl/mesh/query.c; brute.features computes it from every triangle's hits.

from __future__ import annotations

import subprocess
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import vfdsl
from vfdsl.check.kinematics import frame_pose
from vfdsl.compiler.mesh_rows import K, REACH
from vfdsl.errors import VfError
from vfdsl.kinematics.robot import Robot
from vfdsl.mesh import brute
from vfdsl.codegen.build import FLAGS, find_compiler
from vfdsl.mesh.external import SIMILAR, c_source, mesh_query
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


def _answer(function, a, b, cutoff, side=-1.0):
    d, s, u = (np.array(x) for x in function(a, b, [cutoff, side]))
    return d.ravel(), s.ravel(), u.reshape(3, K, order="F")


def _same(answer, reference, points=True):
    """The query's answer is the reference's; ``points=False``: but for the rows' points s on the shaft."""
    (d, s, u), (rd, rs, ru) = answer, reference
    assert np.array_equal(np.isinf(d), np.isinf(rd)), (d, rd)
    assert np.allclose(d[np.isfinite(d)], rd[np.isfinite(rd)], atol=1e-12, rtol=0), (d, rd)
    assert (not points or np.allclose(s, rs, atol=1e-9, rtol=0)) and np.allclose(u, ru, atol=1e-9, rtol=0), (s, rs)


def _along_the_wall(rng, n):
    """Shafts 18 mm long lying 1.2-2 mm from the straight part of the channel's wall, tilted 0.5-3 deg: hundreds
    of triangles nearly equidistant from them (the query's slowest case)."""
    out = []
    for _ in range(n):
        angle, gap = rng.uniform(0, 2 * np.pi), rng.uniform(1.2e-3, 2e-3)
        radial = np.array([np.cos(angle), np.sin(angle), 0.0])
        a = np.array([0.0, 0.0, 0.298]) + (0.005 - gap) * radial
        tilt = np.radians(rng.uniform(0.5, 3)) * rng.choice([-1, 1])
        out.append((a, a + 0.018 * (np.cos(tilt) * np.array([0, 0, 1.0]) + np.sin(tilt) * radial)))
    return out


def _in_the_bend(rng, n):
    """Shafts 30 mm long lying 1.45-2.2 mm from the bend's wall (the centreline x = 10 mm ((295 - z) / 65 mm)^2 below
    z = 295 mm), along it within 2 deg, on every side: the wall curves away from the shaft, so hundreds of triangles
    lie within the K-th row's distance and nearly all of their hits between the ends are merged (benchmarks/mesh.py's
    slowest states; the query leaves them pending, vfdsl/mesh/query.c)."""
    out = []
    for _ in range(n):
        z = rng.uniform(0.245, 0.28)
        x, slope = 10e-3 * ((0.295 - z) / 0.065) ** 2, -2 * 10e-3 * (0.295 - z) / 0.065 ** 2
        along = np.array([slope, 0.0, 1.0]) / np.hypot(slope, 1.0)
        side = rng.uniform(0, 2 * np.pi)
        radial = np.cos(side) * np.array([along[2], 0.0, -along[0]]) + np.sin(side) * np.array([0.0, 1.0, 0.0])
        tilt = np.radians(rng.uniform(-2, 2))
        axis = np.cos(tilt) * along + np.sin(tilt) * np.cross(along, radial)
        middle = np.array([x, 0.0, z]) + (0.005 - rng.uniform(1.45e-3, 2.2e-3)) * radial
        out.append((middle - 0.015 * axis, middle + 0.015 * axis))
    return out


THROUGH_THE_WALL = [(np.array(a), np.array(b)) for a, b in [   # shafts 30 mm long crossing the channel's wall twice
    ([-0.002790383755125069, -0.0004796983128308079, 0.250055810260534],     # (found among 400 random such shafts)
     [-0.002157336508999525, 0.004914020451222921, 0.2795601667029048]),
    ([-0.0014624744027899243, 0.007343263765287279, 0.2609704648275786],
     [-0.00579849025977488, -0.0026349678558437034, 0.28892818040312296]),
    ([0.007250291766473912, -0.0016466407448570857, 0.2705226742957797],
     [0.0013334568340789112, 0.007815735546239978, 0.2983696579620311]),
]]


@pytest.mark.parametrize("side", [-1.0, 1.0])
def test_a_shaft_through_the_wall_gives_the_first_crossing_first(channel, side):
    """Hits at distance 0 (the shaft crosses a triangle) come in the answer's order (part, then the point c): here a
    box the shaft crosses was bounded a little above 0 by rounding (~1e-18 m), so another crossing was taken before it
    was opened (the first row's s and u those of the wrong crossing); the boxes' bounds are now lowered by their
    rounding."""
    mesh, query = channel
    for a, b in THROUGH_THE_WALL:
        for cutoff in (1.0, 0.0015 + REACH):
            answer = _answer(query.function, a, b, cutoff, side)
            assert answer[0][0] == 0
            _same(answer, brute.features(a, b, mesh.vertices, mesh.triangles, cutoff, side, K, SIMILAR))


@pytest.mark.parametrize("segment", [False, True], ids=["point", "capsule"])
def test_query_is_the_brute_force_answer(channel, segment):
    """Every output of the query (d, s, u of the K rows) is brute.features': points and capsules inside and outside
    the channel, with the example's cutoff and with one that admits every triangle; shafts along the wall, straight and
    in the bend. The walk's memory is the function's work vector, reused by every call: asking the first question
    again gives the first answer."""
    mesh, query = channel
    rng = np.random.default_rng(4)
    cases = list(zip(*_samples(rng, 16, segment)))
    if segment:
        cases += _along_the_wall(rng, 8) + _in_the_bend(rng, 12)
    answers = []
    for i, (a, b) in enumerate(cases):
        cutoff = 1.0 if i % 4 == 0 else 0.0015 + REACH
        answers.append(_answer(query.function, a, b, cutoff))
        _same(answers[-1], brute.features(a, b, mesh.vertices, mesh.triangles, cutoff, -1.0, K, SIMILAR))
    again = _answer(query.function, *cases[0], 1.0)
    assert all(np.array_equal(x, y) for x, y in zip(again, answers[0]))


PARALLEL_TO_THE_WALL = [(np.array(a), np.array(a) + [0.0, 0.0, length]) for a, length in [  # shafts along z near the
    ([0.0035064955160189078, 0.0041965398143575406, 0.31531975516936783], -0.003),   # straight wall, in and out
    ([-0.0021111545017843624, 0.0046890899205401923, 0.31498885734312931], 1e-4),    # (found among 600 random
    ([0.00078131212045700553, -0.0046640170718043519, 0.31741876397513591], -0.003),  # segments where a query that
    ([-0.00022332056231567574, -0.0057712199165766611, 0.3031545966742431], 0.1),    # dropped such triangles, or
    ([0.0036668150959751769, 0.001379640134325715, 0.3011804898676938], -0.003),     # keyed them by a corner, gave
]]                                                                                  # other rows)


def test_a_shaft_parallel_to_the_wall_is_the_brute_force_answer(channel):
    """Shafts exactly along the straight part's axis (z), as the example's tool stands at its start, inside the
    channel and outside it: the wall's triangles have an edge parallel to the shaft, so their projection on the plane
    normal to it has no area (1,540 of the channel's triangles). The query measures such a triangle on its projected
    edges (vfm_nearest_on_edges; the face step divided 0 by 0, and every such triangle's hit was computed in full: 90
    at one state of benchmarks/mesh.py). The rows' distances and directions are brute.features', keep in and keep
    out with the example's cutoff, keep in with 1 m (every row), and their points on the shaft are no farther from the
    mesh than their distances. (Where a triangle is parallel to the shaft its nearest points make a line: the query
    and the brute force may pick different ones, and rows at one distance may come in another order, before this
    change too.) Either fault fails it: such triangles dropped, or keyed by a corner."""
    mesh, query = channel
    for a, b in PARALLEL_TO_THE_WALL:
        for cutoff, side in ((0.0015 + REACH, -1.0), (1.0, -1.0), (0.0015 + REACH, 1.0)):
            d, s, u = _answer(query.function, a, b, cutoff, side)
            _same((d, s, u), brute.features(a, b, mesh.vertices, mesh.triangles, cutoff, side, K, SIMILAR),
                  points=False)
            for i in np.flatnonzero(np.isfinite(d) if cutoff == 1.0 else []):
                x = a + s[i] * (b - a)
                nearest = brute.segment_distances(x, x, mesh.vertices, mesh.triangles).min()
                assert nearest <= abs(d[i]) + 1e-12, (i, nearest, d[i])


def _tangent_to_the_bend(rng, n):
    """Shafts 60 mm long touching the bend's outer wall at their middle, 0.1 mm from it, within 15 deg of the bend's
    plane (out of it: hits mirrored across it tie up to rounding): the wall curves away, so the ends lie ~2.1 mm from
    it, beyond a cutoff of 1.2 mm, while the middle has hits in many directions."""
    out = []
    for _ in range(n):
        z = rng.uniform(0.25, 0.275)
        x, slope = 10e-3 * ((0.295 - z) / 0.065) ** 2, -2 * 10e-3 * (0.295 - z) / 0.065 ** 2
        along = np.array([slope, 0.0, 1.0]) / np.hypot(slope, 1.0)
        side = rng.uniform(0.05, 0.25) * rng.choice([-1, 1])
        radial = np.cos(side) * np.array([along[2], 0.0, -along[0]]) + np.sin(side) * np.array([0.0, 1.0, 0.0])
        middle = np.array([x, 0.0, z]) + (0.005 - 1e-4) * radial
        out.append((middle - 0.03 * along, middle + 0.03 * along))
    return out


def test_the_ends_rows_to_come_are_counted_only_when_they_come(channel):
    """The walk stops a part when it and the rows of the other parts make K, counting an end that has no kept hit
    yet when its nearest feature gives it a row (within the cutoff, or on the forbidden side). The same shafts along
    the bend with both ends beyond the cutoff: keeping out (the channel read as a solid) both ends are on the forbidden
    side and have rows of their own, so the middle gives K - 2; keeping in they are on the free side and the middle
    gives all K. Both as brute.features."""
    mesh, query = channel
    cutoff, rows = 1.2e-3, {-1.0: [], 1.0: []}
    for a, b in _tangent_to_the_bend(np.random.default_rng(11), 5):
        for side in (-1.0, 1.0):
            d, s, u = _answer(query.function, a, b, cutoff, side)
            _same((d, s, u), brute.features(a, b, mesh.vertices, mesh.triangles, cutoff, side, K, SIMILAR))
            rows[side].append(((s > 0) & (s < 1) & np.isfinite(d)).sum())
            if side > 0 and rows[side][-1] == K - 2:
                assert sorted(s[(s == 0) | (s == 1)]) == [0, 1] and np.all(d[(s == 0) | (s == 1)] < -cutoff)
    assert K in rows[-1.0] and K - 2 in rows[1.0], rows


def test_a_full_queue_gives_the_same_answer(channel, tmp_path):
    """Built with a queue of 8 entries (the default holds 1,024), the walk overflows on every capsule and ends
    depth-first, one kept hit at a time: the same answers as the default build."""
    mesh, query = channel
    name = "vfmesh_small_queue"
    (tmp_path / f"{name}.c").write_text(c_source(name, mesh, K))
    subprocess.run([*find_compiler().command, *FLAGS, "-DVFM_HEAP=8", "-shared", f"{name}.c", "-o", f"lib{name}.so",
                    "-lm"], cwd=tmp_path, check=True, capture_output=True)
    small = ca.external(name, str(tmp_path / f"lib{name}.so"))
    rng = np.random.default_rng(5)
    for i, (a, b) in enumerate([*zip(*_samples(rng, 10, True)), *_along_the_wall(rng, 5), *_in_the_bend(rng, 5),
                                *THROUGH_THE_WALL]):
        cutoff = 1.0 if i % 3 == 0 else 0.0015 + REACH
        expected = _answer(query.function, a, b, cutoff)
        assert all(np.array_equal(x, y) for x, y in zip(_answer(small, a, b, cutoff), expected))


def test_cutoff_relaxes_rows(channel):
    """Features farther than the cutoff give d = +inf, s = 0, u = 0: rows 0 >= -inf."""
    _, query = channel
    d, s, u = (np.array(x) for x in query.function([0.0, 0.0, 0.27], [0.0, 0.0, 0.27], [0.0037, -1.0]))
    assert np.all(np.isinf(d[1:]) | (np.abs(d[1:]) <= 0.0037))
    assert np.isinf(d).any() and np.all(u.reshape(3, K, order="F")[:, np.isinf(d.ravel())] == 0)


def _far(rng, distance, side):
    """Points and capsules whose ends lie ``distance`` beyond the channel's wall on the forbidden side of ``side``
    (-1, keep in: outside the channel; +1, keep out: the channel read as a solid, ends deep inside it)."""
    out = []
    for _ in range(4):
        angle = rng.uniform(0, 2 * np.pi)
        radial = np.array([np.cos(angle), np.sin(angle), 0.0])
        z = rng.uniform(0.26, 0.29)
        a = np.array([0.0, 0.0, z]) + (0.005 + distance if side < 0 else 0.0) * radial
        b = a + (rng.normal(size=3) * (0.001 if side > 0 else 0.015))
        out += [(a, a), (a, b)]
    return out


@pytest.mark.parametrize("side", [-1.0, 1.0], ids=["outside_keep_in", "inside_keep_out"])
@pytest.mark.parametrize("distance", [1e-3, 1e-2, 1.0])
def test_an_end_on_the_forbidden_side_always_has_a_row(channel, side, distance):
    """Wherever an end is on the forbidden side (1 mm, 10 mm, 1 m outside a keep-in channel; inside the channel read
    as a keep-out solid), far beyond the cutoff, its nearest feature gives a row that asks back by the whole
    distance: d < 0 with |d| the brute-force distance, u from the wall toward the free side, as brute.features."""
    mesh, query = channel
    rng = np.random.default_rng(7)
    cutoff = 0.0015 + REACH
    for a, b in _far(rng, distance, side):
        d, s, u = _answer(query.function, a, b, cutoff, side)
        _same((d, s, u), brute.features(a, b, mesh.vertices, mesh.triangles, cutoff, side, K, SIMILAR))
        inside = brute.winding_number(a, mesh.vertices, mesh.triangles) > 0.5
        if inside != (side < 0):                         # a is on the forbidden side: a row of its own, s = 0
            row = np.flatnonzero(np.isfinite(d) & (s == 0))[0]
            nearest = brute.segment_distances(a, a, mesh.vertices, mesh.triangles).min()
            assert d[row] < 0 and abs(abs(d[row]) - nearest) < 1e-12
            x = a + 1e-6 * u[:, row]                      # a step along u brings the end nearer to the wall
            assert brute.segment_distances(x, x, mesh.vertices, mesh.triangles).min() < nearest
        assert np.any(d < 0) or np.all(np.isinf(d) | (d > 0))


def test_an_end_far_on_the_free_side_has_no_row(channel):
    """A keep-out fixture far from the tool gives no row (0 >= -inf), whatever the query's far-end rule."""
    _, query = channel
    a = np.array([0.5, 0.0, 0.27])
    d = np.array(query.function(a, a + [0, 0, 0.03], [0.0035, 1.0])[0]).ravel()
    assert np.all(np.isinf(d))


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


def _ball(path: Path, centre) -> None:
    """A ball of radius 6 (file units) at ``centre``, as an STL."""
    import trimesh
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=6.0)
    sphere.apply_translation(centre)
    path.parent.mkdir(parents=True, exist_ok=True)
    sphere.export(path)


def _task(folder: Path, mesh_line: str, stl: str = "ball.stl") -> Path:
    _ball(folder / stl, [12, 0, 262])
    path = folder / "t.vf"
    path.write_text("task t\nunits mm, deg\nrobot shr = urdf \"shr7\"\nframe tip = shr.link(\"tool_tip\")\n"
                    f"{mesh_line}\nrequire tip outside_mesh(ball, 1 mm)\n")
    return path


@pytest.mark.parametrize("line, message, column", [
    ('param ball : mesh(unit = 1 m) = "ball.stl"', "larger than a patient", 33),
    ('param ball : mesh(unit = 1 um) = "ball.stl"', "too small for anatomy", 34),
    ('param ball : mesh = "nothing.stl"', "not found", 21),
    ('param ball : mesh = "folder.stl"', "is a directory, not a mesh file", 21),
    ('param ball : mesh(scale = 2) = "ball.stl"', "mesh has no type argument 'scale'", 19),
    ('param ball : mesh = [1, 2, 3] mm', "a mesh is given by its file name", 21),
])
def test_mesh_param_errors(tmp_path, line, message, column):
    (tmp_path / "folder.stl").mkdir()
    with pytest.raises(VfError) as err:
        vfdsl.load(_task(tmp_path, line))
    assert message in err.value.message
    if "not found" in message or "directory" in message:
        assert f"relative to {tmp_path.resolve()}" in err.value.hint       # where the path was looked for
    assert (err.value.pos.line, err.value.pos.column) == (5, column)


@pytest.mark.parametrize("unit, message", [("1e300 mm", "larger than a patient"), ("1e-300 mm", "too small for anatomy"),
                                           ("1e200 m", "larger than a patient")])
def test_absurd_mesh_units_are_refused_before_any_arithmetic(tmp_path, unit, message):
    """A unit that puts the mesh at 1e298 m or 1e-302 m is the unit's mistake: refused at the file name with both
    readings, before the areas or the volume are computed in it (no overflow warning, no 'every triangle is
    degenerate')."""
    import warnings

    line = f'param ball : mesh(unit = {unit}) = "ball.stl"'
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(VfError) as err:
            vfdsl.load(_task(tmp_path, line))
    assert message in err.value.message and "mesh(unit = 1 mm)" in err.value.hint
    assert (err.value.pos.line, err.value.pos.column) == (5, line.index('"') + 1)


def test_units_follow_the_task_default(tmp_path):
    """Without mesh(unit = ...), a file unit is the task's length unit (mm here): the ball is 6 mm."""
    task = vfdsl.load(_task(tmp_path, 'param ball : mesh = "ball.stl"'))
    mesh = read_mesh(task.param("ball").value.file, task.param("ball").value.unit)
    assert mesh.extent == pytest.approx(0.012, rel=1e-6)


START = "start: {x: 0, y: 0, z: 0, rcm_a: 0, rcm_b: 0, roll: 0, insert: 20}\n"   # the tip at (0, 0, 280) mm


def test_a_scene_gives_a_mesh_relative_to_itself(tmp_path):
    """A mesh param's value in a scene file (here in a folder of its own) is a path relative to the scene file,
    read with the param type's unit: the tip's row is that of the scene's ball, 2 mm under the tip (the task's
    own ball is beyond reach)."""
    path = _task(tmp_path, 'param ball : mesh(unit = 1 mm) = "ball.stl"\nscene "setup/scene.yaml"')
    _ball(tmp_path / "setup" / "meshes" / "ball.stl", [0, 0, 272])
    (tmp_path / "setup" / "scene.yaml").write_text("units: mm, deg\n" + START + "params:\n  ball: meshes/ball.stl\n")
    task = vfdsl.load(path)
    assert Path(task.param("ball").value.file) == (tmp_path / "setup" / "meshes" / "ball.stl").resolve()
    ctrl = vfdsl.compile(task, backend="interpreted")
    qp = ctrl.problem(task.start, {}, dt=0.01)
    row = next(i for i, label in enumerate(qp.labels) if "outside_mesh" in label)
    tip = frame_pose(Robot.load(task.robots[0].urdf), task.frame("tip"), task.start)[0]
    ball = read_mesh(tmp_path / "setup" / "meshes" / "ball.stl", 1e-3)
    d = brute.segment_distances(tip, tip, ball.vertices, ball.triangles).min()
    assert d == pytest.approx(0.002, abs=2e-4)
    assert qp.lb[row] == pytest.approx(0.001 - d, abs=1e-12)


@pytest.mark.parametrize("value, message, column", [
    ("meshes/none.stl", "not found", 9),
    ("{file: meshes/ball.stl, unit: 1 m}", "larger than a patient", 16),
    ("{file: meshes/ball.stl, units: 1 mm}", "a mesh in a scene has no key 'units'", 33),
    ("{unit: 1 mm}", "a mesh in a scene needs its file", 9),
    ("[1, 2, 3]", "a mesh is given by its file name", 9),
    ("10.stl", "a mesh is given by its file name", 9),       # a name that reads as a number: the hint says ./10.stl
    ("{file: meshes/ball.stl, unit: 0 mm}", "a mesh's unit must be a positive length", 39),
])
def test_mesh_errors_in_a_scene_point_into_it(tmp_path, value, message, column):
    path = _task(tmp_path, 'param ball : mesh = "ball.stl"\nscene "setup/scene.yaml"')
    _ball(tmp_path / "setup" / "meshes" / "ball.stl", [0, 0, 272])
    (tmp_path / "setup" / "scene.yaml").write_text(f"units: mm\nparams:\n  ball: {value}\n")
    with pytest.raises(VfError) as err:
        vfdsl.load(path)
    assert message in err.value.message
    assert Path(err.value.pos.file).name == "scene.yaml" and (err.value.pos.line, err.value.pos.column) == (3, column)
    if value == "10.stl":
        assert "write it as ./10.stl" in err.value.hint


def test_a_mesh_is_not_a_run_time_param():
    task = vfdsl.load(TASKS / "bone_nerve.vf")
    ctrl = vfdsl.compile(task, backend="interpreted")
    with pytest.raises(VfError) as err:
        ctrl.step(task.start, {"f": [0, 0, 0]}, params={"nerve": "other.stl"})
    assert "'nerve' is a mesh" in err.value.message
    assert "params.nerve" in err.value.hint and "'patient'" in err.value.hint


def test_no_compiler_is_a_clear_error(tmp_path, monkeypatch):
    path = _task(tmp_path, 'param ball : mesh = "ball.stl"')
    monkeypatch.setenv("VFDSL_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    with pytest.raises(VfError) as err:
        vfdsl.compile(vfdsl.load(path), backend="interpreted")
    assert "mesh 'ball'" in err.value.message and "C compiler" in err.value.message
    assert err.value.pos.line == 5
