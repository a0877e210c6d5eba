"""Limits the front end enforces before any work starts: resource limits and the ranges of clause values.

Resource limits sit far above any real task (about ten times the largest example, or more where a real
task could grow, such as a digitized curve), so that a hostile or mistaken file fails fast with a message
that names the limit instead of taking the machine's time or memory. They are listed in docs/language.md
("Limits"); :func:`exceeded` builds the error.

Clause ranges:

- ``within``: a row of the QP holds to the solver's feasibility tolerance
  (:data:`vfdsl.pipeline.FEASIBILITY_TOLERANCE`), so a tolerance must be at least ``TOLERANCE_MARGIN``
  times that, or the solver's own slack would be a visible part of it; an angle tolerance is below 90 deg.
- ``weight``: a weight is a plain number in [rho, 1/rho], rho = the Hessian floor of the QP
  (:data:`vfdsl.compiler.assemble.HESSIAN_FLOOR`): a smaller weight has less effect than the floor that
  keeps the QP positive definite, and a larger one (1e9 and up) gives Hessian entries whose ratio to the
  floor leaves double precision, long before ``1e308`` overflows to inf and the solve returns NaN.
"""

from __future__ import annotations

import math

from vfdsl.compiler.assemble import HESSIAN_FLOOR
from vfdsl.errors import SourcePos, VfError
from vfdsl.pipeline import FEASIBILITY_TOLERANCE
from vfdsl.primitives.spec import Range

FILE_BYTES = 1_000_000           # a task, library, scene or sidecar file
IMPORT_DEPTH = 16                # libraries importing libraries
IMPORTED_FILES = 256             # files in one program
NESTING = 16                     # brackets and calls inside one value: [[[...]]], f(g(...))
NUMBER_CHARS = 40                # characters of one number literal
NAME_CHARS = 100                 # characters of one name
FIXTURE_DEPTH = 16               # `use` inside a fixture inside a fixture ...
EXPANDED_STATEMENTS = 2_000      # statements after expanding every fixture
CONSTRAINTS = 1_000              # `require` statements after expansion
ROWS = 8_192                     # constraint rows (an upper estimate from the resolutions), joint bounds excluded
RESOLUTION = 64                  # directions per angle of a polytope (64 x 64 at most for a sphere)
CURVE_DEGREE = 9
CURVE_POINTS = 256
YAML_NODES = 100_000             # nodes of a scene after alias expansion
YAML_DEPTH = 16                  # nesting of lists and mappings in a scene

TOLERANCE_MARGIN = 100
WEIGHT = Range(low=HESSIAN_FLOOR, high=float(round(1.0 / HESSIAN_FLOOR)))


def tolerance_range(kind: str) -> Range:
    """Allowed `within` values (SI) of a primitive whose tolerance is a ``kind`` ('length' or 'angle')."""
    low = TOLERANCE_MARGIN * FEASIBILITY_TOLERANCE
    return Range(low=low, high=math.pi / 2, high_open=True) if kind == "angle" else Range(low=low)


def exceeded(what: str, limit: int, pos: SourcePos | None, hint: str | None = None) -> VfError:
    """The error for a resource limit: which one was hit, and its value."""
    return VfError(f"{what}: the limit is {limit:,}", pos,
                   hint=hint or "this limit sits far above any real task; split the task or simplify it")
