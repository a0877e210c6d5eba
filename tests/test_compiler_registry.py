"""The compiler finds primitives and objective terms through vfdsl.compiler.registry, below both packages: every
one is registered with its own module's signature and lowering, and no compiler module imports them."""

from __future__ import annotations

import ast
import importlib

import pytest
from conftest import REPO

from vfdsl.compiler import registry
from vfdsl.objectives import OBJECTIVES
from vfdsl.primitives import CONSTRAINTS

@pytest.mark.parametrize("kind", ["primitives", "objectives"])
def test_every_lowering_is_registered_with_its_module(kind):
    """Every primitive (objective term) is registered with its spec and its own module's lower."""
    table, specs, lookup = ((registry.CONSTRAINTS, CONSTRAINTS, registry.constraint) if kind == "primitives"
                            else (registry.OBJECTIVES, OBJECTIVES, registry.objective))
    assert set(table) == set(specs)
    for name, spec in specs.items():
        lowering = lookup(name)
        assert lowering.spec is spec
        assert lowering.lower is importlib.import_module(f"vfdsl.{kind}.{name}").lower


def test_an_unregistered_name_is_named():
    with pytest.raises(LookupError, match="primitive 'no_such_primitive'"):
        registry.constraint("no_such_primitive")
    with pytest.raises(LookupError, match="objective term 'no_such_term'"):
        registry.objective("no_such_term")


def _imported_modules(path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
            if node.module == "vfdsl":                    # from vfdsl import primitives
                names.update(f"vfdsl.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
    return names


def test_the_compiler_imports_neither_primitives_nor_objectives():
    upward = {(path.name, name)
              for path in sorted((REPO / "vfdsl" / "compiler").glob("*.py"))
              for name in _imported_modules(path)
              if name.split(".")[:2] in (["vfdsl", "primitives"], ["vfdsl", "objectives"])}
    assert upward == set()
