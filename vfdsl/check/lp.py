"""Linear programs over one tick's motion dq, solved with HiGHS (scipy.optimize.linprog).

A :class:`LinearSystem` is a set of constraints' rows at one state: general rows lb <= A dq <= ub and the
joint box lo <= dq <= hi (joint limits and speeds, intersected). Its *margin* is

    t* = max t   subject to   lb + t <= A dq <= ub - t  (finite sides),   lo <= dq <= hi,   t <= T_CAP

the amount by which every row could hold with room to spare (SI units of the rows: m or rad). t* >= 0
means the rows can all hold; t* < 0 means they cannot, and -t* is the smallest uniform violation that
makes them hold. The box is kept hard (a crossed box, lo > hi, is infeasible outright).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vfdsl.check.linearized import ConstraintRows

T_CAP = 1.0                          # m or rad: a margin this large means "far from every row"
FEASIBLE = -1e-10                    # margins above this count as feasible (LP noise)
_HIGHS = {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}


def linprog(c, **options):
    """scipy.optimize.linprog, imported at the first call (~0.5 s to import, and only ``check`` solves LPs)."""
    from scipy.optimize import linprog as highs

    return highs(c, **options)


@dataclass(frozen=True)
class LinearSystem:
    A: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    @classmethod
    def from_rows(cls, rows: list[ConstraintRows], nq: int, speed: np.ndarray | None = None) -> "LinearSystem":
        """General rows from the geometric constraints; per-joint bounds intersected into the box, with
        |dq| <= ``speed`` (the URDF's velocity limits over one tick, when the task states no joint_speed)."""
        lo, hi = np.full(nq, -np.inf), np.full(nq, np.inf)
        if speed is not None:
            lo, hi = -np.asarray(speed, dtype=float), np.asarray(speed, dtype=float)
        A, lb, ub = [np.zeros((0, nq))], [np.zeros(0)], [np.zeros(0)]
        for r in rows:
            if r.bounds:
                joints = np.argmax(r.A, axis=1)
                lo[joints] = np.maximum(lo[joints], r.lb)
                hi[joints] = np.minimum(hi[joints], r.ub)
            else:
                A.append(r.A)
                lb.append(r.lb)
                ub.append(r.ub)
        return cls(np.vstack(A), np.concatenate(lb), np.concatenate(ub), lo, hi)

    @property
    def nq(self) -> int:
        return len(self.lo)

    def _inequalities(self) -> tuple[np.ndarray, np.ndarray]:
        """A_ub x <= b_ub over x = [dq; t] for the rows with margin t."""
        low, up = np.isfinite(self.lb), np.isfinite(self.ub)
        A_low = np.hstack([-self.A[low], np.ones((low.sum(), 1))])          # -a dq + t <= -lb
        A_up = np.hstack([self.A[up], np.ones((up.sum(), 1))])              #  a dq + t <= ub
        return np.vstack([A_low, A_up]), np.concatenate([-self.lb[low], self.ub[up]])

    def _box(self) -> list[tuple[float | None, float | None]]:
        return [(None if not np.isfinite(a) else a, None if not np.isfinite(b) else b)
                for a, b in zip(self.lo, self.hi)]

    def margin(self) -> tuple[float, np.ndarray | None]:
        """(t*, the dq that achieves it); (-inf, None) when the box itself is crossed."""
        if np.any(self.lo > self.hi):
            return -float(np.max(self.lo - self.hi)), None
        A_ub, b_ub = self._inequalities()
        c = np.zeros(self.nq + 1)
        c[-1] = -1.0
        result = linprog(c, A_ub=A_ub if len(b_ub) else None, b_ub=b_ub if len(b_ub) else None,
                         bounds=self._box() + [(None, T_CAP)], method="highs", options=_HIGHS)
        if result.status != 0:          # cannot happen for this LP (x = [clipped 0, very negative t] is feasible)
            raise RuntimeError(f"margin LP failed: {result.message}")
        return float(result.x[-1]), result.x[:-1]

    def feasible(self) -> bool:
        return self.margin()[0] >= FEASIBLE

    def reach(self, direction: np.ndarray) -> float:
        """max direction . dq over the system (inf when unbounded)."""
        A_ub = np.vstack([-self.A[np.isfinite(self.lb)], self.A[np.isfinite(self.ub)]])
        b_ub = np.concatenate([-self.lb[np.isfinite(self.lb)], self.ub[np.isfinite(self.ub)]])
        result = linprog(-direction, A_ub=A_ub if len(b_ub) else None, b_ub=b_ub if len(b_ub) else None,
                         bounds=self._box(), method="highs", options=_HIGHS)
        if result.status == 3:
            return np.inf
        if result.status != 0:
            return -np.inf              # infeasible: no motion at all
        return float(-result.fun)
