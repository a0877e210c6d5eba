"""Kinematics at a configuration: does every task frame move, and how well conditioned is it?

For each task frame f, Pinocchio's Jacobian J_f = [J_v; J_w] (6 x nq, world axes, at the frame origin).
A frame whose Jacobian is zero is attached to the base: no joint moves it, and every constraint on it
is either always true or always false (VF602, error). Otherwise, for the block each constraint on f uses
(J_v for positions and speeds, J_w for angles and angular speeds), the singular values s_1 >= ... >= s_3
give its conditioning s_3 / s_1; below NEAR_SINGULAR the frame is near a singularity (VF601, warning): a
small correction in one direction needs a large joint motion. The joints' columns mix m/m (prismatic) and
m/rad (revolute), so the ratio compares motions per SI unit of each joint.

Joints that start within EDGE of their range from a limit are reported (VF603, warning): the first
ticks can only move them one way; outside the limits (a task built in Python; the front end refuses it
in a scene file) is VF604 (error).
"""

from __future__ import annotations

import numpy as np

from vfdsl.primitives.bounds import stated_size
from vfdsl.check.report import Finding, Severity
from vfdsl.compiler.geometry import homogeneous
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot

NEAR_SINGULAR = 1e-3
EDGE = 0.01                      # fraction of a joint's range
_BLOCKS = {"length": "v", "speed": "v", "angle": "w", "angular_speed": "w"}


def blocks_used(task: ir.Task) -> dict[str, set[str]]:
    """frame -> the Jacobian blocks ('v', 'w') its constraints use."""
    used: dict[str, set[str]] = {}
    for c in task.constraints:
        if c.frame is None:
            continue
        stated = stated_size(c, task)
        used.setdefault(c.frame, set()).add(_BLOCKS[stated[0]] if stated else "v")
    return used


def frame_jacobian(robot: Robot, frame: ir.FrameDecl, q) -> np.ndarray:
    return robot.frame_jacobian(q, frame.link, homogeneous(frame.offset, frame.rpy))


def frame_pose(robot: Robot, frame: ir.FrameDecl, q) -> tuple[np.ndarray, np.ndarray]:
    """(origin, rotation) of a task frame in world."""
    return robot.frame_pose(q, frame.link, homogeneous(frame.offset, frame.rpy))


def conditioning(J: np.ndarray) -> tuple[float, float]:
    """(smallest singular value, smallest / largest) of a 3 x nq block (0, 0 when it is zero)."""
    s = np.linalg.svd(J, compute_uv=False)
    return float(s[-1]), float(s[-1] / s[0]) if s[0] > 0 else 0.0


def frame_figures(robot: Robot, task: ir.Task, q) -> dict[str, dict]:
    """Per frame: rank of J, smallest singular value and conditioning of J_v and J_w."""
    out = {}
    for frame in task.frames:
        J = frame_jacobian(robot, frame, q)
        s = np.linalg.svd(J, compute_uv=False)
        entry = {"rank": int(np.sum(s > 1e-9 * max(s[0], 1e-300)))}
        for name, block in (("v", J[:3]), ("w", J[3:])):
            entry[f"sigma_min_{name}"], entry[f"conditioning_{name}"] = conditioning(block)
        out[frame.name] = entry
    return out


def worst_conditioning(robot: Robot, task: ir.Task, q) -> tuple[float, str | None]:
    """The smallest conditioning over the blocks the constraints use, and 'frame.block' where it is."""
    worst, where = np.inf, None
    figures = frame_figures(robot, task, q)
    for name, blocks in blocks_used(task).items():
        for block in blocks:
            value = figures[name][f"conditioning_{block}"]
            if value < worst:
                worst, where = value, f"{name}.{block}"
    return worst, where


def analyse(robot: Robot, task: ir.Task, q, figures: dict) -> list[Finding]:
    findings = []
    frames = frame_figures(robot, task, q)
    figures["frames"] = frames
    used = blocks_used(task)
    for frame in task.frames:
        f = frames[frame.name]
        heading = f"frame {frame.name}"
        if f["rank"] == 0:
            findings.append(Finding("frame-fixed", Severity.ERROR,
                                    f"no joint moves frame '{frame.name}' (link '{frame.link}'): its Jacobian is "
                                    f"zero, so constraints and objectives on it can do nothing", frame.span,
                                    "attach the frame to a link that moves", heading, {"link": frame.link}))
            continue
        for block in sorted(used.get(frame.name, ())):
            sigma, ratio = f[f"sigma_min_{block}"], f[f"conditioning_{block}"]
            if ratio < NEAR_SINGULAR:
                what = "translation" if block == "v" else "rotation"
                findings.append(Finding(
                    "kinematics-near-singular", Severity.WARNING,
                    f"at the start frame '{frame.name}' is near a singularity for {what}: the smallest singular "
                    f"value of its {'J_v' if block == 'v' else 'J_w'} is {sigma:.3g} ({ratio:.2g} of the largest, "
                    f"rank {f['rank']} of the 6 x {robot.nq} Jacobian)", frame.span,
                    "start away from the singular configuration, or drop the constraint on that direction",
                    heading, {"block": block, "sigma_min": sigma, "conditioning": ratio, "rank": f["rank"]}))
    span = task.span
    for name, value, lo, hi in zip(robot.joint_names, q, robot.lower, robot.upper):
        if not (np.isfinite(lo) and np.isfinite(hi)):
            continue
        edge = EDGE * (hi - lo)
        if not lo <= value <= hi:
            findings.append(Finding(
                "start-outside-limits", Severity.ERROR,
                f"joint {name} starts at {value:.6g}, outside its limits [{lo:.6g}, {hi:.6g}] (SI units)", span,
                "start within the joint limits", "task", {"joint": name, "value": float(value)}))
        elif value - lo < edge or hi - value < edge:
            limit = lo if value - lo < edge else hi
            findings.append(Finding(
                "start-near-limit", Severity.WARNING,
                f"joint {name} starts at {value:.6g}, within {abs(value - limit):.3g} of its limit {limit:.6g} "
                f"(SI units; {EDGE:.0%} of its range is {edge:.3g})", span,
                "start nearer the middle of the joint's range", "task",
                {"joint": name, "value": float(value), "limit": float(limit)}))
    return findings
