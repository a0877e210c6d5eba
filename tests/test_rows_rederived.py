"""The angular and port rows far from their references, re-derived here (numpy and Pinocchio, not the compiler).

tests/test_primitives.py checks every primitive's rows near its reference (cones within 1 rad, pin_roll within
0.5 rad, planes of rotation within 0.4 rad); tests/test_wrong_side.py checks what the far ticks do, not their rows.
Here the rows themselves at far states: the tool up to 180 deg from a direction (past 90 deg the length sin theta is
continued as 2 - sin theta along the same axis, docs/primitives.md note 8), on the far side of a cone, nearly along
the axis it should sweep a plane around, and a port at the frame origin or behind it; and at the degenerate states
(axes exactly parallel or opposite, the tool exactly along the axis) the rows are finite and violated at dq = 0.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_primitives import (DEG, ROBOT_FRAMES, FrameState, assert_polygon_rows, assert_sphere_rows, build,
                             random_q, rows_of, unit)

ANGLES = (0.3, 1.5, 100 * DEG, 2.5, 3.0, math.pi - 1e-4)


def continued(delta, cos_angle):
    """sin theta continued as 2 - sin theta past 90 deg, along the same axis."""
    return delta * (2 - np.linalg.norm(delta)) / np.linalg.norm(delta) if cos_angle < 0 else delta


def sk(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_far_rows(tmp_path, robot, frame):
    ctrl = build(tmp_path, f"""
        param d : direction = [0, 0, 1]
        param w : direction = [1, 0, 0]
        param ax : direction = [0, 0, 1]
        param gamma : angle = 0.3
        param port : point = [0, 0, 0.35]
        require {frame} keeps_direction(d) within 0.001
        require {frame} keeps_direction(d, pin_roll = true) within 0.001 resolution 4x4
        require {frame} rotates_around(w) within 0.002
        require {frame} cone(ax, gamma) within 0.001
        require {frame} passes_through(port) within 0.0005
        """, robot)
    rng = np.random.default_rng(61)
    for k in range(3 * len(ANGLES)):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        e = unit(np.cross(f.l, rng.normal(size=3)))
        angle = ANGLES[k % len(ANGLES)]
        l_d = math.cos(angle) * f.l + math.sin(angle) * e
        w = unit(math.cos(min(angle, 1.5)) * np.cross(f.l, e) + math.sin(min(angle, 1.5)) * f.l)   # up to 86 deg out
        gamma = rng.uniform(5, 60) * DEG
        axis = math.cos(angle) * f.l + math.sin(angle) * e                                      # theta = angle
        port = f.p + [0.0, 0.04, -0.04][k % 3] * f.l + (k % 2) * rng.normal(scale=0.01, size=3)   # at p, ahead, behind
        qp = ctrl.problem(q, {}, {"d": l_d, "w": w, "ax": axis, "gamma": gamma, "port": port}, dt=0.01)
        delta = continued(np.cross(l_d, f.l), l_d @ f.l)
        A, _, lb, ub = rows_of(ctrl, qp, "keeps_direction")
        assert_polygon_rows(A[:8], lb[:8], ub[:8], f.Jw, delta, 0.001, f.l, 8)
        assert_sphere_rows(A[8:], lb[8:], ub[8:], f.Jw, delta, 0.001, 4, 4)
        A, _, lb, ub = rows_of(ctrl, qp, "rotates_around")
        l_pi = unit(f.l - (f.l @ w) * w)
        assert_polygon_rows(A, lb, ub, f.Jw, np.cross(l_pi, f.l), 0.002, w, 8, np.cross(l_pi, w))
        A, _, lb, ub = rows_of(ctrl, qp, "cone")
        c = np.cross(f.l, axis)
        d1 = unit(c)
        d2 = unit(np.cross(d1, axis))
        w_d = np.column_stack([d2, axis, -d1]) @ [math.cos(gamma), math.sin(gamma), 0.0]     # eq. (22)
        delta = d1 * math.sin(gamma) - continued(c, f.l @ axis)                                  # eq. (23)
        assert_polygon_rows(A, lb, ub, f.Jw, delta, 0.001, w_d, 8, d1)
        A, _, lb, ub = rows_of(ctrl, qp, "passes_through")
        r = port - f.p
        assert_polygon_rows(A, lb, ub, sk(f.l) @ f.Jv - sk(r) @ sk(f.l) @ f.Jw, np.cross(r, f.l), 0.0005, f.l, 8)


@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_degenerate_rows_are_finite_and_violated(tmp_path, robot, frame):
    """Axes exactly opposite (keeps_direction, tilt_at_most), parallel or opposite (cone), the tool exactly along
    the axis of rotates_around: rows finite, and some row violated at dq = 0 (the fixture is never silently off)."""
    ctrl = build(tmp_path, f"""
        param d : direction = [0, 0, 1]
        param w : direction = [1, 0, 0]
        param ax : direction = [0, 0, 1]
        param t : direction = [0, 0, 1]
        require {frame} keeps_direction(d) within 0.001
        require {frame} rotates_around(w) within 0.001
        require {frame} cone(ax, 0.3) within 0.001
        require {frame} tilt_at_most(t, 0.5)
        """, robot)
    rng = np.random.default_rng(62)
    for k in range(6):
        q = random_q(robot, rng)
        f = FrameState(robot, frame, q)
        qp = ctrl.problem(q, {}, {"d": -f.l, "w": f.l, "ax": (-1) ** k * f.l, "t": -f.l}, dt=0.01)
        for name in ("keeps_direction", "rotates_around", "cone", "tilt_at_most"):
            A, _, lb, ub = rows_of(ctrl, qp, name)
            assert np.all(np.isfinite(A)) and np.all(np.isfinite(lb)), name
            assert lb.max() > 0.1, f"{name}: no violated row at dq = 0 ({lb.max()})"
            assert np.linalg.norm(A[np.argmax(lb)]) > 0.1, f"{name}: its violated row has no gradient"
