"""Reusable fixtures: named, parameterized groups of constraints and objectives, and their expansion.

    fixture virtual_rcm(f: frame, pivot: point, eps: length = 1 um) {
        require f stays_at(pivot) within eps resolution 4x4
    }
    use virtual_rcm(tip, pivot)

Scoping is lexical: a fixture body sees only its formals (not the names of the task that uses it), and the
literals in its body keep the units of the file that defines it. ``use`` binds each actual argument, checked
against the formal's kind at the use site; expansion is recursive, and a fixture that uses itself (directly
or not) is an error. Every expanded statement records the chain of ``use`` sites in ``via``, and an error in
a fixture body names the ``use`` sites it was reached through. Expansion is bounded: at most
``limits.FIXTURE_DEPTH`` nested uses and ``limits.EXPANDED_STATEMENTS`` statements in all.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from vfdsl.errors import VfError, suggest
from vfdsl.ir import model as ir
from vfdsl import limits
from vfdsl.passes.calls import bind_arguments
from vfdsl.passes.diagnostics import Dependent, Errors
from vfdsl.units import DefaultUnits
from vfdsl.primitives.spec import ARG_KINDS, REQUIRED, ArgSpec
from vfdsl.syntax import ast

FORMAL_KINDS = tuple(k for k in ARG_KINDS if k not in ("gain", "angular_gain", "choice"))


@dataclass(frozen=True)
class Scope:
    """Where a statement is read: its file's units, (inside a fixture) the bound formals, and whether values
    captured on entry to a phase may be read (in a phase, a monitor or a transition)."""

    units: DefaultUnits
    bindings: dict[str, ir.Arg] | None = None       # None at task level
    fixture: str | None = None
    via: tuple[ast.Span, ...] = field(default=())
    sources: dict[str, ast.Span] = field(default_factory=dict)   # formal -> where its value was written
    captures: bool = False

    def source_span(self, value: ast.Value) -> ast.Span:
        """Where ``value`` was written: for a formal's name, the actual argument at the use (or the default)."""
        if isinstance(value, ast.NameRef) and self.bindings is not None and value.name in self.sources:
            return self.sources[value.name]
        return value.span

    def note(self, error: VfError) -> VfError:
        """``error`` with the chain of ``use`` sites that brought this scope's statements in, innermost first."""
        for span in reversed(self.via):
            error = error.with_note(f"in a fixture used at {span}")
        return error


@dataclass(frozen=True)
class Fixture:
    definition: ast.FixtureDef
    units: DefaultUnits                               # the units of the file that defines it


@dataclass(frozen=True)
class Fixtures:
    """The fixtures of a program by name, and the names of those whose formals are wrong (their uses are not
    checked: the definition's error is reported)."""

    table: dict[str, Fixture]
    failed: set[str]


# evaluate(value, kind, scope) -> the IR argument for that value, checked against kind
Evaluate = Callable[[ast.Value, str, Scope], ir.Arg]


def collect(modules: list[tuple[ast.Module, DefaultUnits]], errors: Errors) -> Fixtures:
    """Every fixture definition, each checked on its own (a second one of a name is an error, the first kept)."""
    fixtures = Fixtures({}, set())
    for module, units in modules:
        for stmt in module.statements:
            if not isinstance(stmt, ast.FixtureDef):
                continue
            with errors.each() as defined:
                if stmt.name.text in fixtures.table:
                    first = fixtures.table[stmt.name.text].definition.name.span
                    raise VfError(f"fixture '{stmt.name.text}' is defined twice", stmt.name.span,
                                  hint=f"first defined at {first}", code="E202")
                fixtures.table[stmt.name.text] = Fixture(stmt, units)
                _check_formals(stmt)
            if defined.failed and fixtures.table[stmt.name.text].definition is stmt:     # its formals are wrong
                fixtures.failed.add(stmt.name.text)
    return fixtures


