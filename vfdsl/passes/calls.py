"""Binding a call's arguments to a signature, for every kind of call in the language (primitives, objective
terms, fixtures, composite literals such as ``line(...)``): too many, unknown, repeated, missing."""

from __future__ import annotations

from collections.abc import Collection

from vfdsl.errors import VfError, suggest
from vfdsl.syntax import ast


def bind_arguments(call: ast.Call, names: list[str], required: Collection[str], what: str) -> dict[str, ast.Value]:
    """Match positional then keyword arguments to ``names``; every name in ``required`` must be given."""
    if len(call.args) > len(names):
        extra = call.args[len(names)]
        raise VfError(f"{what} takes {len(names)} argument{'s' if len(names) != 1 else ''}, got {len(call.args)}",
                      extra.span, hint=f"its arguments are: {', '.join(names) or 'none'}", code="E501")
    given: dict[str, ast.Value] = dict(zip(names, call.args))
    for kw in call.kwargs:
        if kw.name.text not in names:
            raise VfError(f"{what} has no argument '{kw.name.text}'", kw.name.span,
                          hint=suggest(kw.name.text, names, "arguments"), code="E501")
        if kw.name.text in given:
            raise VfError(f"argument '{kw.name.text}' is given twice", kw.name.span, code="E104")
        given[kw.name.text] = kw.value
    missing = [n for n in names if n in required and n not in given]
    if missing:
        plural = "s" if len(missing) > 1 else ""
        raise VfError(f"{what} is missing argument{plural} {', '.join(missing)}", call.span,
                      hint=f"its arguments are: {', '.join(names)}", code="E501")
    return given
