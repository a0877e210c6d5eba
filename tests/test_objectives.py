"""Objective terms: the QP's P and g against independent formulas.

Each term is a rate error  w || E dq/dt - f ||^2  (lecture slide 47, per second instead of per tick); times dt^2
(the same minimizer) it is w || E dq - f dt ||^2, and the QP over x = [dq; slacks] is  1/2 x'Px + g'x  with

    P = 2 sum_k w_k E_k'E_k + floor I,    g = -2 sum_k w_k E_k'f_k dt      (floor: HESSIAN_FLOOR, assemble.py)

(``problem()`` gives the sum over all priority levels; the levels are tested in closed loop, test_priorities.py).

E and f are written here from the seed and the term docstrings, with Jacobians from Pinocchio
(``Robot.frame_jacobian``, rows [v; w], world axes):

- track (paper eq. 18, admittance):  E = J,  f = [k_v v_in; k_w w_in] dt, where the input's linear part
  drives translation and its angular part rotation (a force has no angular part, a torque no linear part:
  that part is asked to stay still); a twist input is scaled by the (dimensionless) gains;
- distance (lecture slide 44):  E = J_v,  f = (P - p) / max(tau, dt), tau the time constant (default 1 s);
- direction_change (slide 45, eta || alpha x l ||^2):  E'E = J_w'(I - l l')J_w, f = 0;
- damping:  E = I, f = 0;
- centering:  E = diag(1/r_i),  f_i = (c_i - q_i)/(r_i max(tau, dt))  with c, r the middle and half range of
  joint i and tau the time constant (default 1 s).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from test_primitives import ROBOT_FRAMES, ROBOTS, FrameState, build, random_q, urdf_limits  # isort: skip
from vfdsl.compiler.assemble import HESSIAN_FLOOR

TRIALS = 6
ATOL = 1e-10


def assert_qp(qp, P_terms, g_terms, n_slack_weights=()):
    """P, g of the QP equal the sum of the expected terms (plus the floor, and slack costs)."""
    nq = qp.nq
    P = HESSIAN_FLOOR * np.eye(nq) + sum(P_terms)
    g = sum(g_terms) if g_terms else np.zeros(nq)
    scale = max(1.0, np.abs(P).max())
    np.testing.assert_allclose(qp.P[:nq, :nq], P, atol=ATOL * scale, rtol=1e-12)
    np.testing.assert_allclose(qp.g[:nq], g, atol=ATOL * max(1.0, np.abs(g).max()), rtol=1e-12)
    np.testing.assert_allclose(qp.P, qp.P.T, atol=0)
    assert qp.P.shape[0] == nq + len(n_slack_weights)
    if n_slack_weights:
        np.testing.assert_allclose(np.diag(qp.P)[nq:], 2 * np.asarray(n_slack_weights))


def term(E, f, w):
    """(P, g) contributions of w || E dq - f ||^2."""
    return 2 * w * E.T @ E, -2 * w * E.T @ f


def test_floor_is_tiny():
    assert 0 < HESSIAN_FLOOR <= 1e-6


# ================================================================================================ track

@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
@pytest.mark.parametrize("kind", ["force", "torque", "wrench", "twist"])
def test_track(tmp_path, robot, frame, kind):
    if kind == "force":
        call, k_v, k_w = "track({f}, u, gain = 0.002 m/s/N)", 0.002, 0.0
    elif kind == "torque":
        call, k_v, k_w = "track({f}, u, angular_gain = 0.3 rad/s/Nm)", 0.0, 0.3
    elif kind == "wrench":
        call, k_v, k_w = "track({f}, u, gain = 0.002 m/s/N, angular_gain = 0.3 rad/s/Nm)", 0.002, 0.3
    else:
        call, k_v, k_w = "track({f}, u, gain = 0.5, angular_gain = 2)", 0.5, 2.0
    w = 3.5
    ctrl = build(tmp_path, f"input u : {kind}\nminimize {call.format(f=frame)} weight {w}\n", robot)
    size = 3 if kind in ("force", "torque") else 6
    rng = np.random.default_rng(41)
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        fs = FrameState(robot, frame, q)
        u = rng.normal(size=size)
        dt = rng.uniform(0.001, 0.05)
        qp = ctrl.problem(q, {"u": u}, dt=dt)
        if kind == "force":
            v, om = u, np.zeros(3)
        elif kind == "torque":
            v, om = np.zeros(3), u
        else:
            v, om = u[:3], u[3:]
        f = np.concatenate([k_v * v, k_w * om]) * dt          # eq. (18): dx_d = k tau (per tick)
        P, g = term(fs.J, f, w)
        assert_qp(qp, [P], [g])


def test_track_gain_units(tmp_path):
    """The paper task's gains: 1 mm/s/N = 1e-3 m/s/N; 20 deg/s/Nmm = 20 (pi/180) / 1e-3 rad/s/Nm."""
    ctrl = build(tmp_path, """
        input f : force
        input tau : torque
        minimize track(tip, f, gain = 1 mm/s/N)
        minimize track(tip, tau, angular_gain = 20 deg/s/Nmm)
        """, units="mm, deg")
    q = random_q("shr7", np.random.default_rng(42))
    fs = FrameState("shr7", "tip", q)
    F, T, dt = np.array([1.0, -2.0, 0.5]), np.array([0.01, 0.02, -0.03]), 0.01
    qp = ctrl.problem(q, {"f": F, "tau": T}, dt=dt)
    P1, g1 = term(fs.J, np.concatenate([1e-3 * F, np.zeros(3)]) * dt, 1.0)
    P2, g2 = term(fs.J, np.concatenate([np.zeros(3), 20 * math.pi / 180 / 1e-3 * T]) * dt, 1.0)
    assert_qp(qp, [P1, P2], [g1, g2])


