"""Text -> :class:`~vfdsl.syntax.ast.Module`: the Lark parser over ``grammar/vf.lark`` and the tree transformer.

Lark's errors become :class:`~vfdsl.errors.VfError` (:mod:`.syntax_errors`) with the position, what was expected in words, and a
"did you mean" when a keyword is misspelt. A file that does not start like a ``.vf`` file (``task NAME`` or
``library NAME``, or a near miss of those words) is refused without printing any of its text, since it may
be any file on the machine. Before the tree is transformed, nesting of values, number length and name
length are checked against :mod:`vfdsl.limits`, so no recursion can reach Python's own limit.
"""

from __future__ import annotations

import difflib
import json
import re
from functools import lru_cache
from importlib import resources
from pathlib import Path

from lark import Lark, Token, Transformer, Tree, v_args
from lark.exceptions import UnexpectedInput, VisitError

from vfdsl.errors import Span, VfError
from vfdsl import limits
from vfdsl.syntax import ast
from vfdsl.syntax.syntax_errors import syntax_error

_COMMENT = re.compile(r"#[^\n\r\x0b\x0c\x1c-\x1e\x85\u2028\u2029]*")    # as the grammar's COMMENT
_FIRST_WORD = re.compile(rf"(?:\s|{_COMMENT.pattern})*([A-Za-z_]\w*)?")
_LONE_CR = re.compile(r"\r(?!\n)")
_NESTED_RULES = ("vector", "call", "add", "sub", "mul", "neg", "cond_or", "cond_and", "cond_not", "measure_call")


def grammar_path() -> Path:
    """The grammar file the package uses: the copy inside an installed wheel, else the repository's."""
    packaged = resources.files("vfdsl").joinpath("grammar", "vf.lark")
    if packaged.is_file():
        return Path(str(packaged))
    return Path(__file__).resolve().parents[2] / "grammar" / "vf.lark"


@lru_cache(maxsize=1)
def _lark() -> Lark:
    return Lark(grammar_path().read_text(), parser="lalr", lexer="contextual", propagate_positions=True,
                maybe_placeholders=False)


def parse_module(text: str, file: str) -> ast.Module:
    """Parse one ``.vf`` file's text. Raises VfError on any syntax error."""
    parser = _lark()
    text = text.removeprefix("\ufeff")         # a byte-order mark, when the caller read the file itself
    first = _FIRST_WORD.match(text).group(1) or ""
    if not difflib.get_close_matches(first, ["task", "library"], n=1, cutoff=0.6):
        raise VfError(f"{file} is not a .vf file: it does not start with `task NAME` or `library NAME`", code="E102")
    _refuse_lone_carriage_return(text, file)
    try:
        tree = parser.parse(text)
    except UnexpectedInput as exc:
        raise syntax_error(exc, text, file, parser) from None
    _check_limits(tree, text, file)
    try:
        return _ToAst(file, text).transform(tree)
    except VisitError as exc:
        if isinstance(exc.orig_exc, VfError):
            raise exc.orig_exc.with_source(text) from None
        raise


def _refuse_lone_carriage_return(text: str, file: str) -> None:
    """A line ending of a carriage return alone (classic Mac OS) is refused: lines are counted at "\n", so the
    file would be one line, and a comment on it would hide every statement after it."""
    lone = _LONE_CR.search(text)
    if lone:
        line = text.count("\n", 0, lone.start()) + 1
        column = lone.start() - text.rfind("\n", 0, lone.start())
        raise VfError("a carriage return without a newline: lines end with \"\\n\" or \"\\r\\n\"",
                      Span(file=file, line=line, column=column, end_line=line, end_column=column + 1),
                      hint="save the file with Unix (LF) or Windows (CRLF) line endings", code="E101").with_source(text)


def _check_limits(tree: Tree, text: str, file: str) -> None:
    """Nesting of values, and the length of numbers and names (walked with a stack, not recursion)."""
    stack = [(tree, 0)]
    while stack:
        node, depth = stack.pop()
        if node.data in _NESTED_RULES:
            depth += 1
            if depth > limits.NESTING:
                raise limits.exceeded("values nested too deeply", limits.NESTING, _pos_of_meta(node.meta, file),
                                      hint="lists, calls, operators (+ - *) and conditions (and, or, not) nest at "
                                           "most this deep", code="E701") \
                    .with_source(text)
        for child in node.children:
            if isinstance(child, Tree):
                stack.append((child, depth))
            elif isinstance(child, Token):
                too_long = ((limits.NUMBER_CHARS, "number") if child.type in ("SIGNED_NUMBER", "RESOLUTION")
                            else (limits.NAME_CHARS, "name") if child.type == "NAME" else None)
                if too_long and len(child) > too_long[0]:
                    raise limits.exceeded(f"this {too_long[1]} is {len(child):,} characters long", too_long[0],
                                          _span_of_token(child, file), code="E701").with_source(text)


