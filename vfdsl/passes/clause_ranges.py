"""Allowed values of the clauses ``within`` and ``weight`` (the ranges of primitive and objective arguments
are in their SPECs, :mod:`vfdsl.primitives.spec`).

- ``within``: a row of the QP holds to the solver's feasibility tolerance
  (:data:`vfdsl.pipeline.FEASIBILITY_TOLERANCE`; ``LEVELS_TOLERANCE`` on a task with priority levels), so a
  tolerance must be at least ``TOLERANCE_MARGIN`` times the former, or the solver's own slack would be a visible
  part of it; an angle tolerance is below 90 deg, a length tolerance at most :data:`vfdsl.limits.ROW_VALUE` (the
  size of a length argument, :data:`vfdsl.primitives.spec.SIZE`).
- ``weight``: a plain number in [rho, 1/rho], rho the Hessian floor of the QP
  (:data:`vfdsl.compiler.assemble.HESSIAN_FLOOR`): a smaller weight has less effect than the floor that
  keeps the QP positive definite, and a larger one gives Hessian entries whose ratio to the floor leaves
  double precision, long before ``1e308`` overflows to inf and the solve returns NaN.
"""

from __future__ import annotations

import math

from vfdsl import limits
from vfdsl.compiler.assemble import HESSIAN_FLOOR
from vfdsl.pipeline import FEASIBILITY_TOLERANCE
from vfdsl.primitives.spec import Range
from vfdsl.runtime.qp import LEVEL_ACCEPTANCE

TOLERANCE_MARGIN = 100
LEVELS_TOLERANCE = LEVEL_ACCEPTANCE * FEASIBILITY_TOLERANCE
"""What rows hold to on a tick reported OPTIMAL of a task with priority levels (docs/runtime.md, "Feasibility and
agreement, measured"): phase 1 with levels is accepted within LEVEL_ACCEPTANCE times the feasibility tolerance."""
WEIGHT = Range(low=HESSIAN_FLOOR, high=float(round(1.0 / HESSIAN_FLOOR)))


def tolerance_range(kind: str) -> Range:
    """Allowed `within` values (SI) of a primitive whose tolerance is a ``kind`` ('length' or 'angle')."""
    low = TOLERANCE_MARGIN * FEASIBILITY_TOLERANCE
    return (Range(low=low, high=math.pi / 2, high_open=True) if kind == "angle"
            else Range(low=low, high=limits.ROW_VALUE))
