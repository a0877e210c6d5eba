"""The one error type users see, and how it is printed.

Every mistake a user can make (syntax, unknown names, units, shapes, imports, bad runtime inputs) raises
:class:`VfError`. It carries the source position when there is one, and renders like a compiler
diagnostic::

    tasks/x.vf:12:9: error: unknown frame 'tpi'
       12 | require tpi stays_at(pivot) within 1 um
          |         ^^^
    hint: did you mean 'tip'? known frames: tip, shaft
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable


@dataclass(frozen=True)
class SourcePos:
    """A 1-based position range in a source file (end is exclusive, like Lark's)."""

    file: str
    line: int
    column: int
    end_line: int | None = None
    end_column: int | None = None

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}"


class VfError(Exception):
    """A user-facing error: message, optional position, optional hint."""

    def __init__(self, message: str, pos: SourcePos | None = None, hint: str | None = None,
                 source_text: str | None = None):
        super().__init__(message)
        self.message = message
        self.pos = pos
        self.hint = hint
        self._source_text = source_text

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
            lines.append(f" {number} | {src_line}")
            lines.append(f" {gutter} | {' ' * (self.pos.column - 1)}{'^' * width}")
        if self.hint:
            lines.append(f"hint: {self.hint}")
        return "\n".join(lines)

    def _source_line(self) -> str | None:
        if self.pos is None:
            return None
        text = self._source_text
        if text is None:
            try:
                text = Path(self.pos.file).read_text()
            except OSError:
                return None
        all_lines = text.splitlines()
        if 1 <= self.pos.line <= len(all_lines):
            return all_lines[self.pos.line - 1].rstrip("\n")
        return None

    def __str__(self) -> str:
        return self.render()


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
