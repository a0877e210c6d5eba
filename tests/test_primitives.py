"""Every constraint primitive's QP rows against an independent computation from the seed's formulas.

For each primitive a small task file is written to ``tmp_path``, compiled with
``vfdsl.runtime.controller.compile(vfdsl.load(path))``, and evaluated at random joint configurations (within
the joint limits) with random run-time params. The constraint rows (the rows of ``A`` after the variable
bounds, found by their labels) are compared with rows computed here with numpy only:

- frame pose and Jacobian from Pinocchio through ``Robot.frame_pose`` / ``Robot.frame_jacobian`` (rows
  [v; w], LOCAL_WORLD_ALIGNED), never from ``vfdsl.compiler``;
- every row is  u . (delta + dx) <= eps  written as  -u J dq >= -eps + u . delta  (H = -u, h = -eps - H delta:
  the corrected eq. 4, erratum 1), so the sign of h is checked on random, signed offsets;
- the sphere polytope from eq. (3) with repeated directions removed (erratum 3), written here afresh;
- polygons (eqs. 8-9) are checked twice. (a) Basis-free: each row is fitted as -(cos t e1 + sin t e2) J
  in a basis (e1, e2) of the plane chosen here; the fit must be exact with cos^2 + sin^2 = 1, the angles
  t_i must be n equally spaced angles (any phase) and each lower bound -eps + u_i . delta. This compares
  the polytope as a set of half-spaces up to the one thing the paper leaves free (eq. 8's arbitrary
  helper vector l' sets the in-plane phase). (b) Exactly, row by row, with the basis rebuilt as
  ``vfdsl.compiler.geometry.plane_basis`` documents it (l' = x unless |l_x| >= 0.9, then y;
  v1 = l x l' / |.|, v2 = v1 x l / |.|), so that the documented orientation is pinned down too.
- follows: the closest point by dense brute force plus ``scipy.optimize.minimize_scalar`` on scipy's
  ``make_interp_spline`` through the same points (chord-length parameter, as ``vfdsl/compiler/curve.py``);
- cone: eqs. (22)-(23) written out here; passes_through: derived from the lecture's (slide 46)
  constraint w = (c - p) x l = 0, differentiated here (the printed "rearranging" has sign typos).
"""

from __future__ import annotations

import itertools
import math
import shutil
import textwrap
import xml.etree.ElementTree as ET
from functools import partial
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from scipy.interpolate import make_interp_spline
from scipy.optimize import brentq, linear_sum_assignment, minimize_scalar

import vfdsl
from vfdsl.compiler.assemble import SOFT_RESTORE_RATE
from vfdsl.kinematics.robot import ROBOTS_DIR, Robot

compile_task = partial(vfdsl.compile, backend="interpreted")   # rows and solutions; C is tested elsewhere

ATOL = 1e-10          # rows are O(1) (prismatic columns) or O(0.5 m) (lever arms); bounds O(0.1)
TRIALS = 12
DEG = math.pi / 180

ROBOTS = {name: Robot.load(name) for name in ("shr7", "panda7")}

# Task frames used by the tests: name -> (link, translation offset, rpy offset, tool axis in the frame).
FRAMES = {
    "shr7": {
        "tip": ("tool_tip", None, None, (0, 0, 1)),
        "shaft": ("tool_tip", (0.0, 0.0, 0.1), None, (0, 0, 1)),
    },
    "panda7": {
        "tip": ("tool_tip", None, None, (0, 0, 1)),
        "tcp": ("tool_tip", (0.01, -0.02, 0.03), (0.1, 0.2, 0.3), (1, 0, 0)),
    },
}
ROBOT_FRAMES = [(r, f) for r in FRAMES for f in FRAMES[r]]


# ============================================================================================== helpers

def frame_lines(robot: str) -> str:
    out = []
    for name, (link, xyz, rpy, axis) in FRAMES[robot].items():
        line = f'frame {name} = rb.link("{link}")'
        if xyz is not None:
            line += f" offset [{xyz[0]}, {xyz[1]}, {xyz[2]}]"
        if rpy is not None:
            line += f" rotate [{rpy[0]}, {rpy[1]}, {rpy[2]}]"
        if axis != (0, 0, 1):
            line += " axis " + "xyz"[axis.index(1)]
        out.append(line)
    return "\n".join(out)


def build(tmp_path: Path, body: str, robot: str = "shr7", units: str = "m, rad", name: str = "probe"):
    """Write a task (header, frames, body) to tmp_path and compile it; returns the Controller."""
    text = f'task {name}\nunits {units}\nrobot rb = urdf "{robot}"\n{frame_lines(robot)}\n' + textwrap.dedent(body)
    path = tmp_path / f"{name}.vf"
    path.write_text(text)
    return compile_task(vfdsl.load(path))


def offset_matrix(xyz, rpy) -> np.ndarray | None:
    if xyz is None and rpy is None:
        return None
    T = np.eye(4)
    if rpy is not None:
        T[:3, :3] = pin.rpy.rpyToMatrix(*rpy)
    if xyz is not None:
        T[:3, 3] = xyz
    return T


class FrameState:
    """p, R, tool axis l, J (6 x nq), Jv, Jw of a task frame, from Pinocchio."""

    def __init__(self, robot: str, frame: str, q: np.ndarray):
        link, xyz, rpy, axis = FRAMES[robot][frame]
        T = offset_matrix(xyz, rpy)
        rb = ROBOTS[robot]
        self.p, self.R = rb.frame_pose(q, link, T)
        self.J = rb.frame_jacobian(q, link, T)
        self.Jv, self.Jw = self.J[:3], self.J[3:]
        self.l = self.R @ np.asarray(axis, dtype=float)


def random_q(robot: str, rng, shrink: float = 0.9) -> np.ndarray:
    rb = ROBOTS[robot]
    mid, half = (rb.lower + rb.upper) / 2, (rb.upper - rb.lower) / 2
    return mid + shrink * half * rng.uniform(-1, 1, rb.nq)


def unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def random_unit(rng) -> np.ndarray:
    return unit(rng.normal(size=3))


