"""Each primitive's rows are the first-order Taylor expansion of the nonlinear constraint they linearize.

A row  -u J dq >= -eps + g(q0)  stands for  g(q0 + dq) <= eps  with g linearized at q0, so its A must be
-dg/dq at q0 and its lower bound -eps + g(q0). Here g is written out with the reference quantities
(directions u, target or closest point P, line direction, w_d, delta_r...) frozen at q0, its Jacobian taken
by central differences (h = 1e-6) of Pinocchio's forward kinematics, and the rows compared, as a set, with
the controller's at random configurations of both robots:

- position rows (stays_at, within_distance, along, follows, speed, above, on_plane):  g(q) = u . (p(q) - P);
- rotation rows (keeps_direction both forms, rotates_around, cone, angular_speed):
  g(q) = u . (delta_r(q0) + log3(R(q) R(q0)^T)), the rotation vector of the step in world axes in place of dr;
- passes_through:  g(q) = u . ((c - p(q)) x l(q)), the lecture's constraint (slide 46) itself;
- joint_limits, joint_speed:  q_lo - q0 <= dq <= q_hi - q0 and |dq| <= f qdot dt, identity rows.

Where the linearization is also that of the geometric error itself it is checked too: the roll-free
keeps_direction rows against g(q) = u . (l_d x l_t(q)) at a configuration on the reference direction.

Independent geometry (sphere and polygon directions, closest points, eqs. 22-23) comes from
``test_primitives``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import linear_sum_assignment

from test_primitives import (DEG, FRAMES, GENTLE, ROBOT_FRAMES, ROBOTS, ReferenceCurve, build,  # isort: skip
                             cone_reference, cone_tilt, near_direction, offset_matrix, polygon_ref, random_q,
                             random_unit, rows_of, sphere_directions_ref, unit, urdf_limits)

H = 1e-6
RTOL = 1e-6
CONFIGS = 5


# ============================================================================================== helpers

def pose(robot: str, frame: str, q):
    """(p, R, tool axis) of a task frame at q, from Pinocchio's forward kinematics."""
    link, xyz, rpy, axis = FRAMES[robot][frame]
    p, R = ROBOTS[robot].frame_pose(q, link, offset_matrix(xyz, rpy))
    return p, R, R @ np.asarray(axis, dtype=float)


def fd_jacobian(g, q0) -> np.ndarray:
    """Central differences of the vector function g at q0: k x nq."""
    cols = []
    for i in range(len(q0)):
        e = np.zeros(len(q0))
        e[i] = H
        cols.append((g(q0 + e) - g(q0 - e)) / (2 * H))
    return np.column_stack(cols)


def assert_taylor_rows(A, lb, g, eps, q0):
    """The rows (A, lb) are, as a set, (-dg/dq, -eps + g(q0)) at q0."""
    A_fd = -fd_jacobian(g, q0)
    lb_exp = -np.asarray(eps) + g(q0)
    assert A.shape == A_fd.shape, (A.shape, A_fd.shape)
    scale = max(1.0, np.abs(A_fd).max())
    X, Y = np.hstack([A, lb[:, None]]), np.hstack([A_fd, lb_exp[:, None]])
    D = np.abs(Y[:, None, :] - X[None, :, :]).max(axis=2)
    r, c = linear_sum_assignment(D)
    assert D[r, c].max() < RTOL * scale, f"rows differ from the finite-difference Taylor rows by {D[r, c].max():.2e}"


def rotation_g(robot, frame, q0, U, delta_r):
    _, R0, _ = pose(robot, frame, q0)
    return lambda q: U @ (delta_r + pin.log3(pose(robot, frame, q)[1] @ R0.T))


def position_g(robot, frame, U, P):
    return lambda q: U @ (pose(robot, frame, q)[0] - P)


# ============================================================================================ the cases

