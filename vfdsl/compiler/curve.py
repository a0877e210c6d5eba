"""B-spline curves and their closest point, as fixed-cost CasADi expressions (no loops, no branches
that change the operation count, so the same graph can be generated as C).

The curve is the b-spline of the given degree that interpolates the points in order, parametrized by
cumulative chord length s (metres). Closest point to x, every tick:

1. coarse: the nearest of K precomputed samples C(s_k) (a chain of comparisons), which fixes the span;
2. fine: Newton on f(s) = (C(s) - x) . C'(s) = 0 with the span's polynomial,
   s <- s - f / (|C'|^2 + (C - x) . C''), kept inside the span, a fixed number of times.

With samples much denser than the curve's features the coarse point lies in the basin of the true closest
point, and three Newton steps reach it to rounding error (tested against a brute-force search).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy.interpolate import make_interp_spline

from vfdsl.compiler.geometry import normalize

NEWTON_STEPS = 3
SAMPLES_PER_SPAN = 24


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

    def samples(self) -> tuple[np.ndarray, np.ndarray]:
        """Sample parameters and their span indices (the coarse search grid)."""
        params, spans = [], []
        for k in range(len(self.breaks) - 1):
            for t in np.linspace(self.breaks[k], self.breaks[k + 1], SAMPLES_PER_SPAN, endpoint=False):
                params.append(t)
                spans.append(k)
        params.append(self.breaks[-1])
        spans.append(len(self.breaks) - 2)
        return np.array(params), np.array(spans)

    def closest(self, x) -> tuple[ca.SX, ca.SX]:
        """Closest point and unit tangent to x (3-vector, CasADi), as expressions of x."""
        params, spans = self.samples()
        points = np.array([self.evaluate(t) for t in params])
        best_d = ca.sumsqr(x - points[0])
        best_s, best_k = ca.SX(params[0]), ca.SX(spans[0])
        for t, k, c in zip(params[1:], spans[1:], points[1:]):
            d = ca.sumsqr(x - c)
            closer = d < best_d
            best_d = ca.if_else(closer, d, best_d)
            best_s = ca.if_else(closer, t, best_s)
            best_k = ca.if_else(closer, float(k), best_k)
        n_spans = len(self.breaks) - 1
        select = [best_k == k for k in range(n_spans)]
        start = sum(sel * self.breaks[k] for k, sel in enumerate(select))
        width = sum(sel * (self.breaks[k + 1] - self.breaks[k]) for k, sel in enumerate(select))
        coeffs = [sum(sel * ca.DM(self.coeffs[k, j]) for k, sel in enumerate(select)) for j in range(self.degree + 1)]
        tau = best_s - start
        for _ in range(NEWTON_STEPS):
            c0, c1, c2 = (self._poly(coeffs, tau, d) for d in range(3))
            f = ca.dot(c0 - x, c1)
            df = ca.dot(c1, c1) + ca.dot(c0 - x, c2)
            step = ca.if_else(df > 1e-12, f / df, 0.0)
            tau = ca.fmin(ca.fmax(tau - step, 0.0), width)
        return self._poly(coeffs, tau, 0), normalize(self._poly(coeffs, tau, 1))

    def _poly(self, coeffs: list, tau, derivative: int):
        out = 0
        for j in range(derivative, self.degree + 1):
            out = out + coeffs[j] * (math.factorial(j) / math.factorial(j - derivative)) * tau ** (j - derivative)
        return out