def _check_formals(fixture: ast.FixtureDef) -> None:
    seen: set[str] = set()
    for formal in fixture.formals:
        if formal.name.text in seen:
            raise VfError(f"formal '{formal.name.text}' appears twice", formal.name.span, code="E202")
        seen.add(formal.name.text)
        if formal.type.text not in FORMAL_KINDS:
            raise VfError(f"unknown kind '{formal.type.text}'", formal.type.span,
                          hint=suggest(formal.type.text, FORMAL_KINDS, "kinds"), code="E205")


def expand(statements: list, scope: Scope, fixtures: Fixtures, evaluate: Evaluate, errors: Errors,
           active: tuple[str, ...] = ()) -> list[tuple[ast.MinimizeStmt | ast.RequireStmt, Scope]]:
    """Replace every ``use`` by its fixture's body, recursively; keep minimize/require with their scope. A
    ``use`` that fails to bind is recorded in ``errors`` and brings nothing in."""
    out: list[tuple[ast.MinimizeStmt | ast.RequireStmt, Scope]] = []
    for stmt in statements:
        if isinstance(stmt, (ast.MinimizeStmt, ast.RequireStmt)):
            out.append((stmt, scope))
        elif isinstance(stmt, ast.UseStmt):
            with errors.each(scope.note) as used:
                inner = _bind_use(stmt, scope, fixtures, evaluate, active)
            if not used.failed:
                out.extend(expand(fixtures.table[inner.fixture].definition.body, inner, fixtures, evaluate, errors,
                                  active + (inner.fixture,)))
        if len(out) > limits.EXPANDED_STATEMENTS:
            raise scope.note(limits.exceeded("too many statements after expanding fixtures",
                                             limits.EXPANDED_STATEMENTS, stmt.span, code="E701"))
    return out


def _bind_use(use: ast.UseStmt, scope: Scope, fixtures: Fixtures, evaluate: Evaluate,
              active: tuple[str, ...]) -> Scope:
    """The scope of the body of the fixture that ``use`` names, with its formals bound."""
    name = use.call.name
    if name.text in fixtures.failed:
        raise Dependent
    if name.text not in fixtures.table:
        raise VfError(f"unknown fixture '{name.text}'", name.span, hint=suggest(name.text, fixtures.table, "fixtures"),
                      code="E201")
    if name.text in active:
        chain = " -> ".join(active[active.index(name.text):] + (name.text,))
        raise VfError(f"fixture '{name.text}' uses itself: {chain}", use.span, code="E605")
    if len(active) >= limits.FIXTURE_DEPTH:
        raise limits.exceeded("fixtures nested too deeply", limits.FIXTURE_DEPTH, use.span, code="E701")
    clauses = use.clauses
    if clauses.within or clauses.resolution or clauses.weight or clauses.priority or clauses.soft:
        raise VfError("`use` takes no clauses", use.span,
                      hint="put within/resolution/soft/weight/priority on the statements inside the fixture, "
                           "or make them formals of the fixture", code="E502")
    fixture = fixtures.table[name.text]
    formals = [ArgSpec(f.name.text, f.type.text, "", default=f.default if f.default is not None else REQUIRED)
               for f in fixture.definition.formals]
    given = bind_arguments(use.call, [f.name for f in formals], {f.name for f in formals if f.required},
                           f"fixture '{name.text}'")
    definition_scope = Scope(units=fixture.units, bindings={}, fixture=name.text)
    bindings: dict[str, ir.Arg] = {}
    sources: dict[str, ast.Span] = {}
    for formal in formals:
        if formal.name in given:
            bindings[formal.name] = evaluate(given[formal.name], formal.kind, scope)
            sources[formal.name] = scope.source_span(given[formal.name])
        else:
            bindings[formal.name] = evaluate(formal.default, formal.kind, definition_scope)
            sources[formal.name] = formal.default.span
    return Scope(units=fixture.units, bindings=bindings, fixture=name.text, via=scope.via + (use.span,),
                 sources=sources)
