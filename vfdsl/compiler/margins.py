"""A column of checks, written and read through one description.

Each check is a margin m (a CasADi number or symbol) and what it means::

    margins.add(m, Check(...))       # holds iff m is finite and m >= 0 (m > 0 when the check is strict)
    i = margins.first_failure(numbers)                  # -1: every check holds
    raise margins.error(i, numbers, p)                  # the VfError of check i

The writer appends a margin and its :class:`Check` together, so the reader of the evaluated column (in
Python, or the task's generated C through ``strict``) can never take one entry for another.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import casadi as ca
import numpy as np

from vfdsl.errors import Span, VfError


@dataclass(frozen=True)
class Check:
    """What one margin checks: ``message(margin, p)`` says what is wrong (p: the params' numbers, or None)."""

    message: Callable[[float, np.ndarray | None], str]
    meaning: str                     # what the check asks, without numbers (C error strings, metadata)
    pos: Span | None = None     # where the checked expression is written (a derived argument)
    hint: str | None = None
    strict: bool = False             # True: the margin must be > 0, not only >= 0
    param: str | None = None         # the param whose own value is checked (None: a derived argument)
    notes: tuple[str, ...] = ()      # e.g. the fixture's use site of a derived argument written in a library


class Margins:
    """Margins and their checks, in the order they were added."""

    def __init__(self):
        self.column: list = []
        self.checks: list[Check] = []

    def add(self, margin, check: Check) -> None:
        self.column.append(margin)
        self.checks.append(check)

    def __len__(self) -> int:
        return len(self.checks)

    @property
    def strict(self) -> np.ndarray:
        """1 where a check needs a positive margin, else 0 (uint8, for the generated C)."""
        return np.array([c.strict for c in self.checks], dtype=np.uint8)

    @property
    def meanings(self) -> list[str]:
        """What each check asks, without numbers; a derived argument's check starts with its file:line."""
        return [f"{c.pos.file}:{c.pos.line}: {c.meaning}" if c.pos else c.meaning for c in self.checks]

    def symbolic(self):
        """The column as one CasADi vector (0 x 1 when empty)."""
        return ca.vertcat(*self.column) if self.column else ca.SX(0, 1)

    def first_failure(self, numbers) -> int:
        """The index of the first check that fails on the evaluated column, or -1."""
        m = np.asarray(numbers, dtype=float).ravel()
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(m) & np.where(self.strict.astype(bool), m > 0, m >= 0)
        return -1 if ok.all() else int(np.argmin(ok))

    def error(self, i: int, numbers, p: np.ndarray | None = None, when: str = "") -> VfError:
        """Check i's error; ``when`` (e.g. "with params 'a', ") prefixes the messages of derived arguments."""
        check = self.checks[i]
        margin = float(np.asarray(numbers, dtype=float).ravel()[i])
        prefix = "" if check.param else when
        return VfError(prefix + check.message(margin, p), check.pos, hint=check.hint, notes=check.notes)

    def verify(self, numbers, p: np.ndarray | None = None, when: str = "") -> None:
        """Raise the error of the first check that fails."""
        i = self.first_failure(numbers)
        if i >= 0:
            raise self.error(i, numbers, p, when)
