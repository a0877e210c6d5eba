"""The one error type users see, and how it is printed.

Every mistake a user can make (syntax, unknown names, units, shapes, imports, bad runtime inputs) raises
:class:`VfError`. It carries the source position when there is one, and renders like a compiler
diagnostic::

    tasks/x.vf:12:9: error: unknown frame 'tpi'
       12 | require tpi stays_at(pivot) within 1 um
          |         ^^^
    hint: did you mean 'tip'? known frames: tip, shaft

Notes add context, such as the ``use`` site of a fixture whose body holds the mistake. The source line is
the one the parser counted (lines end at "\n" only, so form feeds, U+0085 and U+2028 stay inside a line; a
YAML file's lines end where YAML ends them, at "\r", U+0085, U+2028 and U+2029 too),
and the caret copies the line's tabs so that it lines up under tab-indented text.

A mistake in a task, library or scene file has a stable code from :data:`CODES` (``E201``), printed on a last
``code:`` line. The front end reports every independent mistake of a file at once: :func:`combined` makes
one :class:`VfErrors`, sorted by position, which stands for its first error and renders them all.
"""

from __future__ import annotations

import difflib
import re
import unicodedata
from pathlib import Path
from typing import Iterable

from pydantic import BaseModel, ConfigDict

EXIT_USER_ERROR = 2
"""The command line's exit status for a user's mistake (usage, syntax, names, units, files)."""


CODES: dict[str, str] = {
    "E101": "a syntax error: unexpected text, character or end of file",
    "E102": "not a .vf file: it does not start with `task NAME` or `library NAME`",
    "E103": "a malformed string",
    "E104": "a clause or an argument given twice",
    "E105": "an argument in the wrong form: positional after keyword, or an unnamed type argument",
    "E201": "an unknown name: robot, frame, input, param, fixture, formal, link or joint",
    "E202": "declared twice: a name, fixture or formal, or a second `scene` statement",
    "E203": "a name of the wrong kind here (a robot where a frame is expected, a point where a direction is)",
    "E204": "a frame built on itself or on a frame declared after it",
    "E205": "an unknown primitive, objective term, input type, param type or formal kind",
    "E206": "a name where only a value can stand (a run-time param in a constant, any name in a literal)",
    "E301": "an unknown unit",
    "E302": "a value of the wrong dimension (an angle where a length is expected, a unit on a direction)",
    "E303": "a mistake in a `units` statement or entry",
    "E304": "a number that is not finite, or too large for SI units",
    "E401": "a value of the wrong shape (3 numbers for a point, points for a curve)",
    "E402": "a value out of its allowed range (an argument, a tolerance, a weight, a joint, a period)",
    "E403": "derived geometry whose operands do not fit (adding two points, a point where a direction is needed)",
    "E501": "a call with too many, unknown or missing arguments",
    "E502": "a clause that does not apply to this statement",
    "E503": "a statement that does not fit its primitive, term, input or task (a frame on a whole-robot constraint)",
    "E504": "a param with no value: no default, and the scene sets none",
    "E601": "an import that is not a library, not a .vf file, or closes a cycle",
    "E602": "a mistake in a scene file: its YAML, keys or values",
    "E603": "a robot's URDF that cannot be used",
    "E604": "a mesh file that cannot be used",
    "E605": "a fixture that uses itself",
    "E701": "a resource limit exceeded (vfdsl.limits)",
    "E801": "a transition to or from an unknown phase",
    "E802": "a procedure without exactly one initial phase (none, or two)",
    "E803": "a transition out of a final phase",
    "E804": "a transition from a phase to itself",
    "E805": "a phase, monitor or capture name declared twice or taken by a declaration, or a second `blend`",
    "E806": "a monitor's units do not fit: a threshold, `release` or `for` of another dimension, a `release` on "
            "the wrong side",
    "E807": "an unknown monitor or measure in a condition",
    "E808": "monitors that name each other in a cycle",
    "E809": "a capture of an unknown frame, input or param, or of a part it has not",
    "E810": "a captured value used in a statement outside every phase",
    "E811": "a condition that does not fit its measure (comparing a button, a force as a condition, a wrench's norm)",
}
"""Every front-end error's code and its meaning (docs/language.md, "Error codes", lists them too). A code never
changes meaning; a new class of mistake gets a new code."""


