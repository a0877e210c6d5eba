"""Syntax errors of a ``.vf`` file as a user reads them: what was found, what the grammar expected there in words
(not terminal names), and a hint where a near-miss is likely (a misspelt keyword, a statement word read as a unit,
a micro sign)."""

from __future__ import annotations

import difflib

from lark import Lark, Token
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken

from vfdsl.errors import Span, VfError, non_finite_name

KEYWORDS = ("task", "library", "units", "import", "scene", "robot", "frame", "input", "param",
            "fixture", "minimize", "require", "use", "monitor", "phase", "transition", "blend")
STATEMENT_KEYWORDS = KEYWORDS[2:] + ("capture",)

_OPERATOR_WORDS = {"'+'", "'-'", "'*'"}
_HINTS_FOR_CHARACTERS = {
    "\u00b5": "write micro as 'u': um, not \u00b5m",
    "\u03bc": "write micro as 'u': um, not \u03bcm",
}

_TERMINAL_WORDS = {
    "NAME": "a name", "SIGNED_NUMBER": "a number", "STRING": 'a quoted string ("...")',
    "RESOLUTION": "a resolution such as 8 or 4x4", "UNIT_OP": "'*' or '/'", "$END": "end of file",
    "COMPARE": "a comparison (<, >, <= or >=)",
}


_MISPLACED = {"capture": "a capture is taken on entry to a phase, inside it: phase NAME { capture s = tip.position }"}
"""Where a statement keyword read in the wrong place belongs."""


def _describe(terminal: str, parser: Lark) -> str:
    if terminal in _TERMINAL_WORDS:
        return _TERMINAL_WORDS[terminal]
    try:
        pattern = parser.get_terminal(terminal).pattern
    except KeyError:
        return terminal.lower()
    return f"'{pattern.value}'" if pattern.type == "str" else terminal.lower()


def syntax_error(exc: UnexpectedInput, text: str, file: str, parser: Lark) -> VfError:
    line, column = max(exc.line, 1), max(exc.column, 1)
    expected = sorted(getattr(exc, "expected", None) or getattr(exc, "allowed", None) or [])
    words = sorted({_describe(t, parser) for t in expected})
    statement_words = [f"'{k}'" for k in STATEMENT_KEYWORDS]
    if sum(w in statement_words for w in words) >= 5:
        words = ["a statement (require, minimize, param, ...)"] + [w for w in words if w not in statement_words]
    if len(words) > 1 and set(words) - _OPERATOR_WORDS:
        words = [w for w in words if w not in _OPERATOR_WORDS]   # an operator may follow any value
    width = 1
    hint = None
    if isinstance(exc, UnexpectedToken) and exc.token.type == "$END" or isinstance(exc, UnexpectedEOF):
        message = "unexpected end of file"
        lines = text.rstrip().split("\n")             # lines as the parser counts them
        line, column = len(lines), len(lines[-1]) + 1
    elif isinstance(exc, UnexpectedToken) and (spelt := _non_finite_before(exc, file)) is not None:
        return spelt.with_source(text)            # `within nan mm`: the unit after a non-finite number
    elif isinstance(exc, UnexpectedToken):
        found = str(exc.token)
        width = max(1, len(found))
        message = f"unexpected {_found_word(exc.token)}"
        candidates = [_describe(t, parser).strip("'") for t in expected]
        if any(k in STATEMENT_KEYWORDS for k in candidates):
            candidates += STATEMENT_KEYWORDS
        close = difflib.get_close_matches(found, candidates, n=1, cutoff=0.6)
        previous = (exc.token_history or [None])[-1]
        swallowed = (difflib.get_close_matches(str(previous), STATEMENT_KEYWORDS, n=1, cutoff=0.75)
                     if previous is not None and previous.type == "NAME" and _starts_line(text, previous) else [])
        if close and close[0] == found:     # the word is right, the place is not
            hint = _MISPLACED.get(found, f"'{found}' cannot stand here")
        elif close:
            hint = f"did you mean '{close[0]}'?"
        elif swallowed:
            hint = (f"'{previous}' (line {previous.line}) was read as a unit; did you mean the statement "
                    f"'{swallowed[0]}'?")
        elif found in _CLAUSE_WORDS and "')'" in words:
            hint = f"is a ')' missing before '{found}'? A call's arguments end with ')', and its clauses follow it"
    elif isinstance(exc, UnexpectedCharacters):
        char = text[exc.pos_in_stream] if 0 <= exc.pos_in_stream < len(text) else "?"
        message = f"unexpected character {char!r}"
        hint = _HINTS_FOR_CHARACTERS.get(char)
        if hint is None and not char.isascii() and char.isalnum():
            hint = "names are ASCII: the letters a-z and A-Z, digits and _ (a name such as 'tip_2')"
    else:  # pragma: no cover - lark has no other UnexpectedInput kinds
        message = "syntax error"
    if words:
        message += "; expected " + _join_or(words)
    pos = Span(file=file, line=line, column=column, end_line=line, end_column=column + width)
    return VfError(message, pos, hint, source_text=text, code="E101")


_CLAUSE_WORDS = ("within", "resolution", "weight", "priority", "soft")


def _non_finite_before(exc: UnexpectedToken, file: str) -> VfError | None:
    """E304 when the unexpected token follows a name that spells a non-finite number (``nan mm``, ``inf deg``): the
    parser read it as a name, after which a unit cannot stand; None otherwise."""
    previous = (exc.token_history or [None])[-1]
    if previous is None or previous.type != "NAME" or exc.token.type != "NAME":
        return None
    end = previous.column + len(previous)
    return non_finite_name(str(previous), Span(file=file, line=previous.line, column=previous.column,
                                               end_line=previous.line, end_column=end))


def _starts_line(text: str, token: Token) -> bool:
    """Only blanks stand before ``token`` on its line (a name there may be a statement keyword misspelt, which the
    parser read as the unit of the line before)."""
    lines = text.split("\n")
    return 0 < token.line <= len(lines) and not lines[token.line - 1][:token.column - 1].strip()


def _found_word(token: Token) -> str:
    if token.type == "NAME":
        return f"name '{token}'"
    if token.type == "SIGNED_NUMBER":
        return f"number {token}"
    if token.type == "STRING":
        return f"string {token}"
    return f"'{token}'"


def _join_or(words: list[str]) -> str:
    if len(words) > 8:
        words = words[:8] + ["..."]
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]
