"""A task's procedure: its phases (with their captures), monitors, transitions and blend time, checked into
:class:`~vfdsl.ir.model.Phase`, :class:`~vfdsl.ir.model.Monitor` and :class:`~vfdsl.ir.model.Transition`.

One namespace holds the task's declarations, phases, monitors and captures (each name once; ``elapsed`` and
``least_violation`` are measures). A procedure has exactly one initial phase; a transition names known phases,
never leaves a final phase and never returns to its own source (``*`` stands for every phase but the final
ones and the target). A capture reads a frame's ``position`` or ``axis``, an input or a param; its name is
usable in every phase's statements, monitors and guards, not in a statement outside the phases (that holds
in every phase, before any capture is taken). Each check runs on its own (:mod:`vfdsl.passes.diagnostics`).
"""

from __future__ import annotations

from typing import Callable

from vfdsl.errors import VfError, suggest
from vfdsl.ir import model as ir
from vfdsl.passes import fixtures as fx
from vfdsl.passes.diagnostics import Dependent
from vfdsl.passes.monitors import RESERVED, Conditions
from vfdsl.syntax import ast

_FRAME_PARTS = {"position": "point", "axis": "direction", "pose": "pose"}
UNCAPTURED = {"curve": "a run-time curve (runtime = true) changes when the program sets it",
              "mesh": "a mesh moves with its pose param"}
"""Param kinds a capture cannot hold (their values are not numbers of a fixed count), with what to do instead."""

# statements(body, scope) -> (objectives, constraints) of those statements, fixtures expanded
Statements = Callable[[list, fx.Scope], tuple[list[ir.Objective], list[ir.Constraint]]]