class Span(BaseModel):
    """A range of source text: 1-based line and column, end exclusive (like Lark's). Errors, the syntax tree
    and the IR use it (a pydantic model, so the IR serializes it)."""

    model_config = ConfigDict(frozen=True)
    file: str
    line: int
    column: int
    end_line: int
    end_column: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}"


class VfError(Exception):
    """A user-facing error: message, optional position, hint, notes and code (a key of :data:`CODES`)."""

    def __init__(self, message: str, pos: Span | None = None, hint: str | None = None,
                 source_text: str | None = None, notes: tuple[str, ...] = (), code: str | None = None):
        super().__init__(message)
        if code is not None and code not in CODES:
            raise ValueError(f"unknown error code {code!r}")
        self.message = message
        self.pos = pos
        self.hint = hint
        self.notes = tuple(notes)
        self.code = code
        self._source_text = source_text

    @property
    def errors(self) -> tuple["VfError", ...]:
        """The errors this one reports: itself (several for :class:`VfErrors`)."""
        return (self,)

    def with_source(self, text: str) -> "VfError":
        """The same error, showing its line from ``text`` (the text as it was parsed)."""
        return VfError(self.message, self.pos, self.hint, text, self.notes, self.code)

    def with_code(self, code: str) -> "VfError":
        """The same error with ``code`` (a lower module's error, classified where a file's check meets it)."""
        return VfError(self.message, self.pos, self.hint, self._source_text, self.notes, code)

    def with_note(self, note: str) -> "VfError":
        """The same error with one more note (e.g. the ``use`` site a fixture was expanded from)."""
        return VfError(self.message, self.pos, self.hint, self._source_text, self.notes + (note,), self.code)

    @property
    def line(self) -> int | None:
        return self.pos.line if self.pos else None

    @property
    def column(self) -> int | None:
        return self.pos.column if self.pos else None

    def render(self, severity: str = "error") -> str:
        """The diagnostic as a user reads it: location, message, source line with caret, hint.
        ``severity`` names its kind in the head line (``vfdsl check`` also prints warnings and notes)."""
        head = f"{self.pos}: {severity}: {self.message}" if self.pos else f"{severity}: {self.message}"
        lines = [head]
        src_line = self._source_line()
        if src_line is not None and self.pos is not None:
            number = str(self.pos.line)
            gutter = " " * len(number)
            width = 1
            if self.pos.end_line == self.pos.line and self.pos.end_column:
                width = max(1, self.pos.end_column - self.pos.column)
            start = max(0, self.pos.column - 1 - _CONTEXT) if len(src_line) > 2 * _CONTEXT else 0
            shown = ("..." if start else "") + src_line[start:start + 2 * _CONTEXT] \
                + ("..." if len(src_line) > start + 2 * _CONTEXT else "")
            width = min(width, 2 * _CONTEXT - (self.pos.column - 1 - start))
            lead = ("   " if start else "") + "".join(
                ch if ch == "\t" else " " for ch in src_line[start:self.pos.column - 1])
            lines.append(f" {number} | {shown}")
            lines.append(f" {gutter} | {lead}{'^' * width}")
        if self.hint:
            lines.append(f"hint: {self.hint}")
        lines.extend(f"note: {note}" for note in self.notes)
        if self.code:
            lines.append(f"code: {self.code}, {CODES[self.code]}")
        return "\n".join(lines)

    def _source_line(self) -> str | None:
        if self.pos is None:
            return None
        text = self._source_text
        if text is None:
            try:
                text = Path(self.pos.file).read_text(encoding="utf-8-sig")
            except (OSError, ValueError):
                return None
        yaml = Path(self.pos.file).suffix.lower() in (".yaml", ".yml")
        all_lines = _YAML_LINE_BREAK.split(text) if yaml else text.split("\n")
        if 1 <= self.pos.line <= len(all_lines):
            return _printable(all_lines[self.pos.line - 1].rstrip("\r"))
        return None

    def __str__(self) -> str:
        return self.render()


