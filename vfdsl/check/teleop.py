"""Teleoperation (a `teleop` term, docs/language.md "Teleoperation"): is the haptic wall passive, and can the scaled
master command the tool where the fixture (or the robot) will not let it go?

- **Passivity** (VF970). The force F_k = -K x_k - B (x_k - x_k-1) / T, held over each period T (x the master's depth
  past the acting rows, K the stiffness, B the damping), on a master of physical damping b, is passive iff
  b > K T / 2 + B (Colgate & Schenkel, 1997: the sampled virtual wall; docs/check.md derives it). Without
  ``master_damping`` the finding is a note stating the b the master needs; with it, a warning when b falls short.
- **Anchors** (VF972). A teleop term in a phase re-anchors on each entry only if that phase captures both anchors:
  ``anchor`` the pose of the term's own frame and ``master_anchor`` its own master. An anchor captured elsewhere
  (another phase, another frame or input) or a fixed param keeps an old pose across a clutch: at re-engage the
  goal jumps by the master's motion while clutched (a warning, at the term, naming the anchor). An anchor captured
  from the other side (VF973: the master's pose as ``anchor``, a frame's pose as ``master_anchor``) anchors the goal
  in the wrong coordinates, and the tool moves off with the hands off (an error).
- **Workspace** (VF971). With ``master_reach`` R, the scaled master commands the frame anywhere in the ball of radius
  scale R around its engage pose. From the start, the compiled controller is driven with the master held at R along
  each of WORKSPACE_DIRECTIONS directions (through the camera) for WORKSPACE_SECONDS; where the frame stays short
  of its goal by more than SHORTFALL, the fixture or the robot stops the command there: a warning with the largest
  shortfall, its direction, and the force the master would feel (stiffness x shortfall / scale, saturated).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from vfdsl.check.report import Finding, Severity
from vfdsl.compiler.geometry import rotation
from vfdsl.ir import model as ir
from vfdsl.objectives.haptics import teleop_terms
from vfdsl.sim.geometry import Scene

WORKSPACE_SECONDS = 1.0
SHORTFALL = 1e-3                 # m: a goal this far out of the frame's reach is stopped by something
WORKSPACE_DIRECTIONS = [np.array(d, dtype=float) / np.linalg.norm(d)
                        for d in itertools.product((-1, 0, 1), repeat=3) if any(d)]   # 26


def _value(task: ir.Task, arg: ir.Arg) -> float | None:
    """A scalar argument's value (a literal, or a param's default: the scene's reading); None for a capture."""
    return None if isinstance(arg, ir.CaptureRef) else Scene(task).value(arg).value


def passivity(task: ir.Task, period: float) -> list[Finding]:
    findings = []
    for o in teleop_terms(task):
        K, B, b = (_value(task, o.args[name]) for name in ("stiffness", "damping", "master_damping"))
        if not K or B is None:
            continue
        needed = K * period / 2 + B
        data = {"stiffness": K, "damping": B, "period": period, "master_damping": b, "needed": needed}
        where = f"teleop({o.args['frame'].name})"
        if not b:
            findings.append(Finding(
                "haptic-passivity", Severity.NOTE,
                f"the haptic wall is passive on a master whose own damping exceeds K T / 2 + B = {needed:.3g} N s/m "
                f"(K {K:g} N/m, T {period * 1e3:g} ms, B {B:g} N s/m)", o.span,
                "give master_damping (the master's physical damping) and vfdsl check compares it", where, data))
        elif b <= needed:
            findings.append(Finding(
                "haptic-passivity", Severity.WARNING,
                f"the haptic wall is not passive: the master's damping {b:g} N s/m is below K T / 2 + B = "
                f"{needed:.3g} N s/m (K {K:g} N/m, T {period * 1e3:g} ms, B {B:g} N s/m): the wall may chatter",
                o.span, f"lower the stiffness below {2 * max(b - B, 0.0) / period:.3g} N/m, the damping, or the period",
                where, data))
    return findings


