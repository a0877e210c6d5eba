"""How a constraint is named and read outside the compiler: its label (``stays_at(tip)``), its source line with the
``use`` sites it came through, and the value of a constant or param argument before the controller runs. The check's
findings, the viewer and the MCAP markers all name constraints this way."""

from __future__ import annotations

from vfdsl.errors import VfError
from vfdsl.ir import model as ir


def value_of(arg: ir.Arg, task: ir.Task) -> ir.Value:
    """The value of a constant argument, or the default (or scene) value of a param; of a capture of a param, that
    param's (the value it holds from the first tick until its phase is entered)."""
    if isinstance(arg, ir.Const):
        return arg.value
    if isinstance(arg, ir.CaptureRef):
        source = next(c.source for p in task.phases for c in p.captures if c.name == arg.name)
        if not isinstance(source, ir.ParamRef):
            raise VfError(f"capture '{arg.name}' is not a param's value: no value before the controller runs",
                          next(c.span for p in task.phases for c in p.captures if c.name == arg.name))
        return task.param(source.name).value
    return task.param(arg.name).value


def describe(c: ir.Constraint) -> str:
    """How findings name a constraint: ``stays_at(tip)``, ``joint_limits()``, with ``soft`` when it is."""
    return f"{'soft ' if c.soft else ''}{c.primitive}({c.frame or ''})"


def subject(c: ir.Constraint) -> str:
    """The heading findings about ``c`` are grouped under: ``stays_at(tip) at fixtures.vf:10 via task.vf:18``."""
    return f"{describe(c)} at {where(c)}"


def where(c: ir.Constraint) -> str:
    """Its source line, and the ``use`` sites it was expanded through: ``fixtures.vf:10 via task.vf:18``."""
    return " via ".join(f"{span.file.rsplit('/', 1)[-1]}:{span.line}" for span in [c.span, *c.via])
