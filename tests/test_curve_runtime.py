"""Polylines (curve(degree = 1)) and run-time curves (curve(..., runtime = true)) against numpy/scipy references.

- Polylines: the closest point, tangent and the room left on the segment, against a brute-force search written
  here (every segment projected with numpy, and a dense sampling of every segment as a cross-check); queries
  near and exactly on the corners never give a NaN or zero tangent.
- ``follows`` on a polyline: the along-line rows and the segment row against numpy (Pinocchio kinematics).
- Run-time points: the controller's rows for moved points against a reference built from the moved points
  (brute force on the moved segments; for a b-spline, scipy's ``make_interp_spline`` through the moved
  points at the chord-length parameters of the default points, as docs/language.md defines it).
- Run-time values: wrong count, NaN, repeated points, over-stretched spans, wrong kind: a VfError naming the
  param, before anything moves.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest
from scipy.interpolate import make_interp_spline
from scipy.optimize import brentq, minimize_scalar
from test_primitives import FrameState, assert_polygon_rows, build, random_q, rows_of, unit

from vfdsl.compiler.curve import SplineCurve
from vfdsl.errors import VfError
from vfdsl.ir import model as ir

# A planned cut with corners of 90, 135 and 30 deg (metres), and a b-spline's points.
CUT = np.array([[0.0, 0.0, 0.0], [0.02, 0.0, 0.0], [0.02, 0.015, 0.0], [0.005, 0.03, 0.002],
                [0.03, 0.035, 0.002]])
VESSEL = np.array([[-0.02, 0.0, 0.0], [-0.01, 0.006, 0.0], [0.0, 0.008, 0.001], [0.01, 0.004, 0.002],
                   [0.02, -0.003, 0.002], [0.03, -0.004, 0.001]])


def brute_force_segments(points: np.ndarray, x: np.ndarray):
    """(closest point, index of its segment, t along it) by projecting x on every segment; the later segment on
    a tie within 1e-15 m."""
    best = None
    for k, (a, b) in enumerate(zip(points, points[1:])):
        d = (b - a) / np.linalg.norm(b - a)
        t = min(max((x - a) @ d, 0.0), np.linalg.norm(b - a))
        c = a + t * d
        dist = np.linalg.norm(x - c)
        if best is None or dist <= best[0] + 1e-15:
            best = (dist, c, k, t)
    return best[1], best[2], best[3]


def dense_distance(points: np.ndarray, x: np.ndarray, per_segment: int = 4001) -> float:
    dense = np.concatenate([np.linspace(a, b, per_segment) for a, b in zip(points, points[1:])])
    return float(np.min(np.linalg.norm(dense - x, axis=1)))


def locate_function(curve: SplineCurve) -> ca.Function:
    x = ca.SX.sym("x", 3)
    found = curve.locate(x)
    outputs = [found.point, found.tangent] + ([found.behind, found.ahead] if found.behind is not None else [])
    return ca.Function("locate", [x], outputs)


def near_corner_queries(points: np.ndarray, rng, n: int, spread: float) -> np.ndarray:
    corners = points[rng.integers(0, len(points), n)]
    return np.vstack([corners + rng.normal(scale=spread, size=(n, 3)), points])      # and the vertices exactly


# ============================================================================================ polylines

def test_polyline_closest_point_is_exact():
    curve = SplineCurve.interpolate(CUT, 1)
    f = locate_function(curve)
    rng = np.random.default_rng(51)
    lengths = np.linalg.norm(np.diff(CUT, axis=0), axis=1)
    queries = np.vstack([near_corner_queries(CUT, rng, 120, 0.002),
                         rng.uniform(CUT.min(axis=0) - 0.01, CUT.max(axis=0) + 0.01, size=(120, 3))])
    for x in queries:
        point, tangent, behind, ahead = (np.array(v).ravel() for v in f(x))
        ref, k, t = brute_force_segments(CUT, x)
        assert np.all(np.isfinite(point)) and np.all(np.isfinite(tangent))
        assert np.linalg.norm(tangent) == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(point, ref, atol=1e-14)
        assert np.linalg.norm(x - point) <= dense_distance(CUT, x) + 1e-15
        on_vertex = min(np.linalg.norm(ref - CUT, axis=1)) < 1e-12
        expected = [unit(CUT[k + 1] - CUT[k])]
        if on_vertex:            # a vertex is on two segments: either tangent is a segment's, never a blend
            expected += [unit(b - a) for a, b in zip(CUT, CUT[1:])]
        assert min(np.linalg.norm(tangent - e) for e in expected) < 1e-12
        if not on_vertex:
            assert behind[0] == (math.inf if k == 0 else pytest.approx(t, abs=1e-14))
            assert ahead[0] == (math.inf if k == len(lengths) - 1 else pytest.approx(lengths[k] - t, abs=1e-14))


def test_polyline_vertex_takes_the_next_segment():
    """Exactly on an interior vertex the tie goes to the later segment: the tangent is the next segment's,
    with no room behind (the corner) and the whole segment ahead."""
    f = locate_function(SplineCurve.interpolate(CUT, 1))
    for k in range(1, len(CUT) - 1):
        point, tangent, behind, ahead = (np.array(v).ravel() for v in f(CUT[k]))
        np.testing.assert_allclose(point, CUT[k], atol=1e-15)
        np.testing.assert_allclose(tangent, unit(CUT[k + 1] - CUT[k]), atol=1e-12)
        assert behind[0] == pytest.approx(0.0, abs=1e-15)


def test_outside_a_corner_the_vertex_takes_the_next_segment():
    """Off the polyline, in the wedge outside a corner, the vertex is the closest point of both its segments: a tie,
    which goes to the later segment as on the vertex. (The earlier segment's end was P_k + L_k d_k, a rounding off
    the vertex, so the tie was decided by the last bit: the earlier segment's tangent at 14 of these 722 queries.)"""
    f = locate_function(SplineCurve.interpolate(CUT, 1))
    rng = np.random.default_rng(5)
    ties = 0
    for k in range(1, len(CUT) - 1):
        before, after = unit(CUT[k] - CUT[k - 1]), unit(CUT[k + 1] - CUT[k])
        for v in rng.normal(size=(1200, 3)):
            x = CUT[k] + rng.uniform(1e-4, 0.05) * unit(v)
            if v @ before < 0 or v @ after > 0 or np.linalg.norm(brute_force_segments(CUT, x)[0] - CUT[k]) > 1e-15:
                continue                    # not in the wedge, or another segment is nearer
            ties += 1
            point, tangent, behind, _ = (np.array(z).ravel() for z in f(x))
            np.testing.assert_allclose(point, CUT[k], atol=1e-15)
            np.testing.assert_allclose(tangent, after, atol=1e-12)
            assert behind[0] == 0.0
    assert ties > 700


def test_one_segment_is_a_line():
    """Two points: no corner, so no room to report (follows adds no segment row), the tangent is the segment's."""
    found = SplineCurve.interpolate(CUT[:2], 1).locate(ca.SX.sym("x", 3))
    assert found.behind is None and found.ahead is None
    f = locate_function(SplineCurve.interpolate(CUT[:2], 1))
    point, tangent = (np.array(v).ravel() for v in f(np.array([0.03, 0.001, 0.0])))
    np.testing.assert_allclose(point, CUT[1], atol=1e-15)
    np.testing.assert_allclose(tangent, [1.0, 0.0, 0.0], atol=1e-15)


def test_follows_polyline_rows(tmp_path):
    """Rows of `follows` on a polyline: the octagon around the closest segment's line and the segment row
    -behind <= l . (p + dx - P_c) <= ahead, against numpy."""
    pts = ", ".join(f"[{x!r}, {y!r}, {z!r}]" for x, y, z in CUT.tolist())
    ctrl = build(tmp_path, f"""
        param plate : pose = pose(translation = [0, 0, 0.25], rpy = [0, 0, 0])
        param cut : curve(degree = 1) in plate = [{pts}]
        require tip follows(cut) within 0.0005 resolution 8
        """)
    rng = np.random.default_rng(52)
    lengths = np.linalg.norm(np.diff(CUT, axis=0), axis=1)
    for trial in range(24):
        q = random_q("shr7", rng)
        tip = FrameState("shr7", "tip", q)
        rpy = rng.uniform(-0.3, 0.3, 3)
        R = pin.rpy.rpyToMatrix(*rpy)
        k = rng.integers(0, len(CUT) - 1)          # near a vertex every third trial, else near a random segment
        anchor = CUT[trial % len(CUT)] if trial % 3 == 0 else CUT[k] + rng.uniform(0, 1) * (CUT[k + 1] - CUT[k])
        t = tip.p - R @ (anchor + rng.normal(scale=0.002, size=3))
        qp = ctrl.problem(q, {}, {"plate": {"translation": t, "rpy": rpy}}, dt=0.01)
        A, _, lb, ub = rows_of(ctrl, qp, "follows", "tip")
        local, k, s = brute_force_segments(CUT, R.T @ (tip.p - t))
        P_c, l_c = R @ local + t, R @ unit(CUT[k + 1] - CUT[k])
        P_cl = P_c + ((tip.p - P_c) @ l_c) * l_c
        assert_polygon_rows(A[:8], lb[:8], ub[:8], tip.Jv, tip.p - P_cl, 0.0005, l_c, 8)
        progress = l_c @ (tip.p - P_c)
        np.testing.assert_allclose(A[8], l_c @ tip.Jv, atol=1e-10)
        behind = math.inf if k == 0 else s
        ahead = math.inf if k == len(lengths) - 1 else lengths[k] - s
        assert lb[8] == (-math.inf if behind == math.inf else pytest.approx(-behind - progress, abs=1e-12))
        assert ub[8] == (math.inf if ahead == math.inf else pytest.approx(ahead - progress, abs=1e-12))


# ================================================================================= run-time curves

RUNTIME_TASK = """
    param organ : curve(degree = 1, runtime = true) = [{cut}]
    param vessel : curve(degree = 3, runtime = true) = [{vessel}]
    require tip follows(organ) within 0.0005 resolution 8
    require shaft follows(vessel) within 0.0005 resolution 6
    """


def _literal(points: np.ndarray) -> str:
    return ", ".join(f"[{x!r}, {y!r}, {z!r}]" for x, y, z in points.tolist())


def runtime_controller(tmp_path, origin: np.ndarray):
    return build(tmp_path, RUNTIME_TASK.format(cut=_literal(CUT + origin), vessel=_literal(VESSEL + origin)))


def moved(points: np.ndarray, rng, origin: np.ndarray, scale: float) -> np.ndarray:
    """Points deformed (each moved by ~scale) and the whole rotated and translated a little, around origin."""
    R = pin.exp3(rng.normal(scale=0.2, size=3))
    return (points + rng.normal(scale=scale, size=points.shape)) @ R.T + origin + rng.normal(scale=0.003, size=3)


class FixedParameterSpline:
    """scipy's b-spline through moved points at the default points' chord-length parameters; closest point
    by a dense search refined by minimize_scalar."""

    def __init__(self, default: np.ndarray, points: np.ndarray, degree: int):
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(default, axis=0), axis=1))])
        self.spline = make_interp_spline(s, points, k=degree)
        self.grid = np.linspace(0, s[-1], 40001)
        self.samples = self.spline(self.grid)

    def closest(self, x):
        i = int(np.argmin(np.sum((self.samples - x) ** 2, axis=1)))
        lo, hi = self.grid[max(i - 1, 0)], self.grid[min(i + 1, len(self.grid) - 1)]
        s = minimize_scalar(lambda t: float(np.sum((self.spline(t) - x) ** 2)), bounds=(lo, hi), method="bounded",
                            options={"xatol": 1e-14}).x
        g = lambda t: float((self.spline(t) - x) @ self.spline.derivative()(t))
        if g(lo) < 0 < g(hi):                  # polish: the root of (C(s) - x) . C'(s) in the bracket
            s = brentq(g, lo, hi, xtol=1e-16, rtol=4 * np.finfo(float).eps)
        return self.spline(s), unit(self.spline.derivative()(s))


