"""Scene files: the YAML data a task needs but that is not part of its logic.

    units: mm, deg            # units of bare numbers in this file (default: the task's units)
    period: 10 ms             # control period
    start: {x: 0, y: 0, z: 0, rcm_a: 0, rcm_b: 0, roll: 0, insert: 10}   # or a list in joint order
    params:                   # values of the task's params (override the task file's defaults)
      plate: {translation: [120, 0, 40], rpy: [0, 0, 30]}
      path: [[0, 0, 0], [10, 5, 0], ...]
      bone: anatomy/bone.stl  # a mesh: its file, relative to this file; or {file: ..., unit: 1 mm}

YAML values are turned into the same syntax nodes a ``.vf`` file produces (a list is a vector, a mapping is
a composite such as ``pose(...)``, ``"10 mm"`` is a number with a unit; in ``params``, other text is a string:
a mesh's file name), with positions in the YAML file, so they go through exactly the same unit and shape checks
and their errors point into the scene file.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import yaml

from vfdsl.errors import Span, VfError, suggest
from vfdsl import limits
from vfdsl.files import BoundedLoader, read_text
from vfdsl.units import DefaultUnits, default_units
from vfdsl.syntax import ast

_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z][A-Za-z*/]*)?\s*$")
_TOP_KEYS = ("units", "period", "start", "params")


@dataclass(frozen=True)
class SceneData:
    file: Path
    units: DefaultUnits
    period: ast.Value | None
    start: ast.Value | dict[str, tuple[ast.Value, ast.Span]] | None   # a list, or joint -> (value, key span)
    start_span: ast.Span | None
    params: dict[str, tuple[ast.Value, ast.Span]]        # value, and the span of its key


def load_scene(path: Path, task_units: DefaultUnits, pos: Span | None) -> SceneData:
    if path.suffix not in (".yaml", ".yml"):
        raise VfError(f"a scene file is YAML (.yaml or .yml), not '{path.name}'", pos, code="E602")
    text = read_text(path, "scene file", pos,
                     hint="write it, or point the task at another file with `scene \"file.yaml\"`")
    root = compose(text, path)
    file = str(path)
    if root is None:
        return SceneData(path, task_units, None, None, None, {})
    if not isinstance(root, yaml.MappingNode):
        raise VfError("a scene file is a mapping with keys " + ", ".join(_TOP_KEYS), node_span(root, file), code="E602")
    top = read_mapping(root, file)
    for key, (key_node, _) in top.items():
        if key not in _TOP_KEYS:
            raise VfError(f"unknown scene key '{key}'", node_span(key_node, file), hint=suggest(key, _TOP_KEYS, "keys"),
                          code="E602")
    values = ValueReader(file)
    units = task_units
    if "units" in top:
        units = read_units(top["units"][1], file, task_units)
    period = values.read(top["period"][1]) if "period" in top else None
    start, start_span = None, None
    if "start" in top:
        node = top["start"][1]
        start_span = node_span(node, file)
        start = ({k: (values.read(v), node_span(kn, file))
                  for k, (kn, v) in read_mapping(node, file).items()}
                 if isinstance(node, yaml.MappingNode) else values.read(node))
    params = {}
    if "params" in top:
        node = top["params"][1]
        if not isinstance(node, yaml.MappingNode):
            raise VfError("'params' is a mapping from param names to values", node_span(node, file), code="E602")
        params = {k: (values.read(v, text=True), node_span(kn, file))
                  for k, (kn, v) in read_mapping(node, file).items()}
    return SceneData(path, units, period, start, start_span, params)


def compose(text: str, path: Path) -> yaml.Node | None:
    """The YAML node tree of a file's text (positions kept); VfError at the line of a YAML mistake."""
    try:
        return yaml.compose(text, Loader=BoundedLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line, column = (mark.line + 1, mark.column + 1) if mark else (1, 1)
        where = Span(file=str(path), line=line, column=column, end_line=line, end_column=column + 1)
        raise VfError(f"malformed YAML: {getattr(exc, 'problem', exc)}", where, source_text=text, code="E602") from None


def read_mapping(node: yaml.MappingNode, file: str) -> dict[str, tuple[yaml.Node, yaml.Node]]:
    """A YAML mapping's entries, key -> (key node, value node); VfError at a key that is not a name or repeated."""
    out = {}
    for key_node, value_node in node.value:
        if not isinstance(key_node, yaml.ScalarNode):
            raise VfError("a key must be a plain name", node_span(key_node, file), code="E602")
        key = str(key_node.value)
        if key in out:
            raise VfError(f"key '{key}' appears twice", node_span(key_node, file), code="E602")
        out[key] = (key_node, value_node)
    return out


def read_units(node: yaml.Node, file: str, base: DefaultUnits) -> DefaultUnits:
    """A scene's ``units:`` entry (``mm, deg`` or ``[mm, deg]``) over the units ``base`` gives."""
    items = node.value if isinstance(node, yaml.SequenceNode) else [node]
    if not all(isinstance(n, yaml.ScalarNode) for n in items):
        raise VfError("units are written as `units: mm, deg` or `units: [mm, deg]`", node_span(node, file), code="E602")
    names = [(name.strip(), node_span(n, file)) for n in items for name in str(n.value).split(",")]
    return default_units(names, base)


class ValueReader:
    """YAML nodes -> the syntax nodes a .vf file would give for the same values, counting every node read so
    that aliases cannot expand a small file into a huge value (at most ``limits.YAML_NODES`` in all)."""

    def __init__(self, file: str):
        self.file = file
        self.nodes = 0

    def read(self, node: yaml.Node, inside: tuple = (), text: bool = False) -> ast.Value:
        """``text``: a scalar that is not a number (with or without a unit) nor true/false is a string (else an
        error)."""
        file = self.file
        span = node_span(node, file)
        self.nodes += 1
        if self.nodes > limits.YAML_NODES:
            raise limits.exceeded("the scene's values are too large (YAML aliases expand them)", limits.YAML_NODES,
                                  span, hint="the limit counts list items and mapping values after "
                                                   "expanding aliases", code="E701")
        if any(node is outer for outer in inside):
            raise VfError("a value cannot contain itself (recursive YAML alias)", span, code="E602")
        inside = inside + (node,)
        if isinstance(node, yaml.SequenceNode):
            return ast.Vector(span=span, items=[self.read(n, inside, text) for n in node.value])
        if isinstance(node, yaml.MappingNode):
            fields = read_mapping(node, file)
            kwargs = [ast.KeywordArg(span=node_span(k, file), name=ast.Name(span=node_span(k, file), text=key),
                                     value=self.read(v, inside, text)) for key, (k, v) in fields.items()]
            return ast.Call(span=span, name=ast.Name(span=span, text="{mapping}"), kwargs=kwargs)
        return _scalar(node, span, text)


def _scalar(node: yaml.ScalarNode, span: ast.Span, strings: bool = False) -> ast.Value:
    text = str(node.value)
    if text in ("true", "false"):
        return ast.Bool(span=span, value=text == "true")
    match = _QUANTITY.match(text)
    if match is None and strings:
        return ast.String(span=span, text=text)
    if match is None:
        shown = repr(text) if len(text) <= 40 else repr(text[:40]) + "..."
        raise VfError(f"expected a number (optionally with a unit, like \"10 mm\"), got {shown}", span, code="E602")
    return ast.Quantity(span=span, number=float(match.group(1)), unit=match.group(2))


def node_span(node: yaml.Node, file: str) -> ast.Span:
    """The span of a YAML node in ``file``."""
    start, end = node.start_mark, node.end_mark
    return ast.Span(file=file, line=start.line + 1, column=start.column + 1, end_line=end.line + 1,
                    end_column=end.column + 1)


