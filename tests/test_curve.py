"""SplineCurve (vfdsl/compiler/curve.py): interpolation, and the closest point / tangent it builds as a CasADi
expression, against an independent reference.

Reference: scipy's ``make_interp_spline`` through the same points with the chord-length parameter (the
construction curve.py documents), and for the closest point a dense brute-force search (40 001 samples)
refined by ``minimize_scalar`` and then by the root of (C(s) - x) . C'(s) in the bracket of the best
sample, so that the reference itself is good to ~1e-15 m. The tangent is compared with the direction of a
central difference of that spline at the reference parameter.

Curves: the plate curve of ``tasks/paper_a_follow_curve.yaml`` (degree 5, as the task declares, and 3), the
same curve placed in the world by the scene's plate pose (``PlacedCurve``), a tight helix (radius 4 mm,
a turn every 10 points), and a gentle curve.
"""

from __future__ import annotations

import math
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest
import yaml
from scipy.interpolate import make_interp_spline
from scipy.optimize import brentq, minimize_scalar

from vfdsl.compiler.context import PlacedCurve
from vfdsl.compiler.curve import SplineCurve

TASKS = Path(__file__).resolve().parent.parent / "tasks"
TOL = 1e-9                                   # metres, and radians of tangent direction
N_QUERIES = 200


def paper_a_points() -> tuple[np.ndarray, dict]:
    scene = yaml.safe_load((TASKS / "paper_a_follow_curve.yaml").read_text())
    assert scene["units"].replace(" ", "") == "mm,deg"
    return 1e-3 * np.array(scene["params"]["path"]["points"], dtype=float), scene["params"]["plate"]


PAPER_A, PLATE = paper_a_points()
HELIX = np.array([[0.004 * math.cos(0.6 * k), 0.004 * math.sin(0.6 * k), 0.0004 * k] for k in range(20)])
GENTLE = np.array([[0.0, 0.0, 0], [0.012, 0.004, 0], [0.024, 0.006, 0], [0.036, 0.005, 0],
                   [0.048, 0.001, 0], [0.060, -0.005, 0], [0.072, -0.008, 0], [0.084, -0.006, 0]])


class Reference:
    def __init__(self, points: np.ndarray, degree: int):
        self.s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
        self.spline = make_interp_spline(self.s, points, k=degree)
        self.d1 = self.spline.derivative()
        self.grid = np.linspace(0, self.s[-1], 40001)
        self.samples = self.spline(self.grid)
        self.knots = np.unique(self.spline.t)

    @property
    def length(self) -> float:
        return float(self.s[-1])

    def closest(self, x) -> tuple[np.ndarray, float]:
        i = int(np.argmin(np.sum((self.samples - x) ** 2, axis=1)))
        lo, hi = self.grid[max(i - 1, 0)], self.grid[min(i + 1, len(self.grid) - 1)]
        s = float(minimize_scalar(lambda t: float(np.sum((self.spline(t) - x) ** 2)), bounds=(lo, hi),
                                  method="bounded", options={"xatol": 1e-14}).x)
        g = lambda t: float((self.spline(t) - x) @ self.d1(t))
        if g(lo) < 0 < g(hi):
            s = brentq(g, lo, hi, xtol=1e-16, rtol=4 * np.finfo(float).eps)
        return self.spline(s), s

    def numeric_tangent(self, s: float, h: float = 1e-7) -> np.ndarray:
        a, b = max(s - h, 0.0), min(s + h, self.length)
        d = self.spline(b) - self.spline(a)
        return d / np.linalg.norm(d)


def closest_function(curve) -> ca.Function:
    x = ca.SX.sym("x", 3)
    point, tangent = curve.closest(x)
    return ca.Function("closest", [x], [point, tangent])


def queries(ref: Reference, rng, n: int, spread: float, on_curve_fraction: float = 0.25) -> np.ndarray:
    """Points near the curve: C(s) plus Gaussian noise of ``spread`` (a quarter exactly on the curve)."""
    s = rng.uniform(0, ref.length, n)
    noise = rng.normal(scale=spread, size=(n, 3))
    noise[: int(on_curve_fraction * n)] = 0.0
    return ref.spline(s) + noise


def closest_errors(f: ca.Function, ref: Reference, xs: np.ndarray, to_local=lambda x: x, to_world=None):
    """Per query: (point error, tangent direction error) of vfdsl's closest point vs the reference."""
    to_world = to_world or (lambda p, t: (p, t))
    out = []
    for x in xs:
        point, tangent = (np.array(v).ravel() for v in f(x))
        p_ref, s_ref = ref.closest(to_local(x))
        p_ref, t_ref = to_world(p_ref, ref.numeric_tangent(s_ref))
        error = np.linalg.norm(point - p_ref), np.linalg.norm(tangent - t_ref)
        if np.linalg.norm(point - x) < np.linalg.norm(p_ref - x) - 1e-15:
            error = (0.0, 0.0)       # closer than the reference: where the distance is flat (near a centre of
        out.append(error)            # curvature) the reference's own refinement is the limit
    return np.array(out)


def report(errors: np.ndarray) -> str:
    bad = errors[:, 0] > TOL
    return (f"{bad.sum()} of {len(errors)} closest points off by more than {TOL} m "
            f"(max {errors[:, 0].max():.3e} m, {np.sum(errors[:, 0] > 1e-6)} beyond 1 um, "
            f"{np.sum(errors[:, 0] > 1e-3)} beyond 1 mm); tangent error max {errors[:, 1].max():.3e}")


# ====================================================================================== interpolation

