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

A polyline (degree 1) is searched exactly instead: on each segment P_k + t d_k (t in [0, L_k]) the closest
point is at t = clamp((x - P_k) . d_k, 0, L_k); the nearest of those wins, a later segment on a tie, so at a
vertex the tangent is the next segment's (never the zero vector). A segment clamped at its end takes the vertex
P_(k+1) itself, not P_k + L_k d_k (which rounds off it), so wherever a vertex is the closest point of both its
segments (on it, or anywhere in the wedge outside its corner) the two distances are equal to the bit and the tie
is one. ``locate`` also gives how far the segment
runs behind and ahead of the closest point (infinite past the polyline's ends), so a lowering can keep a
frame from overshooting a corner.

Run-time points (``runtime = true``): the b-spline's per-span coefficients are linear in the points once the
parameters (chord lengths) are fixed, C = W P, with W from the default points; ``moving(P)`` puts symbols for
P in place of the numbers. The coarse samples keep their default parameters; a polyline is searched on its
moved segments, so it is exact for any moved points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from vfdsl.compiler.geometry import normalize

NEWTON_STEPS = 6
SAMPLE_SPACING = 1e-3           # metres of arc length between coarse samples
MIN_SAMPLES = 64


@dataclass(frozen=True)
class Closest:
    """The closest point of a curve and its unit tangent; for a polyline also the room along the tangent to
    the ends of the closest point's segment (inf past the polyline's ends; None on a smooth curve)."""

    point: ca.SX
    tangent: ca.SX
    behind: ca.SX | None = None
    ahead: ca.SX | None = None


@dataclass(frozen=True)
class SplineCurve:
    """A curve as per-span polynomials C(s) = sum_j coeffs[k, j] (s - breaks[k])^j on [breaks[k], breaks[k+1]].

    ``weights`` (S, degree + 1, N) gives the coefficients as linear maps of the N points (coeffs = weights @
    points); ``moving`` is None for a curve fixed at compile time, or the coefficients as expressions of the
    run-time points (per span, per order: 3-vectors).
    """

    degree: int
    breaks: np.ndarray           # (S + 1,)
    coeffs: np.ndarray           # (S, degree + 1, 3), at the default points
    weights: np.ndarray | None = None
    moving_coeffs: tuple | None = None

    @classmethod
    def interpolate(cls, points: np.ndarray, degree: int) -> "SplineCurve":
        from scipy.interpolate import make_interp_spline   # here: ~0.5 s to import, and most commands build no curve

        points = np.asarray(points, dtype=float)
        chords = np.linalg.norm(np.diff(points, axis=0), axis=1)
        if np.any(chords < 1e-12):
            raise ValueError("consecutive curve points coincide")
        s = np.concatenate([[0.0], np.cumsum(chords)])
        spline = make_interp_spline(s, points, k=degree)
        breaks = np.unique(spline.t[degree:-degree])
        coeffs = _span_coefficients(spline, breaks, degree)
        weights = _span_coefficients(make_interp_spline(s, np.eye(len(points)), k=degree), breaks, degree)
        return cls(degree, breaks, coeffs, weights)

    def moving(self, points) -> "SplineCurve":
        """The same curve with run-time points (N x 3 CasADi) in place of the default ones."""
        return replace(self, moving_coeffs=tuple(tuple(points.T @ ca.DM(w) for w in span) for span in self.weights))

    @property
    def length_parameter(self) -> float:
        return float(self.breaks[-1])

    def evaluate(self, s, derivative: int = 0) -> np.ndarray:
        """Numeric C^(derivative)(s): a 3-vector, or one row per parameter when s is an array."""
        s = np.asarray(s, dtype=float)
        k = np.clip(np.searchsorted(self.breaks, s, side="right") - 1, 0, len(self.breaks) - 2)
        tau = (s - self.breaks[k])[..., None]
        out = np.zeros(s.shape + (3,))
        for j in range(derivative, self.degree + 1):
            out += self.coeffs[k, j] * math.factorial(j) / math.factorial(j - derivative) * tau ** (j - derivative)
        return out

    def samples(self) -> np.ndarray:
        """Sample parameters equally spaced in arc length (the coarse search grid)."""
        fine = np.linspace(0.0, self.length_parameter, 200 * (len(self.breaks) - 1) * 8 + 1)
        speed = np.linalg.norm(self.evaluate(fine, 1), axis=1)
        arc = np.concatenate([[0.0], np.cumsum((speed[1:] + speed[:-1]) / 2 * np.diff(fine))])
        count = max(MIN_SAMPLES, int(np.ceil(arc[-1] / SAMPLE_SPACING)) + 1)
        return np.interp(np.linspace(0.0, arc[-1], count), arc, fine)

    def closest(self, x) -> tuple[ca.SX, ca.SX]:
        """Closest point and unit tangent to x (3-vector, CasADi), as expressions of x."""
        found = self.locate(x)
        return found.point, found.tangent

    def locate(self, x) -> Closest:
        """The closest point to x, its tangent and (for a polyline) its segment's room, as expressions of x."""
        if self.degree == 1:
            return self._on_segments(x)
        params = np.union1d(self.samples(), self.breaks)     # knots too: a polyline's corners are closest points
        points = [self._position(t) for t in params]
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
        return Closest(c0, normalize(c1))

    def _on_segments(self, x) -> Closest:
        """Exact closest point on the segments P_k P_(k+1); ties go to the later segment."""
        vertices = [self._coeff(k, 0) for k in range(len(self.breaks) - 1)] + [self._end()]
        last = len(vertices) - 2
        best = None
        for k, (a, b) in enumerate(zip(vertices, vertices[1:])):
            d = normalize(b - a)
            length = ca.dot(b - a, d)
            t = ca.fmin(ca.fmax(ca.dot(x - a, d), 0.0), length)
            point = ca.if_else(t < length, a + t * d, b)    # the end vertex exactly: a tie there is a tie in bits
            found = (ca.sumsqr(x - point), point, d, ca.inf if k == 0 else t, ca.inf if k == last else length - t)
            if best is None:
                best = found
            else:
                closer = found[0] <= best[0]
                best = tuple(ca.if_else(closer, new, old) for new, old in zip(found, best))
        return Closest(*best[1:]) if last else Closest(best[1], best[2])      # one segment: a line, no corner

    def _coeff(self, k: int, j: int):
        """coeffs[k, j] as a 3-vector: numbers, or linear in the run-time points."""
        return ca.DM(self.coeffs[k, j]) if self.moving_coeffs is None else self.moving_coeffs[k][j]

    def _end(self):
        """C at the curve's last parameter."""
        return self._position(self.length_parameter)

    def _position(self, t: float):
        """C(t) at a numeric parameter t: numbers, or an expression of the run-time points."""
        if self.moving_coeffs is None:
            return ca.DM(self.evaluate(t))
        k = int(np.clip(np.searchsorted(self.breaks, t, side="right") - 1, 0, len(self.breaks) - 2))
        return sum((self._coeff(k, j) * (t - self.breaks[k]) ** j for j in range(self.degree + 1)), ca.DM.zeros(3))

    def _at(self, s) -> tuple[ca.SX, ca.SX, ca.SX]:
        """C(s), C'(s), C''(s) with the span chosen from s (symbolic)."""
        inner = self.breaks[1:-1]
        index = sum((s >= b) for b in inner) if len(inner) else ca.SX(0.0)
        select = [index == k for k in range(len(self.breaks) - 1)]
        start = sum(sel * b for sel, b in zip(select, self.breaks[:-1]))
        coeffs = [sum(sel * self._coeff(k, j) for k, sel in enumerate(select)) for j in range(self.degree + 1)]
        tau = s - start
        return tuple(self._poly(coeffs, tau, d) for d in range(3))

    def _poly(self, coeffs: list, tau, derivative: int):
        out = ca.DM.zeros(3)                     # stays zero for derivatives above the degree (a polyline's C'')
        for j in range(derivative, self.degree + 1):
            out = out + coeffs[j] * (math.factorial(j) / math.factorial(j - derivative)) * tau ** (j - derivative)
        return out


def _span_coefficients(spline, breaks: np.ndarray, degree: int) -> np.ndarray:
    """Taylor coefficients C^(j)(b) / j! of ``spline`` at the start b of every span: (S, degree + 1, dim)."""
    return np.array([[spline.derivative(j)(b) / math.factorial(j) if j else spline(b)
                      for j in range(degree + 1)] for b in breaks[:-1]])