def _pos_of_meta(meta, file: str) -> Span:
    return Span(file=file, line=meta.line, column=meta.column, end_line=meta.end_line, end_column=meta.end_column)


# ------------------------------------------------------------------------------------------- transformer

def _own_blends(statements: list) -> list:
    """A `blend` statement that starts on the line where a transition's guard ends is that transition's own
    blend (newlines are otherwise insignificant: the grammar reads both as statements)."""
    out = []
    for stmt in statements:
        previous = out[-1] if out else None
        if (isinstance(stmt, ast.BlendStmt) and isinstance(previous, ast.TransitionStmt) and previous.blend is None
                and stmt.span.line == previous.guard.span.end_line):
            out[-1] = previous.model_copy(update={"blend": stmt.value, "span": previous.span.model_copy(update={
                "end_line": stmt.span.end_line, "end_column": stmt.span.end_column})})
        else:
            out.append(stmt)
    return out


def _span_of_token(tok: Token, file: str) -> ast.Span:
    return ast.Span(file=file, line=tok.line, column=tok.column, end_line=tok.end_line, end_column=tok.end_column)


def _string_value(tok: Token, file: str) -> str:
    """A quoted string's text: JSON escapes (\\" \\\\ \\n \\uXXXX ...), no control characters."""
    try:
        text = json.loads(tok)
    except json.JSONDecodeError as exc:
        raise VfError(f"malformed string: {exc.msg.lower()}", _span_of_token(tok, file), code="E103") from None
    if any(ord(ch) < 32 for ch in text):
        raise VfError("a string cannot contain control characters", _span_of_token(tok, file), code="E103")
    return text