class VfErrors(VfError):
    """Several errors of one file, sorted by position. Its message, position, hint and code are its first
    error's (so a caller that reads one error reads that one); it renders every error, then their count."""

    def __init__(self, errors: list[VfError]):
        first = errors[0]
        super().__init__(first.message, first.pos, first.hint, first._source_text, first.notes, first.code)
        self._errors = tuple(errors)

    @property
    def errors(self) -> tuple[VfError, ...]:
        return self._errors

    def render(self, severity: str = "error") -> str:
        shown = "\n\n".join(error.render(severity) for error in self._errors)
        return f"{shown}\n\n{len(self._errors)} {severity}s"


def combined(errors: list[VfError]) -> VfError:
    """One error for ``errors`` (not empty): the one, or a :class:`VfErrors` of them sorted by file, line and
    column (unpositioned last), an error repeated at the same place with the same message shown once."""
    unique = {(e.pos, e.message): e for e in reversed([e for error in errors for e in error.errors])}
    ordered = sorted(unique.values(), key=lambda e: (e.pos is None,) + ((e.pos.file, e.pos.line, e.pos.column)
                                                                         if e.pos else ()))
    return ordered[0] if len(ordered) == 1 else VfErrors(ordered)


_YAML_LINE_BREAK = re.compile("\r\n|[\r\n\x85\u2028\u2029]")
"""Where YAML ends a line (its positions count these): a scene's line is shown as YAML counted it."""

_CONTEXT = 80          # characters shown on each side of the caret when a source line is long


def _printable(line: str) -> str:
    """``line`` with every control or line-separator character except tab shown as '?', one for one (so the
    caret keeps its column, and a terminal escape sequence in a file is shown, not obeyed)."""
    return "".join("?" if ch != "\t" and (unicodedata.category(ch) in ("Cc", "Zl", "Zp")) else ch for ch in line)


def a_or_an(word: str) -> str:
    """The word with its indefinite article: 'a length', 'an angle', 'an int'."""
    return ("an " if word[:1] in "aeiou" else "a ") + word


NON_FINITE_NAMES = ("nan", "inf", "infinity")


def non_finite_name(name: str, span: Span | None) -> VfError | None:
    """The error for a name that spells a non-finite number (``within nan``, ``weight inf``), where a value stands
    and no declaration has that name; None for any other name. The language has no such numbers (E304)."""
    if name.lower() not in NON_FINITE_NAMES:
        return None
    return VfError(f"'{name}' is not a number: numbers must be finite", span,
                   hint="write a finite number, with its unit where the value has one (e.g. 0.5 mm)", code="E304")


def suggest(name: str, known: Iterable[str], what: str) -> str:
    """A hint for an unknown ``name``: the closest known names, then the full list."""
    known = sorted(set(known))
    if not known:
        return f"none declared ({what})"
    close = difflib.get_close_matches(name, known, n=3, cutoff=0.6)
    listing = ", ".join(known)
    if close:
        quoted = " or ".join(f"'{c}'" for c in close)
        return f"did you mean {quoted}? known {what}: {listing}"
    return f"known {what}: {listing}"


def show_vector(values) -> str:
    """Numbers as a message shows them: ``[10, 5, 285]`` (6 significant digits)."""
    return "[" + ", ".join(f"{float(v):.6g}" for v in values) + "]"