def near_direction(l, rng, max_angle) -> np.ndarray:
    """A unit vector at a random angle in (0.1 max_angle, max_angle) from unit vector l."""
    perp = unit(np.cross(l, random_unit(rng)))
    t = rng.uniform(0.1, 1.0) * max_angle
    return math.cos(t) * l + math.sin(t) * perp


def rows_of(ctrl, qp, primitive: str, frame: str | None = None, soft: bool | None = None):
    """(A over dq, A over all variables, lb, ub) of the constraint rows with this primitive (and frame)."""
    n = qp.P.shape[0]
    idx = [n + i for i, lab in enumerate(ctrl.row_labels)
           if lab.primitive == primitive and (frame is None or lab.frame == frame)
           and (soft is None or lab.soft == soft)]
    assert idx, f"no rows labelled {primitive}({frame})"
    return qp.A[idx, :qp.nq], qp.A[idx], qp.lb[idx], qp.ub[idx]


def sphere_directions_ref(n: int, m: int) -> np.ndarray:
    """Paper eq. (3): u_ij = [c_ai c_bj, c_ai s_bj, s_ai], a_i = 2 pi i/n, b_j = 2 pi j/m, duplicates removed."""
    out: list[np.ndarray] = []
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            a, b = 2 * math.pi * i / n, 2 * math.pi * j / m
            u = np.array([math.cos(a) * math.cos(b), math.cos(a) * math.sin(b), math.sin(a)])
            if all(np.linalg.norm(u - v) > 1e-9 for v in out):
                out.append(u)
    return np.array(out)


def documented_basis(l) -> tuple[np.ndarray, np.ndarray]:
    """The in-plane basis as documented in vfdsl.compiler.geometry.plane_basis (paper eq. 8)."""
    helper = np.array([1.0, 0, 0]) if abs(l[0]) < 0.9 else np.array([0, 1.0, 0])
    v1 = unit(np.cross(l, helper))
    v2 = unit(np.cross(v1, l))
    return v1, v2


def polygon_ref(l, n: int, first=None) -> np.ndarray:
    """Paper eq. (9): u_i = R3 [cos a_i, sin a_i, 0], a_i = 2 pi i / n, with the documented R3 = [v1 v2 l], or
    v1 = ``first`` (the rotation rows' facet n/n along their error's direction), v2 = v1 x l."""
    v1, v2 = documented_basis(l) if first is None else (first, np.cross(first, l))
    return np.array([math.cos(2 * math.pi * i / n) * v1 + math.sin(2 * math.pi * i / n) * v2
                     for i in range(1, n + 1)])


def assert_rows_as_set(A, lb, A_exp, lb_exp, atol=ATOL):
    """The rows (A | lb) equal the expected rows up to a permutation."""
    assert A.shape == A_exp.shape, (A.shape, A_exp.shape)
    X = np.hstack([A, lb[:, None]])
    Y = np.hstack([A_exp, lb_exp[:, None]])
    D = np.linalg.norm(Y[:, None, :] - X[None, :, :], axis=2)
    r, c = linear_sum_assignment(D)
    assert D[r, c].max() < atol, f"rows differ by {D[r, c].max():.3e}"


def assert_sphere_rows(A, lb, ub, J3, delta, eps, n, m):
    U = sphere_directions_ref(n, m)
    assert_rows_as_set(A, lb, -U @ J3, -eps + U @ delta)
    assert np.all(np.isinf(ub)) and np.all(ub > 0)


def assert_polygon_rows(A, lb, ub, J3, delta, eps, normal, n, first=None):
    """(a) basis-free: a regular n-gon of unit normals in the plane normal to ``normal``, any phase;
    (b) exactly the documented basis, row by row."""
    assert A.shape[0] == n
    assert np.all(np.isinf(ub)) and np.all(ub > 0)
    # (a) my own basis of the plane
    e1 = unit(np.cross(normal, random_unit(np.random.default_rng(99))))
    e2 = np.cross(normal, e1)
    M = np.stack([e1 @ J3, e2 @ J3], axis=1)                 # nq x 2
    angles = []
    for i in range(n):
        cs, *_ = np.linalg.lstsq(M, -A[i], rcond=None)
        assert np.allclose(M @ cs, -A[i], atol=ATOL), "row is not a combination of in-plane directions"
        assert abs(np.hypot(*cs) - 1) < 1e-9, f"row normal has length {np.hypot(*cs)}"
        u = cs[0] * e1 + cs[1] * e2
        assert abs(lb[i] - (-eps + u @ delta)) < ATOL, "lower bound is not -eps + u . delta"
        angles.append(math.atan2(cs[1], cs[0]) % (2 * math.pi))
    gaps = np.diff(np.sort(angles + [min(angles) + 2 * math.pi]))
    assert np.allclose(gaps, 2 * math.pi / n, atol=1e-8), f"not a regular {n}-gon: gaps {gaps}"
    # (b) documented orientation, row by row
    U = polygon_ref(normal, n, first)
    np.testing.assert_allclose(A, -U @ J3, atol=ATOL, rtol=0)
    np.testing.assert_allclose(lb, -eps + U @ delta, atol=ATOL, rtol=0)


def urdf_limits(robot: str) -> dict[str, tuple[float, float, float]]:
    """(lower, upper, velocity) per actuated joint, read from the URDF XML (independent of Pinocchio)."""
    root = ET.parse(ROBOTS_DIR / f"{robot}.urdf").getroot()
    out = {}
    for joint in root.iter("joint"):
        if joint.get("type") in ("revolute", "prismatic"):
            lim = joint.find("limit")
            out[joint.get("name")] = (float(lim.get("lower")), float(lim.get("upper")), float(lim.get("velocity")))
    return out


# ====================================================================================== sphere polytope

# Counts derived by hand from eq. (3): a and pi - a give the same ring when m is even (b -> b + pi),
# sin a = +-1 gives a pole (m copies), and a = pi, 2 pi give the same equator.
HAND_COUNTS = {(3, 3): 9, (4, 4): 6, (5, 5): 25, (6, 6): 18, (8, 8): 26, (4, 8): 10, (8, 4): 14, (12, 12): 62}


