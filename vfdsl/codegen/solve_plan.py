"""How the generated C calls DAQP for each conic of a step: a typed plan that travels with the Function.

:func:`vfdsl.runtime.qp.build_step_function` makes the conics and their plans together; the build reads the plans
(:func:`plans_of`) to write each conic's DAQP call (:func:`vfdsl.codegen.patch.patch_generated_c`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import casadi as ca

ITER_LIMIT = 500
"""DAQP iterations one solve may take, on both paths (docs/runtime.md, "A bounded tick"; DAQP's default is 10,000):
2.8 x the most any example's solve took (176, benchmarks/daqp_iterations.py). Reaching it fails the solve (with
priority levels: stops at a point of the hard rows), and the tick goes on to its next safe answer."""


@dataclass(frozen=True)
class SolvePlan:
    """One conic's DAQP solve. ``warm_start``: from the previous call's working set (else cold, as CasADi's own
    interface). ``break_points``: the constraint indices where each priority level ends (none: one plain QP);
    ``rho``: the soft rows' weight (:data:`vfdsl.runtime.qp.LEVEL_ATTEMPTS`); ``partial``: a failed level gives the
    answer of the levels above it; ``exact``: the levels are solved exactly where certified (``lexls.c``); ``start``:
    the levels solved from the conic's x0, a point of the hard rows, by the primal active-set method of ``lexls.c``
    alone (DAQP is not called; phase 2's (B))."""
    warm_start: bool = False
    break_points: tuple[int, ...] = ()
    rho: float = 0.0
    partial: bool = False
    exact: bool = False
    start: bool = False


class PlannedFunction(ca.Function):
    """A CasADi Function and the :class:`SolvePlan` of each DAQP conic in it, by conic name."""

    def __init__(self, fn: ca.Function, plans: Mapping[str, SolvePlan]):
        super().__init__(fn)
        self.plans = MappingProxyType(dict(plans))


def plans_of(fn: ca.Function) -> Mapping[str, SolvePlan]:
    """The solve plans ``fn`` carries (none for a plain Function)."""
    return fn.plans if isinstance(fn, PlannedFunction) else MappingProxyType({})


def record(plans: dict[str, SolvePlan], name: str, plan: SolvePlan) -> None:
    """Add conic ``name``'s plan to ``plans``; a name may not stand for two plans in one step."""
    if plans.setdefault(name, plan) != plan:
        raise ValueError(f"two conics named {name!r} with different solve plans")