@pytest.mark.parametrize("points,degree", [(PAPER_A, 5), (PAPER_A, 3), (HELIX, 5), (HELIX, 3), (GENTLE, 3)],
                         ids=["paperA-5", "paperA-3", "helix-5", "helix-3", "gentle-3"])
def test_interpolates_its_points_and_equals_scipy(points, degree):
    curve = SplineCurve.interpolate(points, degree)
    ref = Reference(points, degree)
    assert curve.length_parameter == pytest.approx(ref.length, abs=1e-15)
    for s, p in zip(ref.s, points):                           # passes through its points, at their chords
        np.testing.assert_allclose(curve.evaluate(s), p, atol=1e-12)
    np.testing.assert_allclose(curve.breaks, ref.knots, atol=1e-15)
    for s in np.linspace(0, ref.length, 301):                 # the same curve as scipy's, derivatives too
        for k in range(3):
            np.testing.assert_allclose(curve.evaluate(s, k), ref.spline(s, nu=k),
                                       atol=1e-9 * max(1.0, np.abs(ref.spline(s, nu=k)).max()))


def test_coincident_points_are_rejected():
    with pytest.raises(ValueError):
        SplineCurve.interpolate(np.array([[0, 0, 0], [1, 0, 0], [1, 0, 0], [2, 1, 0.0]]), 3)


# ======================================================================================= closest point

def test_closest_point_gentle_curve_away_from_knots():
    """Where the algorithm's assumptions hold (span much longer than the sample spacing, closest point in the
    coarse sample's span), the point is exact to rounding and the tangent is the curve's direction."""
    ref = Reference(GENTLE, 3)
    f = closest_function(SplineCurve.interpolate(GENTLE, 3))
    rng = np.random.default_rng(31)
    s = rng.uniform(0, ref.length, 3 * N_QUERIES)
    s = s[np.min(np.abs(s[:, None] - ref.knots[None, :]), axis=1) > 0.003][:N_QUERIES]
    xs = ref.spline(s) + rng.normal(scale=0.0005, size=(len(s), 3))
    errors = closest_errors(f, ref, xs)
    assert np.all(errors[:, 0] < TOL), report(errors)
    assert np.all(errors[:, 1] < 1e-6), report(errors)         # central difference (h = 1e-7) limits this


def test_closest_point_gentle_curve_near_knots():
    """Deterministic reproducer: queries ON the curve, 0.3 sample spacings before each interior knot. The
    nearest coarse sample can be the knot itself; the refinement must be able to cross the knot."""
    ref = Reference(GENTLE, 3)
    curve = SplineCurve.interpolate(GENTLE, 3)
    spacing = np.diff(curve.samples()).min()                 # the coarse search's sample spacing
    xs = np.array([ref.spline(k - 0.3 * spacing) for k in ref.knots[1:-1]])
    f = closest_function(curve)
    errors = closest_errors(f, ref, xs)
    assert np.all(errors[:, 0] < TOL), report(errors)


@pytest.mark.parametrize("degree", [5, 3])
def test_closest_point_paper_a_curve(degree):
    ref = Reference(PAPER_A, degree)
    f = closest_function(SplineCurve.interpolate(PAPER_A, degree))
    errors = closest_errors(f, ref, queries(ref, np.random.default_rng(32), N_QUERIES, 0.001))
    assert np.all(errors[:, 0] < TOL), report(errors)
    assert np.all(errors[:, 1] < 1e-6), report(errors)


def test_closest_point_paper_a_curve_on_the_plate():
    """The task's curve placed by the scene's plate pose (mm, deg): PlacedCurve searches in the plate frame."""
    R = pin.rpy.rpyToMatrix(*np.radians(PLATE["rpy"]))
    t = 1e-3 * np.array(PLATE["translation"], dtype=float)
    placed = PlacedCurve(SplineCurve.interpolate(PAPER_A, 5), ca.SX(ca.DM(R)), ca.SX(ca.DM(t)))
    ref = Reference(PAPER_A, 5)
    xs = np.array([R @ x + t for x in queries(ref, np.random.default_rng(33), N_QUERIES, 0.001)])
    errors = closest_errors(closest_function(placed), ref, xs, to_local=lambda x: R.T @ (x - t),
                            to_world=lambda p, tan: (R @ p + t, R @ tan))
    assert np.all(errors[:, 0] < TOL), report(errors)


@pytest.mark.parametrize("degree", [5, 3])
def test_closest_point_tight_helix(degree):
    ref = Reference(HELIX, degree)
    f = closest_function(SplineCurve.interpolate(HELIX, degree))
    errors = closest_errors(f, ref, queries(ref, np.random.default_rng(34), N_QUERIES, 0.0005))
    assert np.all(errors[:, 0] < TOL), report(errors)
    assert np.all(errors[:, 1] < 1e-6), report(errors)


def test_closest_point_paper_a_on_curve_reproducer():
    """Deterministic reproducer: x = C(0.0138110369...) exactly on the degree-5 curve. The nearest coarse sample
    (s = 0.012401) is 1.5 mm away on the curve; the first Newton step (df = 0.069, small) jumps to s = 0.02997,
    where df < 0, so every later step is 0: the answer is C(0.02997), 38 mm from x."""
    curve = SplineCurve.interpolate(PAPER_A, 5)
    x = curve.evaluate(0.013811036931874219)
    point, _ = (np.array(v).ravel() for v in closest_function(curve)(x))
    assert np.linalg.norm(point - x) < TOL, f"closest point is {np.linalg.norm(point - x):.4f} m from a point on the curve"