def test_runtime_points_move_the_rows(tmp_path):
    origin = np.array([0.0, 0.0, 0.25])
    ctrl = runtime_controller(tmp_path, origin)
    rng = np.random.default_rng(53)
    for _ in range(10):
        q = random_q("shr7", rng)
        tip, shaft = FrameState("shr7", "tip", q), FrameState("shr7", "shaft", q)
        # place the curves near the frames, then deform and move them
        organ = moved(CUT - CUT[2], rng, tip.p, 0.001)
        vessel = moved(VESSEL - VESSEL[2], rng, shaft.p, 0.0005)
        qp = ctrl.problem(q, {}, {"organ": organ, "vessel": vessel}, dt=0.01)
        # the polyline: brute force on the moved segments
        P_c, k, _ = brute_force_segments(organ, tip.p)
        l_c = unit(organ[k + 1] - organ[k])
        A, _, lb, ub = rows_of(ctrl, qp, "follows", "tip")
        assert_polygon_rows(A[:8], lb[:8], ub[:8], tip.Jv, tip.p - P_c - ((tip.p - P_c) @ l_c) * l_c, 0.0005, l_c, 8)
        # the b-spline: scipy through the moved points at the default parameters
        ref = FixedParameterSpline(VESSEL, vessel, 3)
        P_c, l_c = ref.closest(shaft.p)
        A, _, lb, ub = rows_of(ctrl, qp, "follows", "shaft")
        P_cl = P_c + ((shaft.p - P_c) @ l_c) * l_c
        assert_polygon_rows(A, lb, ub, shaft.Jv, shaft.p - P_cl, 0.0005, l_c, 6)


