"""A hard fixture is never silently off, wherever the tool is.

For every geometric primitive, a task on the Steady-Hand-like robot with that one hard fixture and a speed limit
(0.1 mm and 0.11 deg per 10 ms tick) has its run-time params placed so that the tool is 1 mm, 10 mm or 1 m (angles:
2, 20, 90 deg) on the wrong side; for every example task, its params (or its registration) are moved and the
robot's stage is shifted off its fixtures. At every such state, on both paths:

- the fixture has rows, violated at dq = 0 (never the always-true 0 >= -inf);
- a tick that cannot bring the tool back is LEAST_VIOLATION, and every fixture whose rows it leaves violated is
  named in ``violations()``;
- the motion does not go further the wrong way: the fixture's true error, computed here with numpy from
  Pinocchio's kinematics (brute force over the triangles for meshes; for the examples, the simulator's
  independent metrics), is no larger after the step than before.

A run-time value the controller refuses (a VfError before anything moves) also keeps the tool still: the tests
say which placements may be refused, and require the near ones to be solved.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

import vfdsl
from vfdsl.errors import VfError
from vfdsl.kinematics.robot import Robot
from vfdsl.mesh import brute
from vfdsl.mesh.load import read_mesh
from vfdsl.primitives import CONSTRAINTS
from vfdsl.runtime.qp import StepStatus

ROOT = Path(__file__).resolve().parent.parent
CHANNEL = ROOT / "tasks" / "anatomy" / "channel.stl"
DT = 0.01
Q0 = np.array([0, 0, 0, 0, 0, 0, 0.02])          # shr7: the tip at (0, 0, 280) mm, on the channel's straight part
ROBOT = Robot.load("shr7")
DEG = math.pi / 180
LENGTHS = (1e-3, 1e-2, 1.0)
ANGLES = (2 * DEG, 20 * DEG, 90 * DEG)
SPEED_LIMITS = "require tip speed(0.01)\nrequire tip angular_speed(0.2)\nrequire shaft speed(0.01)\n"
RATE_PRIMITIVES = {name for name, spec in CONSTRAINTS.items() if spec.rate} | {"joint_limits"}


def _pose(q):
    p, R = ROBOT.frame_pose(q, "tool_tip")
    return p, R[:, 2], R


P0, L0, R0 = _pose(Q0)
E1 = R0[:, 0]                     # normal to the tool axis
E2 = R0[:, 1]


def _rotated(v, axis, angle):
    """v turned by angle about the unit axis (Rodrigues)."""
    v, k = np.asarray(v, float), np.asarray(axis, float)
    return v * math.cos(angle) + np.cross(k, v) * math.sin(angle) + k * (k @ v) * (1 - math.cos(angle))


def _shaft(q):
    p, R = ROBOT.frame_pose(q, "tool_tip")
    return p + R[:, 2] * 0.03


def _clearance(q, reg, keep_in):
    """The capsule tip-shaft (radius 1 mm) for a keep-in channel; the tip alone for a keep-out one."""
    mesh = read_mesh(CHANNEL, 1e-3)
    a = _pose(q)[0] - reg
    b, radius = (_shaft(q) - reg, 0.001) if keep_in else (a, 0.0)
    return brute.signed_clearance(a, b, radius, mesh.vertices, mesh.triangles, keep_in)


# primitive -> (the fixture and its params' declarations, its placements: magnitude -> (run-time params, true error
# of q under them)); every declared default puts the tool in the fixture, so the task loads.
def _case(primitive):
    p, l = P0, L0
    e = E1
    fmt = lambda v: "[" + ", ".join(f"{x:.12g}" for x in v) + "]"      # noqa: E731
    if primitive == "stays_at":
        return (f"param target : point = {fmt(p)}\nrequire tip stays_at(target) within 0.00001",
                LENGTHS, lambda m: {"target": p + m * e},
                lambda q, m: np.linalg.norm(_pose(q)[0] - (p + m * e)))
    if primitive == "along":
        return (f"param path : line = line(point = {fmt(p)}, direction = {fmt(E2)})\n"
                "require tip along(path) within 0.00001",
                LENGTHS, lambda m: {"path": [*(p + m * e), *E2]},
                lambda q, m: np.linalg.norm(np.cross(_pose(q)[0] - (p + m * e), E2)))
    if primitive == "follows":
        pts = [p + s * E2 for s in np.linspace(-0.02, 0.02, 5)]
        return ("param cut : curve(degree = 1, runtime = true)\nrequire tip follows(cut) within 0.00001",
                LENGTHS, lambda m: {"cut": np.array([x + m * e for x in pts])},
                lambda q, m: np.linalg.norm(np.cross(_pose(q)[0] - (p + m * e), E2)), pts)
    if primitive in ("on_plane", "above", "near_plane"):
        extra = {"on_plane": " within 0.00001", "above": "", "near_plane": ""}[primitive]
        call = "near_plane(wall, 0.001)" if primitive == "near_plane" else f"{primitive}(wall)"
        half = 0.001 if primitive == "near_plane" else 0.0

        def error(q, m):
            h = (_pose(q)[0] - (p + (m + half) * e)) @ e
            return abs(h) - half if primitive != "above" else max(0.0, -h)
        return (f"param wall : plane = plane(point = {fmt(p)}, normal = {fmt(e)})\nrequire tip {call}{extra}",
                LENGTHS, lambda m: {"wall": [*(p + (m + half) * e), *e]}, error)
    if primitive in ("within_distance", "within_sphere"):
        arg = "distance" if primitive == "within_distance" else "radius"
        return (f"param c : point = {fmt(p)}\nrequire tip {primitive}(c, 0.005)",
                LENGTHS, lambda m: {"c": p + (0.005 + m) * e},
                lambda q, m: np.linalg.norm(_pose(q)[0] - (p + (0.005 + m) * e)) - 0.005)
    if primitive == "outside_sphere":
        return (f"param c : point = {fmt(p + 0.01 * e)}\nparam r : length = 0.005\nrequire tip outside_sphere(c, r)",
                LENGTHS, lambda m: {"c": p + 0.005 * e, "r": 0.005 + m},
                lambda q, m: 0.005 + m - np.linalg.norm(_pose(q)[0] - (p + 0.005 * e)))
    if primitive == "passes_through":
        port = p + 0.03 * l
        return (f"param port : point = {fmt(port)}\nrequire tip passes_through(port) within 0.00001",
                LENGTHS, lambda m: {"port": port + m * e},
                lambda q, m: np.linalg.norm(np.cross(port + m * e - _pose(q)[0], _pose(q)[1])))
    if primitive == "keeps_direction":
        return (f"param d : direction = {fmt(l)}\nrequire tip keeps_direction(d) within 0.001",
                ANGLES, lambda a: {"d": _rotated(l, E2, a)},
                lambda q, a: math.acos(np.clip(_pose(q)[1] @ _rotated(l, E2, a), -1, 1)))
    if primitive == "rotates_around":
        return (f"param ax : direction = {fmt(e)}\nrequire tip rotates_around(ax) within 0.001",
                ANGLES[:2], lambda a: {"ax": _rotated(e, E2, -a)},
                lambda q, a: abs(math.pi / 2 - math.acos(np.clip(_pose(q)[1] @ _rotated(e, E2, -a), -1, 1))))
    if primitive in ("cone", "tilt_at_most"):
        call = f"{primitive}(ax, 0.2)" + (" within 0.001" if primitive == "cone" else "")
        axis = lambda a: _rotated(l, E2, 0.2 + a)        # noqa: E731
        angle = lambda q, a: math.acos(np.clip(_pose(q)[1] @ axis(a), -1, 1))      # noqa: E731
        return (f"param ax : direction = {fmt(axis(0))}\nrequire tip {call}",
                ANGLES, lambda a: {"ax": axis(a)},
                (lambda q, a: abs(angle(q, a) - 0.2)) if primitive == "cone" else (lambda q, a: angle(q, a) - 0.2))
    if primitive in ("inside_mesh", "outside_mesh"):
        keep_in = primitive == "inside_mesh"
        call = f"{primitive}(channel, margin = 0.0005" + (", shaft = shaft, radius = 0.001)" if keep_in else ")")
        start = [0, 0, 0] if keep_in else [0.02, 0, 0]
        shift = (lambda m: (0.005 + m) * e) if keep_in else (lambda m: (0.004 - min(m, 0.003)) * e)
        return (f"param reg : pose = pose(translation = {fmt(start)}, rpy = [0, 0, 0])\n"
                f'param channel : mesh(unit = 1 mm) in reg = "{CHANNEL}"\nrequire tip {call}',
                LENGTHS if keep_in else (1e-3, 4e-3), lambda m: {"reg": [*shift(m), 0, 0, 0]},
                lambda q, m: max(0.0, 0.0005 - _clearance(q, shift(m), keep_in)))
    raise KeyError(primitive)


GEOMETRIC = sorted(set(CONSTRAINTS) - RATE_PRIMITIVES)


def test_every_geometric_primitive_has_a_case():
    """A new primitive must be placed on its wrong side here too."""
    for name in GEOMETRIC:
        assert _case(name)


def _task(tmp_path, primitive, backend):
    body, *_ = _case(primitive)
    text = ('task probe\nunits m, rad\nrobot rb = urdf "shr7"\nframe tip = rb.link("tool_tip")\n'
            "frame shaft = tip offset [0, 0, 0.03]\n" + body + "\n" + SPEED_LIMITS)
    (tmp_path / "probe.vf").write_text(text)
    (tmp_path / "probe.yaml").write_text(textwrap.dedent("""\
        units: mm, deg
        period: 10 ms
        start: {x: 0, y: 0, z: 0, rcm_a: 0, rcm_b: 0, roll: 0, insert: 20}
        """))
    extra = _case(primitive)[4:]
    if extra:
        points = "\n".join(f"    - [{x[0] * 1e3:.9g}, {x[1] * 1e3:.9g}, {x[2] * 1e3:.9g}]" for x in extra[0])
        with open(tmp_path / "probe.yaml", "a") as f:
            f.write(f"params:\n  cut:\n    points:\n{points}\n")
    return vfdsl.compile(vfdsl.load(tmp_path / "probe.vf"), backend=backend)


def _rows_of(ctrl, q, params, primitive):
    qp = ctrl.problem(q, None, params, DT)
    start = qp.A.shape[0] - len(ctrl.row_labels)
    idx = [start + i for i, label in enumerate(ctrl.row_labels) if label.primitive == primitive]
    return qp.A[idx, :qp.nq], qp.lb[idx], qp.ub[idx]


@pytest.mark.parametrize("backend", ["native", "interpreted"])
@pytest.mark.parametrize("primitive", GEOMETRIC)
def test_far_on_the_wrong_side_every_primitive(tmp_path, primitive, backend):
    ctrl = _task(tmp_path, primitive, backend)
    _, sizes, place, error, *_ = _case(primitive)
    dq = ctrl.step(Q0, None, None, DT)                   # the declared defaults: inside the fixture
    assert ctrl.status == StepStatus.OPTIMAL and not ctrl.violations() and np.all(np.isfinite(dq))
    for m in sizes:
        params = place(m)
        before = error(Q0, m)
        assert before > 0.9 * m * (1 if m < 0.5 else 0.5) or primitive.endswith("mesh"), (m, before)
        A, lb, ub = _rows_of(ctrl, Q0, params, primitive)
        assert len(lb) and np.all(np.isfinite(A))
        assert np.max(np.maximum(lb, -ub)) > 1e-6, f"{primitive} {m}: no violated row at dq = 0"
        dq = ctrl.step(Q0, None, params, DT)
        assert np.all(np.isfinite(dq))
        assert ctrl.status & StepStatus.LEAST_VIOLATION, f"{primitive} {m}: {ctrl.status!r}"
        assert any(v.label.primitive == primitive for v in ctrl.violations()), (m, ctrl.violations())
        after = error(Q0 + dq, m)
        assert after <= before + 1e-9, f"{primitive} {m}: the step went further the wrong way ({before} -> {after})"
        assert after < before - 1e-6 * (1 if primitive in ("keeps_direction", "rotates_around", "cone",
                                                           "tilt_at_most") else 10), (m, before, after)
