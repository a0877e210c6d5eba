"""B-spline curves and their closest point, as fixed-cost CasADi expressions (no loops, no branches
that change the operation count, so the same graph can be generated as C).

The curve is the b-spline of the given degree that interpolates the points in order, parametrized by
cumulative chord length s (metres). Closest point to x, every tick:

1. coarse: the nearest of K samples C(s_k), equally spaced in arc length at most ``SAMPLE_SPACING`` apart,
   and the knots (a chain of comparisons);
2. fine: Newton on f(s) = (C(s) - x) . C'(s) = 0, s <- s - f / (|C'|^2 + (C - x) . C''), kept inside the
   bracket [s_(k-1), s_(k+1)] of the nearest sample (which may cross a knot: each step evaluates the span
   its s lies in), a fixed number of times; a step whose curvature term is not positive is not taken;
3. the better of the Newton point and the nearest sample is kept.

With samples much denser than the curve's features the closest point lies in the bracket of the nearest
sample, where (C - x) . C' is monotone, and the steps reach it to rounding error (tested against a
brute-force search).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy.interpolate import make_interp_spline

from vfdsl.compiler.geometry import normalize

NEWTON_STEPS = 6
SAMPLE_SPACING = 1e-3           # metres of arc length between coarse samples
MIN_SAMPLES = 64


@dataclass(frozen=True)
class SplineCurve:
    """A curve as per-span polynomials C(s) = sum_j coeffs[k, j] (s - breaks[k])^j on [breaks[k], breaks[k+1]]."""

    degree: int
    breaks: np.ndarray           # (S + 1,)
    coeffs: np.ndarray           # (S, degree + 1, 3)

    @classmethod
    def interpolate(cls, points: np.ndarray, degree: int) -> "SplineCurve":
        points = np.asarray(points, dtype=float)
        chords = np.linalg.norm(np.diff(points, axis=0), axis=1)
        if np.any(chords < 1e-12):
            raise ValueError("consecutive curve points coincide")
        s = np.concatenate([[0.0], np.cumsum(chords)])
        spline = make_interp_spline(s, points, k=degree)
        breaks = np.unique(spline.t[degree:-degree])
        coeffs = np.array([[spline.derivative(j)(b) / math.factorial(j) if j else spline(b)
                            for j in range(degree + 1)] for b in breaks[:-1]])
        return cls(degree, breaks, coeffs)

    @property
    def length_parameter(self) -> float:
        return float(self.breaks[-1])

    def evaluate(self, s: float, derivative: int = 0) -> np.ndarray:
        """Numeric C^(derivative)(s) (for tests and plots)."""
        k = int(np.clip(np.searchsorted(self.breaks, s, side="right") - 1, 0, len(self.breaks) - 2))
        tau = s - self.breaks[k]
        out = np.zeros(3)
        for j in range(derivative, self.degree + 1):
            out += self.coeffs[k, j] * math.factorial(j) / math.factorial(j - derivative) * tau ** (j - derivative)
        return out

    def samples(self) -> np.ndarray:
        """Sample parameters equally spaced in arc length (the coarse search grid)."""
        fine = np.linspace(0.0, self.length_parameter, 200 * (len(self.breaks) - 1) * 8 + 1)
        speed = np.array([np.linalg.norm(self.evaluate(t, 1)) for t in fine])
        arc = np.concatenate([[0.0], np.cumsum((speed[1:] + speed[:-1]) / 2 * np.diff(fine))])
        count = max(MIN_SAMPLES, int(np.ceil(arc[-1] / SAMPLE_SPACING)) + 1)
        return np.interp(np.linspace(0.0, arc[-1], count), arc, fine)

    def closest(self, x) -> tuple[ca.SX, ca.SX]:
        """Closest point and unit tangent to x (3-vector, CasADi), as expressions of x."""
        params = np.union1d(self.samples(), self.breaks)     # knots too: a polyline's corners are closest points
        points = np.array([self.evaluate(t) for t in params])
        before = np.concatenate([[params[0]], params[:-1]])
        after = np.concatenate([params[1:], [params[-1]]])
        best_d = ca.sumsqr(x - points[0])
        s_best, lower, upper = ca.SX(params[0]), ca.SX(before[0]), ca.SX(after[0])
        for k in range(1, len(params)):
            d = ca.sumsqr(x - points[k])
            closer = d < best_d
            best_d = ca.if_else(closer, d, best_d)
            s_best = ca.if_else(closer, params[k], s_best)
            lower = ca.if_else(closer, before[k], lower)
            upper = ca.if_else(closer, after[k], upper)
        s = s_best
        for _ in range(NEWTON_STEPS):
            c0, c1, c2 = self._at(s)
            f = ca.dot(c0 - x, c1)
            df = ca.dot(c1, c1) + ca.dot(c0 - x, c2)
            s = ca.fmin(ca.fmax(s - ca.if_else(df > 0, f / df, 0.0), lower), upper)
        c0, c1, _ = self._at(s)
        newton_better = ca.sumsqr(c0 - x) <= best_d
        s = ca.if_else(newton_better, s, s_best)
        c0, c1, _ = self._at(s)
        return c0, normalize(c1)

    def _at(self, s) -> tuple[ca.SX, ca.SX, ca.SX]:
        """C(s), C'(s), C''(s) with the span chosen from s (symbolic)."""
        inner = self.breaks[1:-1]
        index = sum((s >= b) for b in inner) if len(inner) else ca.SX(0.0)
        select = [index == k for k in range(len(self.breaks) - 1)]
        start = sum(sel * b for sel, b in zip(select, self.breaks[:-1]))
        coeffs = [sum(sel * ca.DM(self.coeffs[k, j]) for k, sel in enumerate(select)) for j in range(self.degree + 1)]
        tau = s - start
        return tuple(self._poly(coeffs, tau, d) for d in range(3))

    def _poly(self, coeffs: list, tau, derivative: int):
        out = ca.DM.zeros(3)                     # stays zero for derivatives above the degree (a polyline's C'')
        for j in range(derivative, self.degree + 1):
            out = out + coeffs[j] * (math.factorial(j) / math.factorial(j - derivative)) * tau ** (j - derivative)
        return out
