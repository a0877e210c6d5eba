"""A procedure's captured values read as params: for the simulator's metrics and for ``vfdsl check``'s analyses of
one phase.

A phase's fixture may read values captured on entry (``along(line(start, axis0))``). A tool that measures or
analyses it without running the phase machine reads each capture of a point, a direction, a vector or a pose as a
param of that kind (:func:`as_params`) holding the value it has at that time: ``Controller.captures`` at a tick
(:func:`values`), the simulator taking a new value at every transition; ``check`` the start configuration's. A
capture of another kind (a force's or a scalar param's value) stays a capture, and a statement that reads one is
not measurable this way (:func:`readable`). :func:`phase_task` is one phase alone as a task without phases.
"""

from __future__ import annotations

import numpy as np

from vfdsl.ir import model as ir

VALUES = {"point": ir.PointValue, "direction": ir.DirectionValue, "vector": ir.VectorValue, "pose": ir.PoseValue}
"""The kinds of capture a metric reads, and the value class of each."""


def _value(kind: str, numbers) -> ir.Value:
    """The IR value of a capture of ``kind`` from its flat numbers (a pose: [translation; roll, pitch, yaw])."""
    flat = [float(x) for x in numbers]
    return ir.PoseValue(translation=flat[:3], rpy=flat[3:6]) if kind == "pose" else VALUES[kind](xyz=flat)


def _kinds(task: ir.Task) -> dict[str, str]:
    return {c.name: c.kind for p in task.phases for c in p.captures}


def _as_refs(node, names: set[str]):
    """A dumped IR node with every capture reference among ``names`` made a param reference."""
    if isinstance(node, dict):
        if node.get("ref") == "capture" and node.get("name") in names:
            return {**node, "ref": "param"}
        return {k: _as_refs(v, names) for k, v in node.items()}
    if isinstance(node, list):
        return [_as_refs(v, names) for v in node]
    return node


def _captures_read(node) -> set[str]:
    if isinstance(node, dict):
        found = {node["name"]} if node.get("ref") == "capture" else set()
        return found.union(*(_captures_read(v) for v in node.values()))
    if isinstance(node, list):
        return set().union(*(_captures_read(v) for v in node))
    return set()


def readable(c: ir.Constraint) -> bool:
    """Whether a metric can measure constraint ``c`` of :func:`as_params`' task: it reads no capture left as one."""
    return not _captures_read(c.model_dump())


def as_params(task: ir.Task, given: dict[str, ir.Value] | None = None) -> ir.Task:
    """``task`` with each capture of a point, a direction or a vector a param of its kind (its value in ``given``,
    else a placeholder until a scene gives it one), read as that param in the phases' statements; a task without
    captures unchanged."""
    kinds = {name: kind for name, kind in _kinds(task).items() if kind in VALUES}
    if not kinds:
        return task
    given = given or {}
    spans = {c.name: c.span for p in task.phases for c in p.captures}
    placeholder = {"pose": [0.0] * 6}
    params = [ir.ParamDecl(name=name, type=kind, value=given.get(name, _value(kind, placeholder.get(kind, [0, 0, 1]))),
                           span=spans[name]) for name, kind in kinds.items()]
    phases = [ir.Phase.model_validate(_as_refs(p.model_dump(), set(kinds))) for p in task.phases]
    return task.model_copy(update={"params": [*task.params, *params], "phases": phases})


def phase_task(task: ir.Task, phase: str, given: dict[str, ir.Value]) -> ir.Task | None:
    """Phase ``phase`` of a procedure alone: the statements outside the phases and its own, its captures read as
    params of the ``given`` values (:func:`as_params`), no phase, monitor or transition (a task of one moment, as
    the tools of one moment analyse); None when its statements read a capture that cannot be a param."""
    view = as_params(task, given)
    own = next(p for p in view.phases if p.name == phase)
    if not all(readable(c) for c in own.constraints) or _captures_read([o.model_dump() for o in own.objectives]):
        return None
    return view.model_copy(update={"constraints": [*view.constraints, *own.constraints],
                                   "objectives": [*view.objectives, *own.objectives],
                                   "phases": [], "monitors": [], "transitions": []})


def values(task: ir.Task, captured: dict[str, np.ndarray]) -> dict[str, ir.Value]:
    """The values of :func:`as_params`' capture params, from ``Controller.captures`` (SI)."""
    kinds = _kinds(task)
    return {name: _value(kinds[name], value) for name, value in captured.items() if kinds.get(name) in VALUES}
