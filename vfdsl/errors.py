"""The one error type users see, and how it is printed.

Every mistake a user can make (syntax, unknown names, units, shapes, imports, bad runtime inputs) raises
:class:`VfError`. It carries the source position when there is one, and renders like a compiler
diagnostic::

    tasks/x.vf:12:9: error: unknown frame 'tpi'
       12 | require tpi stays_at(pivot) within 1 um
          |         ^^^
    hint: did you mean 'tip'? known frames: tip, shaft

Notes add context, such as the ``use`` site of a fixture whose body holds the mistake. The source line is
the one the parser counted (lines end at "\n" only, so form feeds, U+0085 and U+2028 stay inside a line),
and the caret copies the line's tabs so that it lines up under tab-indented text.
"""

from __future__ import annotations

import difflib
import unicodedata
from pathlib import Path
from typing import Iterable

from pydantic import BaseModel, ConfigDict

EXIT_USER_ERROR = 2
"""The command line's exit status for a user's mistake (usage, syntax, names, units, files)."""


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
    """A user-facing error: message, optional position, optional hint."""

    def __init__(self, message: str, pos: Span | None = None, hint: str | None = None,
                 source_text: str | None = None, notes: tuple[str, ...] = ()):
        super().__init__(message)
        self.message = message
        self.pos = pos
        self.hint = hint
        self.notes = tuple(notes)
        self._source_text = source_text

    def with_source(self, text: str) -> "VfError":
        """The same error, showing its line from ``text`` (the text as it was parsed)."""
        return VfError(self.message, self.pos, self.hint, text, self.notes)

    def with_note(self, note: str) -> "VfError":
        """The same error with one more note (e.g. the ``use`` site a fixture was expanded from)."""
        return VfError(self.message, self.pos, self.hint, self._source_text, self.notes + (note,))

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
        all_lines = text.split("\n")
        if 1 <= self.pos.line <= len(all_lines):
            return _printable(all_lines[self.pos.line - 1].rstrip("\r"))
        return None

    def __str__(self) -> str:
        return self.render()


_CONTEXT = 80          # characters shown on each side of the caret when a source line is long


def _printable(line: str) -> str:
    """``line`` with every control or line-separator character except tab shown as '?', one for one (so the
    caret keeps its column, and a terminal escape sequence in a file is shown, not obeyed)."""
    return "".join("?" if ch != "\t" and (unicodedata.category(ch) in ("Cc", "Zl", "Zp")) else ch for ch in line)


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