@v_args(meta=True)
class _ToAst(Transformer):
    """Lark tree -> pydantic AST. One method per grammar rule; positions come from Lark's meta."""

    def __init__(self, file: str, text: str = ""):
        super().__init__()
        self.file = file
        self.lines = text.split("\n")

    def _span(self, meta) -> ast.Span:
        return ast.Span(file=self.file, line=meta.line, column=meta.column, end_line=meta.end_line,
                        end_column=meta.end_column)

    def _name(self, tok: Token) -> ast.Name:
        return ast.Name(span=_span_of_token(tok, self.file), text=str(tok))

    # header and top level
    def start(self, meta, children):
        header_kind, name = children[0]
        return ast.Module(span=self._span(meta), file=self.file, header=header_kind, name=name,
                          statements=_own_blends(children[1:]))

    def task_header(self, meta, children):
        return ("task", self._name(children[0]))

    def library_header(self, meta, children):
        return ("library", self._name(children[0]))

    # declarations
    def units_stmt(self, meta, children):
        return ast.UnitsStmt(span=self._span(meta), names=[self._name(t) for t in children])

    def import_stmt(self, meta, children):
        return ast.ImportStmt(span=self._span(meta), path=_string_value(children[0], self.file))

    def scene_stmt(self, meta, children):
        return ast.SceneStmt(span=self._span(meta), path=_string_value(children[0], self.file))

    def robot_stmt(self, meta, children):
        return ast.RobotStmt(span=self._span(meta), name=self._name(children[0]), urdf=_string_value(children[1], self.file))

    def link_frame(self, meta, children):
        name, robot, link, *clauses = children
        return ast.FrameStmt(span=self._span(meta), name=self._name(name), robot=self._name(robot),
                             link=ast.Name(span=_span_of_token(link, self.file), text=_string_value(link, self.file)),
                             **self._frame_clauses(clauses))

    def derived_frame(self, meta, children):
        name, base, *clauses = children
        return ast.FrameStmt(span=self._span(meta), name=self._name(name), base=self._name(base),
                             **self._frame_clauses(clauses))

    @staticmethod
    def _frame_clauses(clauses) -> dict:
        fields = {}
        for key, value in clauses:
            if key in fields:
                raise VfError(f"the '{key}' clause is given twice", value.span, code="E104")
            fields[key] = value
        return fields

    def offset_clause(self, meta, children):
        return ("offset", children[0])

    def rotate_clause(self, meta, children):
        return ("rotate", children[0])

    def axis_clause(self, meta, children):
        return ("axis", children[0])

    def input_stmt(self, meta, children):
        return ast.InputStmt(span=self._span(meta), name=self._name(children[0]), type=self._name(children[1]))

    def param_stmt(self, meta, children):
        name, (type_name, type_args), *rest = children
        frame = next((c[1] for c in rest if isinstance(c, tuple) and c[0] == "in"), None)
        default = next((c[1] for c in rest if isinstance(c, tuple) and c[0] == "="), None)
        return ast.ParamStmt(span=self._span(meta), name=self._name(name), type=type_name, type_args=type_args,
                             frame=frame, default=default)

    def type_spec(self, meta, children):
        name = self._name(children[0])
        args, kwargs = children[1] if len(children) > 1 else ([], [])
        if args:
            raise VfError("type arguments must be named, e.g. curve(degree = 5)", args[0].span, code="E105")
        return (name, kwargs)

    def param_frame(self, meta, children):
        return ("in", self._name(children[0]))

    def param_default(self, meta, children):
        return ("=", children[0])

    # statements with clauses
    def _clauses(self, items) -> ast.Clauses:
        fields: dict = {}
        for key, value, span in items:
            if key in fields:
                raise VfError(f"the '{key}' clause is given twice", span, code="E104")
            fields[key] = value
        return ast.Clauses(**fields)

    def minimize_stmt(self, meta, children):
        return ast.MinimizeStmt(span=self._span(meta), call=children[0], clauses=self._clauses(children[1:]))

    def frame_require(self, meta, children):
        return ast.RequireStmt(span=self._span(meta), subject=self._name(children[0]), call=children[1],
                               clauses=self._clauses(children[2:]))

    def global_require(self, meta, children):
        return ast.RequireStmt(span=self._span(meta), subject=None, call=children[0],
                               clauses=self._clauses(children[1:]))

    def use_stmt(self, meta, children):
        return ast.UseStmt(span=self._span(meta), call=children[0], clauses=self._clauses(children[1:]))

    def within_clause(self, meta, children):
        return ("within", children[0], self._span(meta))

    def weight_clause(self, meta, children):
        return ("weight", children[0], self._span(meta))

    def priority_clause(self, meta, children):
        return ("priority", children[0], self._span(meta))

    def soft_clause(self, meta, children):
        span = self._span(meta)
        return ("soft", span, span)

    def resolution_clause(self, meta, children):
        tok = children[0]
        span = _span_of_token(tok, self.file)
        counts = [int(part) for part in str(tok).replace(" ", "").split("x")]
        return ("resolution", ast.Resolution(span=span, counts=counts), self._span(meta))

    # fixtures
    def fixture_def(self, meta, children):
        name = self._name(children[0])
        formals = [c for c in children[1:] if isinstance(c, ast.Formal)]
        body = [c for c in children[1:] if c is not None and not isinstance(c, ast.Formal)]
        return ast.FixtureDef(span=self._span(meta), name=name, formals=formals, body=body)

    def formal(self, meta, children):
        default = children[2][1] if len(children) > 2 else None
        return ast.Formal(span=self._span(meta), name=self._name(children[0]), type=self._name(children[1]),
                          default=default)

    # values
    def call(self, meta, children):
        args, kwargs = children[1] if len(children) > 1 else ([], [])
        return ast.Call(span=self._span(meta), name=self._name(children[0]), args=args, kwargs=kwargs)

    def arguments(self, meta, children):
        args, kwargs = [], []
        for child in children:
            if isinstance(child, ast.KeywordArg):
                if any(k.name.text == child.name.text for k in kwargs):
                    raise VfError(f"argument '{child.name.text}' is given twice", child.name.span, code="E104")
                kwargs.append(child)
            elif kwargs:
                raise VfError("a positional argument cannot follow a keyword argument", child.span, code="E105")
            else:
                args.append(child)
        return (args, kwargs)

    def keyword_argument(self, meta, children):
        return ast.KeywordArg(span=self._span(meta), name=self._name(children[0]), value=children[1])

    def quantity(self, meta, children):
        unit = children[1] if len(children) > 1 else None
        return ast.Quantity(span=self._span(meta), number=float(children[0]), unit=unit)

    def vector(self, meta, children):
        unit = children[-1] if children and isinstance(children[-1], str) else None
        items = [c for c in children if c is not None and not isinstance(c, str)]
        return ast.Vector(span=self._span(meta), items=items, unit=unit)

    def _binary(self, meta, children, op: str):
        return ast.BinOp(span=self._span(meta), op=op, left=children[0], right=children[1])

    def add(self, meta, children):
        return self._binary(meta, children, "+")

    def sub(self, meta, children):
        return self._binary(meta, children, "-")

    def mul(self, meta, children):
        return self._binary(meta, children, "*")

    def neg(self, meta, children):
        operand = children[0]
        if isinstance(operand, ast.Quantity):        # - 5 mm is the number -5 mm
            return operand.model_copy(update={"number": -operand.number, "span": self._span(meta)})
        return ast.Neg(span=self._span(meta), operand=operand)

    def unit(self, meta, children):
        return "".join(str(c) for c in children)

    def name_ref(self, meta, children):
        return ast.NameRef(span=self._span(meta), name=str(children[0]))

    def string(self, meta, children):
        return ast.String(span=self._span(meta), text=_string_value(children[0], self.file))

    def true(self, meta, children):
        return ast.Bool(span=self._span(meta), value=True)

    def false(self, meta, children):
        return ast.Bool(span=self._span(meta), value=False)

    # procedures
    def monitor_stmt(self, meta, children):
        hold = children[2] if len(children) > 2 else None
        return ast.MonitorStmt(span=self._span(meta), name=self._name(children[0]), condition=children[1],
                               text=self._text(children[1].span), hold=hold)

    def hold(self, meta, children):
        return children[0]

    def phase_stmt(self, meta, children):
        name, *rest = children
        marks = {}
        for item in rest:
            if isinstance(item, tuple):
                if item[0] in marks:
                    raise VfError(f"phase '{name}' is marked `{item[0]}` twice", item[1], code="E104")
                marks[item[0]] = item[1]
        body = [item for item in rest if not isinstance(item, tuple)]
        return ast.PhaseStmt(span=self._span(meta), name=self._name(name), body=body, **marks)

    def initial_mark(self, meta, children):
        return ("initial", self._span(meta))

    def final_mark(self, meta, children):
        return ("final", self._span(meta))

    def capture_stmt(self, meta, children):
        field = self._name(children[2]) if len(children) > 2 else None
        return ast.CaptureStmt(span=self._span(meta), name=self._name(children[0]), source=self._name(children[1]),
                               field=field)

    def transition_stmt(self, meta, children):
        (source, source_span), target, guard = children
        return ast.TransitionStmt(span=self._span(meta), source=source, source_span=source_span,
                                  target=self._name(target), guard=guard, guard_text=self._text(guard.span))

    def transition_source(self, meta, children):
        return (self._name(children[0]), self._span(meta))

    def any_phase(self, meta, children):
        return (None, self._span(meta))

    def blend_stmt(self, meta, children):
        return ast.BlendStmt(span=self._span(meta), value=children[0])

    def _text(self, span: ast.Span) -> str:
        """The source text of ``span``, its whitespace collapsed to single spaces."""
        lines = self.lines[span.line - 1:span.end_line]
        lines[-1] = lines[-1][:span.end_column - 1]
        lines[0] = lines[0][span.column - 1:]
        return " ".join(" ".join(_COMMENT.sub("", line) for line in lines).split())

    def _logic(self, meta, op, children):
        items = []
        for child in children:        # a chain of one operator is one node: a or b or c
            items.extend(child.items if isinstance(child, ast.Logic) and child.cond == op != "not" else [child])
        return ast.Logic(span=self._span(meta), cond=op, items=items)

    def cond_or(self, meta, children):
        return self._logic(meta, "or", children)

    def cond_and(self, meta, children):
        return self._logic(meta, "and", children)

    def cond_not(self, meta, children):
        return self._logic(meta, "not", children)

    def cond_test(self, meta, children):
        return ast.Test(span=self._span(meta), measure=children[0])

    def comparison(self, meta, children):
        measure, op, threshold, *release = children
        return ast.Comparison(span=self._span(meta), measure=measure, op=str(op), threshold=threshold,
                              release=release[0] if release else None)

    def release(self, meta, children):
        return children[0]

    def measure_name(self, meta, children):
        return ast.Measure(span=self._span(meta), name=self._name(children[0]))

    def measure_call(self, meta, children):
        return ast.Measure(span=self._span(meta), name=self._name(children[0]),
                           args=[c for c in children[1:] if c is not None])

    def member(self, meta, children):
        return ast.Member(span=self._span(meta), base=self._name(children[0]), field=self._name(children[1]))