def anchors(task: ir.Task) -> list[Finding]:
    """VF972 (module docstring) for every teleop term inside a phase."""
    findings = []
    every = {c.name: c.source for phase in task.phases for c in phase.captures}
    for phase in task.phases:
        taken = {c.name: c.source for c in phase.captures}
        for o in phase.objectives:
            if o.term != "teleop":
                continue
            wanted = {"anchor": ir.FrameMeasure(frame=o.args["frame"].name, part="pose"),
                      "master_anchor": ir.InputRef(name=o.args["master"].name)}
            for arg, source in wanted.items():
                given = o.args[arg]
                if isinstance(given, ir.CaptureRef) and taken.get(given.name) == source:
                    continue
                if isinstance(given, ir.CaptureRef) and every[given.name].ref != source.ref:
                    findings.append(_swapped(o, arg, every[given.name], phase.name))
                    continue
                what = (f"captured in another phase or of another {'frame' if arg == 'anchor' else 'input'}"
                        if isinstance(given, ir.CaptureRef) else "not captured")
                expected = (f"capture NAME = {o.args['frame'].name}.pose" if arg == "anchor"
                            else f"capture NAME = {o.args['master'].name}")
                findings.append(Finding(
                    "teleop-anchor-kept", Severity.WARNING,
                    f"teleop's {arg} in phase '{phase.name}' is {what}: it is not retaken when '{phase.name}' is "
                    "entered, so at each re-engage the goal jumps by the master's motion in between", o.span,
                    f"capture it in phase '{phase.name}': `{expected}`", f"teleop({o.args['frame'].name})",
                    {"phase": phase.name, "argument": arg}))
    return findings


def _swapped(o, arg: str, source, phase: str) -> Finding:
    """VF973: a teleop anchor captured from the other side (the master's pose as the frame's, or the reverse)."""
    frame, master = o.args["frame"].name, o.args["master"].name
    given = f"the pose of input '{source.name}'" if source.ref == "input" else f"the pose of frame '{source.frame}'"
    expected = f"capture NAME = {frame}.pose" if arg == "anchor" else f"capture NAME = {master}"
    return Finding(
        "teleop-anchor-swapped", Severity.ERROR,
        f"teleop's {arg} in phase '{phase}' is {given}: the {'frame' if arg == 'anchor' else 'master'}'s pose at "
        "engage is meant, and the goal is anchored in the other side's coordinates, so the tool leaves its engage "
        "pose with the hands off", o.span, f"give {arg} a capture of the phase: `{expected}`", f"teleop({frame})",
        {"phase": phase, "argument": arg})


def workspace(controller, task: ir.Task, period: float, figures: dict) -> list[Finding]:
    """VF971 (module docstring) for each teleop term with a master_reach, from the task's start."""
    findings = []
    for o in teleop_terms(task):
        reach, scale = _value(task, o.args["master_reach"]), _value(task, o.args["scale"])
        if not reach or scale is None:
            continue
        R_c = rotation(Scene(task).value(o.args["camera"]).rpy)
        worst = (0.0, None, 0.0)
        ticks = max(1, math.ceil(WORKSPACE_SECONDS / period))
        for d in WORKSPACE_DIRECTIONS:
            master = np.concatenate([reach * (R_c.T @ d), np.zeros(3)])
            inputs = {i.name: (master if i.name == o.args["master"].name else np.zeros(i.size)) for i in task.inputs}
            controller.reset()
            q = np.array(task.start, dtype=float)
            for _ in range(ticks):
                q = q + controller.step(q, inputs, dt=period)
            out = controller.teleop
            short = float(np.linalg.norm(out.goal - out.setpoint[:3]))
            if short > worst[0]:
                worst = (short, d, float(np.linalg.norm(out.force)))
        controller.reset()
        figures.setdefault("teleop_workspace", {})[o.args["frame"].name] = {
            "radius": scale * reach, "largest_shortfall": worst[0],
            "direction": None if worst[1] is None else worst[1].tolist()}
        if worst[0] > SHORTFALL:
            findings.append(Finding(
                "teleop-workspace", Severity.WARNING,
                f"the scaled master reaches {scale * reach * 1e3:.3g} mm from the start, but the tool stops "
                f"{worst[0] * 1e3:.3g} mm short of its goal toward [{', '.join(f'{x:.2f}' for x in worst[1])}] "
                f"(the fixture or the robot's limits): the master feels {worst[2]:.3g} N there", o.span,
                "expected at a keep-out region; otherwise lower the scale or re-centre with the clutch",
                f"teleop({o.args['frame'].name})", {"shortfall": worst[0], "direction": worst[1].tolist(),
                                                    "force": worst[2], "radius": scale * reach}))
    return findings