def test_runtime_spline_closest_point_against_scipy():
    """SplineCurve.moving: closest points of the moved b-spline to 1e-9 m, queries spread along the curve."""
    curve = SplineCurve.interpolate(VESSEL, 3)
    P = ca.SX.sym("P", len(VESSEL), 3)
    x = ca.SX.sym("x", 3)
    found = curve.moving(P).locate(x)
    f = ca.Function("closest", [P, x], [found.point, found.tangent])
    rng = np.random.default_rng(54)
    for _ in range(5):
        points = VESSEL + rng.normal(scale=0.001, size=VESSEL.shape)
        ref = FixedParameterSpline(VESSEL, points, 3)
        for s in rng.uniform(0, ref.grid[-1], 20):
            query = ref.spline(s) + rng.normal(scale=0.0005, size=3)
            point, tangent = (np.array(v).ravel() for v in f(points, query))
            p_ref, t_ref = ref.closest(query)
            assert np.linalg.norm(query - point) <= np.linalg.norm(query - p_ref) + 1e-12
            np.testing.assert_allclose(point, p_ref, atol=1e-9)
            np.testing.assert_allclose(tangent, t_ref, atol=1e-6)


def test_runtime_defaults_are_the_declared_points(tmp_path):
    """No params: the default points, the same rows as a compile-time curve through them."""
    origin = np.array([0.0, 0.0, 0.25])
    ctrl = runtime_controller(tmp_path, origin)
    fixed = build(tmp_path, RUNTIME_TASK.replace(", runtime = true", "").format(
        cut=_literal(CUT + origin), vessel=_literal(VESSEL + origin)), name="fixed")
    q = random_q("shr7", np.random.default_rng(55))
    a, b = ctrl.problem(q, {}, dt=0.01), fixed.problem(q, {}, dt=0.01)
    np.testing.assert_allclose(a.A, b.A, atol=1e-12)
    np.testing.assert_allclose(a.lb, b.lb, atol=1e-12)
    c = ctrl.problem(q, {}, {"organ": CUT + origin, "vessel": VESSEL + origin}, dt=0.01)
    np.testing.assert_allclose(c.lb, a.lb, atol=1e-12)


