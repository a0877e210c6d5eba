"""Every independent mistake of a file at once, none that only follows from another.

A check that may fail on its own (one declaration, one statement, one argument or clause of it) runs in
:meth:`Errors.each`, which records its error and lets the next check run. A check that reads what an earlier
one failed to declare (a frame built on a frame whose link is unknown, a constraint on that frame) raises
:class:`Dependent` instead: the earlier error is reported, this one would be its echo. :meth:`Errors.report`
raises what was found as one error (:func:`vfdsl.errors.combined`: sorted by position); an error raised
outside every ``each`` (a limit on the whole file) stops the file there, reported with those found before it.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
from typing import Callable, Iterator

from vfdsl.errors import VfError, combined


class Dependent(Exception):
    """A check that reads a declaration whose own check failed (and was reported)."""


@dataclass
class Outcome:
    """Whether one check of :meth:`Errors.each` failed (its error recorded, or it depended on one that did)."""

    failed: bool = False


class Errors:
    """The errors found so far in one file's checks."""

    def __init__(self):
        self.found: list[VfError] = []

    @contextmanager
    def each(self, note: Callable[[VfError], VfError] | None = None) -> Iterator[Outcome]:
        """One independent check: its error is recorded (passed through ``note``, e.g. the ``use`` sites of a
        fixture), not raised."""
        outcome = Outcome()
        try:
            yield outcome
        except Dependent:
            self._dropped()
            outcome.failed = True
        except VfError as error:
            outcome.failed = True
            self.found.extend(note(e) if note else e for e in error.errors)

    def settle(self, *outcomes: Outcome) -> None:
        """Raise :class:`Dependent` when one of ``outcomes`` failed: what is built from them is not built."""
        if any(o.failed for o in outcomes):
            raise Dependent

    def checkpoint(self) -> None:
        """Stop when errors were found: what follows reads every check before it."""
        if self.found:
            raise Dependent

    @contextmanager
    def report(self) -> Iterator[None]:
        """Run a file's checks, then raise every error found (an error raised here stops the checks)."""
        try:
            yield
        except Dependent:
            self._dropped()
        except VfError as error:
            self.found.extend(error.errors)
        if self.found:
            raise combined(self.found)

    def _dropped(self) -> None:
        """A check is dropped only after an error was found: never silently."""
        if not self.found:
            raise RuntimeError("a check was skipped for a failure that reported no error")