@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_position_rows(tmp_path, robot, frame):
    """stays_at, within_distance, along, speed, above, on_plane."""
    ctrl = build(tmp_path, f"""
        param target : point = [0, 0, 0.3]
        param goal : point = [0, 0, 0.3]
        param path : line = line(point = [0, 0, 0.28], direction = [1, 1, 0])
        param wall : plane = plane(point = [0, 0, 0.27], normal = [0, 0, 1])
        require {frame} stays_at(target) within 0.002 resolution 6x6
        require {frame} within_distance(goal, 3 mm) resolution 8x8
        require {frame} along(path) within 0.0005 resolution 8
        require {frame} speed(0.02 m/s) resolution 4x4
        require {frame} above(wall)
        require {frame} on_plane(wall) within 0.0003
        """, robot)
    rng = np.random.default_rng(21)
    for _ in range(CONFIGS):
        q0 = random_q(robot, rng)
        p0, _, _ = pose(robot, frame, q0)
        target, goal = p0 + rng.normal(scale=0.004, size=(2, 3))
        l, d = random_unit(rng), random_unit(rng)
        L0, P = p0 + rng.normal(scale=0.003, size=(2, 3))
        dt = 0.01
        qp = ctrl.problem(q0, {}, {"target": target, "goal": goal, "path": {"point": L0, "direction": l},
                                   "wall": {"point": P, "normal": d}}, dt=dt)

        A, _, lb, _ = rows_of(ctrl, qp, "stays_at")
        U = sphere_directions_ref(6, 6)
        assert_taylor_rows(A, lb, position_g(robot, frame, U, target), 0.002, q0)

        A, _, lb, _ = rows_of(ctrl, qp, "within_distance")
        U = sphere_directions_ref(8, 8)
        assert_taylor_rows(A, lb, position_g(robot, frame, U, goal), 0.003, q0)

        A, _, lb, _ = rows_of(ctrl, qp, "along")
        P_cl = L0 + ((p0 - L0) @ l) * l                  # frozen closest point on the line
        assert_taylor_rows(A, lb, position_g(robot, frame, polygon_ref(l, 8), P_cl), 0.0005, q0)

        A, _, lb, _ = rows_of(ctrl, qp, "speed")         # || p(q) - p(q0) || <= v dt
        assert_taylor_rows(A, lb, position_g(robot, frame, sphere_directions_ref(4, 4), p0), 0.02 * dt, q0)

        A, _, lb, _ = rows_of(ctrl, qp, "above")         # d . (p - P_cl) >= 0  <=>  -d . (p - P_cl) <= 0
        P_cl = p0 - ((p0 - P) @ d) * d
        assert_taylor_rows(A, lb, position_g(robot, frame, -d[None], P_cl), 0.0, q0)

        A, _, lb, _ = rows_of(ctrl, qp, "on_plane")      # and d . (p - P_cl) <= eps
        assert_taylor_rows(A, lb, position_g(robot, frame, np.vstack([-d, d]), P_cl), [0.0, 0.0003], q0)