@pytest.mark.parametrize("name,value,message", [
    ("organ", CUT[:4].tolist(), r"param 'organ' must be 5 points \[x, y, z\] \(its declared count\), got 4 points"),
    ("organ", CUT[:4], r"must be 5 points \[x, y, z\] \(its declared count\), got an array of float64, shape \(4, 3\)"),
    ("organ", CUT.reshape(-1), r"got an array of float64, shape \(15,\)"),
    ("organ", CUT.astype(complex), r"got an array of complex128"),
    ("organ", np.vstack([CUT[:2], CUT[1:4]]), r"param 'organ''s points 2 and 3 are 0 m apart: a repeated point"),
    ("organ", np.where(np.arange(15).reshape(5, 3) == 7, np.nan, CUT), r"param 'organ''s point 3 contains NaN"),
    ("organ", "points", r"param 'organ' must be 5 points"),
    ("organ", [[0, 0, 0]] * 4 + [[0, 0, "a"]], r"point 5 must be 3 real numbers; item 2 is the string 'a'"),
    ("organ", CUT * 1e3, r"param 'organ''s point 2 is \[20, 0, 0\] m: beyond 2.16 m, the largest coordinate plausible"),
    ("organ", CUT * 1e200, r"param 'organ''s point 2 is \[2e\+198, 0, 0\] m: beyond 2.16 m"),
    ("vessel", VESSEL * 3, r"param 'vessel''s points 1 and 2 are .* 3 x their default distance"),
    ("vessel", VESSEL * 0.4, r"0.4 x their default distance"),
    ("vessel", ir.CurveValue(degree=1, points=VESSEL.tolist(), runtime=True), r"is a degree-3 curve, got a degree-1"),
])
def test_runtime_points_are_checked_before_anything_moves(tmp_path, name, value, message):
    ctrl = runtime_controller(tmp_path, np.zeros(3))
    q = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.02])
    with pytest.raises(VfError, match=message):
        ctrl.step(q, {}, {name: value}, dt=0.01)
    ctrl.step(q, {}, {name: ir.CurveValue(degree=1 if name == "organ" else 3,
                                          points=(CUT if name == "organ" else VESSEL * 1.5).tolist())}, dt=0.01)