class Procedure:
    """The procedure of one task; ``resolver`` holds its declarations (and receives its captures)."""

    def __init__(self, resolver, statements: list):
        self.resolver = resolver
        self.phase_stmts = [s for s in statements if isinstance(s, ast.PhaseStmt)]
        self.monitor_stmts = [s for s in statements if isinstance(s, ast.MonitorStmt)]
        self.transition_stmts = [s for s in statements if isinstance(s, ast.TransitionStmt)]
        self.blend_stmts = [s for s in statements if isinstance(s, ast.BlendStmt)]
        self.names: dict[str, ast.Span] = {}
        self.phases: dict[str, ast.PhaseStmt] = {}
        self.captures: dict[str, ir.Capture] = {}
        self.conditions = Conditions(resolver, {s.name.text for s in self.monitor_stmts})

    @property
    def empty(self) -> bool:
        return not (self.phase_stmts or self.monitor_stmts or self.transition_stmts or self.blend_stmts)

    # ------------------------------------------------------------------------------------------ names
    def declare(self) -> dict[str, ir.Capture]:
        """Every phase, monitor and capture name (checked against each other and the declarations), and the
        captures read; the names of failed captures are marked failed in the resolver."""
        errors = self.resolver.errors
        for stmt in self.phase_stmts:
            with errors.each() as named:
                self._name(stmt.name, "phase")
            if not named.failed:
                self.phases[stmt.name.text] = stmt
        for stmt in self.monitor_stmts:
            with errors.each():
                self._name(stmt.name, "monitor")
        for phase in self.phase_stmts:
            for stmt in phase.body:
                if isinstance(stmt, ast.CaptureStmt):
                    with errors.each() as captured:
                        self._name(stmt.name, "capture")
                        self.captures[stmt.name.text] = self._capture(stmt)
                    if captured.failed and stmt.name.text not in self.captures:
                        self.resolver.failed.add(stmt.name.text)
        return self.captures

    def _name(self, name: ast.Name, what: str) -> None:
        first = self.names.get(name.text) or getattr(self.resolver.declared.get(name.text), "span", None)
        if first is not None:
            raise VfError(f"{what} '{name.text}' is declared twice", name.span, hint=f"first declared at {first}",
                          code="E805")
        if what == "monitor" and name.text in RESERVED:
            raise VfError(f"'{name.text}' is a measure; a monitor cannot take its name", name.span, code="E805")
        self.names[name.text] = name.span

    def _capture(self, stmt: ast.CaptureStmt) -> ir.Capture:
        """``capture NAME = FRAME.position | FRAME.axis | FRAME.pose | INPUT | PARAM``."""
        r = self.resolver
        source, part = stmt.source.text, stmt.field
        if source in r.frames:
            if part is None or part.text not in _FRAME_PARTS:
                where = part.span if part is not None else stmt.source.span
                raise VfError(f"a capture of frame '{source}' reads its position, its axis or its pose", where,
                              hint=f"capture {stmt.name.text} = {source}.position (or {source}.axis, {source}.pose)",
                              code="E809")
            return ir.Capture(name=stmt.name.text, kind=_FRAME_PARTS[part.text], span=stmt.span,
                              source=ir.FrameMeasure(frame=source, part=part.text))
        if source in r.failed:
            raise Dependent
        if source in r.inputs or source in r.params:
            if part is not None:
                raise VfError(f"'{source}' has no part '{part.text}' to capture", part.span,
                              hint=f"capture the whole value: capture {stmt.name.text} = {source}", code="E809")
            if source in r.inputs:
                return ir.Capture(name=stmt.name.text, kind=r.inputs[source].type, span=stmt.span,
                                  source=ir.InputRef(name=source))
            kind = r.params[source].type
            if kind in UNCAPTURED:
                raise VfError(f"a {kind} param cannot be captured: '{source}' is read where it is used",
                              stmt.source.span,
                              hint=f"use {source} itself in the phase's statements ({UNCAPTURED[kind]})", code="E809")
            return ir.Capture(name=stmt.name.text, kind=kind, span=stmt.span, source=ir.ParamRef(name=source))
        raise VfError(f"cannot capture '{source}': it is not a frame, an input or a param", stmt.source.span,
                      hint=suggest(source, [*r.frames, *r.inputs, *r.params], "frames, inputs and params"),
                      code="E809")

    # ----------------------------------------------------------------------------------------- phases
    def read_phases(self, statements: Statements) -> list[ir.Phase]:
        """Each phase with its own statements (read in a scope that sees the captures)."""
        errors = self.resolver.errors
        with errors.each():
            self._initial()
        scope = fx.Scope(units=self.resolver.units, captures=True)
        phases = []
        for name, stmt in self.phases.items():
            body = [s for s in stmt.body if not isinstance(s, ast.CaptureStmt)]
            objectives, constraints = statements(body, scope)
            phases.append(ir.Phase(name=name, initial=stmt.initial is not None, final=stmt.final is not None,
                                   constraints=constraints, objectives=objectives, span=stmt.span,
                                   captures=[self.captures[s.name.text] for s in stmt.body
                                             if isinstance(s, ast.CaptureStmt) and s.name.text in self.captures]))
        return phases

    def _initial(self) -> None:
        if not self.phase_stmts:
            return
        initial = [s for s in self.phase_stmts if s.initial is not None]
        if not initial:
            first = self.phase_stmts[0]
            raise VfError("no initial phase: the procedure cannot start", first.name.span,
                          hint=f"mark the phase it starts in: phase {first.name.text} initial {{ ... }}", code="E802")
        if len(initial) > 1:
            raise VfError(f"two initial phases: '{initial[0].name.text}' and '{initial[1].name.text}'",
                          initial[1].initial, hint=f"the first is marked at {initial[0].initial}; a procedure "
                                                   "starts in one phase", code="E802")

    # ----------------------------------------------------------------------------- monitors, transitions
    def read_monitors(self) -> list[ir.Monitor]:
        errors = self.resolver.errors
        monitors = []
        for stmt in self.monitor_stmts:
            with errors.each():
                monitors.append(self.conditions.monitor(stmt))
        with errors.each():
            Conditions.cycles(monitors)
        return monitors

    def read_blend(self) -> float:
        """The task's default blend time (s)."""
        if len(self.blend_stmts) > 1:
            raise VfError("a second `blend` statement", self.blend_stmts[1].span,
                          hint=f"the first is at {self.blend_stmts[0].span}; give a transition its own with "
                               "`transition A -> B when ... blend 100 ms`", code="E805")
        if not self.blend_stmts:
            return 0.0
        return self.conditions.duration(self.blend_stmts[0].value, "a blend", positive=False)

    def read_transitions(self, blend: float) -> list[ir.Transition]:
        errors = self.resolver.errors
        transitions = []
        for order, stmt in enumerate(self.transition_stmts):
            with errors.each() as ends:
                self._ends(stmt)
            with errors.each() as guarded:
                guard = self.conditions.condition(stmt.guard)
            with errors.each() as blended:
                own = blend if stmt.blend is None else self.conditions.duration(stmt.blend, "a blend", positive=False)
            if not (ends.failed or guarded.failed or blended.failed):
                transitions.append(ir.Transition(source=stmt.source.text if stmt.source else None,
                                                 target=stmt.target.text, guard=guard, blend=own, order=order,
                                                 text=stmt.guard_text, span=stmt.span))
        return transitions

    def _ends(self, stmt: ast.TransitionStmt) -> None:
        """Its phases are known; it leaves no final phase and does not return to its source."""
        for end in (stmt.source, stmt.target):
            if end is not None and end.text not in self.phases:
                if end.text in self.names or end.text in self.resolver.declared:
                    hint = f"'{end.text}' is not a phase; " + suggest(end.text, self.phases, "phases")
                else:
                    hint = suggest(end.text, self.phases, "phases")
                raise VfError(f"unknown phase '{end.text}'", end.span, hint=hint, code="E801")
        if stmt.source is None:
            return
        if self.phases[stmt.source.text].final is not None:
            raise VfError(f"a transition out of final phase '{stmt.source.text}'", stmt.source.span,
                          hint=f"a final phase ends the procedure (marked at {self.phases[stmt.source.text].final}); "
                               "remove `final` to continue from it", code="E803")
        if stmt.source.text == stmt.target.text:
            raise VfError(f"a transition from phase '{stmt.source.text}' to itself", stmt.target.span,
                          hint="a phase is entered once per transition into it; to restart its timer or captures, "
                               "pass through another phase", code="E804")
