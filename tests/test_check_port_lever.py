"""VF605 port-lever-short: a port a few mm from the tracked tip makes the tool pivot fast to move the tip slowly.

The figures of `vfdsl check` are compared with an independent computation: the lever by direct geometry (the
port placed on the tool axis), the rotation rate as 1 / lever, and the fastest sideways tip speed by a linear
program written from Jacobians taken by central finite differences of the tool's pose, with the port held by
the tool's own material point at the port (its velocity normal to the axis is zero), over 360 directions.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import TASKS_DIR, port_task, run_cli
from scipy.optimize import linprog

import vfdsl
from vfdsl.check import check

WARNS = {("panda7", 2), ("panda7", 4), ("shr7", 2), ("shr7", 4), ("shr7", 12)}
DIRECTIONS = 360            # the check samples 24: it may find up to 1 / cos(pi / 48) = 0.2 % more
STEP = 1e-7                 # rad or m, central differences


def _lever_findings(report):
    return [f for f in report.findings if f.code == "VF605"]


def _point_jacobian(robot, q, offset):
    """3 x nq: d(position of the tool's point at ``offset``, in tool_tip axes)/dq by central differences."""
    T = np.eye(4)
    T[:3, 3] = offset
    columns = []
    for k in range(robot.nq):
        dq = np.zeros(robot.nq)
        dq[k] = STEP
        columns.append((robot.frame_pose(q + dq, "tool_tip", T)[0] - robot.frame_pose(q - dq, "tool_tip", T)[0])
                       / (2 * STEP))
    return np.array(columns).T


def _slowest_sideways_speed(robot, q, R0, up, lever, limits):
    """min over sideways u of max s: tip velocity s u, the tool's point at the port moving along the axis only,
    |qdot| <= limits."""
    J_tip = _point_jacobian(robot, q, np.zeros(3))
    J_port = _point_jacobian(robot, q, R0.T @ (lever * up))
    a = np.cross(up, [1.0, 0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(up, a)
    nq = robot.nq
    speeds = []
    for angle in np.pi * np.arange(DIRECTIONS) / DIRECTIONS:
        u = np.cos(angle) * a + np.sin(angle) * b
        A_eq = np.vstack([np.hstack([J_tip, -u[:, None]]), np.hstack([np.vstack([a, b]) @ J_port, np.zeros((2, 1))])])
        result = linprog(np.r_[np.zeros(nq), -1.0], A_eq=A_eq, b_eq=np.zeros(5),
                         bounds=[(-v, v) for v in limits] + [(0, None)], method="highs")
        assert result.status == 0
        speeds.append(result.x[-1])
    return min(speeds)


@pytest.mark.parametrize("robot_name", ["panda7", "shr7"])
@pytest.mark.parametrize("distance_mm", [2, 4, 12, 60])
def test_a_port_close_to_the_tip_warns_with_the_figures(tmp_path, robot_name, distance_mm):
    lever = distance_mm * 1e-3
    task, robot, _, R0, up = port_task(tmp_path, robot_name, lever)
    report = check(task, samples=0, backend="interpreted")
    figure = report.figures["levers"]["passes_through(tip) at port.vf:9 -> tip"]
    assert figure["lever"] == pytest.approx(lever, abs=1e-9)
    assert figure["pivot_rate"] == pytest.approx(1 / lever, rel=1e-6)
    slowest = _slowest_sideways_speed(robot, task.start, R0, up, lever, robot.velocity_limit)
    assert slowest * (1 - 1e-6) <= figure["sideways_speed"] <= slowest / np.cos(np.pi / 48) * (1 + 1e-6)
    found = _lever_findings(report)
    if (robot_name, distance_mm) not in WARNS:
        assert found == []
        return
    finding, = found
    assert finding.severity.value == "warning" and (finding.span.line, finding.span.column) == (9, 1)
    speed = figure["sideways_speed"]
    for text in (f"the port is {distance_mm:g} mm from the tracked point 'tip'", f"{1 / distance_mm:.3g} rad/s",
                 f"at most {speed * 1e3:.4g} mm/s", f"1 mm/s takes {1e-3 / speed:.1%} of {figure['joint']}'s limit",
                 f"a sideways push above {speed * 1e3:.3g} N"):
        assert text in finding.message, (text, finding.message)
    assert "move the port farther from 'tip'" in finding.suggestion and "vfdsl simulate" in finding.suggestion


def test_the_joint_speed_fraction_scales_the_figure_and_a_slow_robot_is_not_blamed_on_its_port(tmp_path):
    """At half the joint speeds the shr7's tip moves sideways at 12 mm/s at 60 mm, under 20 mm/s, but it moves at
    12.6 mm/s without the port: the port is not what holds it. At 4 mm the port still is."""
    for distance_mm, warns in ((60, False), (4, True)):
        folder = tmp_path / f"port_{distance_mm}mm"
        folder.mkdir()
        task = port_task(folder, "shr7", distance_mm * 1e-3)[0]
        full = check(task, samples=0, backend="interpreted").figures["levers"]
        path = folder / "port.vf"
        path.write_text(path.read_text().replace("joint_speed()", "joint_speed(fraction = 0.5)"))
        report = check(vfdsl.load(path), samples=0, backend="interpreted")
        (key, half), = report.figures["levers"].items()
        assert half["sideways_speed"] == pytest.approx(full[key]["sideways_speed"] / 2, rel=1e-6)
        assert half["free_speed"] == pytest.approx(full[key]["free_speed"] / 2, rel=1e-6)
        assert bool(_lever_findings(report)) == warns


def test_a_torque_input_commands_no_sideways_speed(tmp_path):
    """A torque turns the tool about the port (a close port makes that easy): nothing to warn about."""
    task = port_task(tmp_path, "shr7", 2e-3, torque=True)[0]
    report = check(task, samples=0, backend="interpreted")
    assert _lever_findings(report) == [] and "levers" not in report.figures


def test_the_lecture_remote_center_port_is_far_enough():
    report = check(vfdsl.load(TASKS_DIR / "lecture_remote_center.vf"), samples=0, backend="interpreted")
    (figure,) = report.figures["levers"].values()
    assert figure["lever"] == pytest.approx(60e-3, abs=1e-6) and figure["sideways_speed"] > 0.1
    assert _lever_findings(report) == []


def test_the_finding_in_the_json_output(tmp_path):
    port_task(tmp_path, "panda7", 4e-3)
    proc = run_cli("check", str(tmp_path / "port.vf"), "--json", "--samples", "0")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    finding, = [f for f in data["findings"] if f["name"] == "port-lever-short"]
    assert finding["code"] == "VF605" and finding["severity"] == "warning"
    assert (finding["location"]["line"], finding["location"]["column"]) == (9, 1)
    assert finding["data"]["lever"] == pytest.approx(4e-3) and finding["data"]["joint"] == "joint6"
    assert finding["data"]["sideways_speed"] == pytest.approx(11.3e-3, rel=0.01)
    assert data["figures"]["levers"]["passes_through(tip) at port.vf:9 -> tip"] == finding["data"]