@pytest.mark.parametrize("nm", sorted(HAND_COUNTS))
def test_sphere_facet_counts(tmp_path, nm):
    n, m = nm
    U = sphere_directions_ref(n, m)
    assert len(U) == HAND_COUNTS[nm]
    ctrl = build(tmp_path, f"require tip stays_at([0, 0, 0.28]) within 0.001 resolution {n}x{m}\n")
    qp = ctrl.problem(np.zeros(7), {}, dt=0.01)
    A, _, _, _ = rows_of(ctrl, qp, "stays_at")
    assert A.shape[0] == HAND_COUNTS[nm]


def facet_count_formula(n: int, m: int) -> int:
    """The unique-facet count documented in docs/primitives.md."""
    if n % 2:
        return n * m
    if m % 2:
        return n * m - 2 * (m - 1) if n % 4 == 0 else n * m
    return (n // 2 - 1) * m + 2 if n % 4 == 0 else (n // 2) * m


def test_sphere_facet_count_formula():
    from vfdsl.compiler.geometry import sphere_directions
    for n, m in itertools.product(range(3, 11), repeat=2):
        assert len(sphere_directions_ref(n, m)) == facet_count_formula(n, m) == len(sphere_directions(n, m)), (n, m)


def test_four_by_four_is_a_cube():
    U = sphere_directions_ref(4, 4)
    assert len(U) == 6
    assert_rows_as_set(U, np.zeros(6), np.vstack([np.eye(3), -np.eye(3)]), np.zeros(6), atol=1e-12)


# ============================================================================================ stays_at

@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
@pytest.mark.parametrize("nm", [(4, 4), (6, 6), (8, 8), (3, 3)])
def test_stays_at(tmp_path, robot, frame, nm):
    n, m = nm
    eps = 0.002
    ctrl = build(tmp_path, f"""
        param target : point = [0, 0, 0.3]
        require {frame} stays_at(target) within {eps} resolution {n}x{m}
        """, robot)
    rng = np.random.default_rng(1)
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        target = f.p + rng.normal(scale=0.005, size=3)
        qp = ctrl.problem(q, {}, {"target": target}, dt=0.01)
        A, Afull, lb, ub = rows_of(ctrl, qp, "stays_at", frame)
        assert_sphere_rows(A, lb, ub, f.Jv, f.p - target, eps, n, m)
        assert np.all(Afull[:, qp.nq:] == 0)


def test_stays_at_units_and_sign(tmp_path):
    """mm file: `within 0.01` is 1e-5 m; the tip 20 mm above the target violates only the +z facet."""
    ctrl = build(tmp_path, "require tip stays_at([0, 0, 280]) within 0.01 resolution 4x4\n", units="mm, deg")
    qp = ctrl.problem(np.zeros(7), {}, dt=0.01)                       # tip at (0, 0, 300) mm
    A, _, lb, _ = rows_of(ctrl, qp, "stays_at")
    J = FrameState("shr7", "tip", np.zeros(7)).Jv
    for u, a, h in zip(sphere_directions_ref(4, 4), A, lb):
        np.testing.assert_allclose(a, -u @ J, atol=ATOL)
        # u . (delta + dx) <= eps with delta = (0, 0, 0.02): h = -eps + u . delta
        assert h == pytest.approx(-1e-5 + 0.02 * u[2], abs=1e-15)
    # dq = 0 must violate exactly the +z facet (h > 0 there) and satisfy the others
    assert [bool(h > 0) for h in lb] == [bool(u[2] > 0.5) for u in sphere_directions_ref(4, 4)]


# ===================================================================================== keeps_direction

@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
@pytest.mark.parametrize("n", [8, 6, 3])
def test_keeps_direction_roll_free(tmp_path, robot, frame, n):
    eps = 0.01
    ctrl = build(tmp_path, f"""
        param d : direction = [0, 0, 1]
        require {frame} keeps_direction(d) within {eps} resolution {n}
        """, robot)
    rng = np.random.default_rng(2)
    for k in range(TRIALS):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        l_d = near_direction(f.l, rng, 0.3) if k % 2 else random_unit(rng)
        qp = ctrl.problem(q, {}, {"d": 2.5 * l_d}, dt=0.01)        # unnormalized on purpose
        A, _, lb, ub = rows_of(ctrl, qp, "keeps_direction", frame)
        delta_r = np.cross(l_d, f.l)                                  # paper II-B.2: l_d x l_t
        if l_d @ f.l < 0:                                             # past 90 deg: length 2 - sin (primitives.md 8)
            delta_r *= (2 - np.linalg.norm(delta_r)) / np.linalg.norm(delta_r)
        assert_polygon_rows(A, lb, ub, f.Jw, delta_r, eps, f.l, n)   # polygon normal to the tool axis


@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
@pytest.mark.parametrize("nm", [(4, 4), (6, 6)])
def test_keeps_direction_pin_roll(tmp_path, robot, frame, nm):
    n, m = nm
    eps = 0.01
    ctrl = build(tmp_path, f"""
        param d : direction = [0, 0, 1]
        require {frame} keeps_direction(d, pin_roll = true) within {eps} resolution {n}x{m}
        """, robot)
    rng = np.random.default_rng(3)
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        l_d = near_direction(f.l, rng, 0.5)
        qp = ctrl.problem(q, {}, {"d": l_d}, dt=0.01)
        A, _, lb, ub = rows_of(ctrl, qp, "keeps_direction", frame)
        assert_sphere_rows(A, lb, ub, f.Jw, np.cross(l_d, f.l), eps, n, m)   # paper eq. (6)


def test_keeps_direction_roll_column(tmp_path):
    """shr7's roll joint turns the tool about its own axis: the roll-free rows ignore it, the paper's
    3-D polytope (pin_roll) bounds it (erratum 4)."""
    ctrl = build(tmp_path, """
        require tip keeps_direction([0, 0.1, 1]) within 0.01
        require shaft keeps_direction([0, 0.1, 1], pin_roll = true) within 0.01
        """)
    roll = ROBOTS["shr7"].joint_names.index("roll")
    rng = np.random.default_rng(4)
    for _ in range(5):
        q = random_q("shr7", rng)
        qp = ctrl.problem(q, {}, dt=0.01)
        free, _, _, _ = rows_of(ctrl, qp, "keeps_direction", "tip")
        pinned, _, _, _ = rows_of(ctrl, qp, "keeps_direction", "shaft")
        assert np.abs(free[:, roll]).max() < 1e-12
        assert np.abs(pinned[:, roll]).max() > 0.5


# =============================================================================================== along

@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
@pytest.mark.parametrize("n", [8, 4])
def test_along(tmp_path, robot, frame, n):
    eps = 0.0005
    ctrl = build(tmp_path, f"""
        param path : line = line(point = [0, 0, 0.28], direction = [1, 1, 0])
        require {frame} along(path) within {eps} resolution {n}
        """, robot)
    rng = np.random.default_rng(5)
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        l = random_unit(rng)
        L0 = f.p + rng.normal(scale=0.004, size=3) + rng.uniform(-0.1, 0.1) * l
        qp = ctrl.problem(q, {}, {"path": {"point": L0, "direction": 3 * l}}, dt=0.01)
        A, _, lb, ub = rows_of(ctrl, qp, "along", frame)
        P_cl = L0 + ((f.p - L0) @ l) * l                              # closest point on L(s) (II-B.3)
        assert_polygon_rows(A, lb, ub, f.Jv, f.p - P_cl, eps, l, n)   # eqs. (9)-(10)


@pytest.mark.parametrize("l", [[1, 0.05, 0.02], [0.85, 0.5, 0.17], [-0.95, 0.3, 0.0], [0, 0, 1]])
def test_polygon_helper_switch(tmp_path, l):
    """Both branches of the documented helper (x unless |l_x| >= 0.9, then y) give the documented rows."""
    ctrl = build(tmp_path, "param path : line = line(point = [0, 0, 0.28], direction = [1, 1, 0])\n"
                           "require tip along(path) within 0.0005 resolution 8\n")
    q = random_q("shr7", np.random.default_rng(19))
    f = FrameState("shr7", "tip", q)
    l = unit(l)
    L0 = f.p + np.array([0.001, -0.002, 0.003])
    qp = ctrl.problem(q, {}, {"path": {"point": L0, "direction": l}}, dt=0.01)
    A, _, lb, ub = rows_of(ctrl, qp, "along")
    assert_polygon_rows(A, lb, ub, f.Jv, f.p - L0 - ((f.p - L0) @ l) * l, 0.0005, l, 8)


# ====================================================================================== rotates_around

@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_rotates_around(tmp_path, robot, frame):
    eps, n = 0.002, 8
    ctrl = build(tmp_path, f"""
        param w : direction = [1, 0, 0]
        require {frame} rotates_around(w) within {eps} resolution {n}
        """, robot)
    rng = np.random.default_rng(6)
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        # an axis nearly perpendicular to the tool (the tool is near the plane it should sweep)
        w = near_direction(unit(np.cross(f.l, random_unit(rng))), rng, 0.4)
        qp = ctrl.problem(q, {}, {"w": w}, dt=0.01)
        A, _, lb, ub = rows_of(ctrl, qp, "rotates_around", frame)
        l_pi = unit(f.l - (f.l @ w) * w)                              # projection of l_t on the plane
        delta_r = np.cross(l_pi, f.l)                                 # II-B.4: l_Pi x l_t
        assert_polygon_rows(A, lb, ub, f.Jw, delta_r, eps, w, n, np.cross(l_pi, w))   # eq. (13), erratum 2


# ======================================================================================= above, on_plane

@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_above(tmp_path, robot, frame):
    ctrl = build(tmp_path, f"""
        param wall : plane = plane(point = [0, 0, 0.27], normal = [0, 0, 1])
        require {frame} above(wall)
        """, robot)
    rng = np.random.default_rng(7)
    signs = []
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        d = random_unit(rng)
        P = f.p + rng.normal(scale=0.01, size=3)
        qp = ctrl.problem(q, {}, {"wall": {"point": P, "normal": 0.3 * d}}, dt=0.01)
        A, _, lb, ub = rows_of(ctrl, qp, "above", frame)
        P_cl = f.p - ((f.p - P) @ d) * d                              # closest point of the plane
        delta = f.p - P_cl
        # eq. (14): d . (delta + dx) >= 0  ->  H = [d^T 0 0 0], h = -H delta (eq. 15)
        np.testing.assert_allclose(A, (d @ f.Jv)[None], atol=ATOL)
        np.testing.assert_allclose(lb, [-(d @ delta)], atol=ATOL)
        assert np.isinf(ub[0]) and ub[0] > 0
        signs.append(np.sign(lb[0]))
    assert {-1.0, 1.0} <= set(signs)          # both sides of the plane were visited


@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_on_plane(tmp_path, robot, frame):
    eps = 0.0003
    ctrl = build(tmp_path, f"""
        param wall : plane = plane(point = [0, 0, 0.27], normal = [0, 0, 1])
        require {frame} on_plane(wall) within {eps}
        """, robot)
    rng = np.random.default_rng(8)
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        d = random_unit(rng)
        P = f.p + rng.normal(scale=0.001, size=3)
        qp = ctrl.problem(q, {}, {"wall": {"point": P, "normal": d}}, dt=0.01)
        A, _, lb, ub = rows_of(ctrl, qp, "on_plane", frame)
        delta = ((f.p - P) @ d) * d                                    # p - P_cl
        H = np.vstack([d @ f.Jv, -d @ f.Jv])                           # eq. (17)
        h = np.array([0.0, -eps]) - np.array([d @ delta, -(d @ delta)])
        np.testing.assert_allclose(A, H, atol=ATOL)
        np.testing.assert_allclose(lb, h, atol=ATOL)
        assert np.all(np.isinf(ub))


# ================================================================================================ cone

def cone_reference(l_t, l_a_raw, gamma):
    """Paper eqs. (22)-(23), as printed (with unit l_a)."""
    l_a = unit(l_a_raw)
    c = np.cross(l_t, l_a)
    d1 = c / np.linalg.norm(c)
    d2 = unit(np.cross(d1, l_a))
    R = np.column_stack([d2, l_a, -d1])
    w_d = R @ np.array([math.cos(gamma), math.sin(gamma), 0.0])
    delta_r = d1 * math.sin(gamma) - c
    return w_d, delta_r


def cone_tilt(l_t, l_a):
    """d1 = l_t x l_a / |.|: the direction of the cone's delta_r, its polygon's facet n/n."""
    return unit(np.cross(l_t, unit(l_a)))


@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_cone(tmp_path, robot, frame):
    eps, n = 0.001, 8
    ctrl = build(tmp_path, f"""
        param axis : direction = [0, -0.2, 1]
        param gamma : angle = 0.26
        require {frame} cone(axis, gamma) within {eps} resolution {n}
        """, robot)
    rng = np.random.default_rng(9)
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        l_a = 1.7 * near_direction(f.l, rng, 1.0)
        gamma = rng.uniform(5, 40) * DEG
        qp = ctrl.problem(q, {}, {"axis": l_a, "gamma": gamma}, dt=0.01)
        A, _, lb, ub = rows_of(ctrl, qp, "cone", frame)
        w_d, delta_r = cone_reference(f.l, l_a, gamma)
        assert_polygon_rows(A, lb, ub, f.Jw, delta_r, eps, w_d, n, cone_tilt(f.l, l_a))   # eq. (13) about w_d


def test_cone_geometry_on_the_cone(tmp_path):
    """With the tool exactly on the cone, eq. (23) gives delta_r = 0 (h = -eps on every facet) and eq. (22)'s
    w_d is perpendicular to the tool, so the polygon's plane contains the tool axis: the rows bound roll."""
    ctrl = build(tmp_path, """
        param axis : direction = [0, -0.2, 1]
        require tip cone(axis, 15 deg) within 0.001 resolution 8
        """)
    rng = np.random.default_rng(10)
    roll = ROBOTS["shr7"].joint_names.index("roll")
    for _ in range(5):
        q = random_q("shr7", rng)
        f = FrameState("shr7", "tip", q)
        perp = unit(np.cross(f.l, random_unit(rng)))
        l_a = math.cos(15 * DEG) * f.l + math.sin(15 * DEG) * perp     # tool at exactly 15 deg from l_a
        qp = ctrl.problem(q, {}, {"axis": l_a}, dt=0.01)
        A, _, lb, _ = rows_of(ctrl, qp, "cone")
        w_d, delta_r = cone_reference(f.l, l_a, 15 * DEG)
        assert np.linalg.norm(delta_r) < 1e-12 and abs(w_d @ f.l) < 1e-12
        np.testing.assert_allclose(lb, -0.001, atol=1e-12)
        assert np.abs(A[:, roll]).max() > 0.5                          # roll about the tool axis is bounded


@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_a_roll_meets_no_facet_a_turn_must(tmp_path, robot, frame):
    """cone and rotates_around's polygons lie in a plane that holds (nearly) the tool axis, so their rows on J_w dq
    see a roll about it (J dq = [0; l]: the axis and origin stay). Their facet n/n lies along +-delta_r: the worst
    has no roll in it, and the facets off at rest come in pairs mirrored about it, a roll meeting one as much as it
    leaves the other. So a roll meets no set of facets off at rest. With the polygon's phase from a fixed basis
    (before) a roll met a facet off at rest that it never changes: hands off, panda7's tool rolled 1.4e-4 rad a
    tick for good, OPTIMAL, beside a port that held it a facet off its cone."""
    ctrl = build(tmp_path, f"""
        param w : direction = [1, 0, 0]
        param axis : direction = [0, -0.2, 1]
        require {frame} rotates_around(w) within 0.002
        require {frame} cone(axis, 15 deg) within 0.001
        """, robot)
    rng = np.random.default_rng(12)
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        roll, *_ = np.linalg.lstsq(f.J, np.concatenate([np.zeros(3), f.l]), rcond=None)
        assert np.allclose(f.J @ roll, np.concatenate([np.zeros(3), f.l]), atol=1e-9)    # a pure roll
        w, axis = unit(f.l + rng.normal(scale=2.0, size=3)), near_direction(f.l, rng, 1.0)
        qp = ctrl.problem(q, {}, {"w": w, "axis": axis}, dt=0.01)
        for primitive in ("rotates_around", "cone"):
            A, _, lb, _ = rows_of(ctrl, qp, primitive, frame)
            off = lb > 1e-9                                    # the facets off at rest
            worst = int(np.argmax(lb))                         # facet n/n along delta_r, or n/2 against it
            assert off.any() and worst in (3, 7), primitive
            assert abs(A[worst] @ roll) < 1e-9, primitive
            assert not np.all(A[off] @ roll > 1e-12) and not np.all(A[off] @ roll < -1e-12), primitive


# ====================================================================================== passes_through

@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_passes_through(tmp_path, robot, frame):
    eps, n = 0.0005, 8
    ctrl = build(tmp_path, f"""
        param port : point = [0, 0, 0.35]
        require {frame} passes_through(port) within {eps} resolution {n}
        """, robot)
    rng = np.random.default_rng(11)
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        c = f.p + rng.uniform(0.02, 0.1) * f.l + rng.normal(scale=0.003, size=3)
        qp = ctrl.problem(q, {}, {"port": c}, dt=0.01)
        A, _, lb, ub = rows_of(ctrl, qp, "passes_through", frame)
        # slide 46: w = (c - p) x l = 0. A step (dp, dr) moves p -> p + dp, l -> l + dr x l, so
        # w + dw with dw = -(dp x l) + (c - p) x (dr x l) = [l]x dp - [c - p]x [l]x dr.
        r = c - f.p
        w = np.cross(r, f.l)
        sk = lambda v: np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
        J_w = sk(f.l) @ f.Jv - sk(r) @ sk(f.l) @ f.Jw
        assert abs(np.linalg.norm(w) - np.linalg.norm(r - (r @ f.l) * f.l)) < 1e-12   # |w| = line distance
        assert_polygon_rows(A, lb, ub, J_w, w, eps, f.l, n)


# ============================================================================ within_distance, speeds

@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_within_distance(tmp_path, robot, frame):
    ctrl = build(tmp_path, f"""
        param goal : point = [0, 0, 0.3]
        param radius : length = 0.003
        require {frame} within_distance(goal, radius) resolution 8x8
        """, robot)
    rng = np.random.default_rng(12)
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        goal = f.p + rng.normal(scale=0.003, size=3)
        radius = rng.uniform(0.001, 0.005)
        qp = ctrl.problem(q, {}, {"goal": goal, "radius": radius}, dt=0.01)
        A, _, lb, ub = rows_of(ctrl, qp, "within_distance", frame)
        assert_sphere_rows(A, lb, ub, f.Jv, f.p - goal, radius, 8, 8)


@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_speed_and_angular_speed(tmp_path, robot, frame):
    ctrl = build(tmp_path, f"""
        require {frame} speed(0.02 m/s)
        require {frame} angular_speed(0.5 rad/s) resolution 6x6
        """, robot)
    rng = np.random.default_rng(13)
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        dt = rng.uniform(0.001, 0.05)
        qp = ctrl.problem(q, {}, dt=dt)
        A, _, lb, ub = rows_of(ctrl, qp, "speed", frame)
        assert_sphere_rows(A, lb, ub, f.Jv, np.zeros(3), 0.02 * dt, 4, 4)
        A, _, lb, ub = rows_of(ctrl, qp, "angular_speed", frame)
        assert_sphere_rows(A, lb, ub, f.Jw, np.zeros(3), 0.5 * dt, 6, 6)


# ========================================================================= joint limits and speeds

@pytest.mark.parametrize("robot", ["shr7", "panda7"])
def test_joint_limits_and_speed_are_variable_bounds(tmp_path, robot):
    limits = urdf_limits(robot)
    names = ROBOTS[robot].joint_names
    lo = np.array([limits[j][0] for j in names])
    hi = np.array([limits[j][1] for j in names])
    vmax = np.array([limits[j][2] for j in names])
    only_limits = build(tmp_path, "require joint_limits()\n", robot, name="limits")
    both = build(tmp_path, "require joint_limits()\nrequire joint_speed(fraction = 0.4)\n", robot, name="both")
    rng = np.random.default_rng(14)
    nq = len(names)
    for _ in range(TRIALS):
        q = random_q(robot, rng, shrink=0.999)
        dt = rng.uniform(0.001, 0.1)                  # long periods (up to 10x the assumed 10 ms) make the position limits bind too
        qp = only_limits.problem(q, {}, dt=dt)
        assert qp.A.shape[0] == nq and np.array_equal(qp.A[:nq], np.eye(nq))   # no rows, only bounds
        np.testing.assert_allclose(qp.lb, np.maximum(lo - q, -vmax * dt), atol=1e-15)   # without joint_speed(): the
        np.testing.assert_allclose(qp.ub, np.minimum(hi - q, vmax * dt), atol=1e-15)    # URDF's velocity limits
        assert all("the URDF's velocity limit" in label for label in qp.labels[:nq])
        qp = both.problem(q, {}, dt=dt)
        assert qp.A.shape[0] == nq and not both.row_labels
        np.testing.assert_allclose(qp.lb, np.maximum(lo - q, -0.4 * vmax * dt), atol=1e-15)
        np.testing.assert_allclose(qp.ub, np.minimum(hi - q, 0.4 * vmax * dt), atol=1e-15)
        for j, label in zip(names, qp.labels[:nq]):
            assert label.startswith(f"bounds of joint {j}:") and "joint_limits" in label and "joint_speed" in label


# =============================================================================================== soft

def test_soft_constraints_slack_columns(tmp_path):
    """Each soft constraint gets one slack s >= 0: its rows A dq + s >= lb (and A dq - s <= ub on two-sided
    rows), and cost w s^2, i.e. 2 w on the slack's diagonal of P (P = 2 sum w E'E for the dq block)."""
    ctrl = build(tmp_path, """
        require tip stays_at([0, 0, 0.28]) within 0.001 resolution 4x4 soft weight 250
        require tip above(plane(point = [0, 0, 0.27], normal = [0, 0, 1])) soft
        require joint_limits() soft weight 7
        require shaft stays_at([0, 0, 0.4]) within 0.001 resolution 4x4
        """)
    rng = np.random.default_rng(15)
    limits = urdf_limits("shr7")
    names = ROBOTS["shr7"].joint_names
    lo = np.array([limits[j][0] for j in names])
    hi = np.array([limits[j][1] for j in names])
    for _ in range(4):
        q = random_q("shr7", rng)
        f = FrameState("shr7", "tip", q)
        qp = ctrl.problem(q, {}, dt=0.1)        # restore share min(1, k dt) = 1: the rows of the hard form
        nq, n = qp.nq, qp.P.shape[0]
        assert n == nq + 3
        # variable bounds: the dq only within the URDF's speed (joint_limits is soft), the slacks are >= 0
        assert np.array_equal(qp.A[:n], np.eye(n))
        vmax = np.array([limits[j][2] for j in names])
        np.testing.assert_allclose(qp.lb[:nq], -vmax * 0.1, rtol=1e-15)
        np.testing.assert_allclose(qp.ub[:nq], vmax * 0.1, rtol=1e-15)
        assert np.all(qp.lb[nq:n] == 0) and np.all(np.isinf(qp.ub[nq:n]))
        # costs: 2 w on the slack diagonal (default soft weight 1 for `above`), no linear term
        np.testing.assert_allclose(np.diag(qp.P)[nq:], [2 * 250, 2 * 1, 2 * 7])
        assert np.count_nonzero(qp.P[nq:, :nq]) == 0 and np.count_nonzero(qp.g[nq:]) == 0
        # stays_at: slack 0 with +1, same rows as the hard form
        A, Afull, lb, ub = rows_of(ctrl, qp, "stays_at", "tip")
        assert_sphere_rows(A, lb, ub, f.Jv, f.p - np.array([0, 0, 0.28]), 0.001, 4, 4)
        np.testing.assert_array_equal(Afull[:, nq:], np.tile([1, 0, 0], (6, 1)))
        # above: slack 1, one row, +1
        _, Afull, _, ub = rows_of(ctrl, qp, "above")
        np.testing.assert_array_equal(Afull[:, nq:], [[0, 1, 0]])
        assert np.isinf(ub).all()
        # joint_limits: two-sided -> lower rows (+1) and upper rows (-1) on slack 2
        A, Afull, lb, ub = rows_of(ctrl, qp, "joint_limits")
        assert A.shape == (2 * nq, nq)
        lower = [i for i, lab in enumerate(l for l in ctrl.row_labels if l.primitive == "joint_limits")
                 if lab.facet.endswith("(lower)")]
        upper = [i for i, lab in enumerate(l for l in ctrl.row_labels if l.primitive == "joint_limits")
                 if lab.facet.endswith("(upper)")]
        assert len(lower) == len(upper) == nq
        np.testing.assert_array_equal(A[lower], np.eye(nq))
        np.testing.assert_array_equal(A[upper], np.eye(nq))
        np.testing.assert_array_equal(Afull[lower, nq:], np.tile([0, 0, 1], (nq, 1)))
        np.testing.assert_array_equal(Afull[upper, nq:], np.tile([0, 0, -1], (nq, 1)))
        np.testing.assert_allclose(lb[lower], lo - q, atol=1e-15)
        assert np.all(np.isinf(ub[lower])) and np.all(np.isinf(lb[upper]))
        np.testing.assert_allclose(ub[upper], hi - q, atol=1e-15)
        # the hard constraint has no slack
        _, Afull, _, _ = rows_of(ctrl, qp, "stays_at", "shaft")
        assert np.count_nonzero(Afull[:, nq:]) == 0
        # at dt = 10 ms a soft position row is restored at k = SOFT_RESTORE_RATE: its offsets are scaled by k dt;
        # the hard rows are not
        fast = ctrl.problem(q, {}, dt=0.01)
        for name, frame in (("stays_at", "tip"), ("joint_limits", None), ("stays_at", "shaft")):
            _, _, lb_1, ub_1 = rows_of(ctrl, qp, name, frame)
            _, _, lb_2, ub_2 = rows_of(ctrl, fast, name, frame)
            share = min(1.0, SOFT_RESTORE_RATE * 0.01) if frame != "shaft" else 1.0
            np.testing.assert_allclose(lb_2, lb_1 * share, rtol=1e-12, atol=1e-15)
            np.testing.assert_allclose(ub_2, ub_1 * share, rtol=1e-12, atol=1e-15)


# ============================================================================================= follows

GENTLE = np.array([[0.0, 0.0, 0], [0.012, 0.004, 0], [0.024, 0.006, 0], [0.036, 0.005, 0],
                   [0.048, 0.001, 0], [0.060, -0.005, 0], [0.072, -0.008, 0], [0.084, -0.006, 0]])
PAPER_A = 1e-3 * np.array([[-40, -10, 0], [-28, 12, 0], [-15, -8, 0], [-4, 15, 0],
                           [8, -12, 0], [20, 10, 0], [30, -5, 0], [40, 8, 0]])


class ReferenceCurve:
    """scipy's interpolating b-spline through the points, chord-length parameter; closest point by brute
    force on a dense grid, refined with minimize_scalar (bounded) around the best sample."""

    def __init__(self, points: np.ndarray, degree: int):
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
        self.spline = make_interp_spline(s, points, k=degree)
        self.d1 = self.spline.derivative()
        self.grid = np.linspace(0, s[-1], 40001)
        self.samples = self.spline(self.grid)
        self.length = s[-1]

    def closest(self, x) -> tuple[np.ndarray, np.ndarray, float]:
        i = int(np.argmin(np.sum((self.samples - x) ** 2, axis=1)))
        lo, hi = self.grid[max(i - 1, 0)], self.grid[min(i + 1, len(self.grid) - 1)]
        res = minimize_scalar(lambda t: float(np.sum((self.spline(t) - x) ** 2)), bounds=(lo, hi),
                              method="bounded", options={"xatol": 1e-14})
        s = float(res.x)
        # The squared distance is flat at its minimum, so Brent stops ~1e-11 short; polish with the root of
        # its derivative (C(s) - x) . C'(s) when the bracket holds one (an interior closest point).
        g = lambda t: float((self.spline(t) - x) @ self.d1(t))
        if g(lo) < 0 < g(hi):
            s = brentq(g, lo, hi, xtol=1e-16, rtol=4 * np.finfo(float).eps)
        return self.spline(s), unit(self.d1(s)), s


def follows_task(tmp_path, points, degree):
    pts = ", ".join(f"[{float(x)!r}, {float(y)!r}, {float(z)!r}]" for x, y, z in points)
    return build(tmp_path, f"""
        param plate : pose = pose(translation = [0, 0, 0.25], rpy = [0, 0, 0])
        param path : curve(degree = {degree}) in plate = bspline(points = [{pts}])
        require tip follows(path) within 0.001 resolution 8
        require shaft follows(path, shift = [0, 0, 0.1], anchor = tip) within 0.0007 resolution 6
        """)


def check_follows(ctrl, ref: ReferenceCurve, seed: int, trials: int, spread: float, margin: float = 0.0):
    """Random q; the plate placed so that the tip is within ~``spread`` of the curve point at a random
    parameter at least ``margin`` away from every knot of the spline."""
    rng = np.random.default_rng(seed)
    knots = np.unique(ref.spline.t)
    for _ in range(trials):
        q = random_q("shr7", rng)
        tip, shaft = FrameState("shr7", "tip", q), FrameState("shr7", "shaft", q)
        rpy = rng.uniform(-0.3, 0.3, 3)
        R = pin.rpy.rpyToMatrix(*rpy)
        while True:
            s0 = rng.uniform(0, ref.length)
            if np.min(np.abs(knots - s0)) >= margin:
                break
        t = tip.p - R @ (ref.spline(s0) + rng.normal(scale=spread, size=3))
        qp = ctrl.problem(q, {}, {"plate": {"translation": t, "rpy": rpy}}, dt=0.01)
        local, tangent_local, _ = ref.closest(R.T @ (tip.p - t))
        P_c, l_c = R @ local + t, R @ tangent_local
        # tip: "along" the tangent line through P_c (paper eq. 19)
        A, _, lb, ub = rows_of(ctrl, qp, "follows", "tip")
        P_cl = P_c + ((tip.p - P_c) @ l_c) * l_c
        assert_polygon_rows(A, lb, ub, tip.Jv, tip.p - P_cl, 0.001, l_c, 8)
        # shaft: the curve shifted by 100 mm along the plate normal, same tangent, the tip's closest
        # point (anchor = tip; eq. 20)
        P_c2 = P_c + R @ np.array([0, 0, 0.1])
        A, _, lb, ub = rows_of(ctrl, qp, "follows", "shaft")
        P_cl2 = P_c2 + ((shaft.p - P_c2) @ l_c) * l_c
        assert_polygon_rows(A, lb, ub, shaft.Jv, shaft.p - P_cl2, 0.0007, l_c, 6)


def test_follows_gentle_curve_away_from_knots(tmp_path):
    """The rows of follows on a gentle curve, away from its knots."""
    ctrl = follows_task(tmp_path, GENTLE, 3)
    check_follows(ctrl, ReferenceCurve(GENTLE, 3), seed=16, trials=40, spread=0.0003, margin=0.003)


def test_follows_gentle_curve_near_knots(tmp_path):
    ctrl = follows_task(tmp_path, GENTLE, 3)
    ref = ReferenceCurve(GENTLE, 3)
    knots = np.unique(ref.spline.t)[1:-1]
    rng = np.random.default_rng(18)
    for _ in range(20):
        q = random_q("shr7", rng)
        tip = FrameState("shr7", "tip", q)
        s0 = rng.choice(knots) - rng.uniform(0.0001, 0.0004)         # just before an interior knot
        t = tip.p - ref.spline(s0)
        qp = ctrl.problem(q, {}, {"plate": {"translation": t, "rpy": [0, 0, 0]}}, dt=0.01)
        P_c, l_c, _ = ref.closest(tip.p - t)
        P_c = P_c + t
        A, _, lb, ub = rows_of(ctrl, qp, "follows", "tip")
        P_cl = P_c + ((tip.p - P_c) @ l_c) * l_c
        assert_polygon_rows(A, lb, ub, tip.Jv, tip.p - P_cl, 0.001, l_c, 8)


def test_follows_paper_a_curve(tmp_path):
    ctrl = follows_task(tmp_path, PAPER_A, 5)
    check_follows(ctrl, ReferenceCurve(PAPER_A, 5), seed=17, trials=40, spread=0.0003)


# =========================================================================== every primitive covered

def test_every_primitive_is_covered():
    from vfdsl.primitives import CONSTRAINTS
    covered = {"stays_at", "keeps_direction", "along", "rotates_around", "above", "on_plane", "follows", "cone",
               "passes_through", "within_distance", "joint_limits", "joint_speed", "speed", "angular_speed",
               "within_sphere", "outside_sphere", "near_plane"}     # the last three: test_primitive_spheres.py
    covered |= {"tilt_at_most"}                  # its rows: tests/test_tilt_at_most.py
    covered |= {"outside_mesh", "inside_mesh"}   # their rows: tests/test_mesh_rows.py
    assert set(CONSTRAINTS) == covered


# ================================================================================ docs/primitives.md

DOCS = Path(__file__).resolve().parent.parent / "docs" / "primitives.md"


def test_docs_examples_compile(tmp_path):
    """Every ```vf block of docs/primitives.md compiles after the page's prelude (the block that starts with
    `task`), and the tick's QP is finite at the robot's home configuration."""
    import re
    blocks = re.findall(r"```vf\n(.*?)```", DOCS.read_text(), flags=re.DOTALL)
    prelude = [b for b in blocks if b.lstrip().startswith("task ")]
    assert len(prelude) == 1
    examples = [b for b in blocks if b is not prelude[0]]
    assert len(examples) >= 20
    path = tmp_path / "doc_examples.vf"
    path.write_text(prelude[0] + "".join(examples))
    shutil.copytree(DOCS.parent.parent / "tasks" / "anatomy", tmp_path / "anatomy")    # the prelude's meshes
    ctrl = compile_task(vfdsl.load(path))
    q = np.array([0, 0, 0, 0, 0, 0, 0.01])
    qp = ctrl.problem(q, {"f": [0, 0, 1], "tau": [0, 0, 0.01], "hand": [0] * 6, "stick": [0] * 6}, dt=0.01)
    assert np.all(np.isfinite(qp.P)) and np.all(np.isfinite(qp.A)) and np.all(np.isfinite(qp.g))
    used = {lab.primitive for lab in ctrl.row_labels} | {"joint_limits", "joint_speed"}
    from vfdsl.primitives import CONSTRAINTS
    assert used == set(CONSTRAINTS), set(CONSTRAINTS) - used


def test_follows_takes_a_run_time_shift(tmp_path):
    """A `shift` given by a param gives the rows of the same literal shift, and follows the param at run time."""
    scene = (Path(__file__).parent.parent / "tasks" / "paper_a_follow_curve.yaml").resolve()
    body = """task shifted
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
frame shaft = shr.link("tool_tip") offset [0, 0, 100]
param plate : pose
param path : curve(degree = 5) in plate
{decl}
require tip follows(path) within 0.001 resolution 8
require shaft follows(path, shift = {shift}, anchor = tip) within 0.001 resolution 8
scene "{scene}"
"""
    (tmp_path / "param.vf").write_text(body.format(decl="param up : vector = [0, 0, 100]", shift="up", scene=scene))
    (tmp_path / "literal.vf").write_text(body.format(decl="", shift="[0, 0, 100]", scene=scene))
    (tmp_path / "moved.vf").write_text(body.format(decl="", shift="[0, 0, 90]", scene=scene))
    tasks = {name: vfdsl.load(tmp_path / f"{name}.vf") for name in ("param", "literal", "moved")}
    ctrls = {name: compile_task(task) for name, task in tasks.items()}
    q = tasks["param"].start
    qp = {name: ctrl.problem(q, {}) for name, ctrl in ctrls.items()}
    np.testing.assert_allclose(qp["param"].A, qp["literal"].A, atol=1e-12)
    np.testing.assert_allclose(qp["param"].lb, qp["literal"].lb, atol=1e-12)
    moved = ctrls["param"].problem(q, {}, {"up": [0.0, 0.0, 0.09]})
    np.testing.assert_allclose(moved.lb, qp["moved"].lb, atol=1e-12)
    assert not np.allclose(moved.lb, qp["param"].lb)