def test_runtime_flag_syntax(tmp_path):
    with pytest.raises(VfError, match="curve has no type argument 'moving'"):
        build(tmp_path, "param c : curve(degree = 1, moving = true) = [[0, 0, 0], [0.01, 0, 0]]\n")
    with pytest.raises(VfError, match="true or false"):
        build(tmp_path, "param c : curve(runtime = 3) = [[0, 0, 0], [0.01, 0, 0], [0.02, 0.01, 0], [0.03, 0, 0]]\n")
    ctrl = build(tmp_path, "param c : curve(degree = 1, runtime = false) = [[0, 0, 0], [0.01, 0, 0]]\n"
                           "require tip follows(c)\n")
    with pytest.raises(VfError, match="unknown run-time param 'c'"):
        ctrl.step(np.zeros(7), {}, {"c": [[0, 0, 0], [0.01, 0, 0]]}, dt=0.01)


def test_runtime_spline_stretched_to_the_limits():
    """Points moved so that spans stretch or shrink by up to the allowed factor: the closest point is still the
    reference's (queries within ~1 mm of the curve), as near as the reference resolves it."""
    curve = SplineCurve.interpolate(VESSEL, 3)
    P, x = ca.SX.sym("P", len(VESSEL), 3), ca.SX.sym("x", 3)
    f = ca.Function("closest", [P, x], [curve.moving(P).locate(x).point])
    rng = np.random.default_rng(56)
    defaults = np.linalg.norm(np.diff(VESSEL, axis=0), axis=1)
    checked = 0
    for scale in (0.55, 0.7, 1.4, 1.9):
        points = VESSEL * scale + rng.normal(scale=0.001, size=VESSEL.shape)
        ratio = np.linalg.norm(np.diff(points, axis=0), axis=1) / defaults
        assert 0.5 <= ratio.min() and ratio.max() <= 2.0
        ref = FixedParameterSpline(VESSEL, points, 3)
        for s in rng.uniform(0, ref.grid[-1], 15):
            query = ref.spline(s) + rng.normal(scale=0.001, size=3)
            point = np.array(f(points, query)).ravel()
            p_ref, _ = ref.closest(query)
            assert np.linalg.norm(query - point) <= np.linalg.norm(query - p_ref) + 1e-12
            np.testing.assert_allclose(point, p_ref, atol=1e-9)
            checked += 1
    assert checked == 60


