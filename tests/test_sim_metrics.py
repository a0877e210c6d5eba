"""The simulator's parts against independent computations: metrics on hand-computed poses, the curve
distance against a brute-force search, the tracker's noise statistics, the hand's tremor spectrum and drift,
the robot model's latency, servo lag and resolution, and pooled statistics against numpy."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from conftest import TASKS_DIR
from scipy.spatial.transform import Rotation

import vfdsl
from vfdsl.check.kinematics import frame_pose
from vfdsl.cli import main
from vfdsl.kinematics.robot import Robot
from vfdsl.mesh import brute
from vfdsl.mesh.load import read_mesh
from vfdsl.sim import tracker
from vfdsl.sim.geometry import Curve, Scene
from vfdsl.sim.hand import drift, tremor
from vfdsl.sim.metrics import Poses, Stats, errors, metric_defs
from vfdsl.sim.robot import SimRobot
from vfdsl.sim.settings import MetricSpec


@pytest.fixture(scope="module")
def task_b():
    return vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf")


@pytest.fixture(scope="module")
def task_a():
    return vfdsl.load(TASKS_DIR / "paper_a_follow_curve.vf")


def _cone_pose(axis: np.ndarray, angle: float, around: float) -> np.ndarray:
    """A rotation whose z axis is ``angle`` from ``axis``, at phase ``around`` about it."""
    e1 = np.cross(axis, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    z = math.cos(angle) * axis + math.sin(angle) * (math.cos(around) * e1 + math.sin(around) * e2)
    return Rotation.align_vectors([z], [[0.0, 0.0, 1.0]])[0].as_matrix()


def test_pivot_and_cone_errors_of_hand_computed_poses(task_b):
    """Tip 3 um and 4 um off the pivot (5 um = 0.005 mm); tool axis 15.5 deg from the cone axis (0.5 deg)."""
    robot = Robot.load("shr7")
    axis = np.array([0.0, -0.2, 1.0]) / math.hypot(0.2, 1.0)
    pivot = np.array([0.0, 0.0, 0.29])
    p = np.array([pivot + [3e-6, 4e-6, 0.0], pivot])
    R = np.array([_cone_pose(axis, math.radians(15.5), 0.3), _cone_pose(axis, math.radians(15.0), 2.0)])
    poses = Poses({"tip": p}, {"tip": R})
    specs = (MetricSpec("pivot_error", error_of="tip stays_at"), MetricSpec("tool_angle_error", error_of="tip cone"))
    defs = {d.name: d for d in metric_defs(task_b, robot, specs)}
    scene = Scene(task_b)
    pivot_error = errors(defs["pivot_error_mm"], task_b, robot, scene, poses, np.zeros((2, 7)), 0.01)
    angle_error = errors(defs["tool_angle_error_deg"], task_b, robot, scene, poses, np.zeros((2, 7)), 0.01)
    np.testing.assert_allclose(pivot_error, [0.005, 0.0], atol=1e-12)
    np.testing.assert_allclose(angle_error, [0.5, 0.0], atol=1e-9)
    assert defs["pivot_error_mm"].tolerance == pytest.approx(0.001)


def test_curve_distance_matches_a_brute_force_search(task_a):
    curve = Curve(task_a.param("path").value)
    rng = np.random.default_rng(3)
    s = rng.uniform(0.05 * curve.length, 0.95 * curve.length, 200)
    points = curve.spline(s) + rng.normal(scale=2e-3, size=(200, 3))
    _, distance = curve.closest(points)
    dense = curve.spline(np.linspace(0.0, curve.length, 400_001))
    brute = np.array([np.sqrt(np.min(np.sum((dense - x) ** 2, axis=1))) for x in points])
    assert np.all(distance <= brute + 1e-12)                   # never worse than the dense search
    np.testing.assert_allclose(distance, brute, atol=1e-8)
    # Past an end the distance is to the curve (the paper's figure), not to its end tangent: 3 mm along the
    # end tangent and 2 mm across it is sqrt(13) mm from the end point, and the closest point is the end.
    for s_end, sign in ((curve.length, 1.0), (0.0, -1.0)):
        tangent = curve.tangent(s_end)
        across = np.cross(tangent, [0.0, 0.0, 1.0])
        beyond = curve.spline(s_end) + sign * 3e-3 * tangent + 2e-3 * across / np.linalg.norm(across)
        (s_found,), (distance,) = curve.closest(beyond)
        assert distance == pytest.approx(math.sqrt(13) * 1e-3, rel=1e-9)
        assert s_found == s_end


def test_joint_limit_metric_of_a_configuration_outside_the_limits(task_b):
    robot = Robot.load("shr7")
    q = np.zeros((2, 7))
    q[1, 0] = robot.upper[0] + 2e-3                             # the x stage 2 mm beyond its limit
    q[1, 3] = robot.lower[3] - math.radians(1.5)                # rcm_a 1.5 deg beyond its limit
    defs = {d.name: d for d in metric_defs(task_b, robot, ())}
    poses = Poses({}, {})
    scene = Scene(task_b)
    np.testing.assert_allclose(errors(defs["joint_limits_mm"], task_b, robot, scene, poses, q, 0.01), [0, 2.0])
    np.testing.assert_allclose(errors(defs["joint_limits_deg"], task_b, robot, scene, poses, q, 0.01), [0, 1.5])


def test_tracker_noise_has_the_stated_rms(task_b):
    """Per marker 3-D RMS = noise; the measured tool axis deviates by RMS 2 sigma / d (two markers, two
    directions across the axis, sigma = noise / sqrt(3) per axis)."""
    n = 40_000
    R = np.repeat(np.eye(3)[None], n, axis=0)
    truth = Poses({"tip": np.zeros((n, 3))}, {"tip": R})
    noise, d = 2e-4, 0.1
    seen = tracker.measure(truth, task_b, noise, d, np.random.default_rng(0))
    rms_position = np.sqrt(np.mean(np.sum(seen.p["tip"] ** 2, axis=1)))
    tilt = np.arccos(np.clip(seen.axis(task_b.frame("tip")) @ [0.0, 0.0, 1.0], -1, 1))
    assert rms_position == pytest.approx(noise, rel=0.02)
    assert np.sqrt(np.mean(tilt ** 2)) == pytest.approx(2 * noise / math.sqrt(3) / d, rel=0.03)


def test_tremor_is_in_its_band_with_its_rms_and_repeatable():
    period, ticks = 0.001, 20_000
    signal = tremor(np.random.default_rng(5), ticks, period, 0.3, (8.0, 12.0))
    again = tremor(np.random.default_rng(5), ticks, period, 0.3, (8.0, 12.0))
    np.testing.assert_array_equal(signal, again)
    assert np.sqrt(np.mean(np.sum(signal ** 2, axis=1))) == pytest.approx(0.3, rel=0.15)
    spectrum = np.abs(np.fft.rfft(signal, axis=0)) ** 2
    frequency = np.fft.rfftfreq(ticks, period)
    in_band = (frequency >= 7.5) & (frequency <= 12.5)
    assert spectrum[in_band].sum() / spectrum.sum() > 0.95


def test_drift_has_its_rms_and_correlation_time():
    period, tau = 0.01, 2.0
    x = drift(np.random.default_rng(1), 400_000, period, 0.3, tau)
    assert np.sqrt(np.mean(np.sum(x ** 2, axis=1))) == pytest.approx(0.3, rel=0.05)
    lag = int(tau / period)
    correlation = np.mean(x[:-lag] * x[lag:]) / np.mean(x * x)
    assert correlation == pytest.approx(math.exp(-1), abs=0.05)


def test_robot_latency_servo_lag_and_resolution():
    robot = Robot.load("shr7")
    q0 = np.zeros(7)
    late = SimRobot(robot, q0, latency=0.025)
    dq = np.full(7, 1e-3)
    late.command(0.0, dq)
    late.advance(0.0, 0.01)
    np.testing.assert_array_equal(late.read(), q0)               # still in flight
    late.advance(0.01, 0.02)
    np.testing.assert_array_equal(late.read(), q0)
    late.advance(0.02, 0.03)
    np.testing.assert_array_equal(late.read(), dq)               # arrived at 25 ms
    lagging = SimRobot(robot, q0, servo_lag=0.02)
    lagging.command(0.0, dq)
    lagging.advance(0.0, 0.01)
    np.testing.assert_allclose(lagging.read(), dq * (1 - math.exp(-0.5)), rtol=1e-12)
    coarse = SimRobot(robot, q0, resolution=robot.resolution)
    coarse.command(0.0, np.array([13e-6, 4e-6, 0, 1.6e-4, 0, 0, 0]))
    np.testing.assert_allclose(coarse.read(), [1e-5, 0, 0, 2e-4, 0, 0, 0], atol=1e-15)
    for _ in range(2):                                          # 4 um increments add up: 12 um -> 10 um
        coarse.command(0.0, np.array([0, 4e-6, 0, 0, 0, 0, 0]))
    np.testing.assert_allclose(coarse.read()[1], 1e-5, atol=1e-15)


def test_pooled_statistics_match_numpy():
    rng = np.random.default_rng(2)
    parts = [rng.random(n) for n in (5, 17, 1, 40)]
    total = Stats()
    for part in parts:
        total = total.merge(Stats().add(part))
    everything = np.concatenate(parts)
    assert total.mean == pytest.approx(everything.mean(), rel=1e-12)
    assert total.std == pytest.approx(everything.std(), rel=1e-9)
    assert total.worst == everything.max() and total.count == everything.size
    assert total.least == everything.min()


def test_frame_poses_match_the_robot_model_with_offsets(task_a):
    """The batch kinematics of the scoring (tip, and the shaft 100 mm up the tool) equal Robot.frame_pose."""
    from vfdsl.sim.metrics import frame_poses
    from vfdsl.sim.robot import frame_offset

    robot = Robot.load("shr7")
    rng = np.random.default_rng(4)
    qs = task_a.start + rng.normal(scale=0.02, size=(20, 7))
    poses = frame_poses(robot, task_a, qs)
    for frame in task_a.frames:
        for i, q in enumerate(qs):
            p, R = robot.frame_pose(q, frame.link, frame_offset(frame))
            np.testing.assert_allclose(poses.p[frame.name][i], p, atol=1e-15)
            np.testing.assert_allclose(poses.R[frame.name][i], R, atol=1e-15)


def test_pooled_std_of_a_near_constant_metric_is_not_lost_to_rounding():
    rng = np.random.default_rng(6)
    parts = [1e3 + 1e-6 * rng.standard_normal(n) for n in (300, 700)]
    total = Stats().add(parts[0]).merge(Stats().add(parts[1]))
    assert total.std == pytest.approx(np.concatenate(parts).std(), rel=1e-6)


def _capsule_distance(a: np.ndarray, b: np.ndarray, corners: np.ndarray, spacing: float = 5e-5) -> float:
    """The distance from the segment a b to triangles ``corners``, by trimesh's closest point on a triangle from
    points of the segment every ``spacing`` (too coarse by at most spacing^2 / (8 d) at a distance d), against
    the triangles whose centre is within 3 mm of the nearest centre's distance (the channel's are 2 mm wide)."""
    import trimesh

    n = int(np.ceil(np.linalg.norm(b - a) / spacing)) + 1
    points = a + np.linspace(0, 1, n)[:, None] * (b - a)
    centres = corners.mean(axis=1)
    along = np.clip((centres - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
    gap = np.linalg.norm(centres - (a + along[:, None] * (b - a)), axis=1)
    near = corners[gap < gap.min() + 0.003]
    pairs_t = np.repeat(near, n, axis=0)
    pairs_p = np.tile(points, (len(near), 1))
    closest = trimesh.triangles.closest_point(pairs_t, pairs_p)
    return float(np.linalg.norm(closest - pairs_p, axis=1).min())


def test_mesh_clearance_is_measured_on_its_own(tmp_path):
    """`vfdsl simulate` of tasks/sinus_channel.vf for 3 s (the hand brings the shaft onto the bend's wall): its
    channel_wall_clearance_mm is the capsule's clearance from the channel at every tick, and the summary's min is
    the run's minimum clearance. Checked against a computation of its own from the trace's joint readings
    (check's frame_pose), the shaft sampled every 0.05 mm and measured to the triangles by trimesh, less the
    1 mm radius, at every 20th tick and at the tick of the minimum; inside the channel by the winding number."""
    summary, trace = tmp_path / "run.json", tmp_path / "t.csv"
    assert main(["simulate", str(TASKS_DIR / "sinus_channel.vf"), "--duration", "3s", "--trials", "1", "--quiet",
                 "--json", str(summary), "--trace", str(trace)]) == 0
    metric = json.loads(summary.read_text())["metrics"]["channel_wall_clearance_mm"]
    with open(trace, newline="") as f:
        rows = list(csv.DictReader(f))
    task = vfdsl.load(TASKS_DIR / "sinus_channel.vf")
    robot = Robot.load(task.robots[0].urdf)
    columns = [f"q.{n}_{'m' if t == 'prismatic' else 'rad'}" for n, t in zip(robot.joint_names, robot.joint_types)]
    channel = read_mesh(TASKS_DIR / "anatomy" / "channel.stl", 1e-3)
    corners = channel.vertices[channel.triangles]
    traced = np.array([float(r["metric.channel_wall_clearance_m"]) for r in rows])
    assert metric["samples"] == len(rows) == 300 and metric["unit"] == "mm"
    assert metric["min"] == pytest.approx(1e3 * traced.min(), abs=1e-9)
    assert 0.45 < metric["min"] < 0.55            # mm: it reached the wall's 0.5 mm margin
    least = int(np.argmin(traced))
    for k in sorted({*range(0, len(rows), 20), least}):
        q = np.array([float(rows[k][c]) for c in columns])
        a, b = frame_pose(robot, task.frame("tip"), q)[0], frame_pose(robot, task.frame("shaft"), q)[0]
        assert all(brute.winding_number(x, channel.vertices, channel.triangles) > 0.5 for x in (a, b))
        assert traced[k] == pytest.approx(_capsule_distance(a, b, corners) - 0.001, abs=1e-6), k


def test_mesh_metrics_are_brute_force_without_computing_it(monkeypatch):
    """The three metrics of each mesh fixture of tasks/bone_nerve.vf, on a tool path down onto the bone and past
    the nerve (through both), equal brute force over every triangle; computing them calls no brute-force routine
    (10 ms a tick on these meshes: a mesh task simulated slower than real time)."""
    task = vfdsl.load(TASKS_DIR / "bone_nerve.vf")
    robot = Robot.load(task.robots[0].urdf)
    t = np.linspace(0, 1, 40)[:, None]
    tip = np.array([-0.030, 0.0, 0.262]) + t * np.array([0.040, 0.0, -0.018])     # into the bone, under the nerve
    R = np.repeat(np.eye(3)[None], len(t), axis=0)
    poses = Poses({"tip": tip, "neck": tip + [0, 0, 0.005], "shaft": tip + [0, 0, 0.040]}, {f: R for f in
                                                                                           ("tip", "neck", "shaft")})
    scene = Scene(task)
    expected = {}
    for frame, mesh, keep_off in (("neck", "bone", 0.001), ("tip", "nerve", 0.002)):
        m = read_mesh(TASKS_DIR / "anatomy" / f"{mesh}.stl", 1e-3)
        expected[frame] = np.array([brute.signed_clearance(a, b, 0.001, m.vertices, m.triangles, False)
                                    for a, b in zip(poses.p[frame], poses.p["shaft"])]), keep_off
    for frame in ("neck", "tip"):                 # clear of the bone and nerve, then inside or through them
        assert expected[frame][0].min() <= -0.001 < 0.001 < expected[frame][0].max()
    for name in ("signed_clearance", "segment_distances", "winding_number", "point_triangles"):
        monkeypatch.setattr(brute, name, lambda *a, **k: pytest.fail("brute force in a metric"))
    defs = [d for d in metric_defs(task, robot, ()) if d.constraint is not None and "mesh" in d.constraint.primitive]
    assert len(defs) == 6
    for d in defs:
        clearance, margin = expected[d.constraint.frame]
        value = errors(d, task, robot, scene, poses, np.zeros((len(t), robot.nq)), 0.01)
        want = {"clearance": 1e3 * clearance, "contact": 100.0 * (clearance <= margin + 0.05e-3),
                "length": 1e3 * np.maximum(0.0, margin - clearance)}[d.dimension]
        np.testing.assert_allclose(value, want, rtol=0, atol=1e-9, err_msg=d.name)


def test_scoring_a_mesh_task_shows_progress(monkeypatch):
    """Scoring a trial of a mesh task reports progress as its clearances are measured (every CHUNK capsules),
    the scoring's share of the trial's ticks in all (the loop reports the other share): the bar moves while a
    long run is scored. Without a tracker, and with one (which measures the clearances a second time)."""
    from vfdsl.mesh import clearance
    from vfdsl.sim import runner
    from vfdsl.sim.scene_file import default_scene, load_settings

    monkeypatch.setattr(clearance, "CHUNK", 10)
    file = str(TASKS_DIR / "bone_nerve.vf")
    task = vfdsl.load(file)
    robot = Robot.load(task.robots[0].urdf)
    qs = task.start + np.linspace(0, 1, 100)[:, None] * np.linspace(-0.01, 0.01, robot.nq)
    for noise, per_tick in ((0.0, 2), (2e-4, 4)):          # clearances measured per tick: 2 meshes (x 2 tracked)
        settings = load_settings(task, default_scene(file)).replace(duration=1.0, trials=1, noise=noise)
        [job] = runner.make_jobs(file, settings)
        reports = []
        runner._score(job, task, robot, qs, [(0, dict(Scene(task).values))], np.random.default_rng(0), 0, 0,
                      None, {}, None, reports.append)
        assert sum(reports) == pytest.approx((1 - runner.SIMULATED) * 100)
        assert len(reports) == per_tick * 100 // 10