@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_rotation_rows(tmp_path, robot, frame):
    """keeps_direction (roll-free and pin_roll), rotates_around, cone, angular_speed."""
    ctrl = build(tmp_path, f"""
        param d : direction = [0, 0, 1]
        param w : direction = [1, 0, 0]
        param axis : direction = [0, -0.2, 1]
        require {frame} keeps_direction(d) within 0.01 resolution 8
        require {frame} keeps_direction(d, pin_roll = true) within 0.01 resolution 4x4
        require {frame} rotates_around(w) within 0.002 resolution 6
        require {frame} cone(axis, 15 deg) within 0.001 resolution 8
        require {frame} angular_speed(0.5 rad/s) resolution 6x6
        """, robot)
    rng = np.random.default_rng(22)
    for _ in range(CONFIGS):
        q0 = random_q(robot, rng)
        _, _, l_t = pose(robot, frame, q0)
        l_d = near_direction(l_t, rng, 0.3)
        w = near_direction(unit(np.cross(l_t, random_unit(rng))), rng, 0.4)
        l_a = near_direction(l_t, rng, 0.8)
        dt = 0.02
        qp = ctrl.problem(q0, {}, {"d": l_d, "w": w, "axis": l_a}, dt=dt)
        labels = ctrl.row_labels
        n = qp.P.shape[0]

        kd = [n + i for i, lab in enumerate(labels) if lab.primitive == "keeps_direction"]
        free, pinned = kd[:8], kd[8:]
        delta_r = np.cross(l_d, l_t)
        assert_taylor_rows(qp.A[free, :qp.nq], qp.lb[free],
                           rotation_g(robot, frame, q0, polygon_ref(l_t, 8), delta_r), 0.01, q0)
        assert_taylor_rows(qp.A[pinned, :qp.nq], qp.lb[pinned],
                           rotation_g(robot, frame, q0, sphere_directions_ref(4, 4), delta_r), 0.01, q0)

        A, _, lb, _ = rows_of(ctrl, qp, "rotates_around")
        l_pi = unit(l_t - (l_t @ w) * w)
        U = polygon_ref(w, 6, np.cross(l_pi, w))
        assert_taylor_rows(A, lb, rotation_g(robot, frame, q0, U, np.cross(l_pi, l_t)), 0.002, q0)

        A, _, lb, _ = rows_of(ctrl, qp, "cone")
        w_d, delta_r = cone_reference(l_t, l_a, 15 * DEG)
        U = polygon_ref(w_d, 8, cone_tilt(l_t, l_a))
        assert_taylor_rows(A, lb, rotation_g(robot, frame, q0, U, delta_r), 0.001, q0)

        A, _, lb, _ = rows_of(ctrl, qp, "angular_speed")
        assert_taylor_rows(A, lb, rotation_g(robot, frame, q0, sphere_directions_ref(6, 6), np.zeros(3)),
                           0.5 * dt, q0)


@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_keeps_direction_is_the_linearized_direction_error(tmp_path, robot, frame):
    """On the reference direction (delta_r = 0) the roll-free rows are exactly the linearization of the
    paper's error l_d x l_t(q) (II-B.2) projected on the polygon: roll about the tool axis is free."""
    ctrl = build(tmp_path, f"""
        param d : direction = [0, 0, 1]
        require {frame} keeps_direction(d) within 0.01 resolution 8
        """, robot)
    rng = np.random.default_rng(23)
    for _ in range(CONFIGS):
        q0 = random_q(robot, rng)
        _, _, l_d = pose(robot, frame, q0)
        qp = ctrl.problem(q0, {}, {"d": l_d}, dt=0.01)
        A, _, lb, _ = rows_of(ctrl, qp, "keeps_direction")
        U = polygon_ref(l_d, 8)
        assert_taylor_rows(A, lb, lambda q, U=U, l_d=l_d: U @ np.cross(l_d, pose(robot, frame, q)[2]), 0.01, q0)


@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_passes_through_rows(tmp_path, robot, frame):
    ctrl = build(tmp_path, f"""
        param port : point = [0, 0, 0.35]
        require {frame} passes_through(port) within 0.0005 resolution 8
        """, robot)
    rng = np.random.default_rng(24)
    for _ in range(CONFIGS):
        q0 = random_q(robot, rng)
        p0, _, l0 = pose(robot, frame, q0)
        c = p0 + rng.uniform(0.02, 0.1) * l0 + rng.normal(scale=0.003, size=3)
        qp = ctrl.problem(q0, {}, {"port": c}, dt=0.01)
        A, _, lb, _ = rows_of(ctrl, qp, "passes_through")
        U = polygon_ref(l0, 8)

        def g(q, U=U, c=c):
            p, _, l = pose(robot, frame, q)
            return U @ np.cross(c - p, l)                 # slide 46: (c - p) x l = 0, bounded by eps
        assert_taylor_rows(A, lb, g, 0.0005, q0)