# ====================================================================================== other terms

@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
@pytest.mark.parametrize("tau", [None, 0.25, 0.004])
def test_distance(tmp_path, robot, frame, tau):
    w = 0.7
    clause = "" if tau is None else f", time_constant = {tau} s"
    ctrl = build(tmp_path, f"param goal : point = [0, 0, 0.3]\nminimize distance({frame}, goal{clause}) weight {w}\n",
                 robot)
    rng = np.random.default_rng(43)
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        fs = FrameState(robot, frame, q)
        goal = fs.p + rng.normal(scale=0.01, size=3)
        dt = rng.uniform(0.001, 0.02)
        qp = ctrl.problem(q, {}, {"goal": goal}, dt=dt)
        share = min(dt / (1.0 if tau is None else tau), 1.0)      # of the gap, per tick: never more than all
        P, g = term(fs.Jv, (goal - fs.p) * share, w)          # || J_v dq - (P - p) dt / tau ||^2
        assert_qp(qp, [P], [g])


@pytest.mark.parametrize("robot,frame", ROBOT_FRAMES)
def test_direction_change(tmp_path, robot, frame):
    w = 10.0
    ctrl = build(tmp_path, f"minimize direction_change({frame}) weight {w}\n", robot)
    rng = np.random.default_rng(44)
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        fs = FrameState(robot, frame, q)
        qp = ctrl.problem(q, {}, dt=0.01)
        # || alpha x l ||^2 = alpha'(I - l l')alpha for unit l (slide 45)
        P = 2 * w * fs.Jw.T @ (np.eye(3) - np.outer(fs.l, fs.l)) @ fs.Jw
        assert_qp(qp, [P], [])
        # a pure roll about the tool axis costs nothing; on shr7 that is the roll joint
        if robot == "shr7":
            roll = ROBOTS["shr7"].joint_names.index("roll")
            e = np.zeros(qp.nq)
            e[roll] = 1.0
            assert e @ (qp.P - HESSIAN_FLOOR * np.eye(qp.nq)) @ e < 1e-12


@pytest.mark.parametrize("robot", ["shr7", "panda7"])
def test_damping_and_centering(tmp_path, robot):
    ctrl = build(tmp_path, "minimize damping() weight 0.01\nminimize centering() weight 0.2\n", robot)
    limits = urdf_limits(robot)
    names = ROBOTS[robot].joint_names
    lo = np.array([limits[j][0] for j in names])
    hi = np.array([limits[j][1] for j in names])
    c, r = (lo + hi) / 2, (hi - lo) / 2
    rng = np.random.default_rng(45)
    for _ in range(TRIALS):
        q = random_q(robot, rng)
        qp = ctrl.problem(q, {}, dt=0.01)
        nq = len(q)
        P1, g1 = term(np.eye(nq), np.zeros(nq), 0.01)
        P2, g2 = term(np.diag(1 / r), (c - q) / r * 0.01, 0.2)   # sum ((dq - (c - q) dt / tau) / r)^2, tau = 1 s
        assert_qp(qp, [P1, P2], [g1, g2])


def test_sum_of_terms_with_soft_constraint(tmp_path):
    """Terms add up; a soft constraint adds its slack's 2 w on the diagonal and nothing to g."""
    ctrl = build(tmp_path, """
        input f : wrench
        param goal : point = [0, 0, 0.3]
        minimize track(tip, f, gain = 0.001 m/s/N, angular_gain = 0.05 rad/s/Nm)
        minimize distance(shaft, goal) weight 4
        minimize direction_change(tip) weight 2
        minimize damping() weight 1e-4
        minimize centering() weight 1e-3
        require tip stays_at(goal) within 0.001 soft weight 50
        """)
    limits = urdf_limits("shr7")
    names = ROBOTS["shr7"].joint_names
    lo = np.array([limits[j][0] for j in names])
    hi = np.array([limits[j][1] for j in names])
    c, r = (lo + hi) / 2, (hi - lo) / 2
    rng = np.random.default_rng(46)
    for _ in range(TRIALS):
        q = random_q("shr7", rng)
        tip, shaft = FrameState("shr7", "tip", q), FrameState("shr7", "shaft", q)
        u, goal, dt = rng.normal(size=6), tip.p + rng.normal(scale=0.005, size=3), 0.02
        qp = ctrl.problem(q, {"f": u}, {"goal": goal}, dt=dt)
        parts = [term(tip.J, np.concatenate([0.001 * u[:3], 0.05 * u[3:]]) * dt, 1.0),
                 term(shaft.Jv, (goal - shaft.p) * dt, 4.0),
                 (2 * 2.0 * tip.Jw.T @ (np.eye(3) - np.outer(tip.l, tip.l)) @ tip.Jw, np.zeros(7)),
                 term(np.eye(7), np.zeros(7), 1e-4),
                 term(np.diag(1 / r), (c - q) / r * dt, 1e-3)]
        assert_qp(qp, [p for p, _ in parts], [g for _, g in parts], n_slack_weights=[50.0])
        assert np.all(qp.g[7:] == 0) and np.all(qp.P[7:, :7] == 0)