@pytest.mark.slow
def test_closed_loop_follows_a_moving_deforming_polyline(tmp_path):
    """A tracked polyline (in a tracked pose) translates at 2 mm/s and bends while a hand pushes the tip along it:
    after every tick the tip is within the octagon's bound (eps / cos(pi/8)) of the polyline the controller
    was given that tick (brute force on the segments, Pinocchio for the tip), and it passes a corner."""
    base = np.array([[-0.02, 0.0, 0.0], [0.0, 0.0, 0.0], [0.01, 0.015, 0.0], [0.03, 0.015, 0.0]])
    ctrl = build(tmp_path, f"""
        input f : force
        param plate : pose = pose(translation = [0, 0, 0.28], rpy = [0, 0, 0])
        param organ : curve(degree = 1, runtime = true) in plate = [{_literal(base)}]
        minimize track(tip, f, gain = 0.001)
        minimize damping() weight 1e-6
        require tip follows(organ) within 0.0001 resolution 8
        require tip keeps_direction([0, 0, 1]) within 0.01
        require joint_limits()
        require joint_speed()
        """, units="m, rad")
    q = np.array([-0.02, 0.0, 0.0, 0.0, 0.0, 0.0, 0.02])        # the tip on the first point
    eps = 1e-4
    distances, segments = [], set()
    for k in range(1500):
        points = base + np.array([0.0, 0.002 * k * 0.01, 0.0])     # 2 mm/s across
        points[2:, 1] += 0.002 * math.sin(0.004 * k)              # and the far end swings by 2 mm
        yaw = 0.05 * math.sin(0.003 * k)                          # the tracked plate turns a little
        R, t = pin.rpy.rpyToMatrix(0.0, 0.0, yaw), np.array([0.0, 0.0, 0.28])
        local = R.T @ (FrameState("shr7", "tip", q).p - t)
        _, k_seg, _ = brute_force_segments(points, local)
        goal = k_seg + 1 if np.linalg.norm(points[k_seg + 1] - local) > 2e-5 else min(k_seg + 2, len(points) - 1)
        push = 4.0 * R @ unit(points[goal] - local)
        q = q + ctrl.step(q, {"f": push}, {"organ": points, "plate": {"translation": t, "rpy": [0, 0, yaw]}},
                          dt=0.01)
        local = R.T @ (FrameState("shr7", "tip", q).p - t)
        point, k_seg, _ = brute_force_segments(points, local)
        distances.append(np.linalg.norm(local - point))
        segments.add(k_seg)
    assert max(distances) <= eps / math.cos(math.pi / 8), max(distances)
    assert segments == {0, 1, 2}, "the tip should pass both corners"


@pytest.mark.slow
def test_generated_code_reads_the_runtime_points(tmp_path):
    """The generated C and the interpreted graph give the same step for moved points (both take the points from
    the run-time param vector)."""
    import vfdsl
    origin = np.array([0.0, 0.0, 0.25])
    path = tmp_path / "rt.vf"
    path.write_text('task rt\nunits m, rad\nrobot rb = urdf "shr7"\nframe tip = rb.link("tool_tip")\n'
                    'input f : force\nminimize track(tip, f, gain = 0.001)\nminimize damping() weight 1e-6\n'
                    + RUNTIME_TASK.format(cut=_literal(CUT + origin), vessel=_literal(VESSEL + origin))
                    .replace("require shaft", "require tip").replace("\n    ", "\n"))
    task = vfdsl.load(path)
    native, interpreted = vfdsl.compile(task, backend="native"), vfdsl.compile(task, backend="interpreted")
    assert native.backend == "native"
    rng = np.random.default_rng(57)
    for _ in range(5):
        q = random_q("shr7", rng, 0.2)
        params = {"organ": moved(CUT - CUT[2], rng, origin, 0.001), "vessel": moved(VESSEL - VESSEL[2], rng, origin, 5e-4)}
        f = rng.normal(size=3)
        a = native.step(q, {"f": f}, params, dt=0.01)
        b = interpreted.step(q, {"f": f}, params, dt=0.01)
        np.testing.assert_allclose(a, b, atol=1e-12)
        assert native.status == interpreted.status