def test_follows_rows(tmp_path):
    """follows = along the tangent line at the anchor's closest point (frozen at q0), tip and shaft."""
    pts = ", ".join(f"[{float(x)!r}, {float(y)!r}, {float(z)!r}]" for x, y, z in GENTLE)
    ctrl = build(tmp_path, f"""
        param plate : pose = pose(translation = [0, 0, 0.25], rpy = [0, 0, 0])
        param path : curve(degree = 3) in plate = bspline(points = [{pts}])
        require tip follows(path) within 0.001 resolution 8
        require shaft follows(path, shift = [0, 0, 0.1], anchor = tip) within 0.0007 resolution 6
        """)
    ref = ReferenceCurve(GENTLE, 3)
    rng = np.random.default_rng(25)
    for s0 in (0.012, 0.031, 0.044, 0.056, 0.075):        # away from the knots (see test_primitives)
        q0 = random_q("shr7", rng)
        tip_p, _, _ = pose("shr7", "tip", q0)
        rpy = rng.uniform(-0.3, 0.3, 3)
        R = pin.rpy.rpyToMatrix(*rpy)
        t = tip_p - R @ (ref.spline(s0) + rng.normal(scale=0.0003, size=3))
        qp = ctrl.problem(q0, {}, {"plate": {"translation": t, "rpy": rpy}}, dt=0.01)
        local, tangent, _ = ref.closest(R.T @ (tip_p - t))
        P_c, l_c = R @ local + t, R @ tangent
        A, _, lb, _ = rows_of(ctrl, qp, "follows", "tip")
        assert_taylor_rows(A, lb, position_g("shr7", "tip", polygon_ref(l_c, 8), P_c), 0.001, q0)
        A, _, lb, _ = rows_of(ctrl, qp, "follows", "shaft")
        P_c2 = P_c + R @ np.array([0, 0, 0.1])
        assert_taylor_rows(A, lb, position_g("shr7", "shaft", polygon_ref(l_c, 6), P_c2), 0.0007, q0)


@pytest.mark.parametrize("robot", ["shr7", "panda7"])
def test_joint_rows(tmp_path, robot):
    """joint_limits: g(q) = (q - q_hi, q_lo - q) <= 0; joint_speed: |q - q0| <= f qdot dt, as variable bounds."""
    ctrl = build(tmp_path, "require joint_limits()\nrequire joint_speed(fraction = 0.3)\n", robot)
    limits = urdf_limits(robot)
    names = ROBOTS[robot].joint_names
    lo, hi, vmax = (np.array([limits[j][k] for j in names]) for k in range(3))
    rng = np.random.default_rng(26)
    for _ in range(CONFIGS):
        q0 = random_q(robot, rng, shrink=0.999)
        dt = rng.uniform(0.001, 0.1)          # up to 10x the 10 ms assumed without a scene period
        qp = ctrl.problem(q0, {}, dt=dt)
        nq = qp.nq
        # upper: g(q) = q - q_hi <= 0  ->  -dg/dq = -I, row  -dq >= -(q_hi - q0); as a bound  dq <= q_hi - q0
        np.testing.assert_allclose(fd_jacobian(lambda q: q - hi, q0), np.eye(nq), atol=1e-9)
        np.testing.assert_array_equal(qp.A[:nq], np.eye(nq))
        np.testing.assert_allclose(qp.ub, np.minimum(hi - q0, 0.3 * vmax * dt), atol=1e-15)
        np.testing.assert_allclose(qp.lb, np.maximum(lo - q0, -0.3 * vmax * dt), atol=1e-15)


def test_fd_check_detects_a_wrong_sign(tmp_path):
    """The check has teeth: a row with a flipped sign (or the rotation part of J) fails it."""
    ctrl = build(tmp_path, "param target : point = [0, 0, 0.3]\nrequire tip stays_at(target) within 0.002\n")
    q0 = random_q("shr7", np.random.default_rng(27))
    p0, _, _ = pose("shr7", "tip", q0)
    qp = ctrl.problem(q0, {}, {"target": p0 + 0.001}, dt=0.01)
    A, _, lb, _ = rows_of(ctrl, qp, "stays_at")
    g = position_g("shr7", "tip", sphere_directions_ref(4, 4), p0 + 0.001)
    assert_taylor_rows(A, lb, g, 0.002, q0)
    with pytest.raises(AssertionError):
        assert_taylor_rows(-A, lb, g, 0.002, q0)
    with pytest.raises(AssertionError):
        assert_taylor_rows(A, -lb, g, 0.002, q0)
