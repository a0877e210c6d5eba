"""The jobs benchmarks/tick.py times: the tasks it writes (the row sweep's, the tracked vessel's), the hand's
inputs that drive each experiment's closed loop, the Panda task, and pink's two jobs (the baseline)."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

import vfdsl
from vfdsl.kinematics.robot import Robot

from tick_timing import WARMUP, interleaved, stats

ROOT = Path(__file__).resolve().parent.parent
TASKS = ROOT / "tasks"
BENCH = Path(__file__).resolve().parent
READY_DEG = [0, -45, 0, -135, 0, 90, 45]           # the Panda's ready pose
# A row-count task of section 4: one stays_at polytope of n x n directions on shr7.
ROWS_TASK = """task rows_{n}x{n}
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
param p : point = [0, 0, 290]
minimize track(tip, f, gain = 1 mm/s/N)
minimize damping() weight 1e-6
require tip stays_at(p) within 1 um resolution {n}x{n}
require joint_limits()
require joint_speed()
"""
# n of the sweep. Unique facets: n^2 for odd n, about n^2/2 for even n (erratum 3 removes repeats);
# 31x31 gives 961 rows (closest to 1,000), 45x45 gives 2,025 (the first >= 2,000).
SWEEP_FULL = (3, 8, 12, 16, 24, 32, 31, 45)
SWEEP_QUICK = (3, 8, 16, 24)

# Section 6: a tracked vessel, a 20-point run-time b-spline 10 mm under the paper B tip, followed by the tip.
VESSEL_TASK = """task vessel_20
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
param vessel : curve(degree = 3, runtime = true) = [{points}]
minimize track(tip, f, gain = 0.002)
minimize damping() weight 1e-6
require tip follows(vessel) within 0.0005 resolution 8
require joint_limits()
require joint_speed()
"""


# ------------------------------------------------------------------------------------- trajectories
def push_along_curve(task):
    """Experiment A: the hand pushes the tip 3 N along the plate's x axis (the curve's overall direction),
    forward for 500 ticks then back, with a 0.5 N sideways wobble."""
    from scipy.spatial.transform import Rotation
    plate = task.param("plate").value
    x_axis = Rotation.from_euler("xyz", plate.rpy).as_matrix()[:, 0]

    def inputs(k, q):
        direction = 1.0 if (k // 500) % 2 == 0 else -1.0
        wobble = 0.5 * np.array([np.sin(0.3 * k), np.cos(0.2 * k), 0.0])
        return {"f": 3.0 * direction * x_axis + wobble}
    return inputs


def twist_about_cone(task):
    """Experiment B: a torque about the cone axis (reversed every 1,000 ticks) plus a slowly turning wobble."""
    axis = np.array(task.param("axis").value.xyz)

    def inputs(k, q):
        direction = 1.0 if (k // 1000) % 2 == 0 else -1.0
        return {"tau": 0.01 * direction * axis + 0.005 * np.array([np.cos(0.01 * k), np.sin(0.01 * k), 0.0])}
    return inputs


def circle_target(k: int, dt: float) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """The moving target of the Panda comparison: a 20 mm circle in 4 s, yawing +-0.1 rad.
    Returns (translation offset, yaw, linear velocity, angular velocity) at tick k."""
    t, w = k * dt, 2 * np.pi / 4.0
    offset = 0.02 * np.array([np.cos(w * t) - 1.0, np.sin(w * t), 0.0])
    velocity = 0.02 * w * np.array([-np.sin(w * t), np.cos(w * t), 0.0])
    yaw = 0.1 * np.sin(w * t)
    return offset, yaw, velocity, np.array([0.0, 0.0, 0.1 * w * np.cos(w * t)])


def follow_circle(dt: float):
    def inputs(k, q):
        _, _, v, omega = circle_target(k, dt)
        return {"v": np.concatenate([v, omega])}
    return inputs


def slide_on_polytope(k, q):
    """Section 4: a force turning in the plane (and a little out of it): the tip slides over the polytope."""
    return {"f": 2.0 * np.array([np.cos(0.02 * k), np.sin(0.02 * k), 0.3 * np.sin(0.013 * k)])}



# ---------------------------------------------------------------------------------------- pink
def pink_ticks(dt: float, errors: list) -> Callable[[int], tuple[int, int]]:
    """tick(k) -> (ns of pink's solve_ik, ns of its integrate + update) at tick k of the moving target (ticks are
    taken in order, warm-up first); every 100th timed tick, the tip's distance from the target appended to errors."""
    import pink
    import pinocchio as pin
    from pink.tasks import FrameTask

    model = pin.buildModelFromUrdf(str(ROOT / "vfdsl" / "robots" / "panda7.urdf"))
    data = model.createData()
    configuration = pink.Configuration(model, data, np.radians(READY_DEG))
    task = FrameTask("tool_tip", position_cost=1.0, orientation_cost=1.0)
    start = configuration.get_transform_frame_to_world("tool_tip").copy()
    target = start.copy()
    solve_ik, pc = pink.solve_ik, time.perf_counter_ns

    def tick(k: int) -> tuple[int, int]:
        offset, yaw, _, _ = circle_target(k + WARMUP + 1, dt)      # where the target is at the end of this tick
        target.translation = start.translation + offset
        target.rotation = pin.rpy.rpyToMatrix(0.0, 0.0, yaw) @ start.rotation
        task.set_target(target)
        t0 = pc()
        v = solve_ik(configuration, [task], dt, solver="daqp")
        t1 = pc()
        configuration.update(configuration.integrate(v, dt))
        t2 = pc()
        if k >= 0 and k % 100 == 0:
            errors.append(np.linalg.norm(configuration.get_transform_frame_to_world("tool_tip").translation
                                         - target.translation))
        return t1 - t0, t2 - t1
    return tick


def pink_pivot_ticks(task, qs: np.ndarray, errors: list) -> Callable[[int], tuple[int, int]]:
    """tick(k) -> (ns of pink's solve_ik, ns of its Configuration.update) on a job close to experiment B's, at B's
    recorded state k (shr7, ``vfdsl/robots/shr7.urdf``): one FrameTask on tool_tip whose position target is the pivot
    (position_cost 100: hold it) and whose orientation target is B's tip at the next recorded state (track B's
    motion), a DampingTask (cost 1e-3: weight 1e-6 as B's damping), a PositionBarrier keeping the tip in the box of
    +-1 um about the pivot, pink's default limits, DAQP. pink has no cone barrier: B's 15 deg cone (8 rows) has no
    counterpart. The configuration is set to the recorded state before the tick (update, outside solve_ik's time,
    as in :func:`pink_ticks`); every 100th timed tick, the tip's distance from the pivot after pink's step is
    appended to errors."""
    import pink
    import pinocchio as pin
    from pink.barriers import PositionBarrier
    from pink.tasks import DampingTask, FrameTask

    model = pin.buildModelFromUrdf(str(ROOT / "vfdsl" / "robots" / "shr7.urdf"))
    configuration = pink.Configuration(model, model.createData(), qs[0])
    pivot = np.array(task.param("pivot").value.xyz)
    rotations = []
    for q in qs:                                # B's tip orientation at every recorded state
        configuration.update(q)
        rotations.append(configuration.get_transform_frame_to_world("tool_tip").rotation.copy())
    frame = FrameTask("tool_tip", position_cost=100.0, orientation_cost=1.0)
    tasks = [frame, DampingTask(cost=1e-3)]
    barriers = [PositionBarrier("tool_tip", p_min=pivot - 1e-6, p_max=pivot + 1e-6)]
    target = pin.SE3(rotations[0], pivot)
    solve_ik, pc, m, dt = pink.solve_ik, time.perf_counter_ns, len(qs), task.scene.period
    after = model.createData()

    def tick(k: int) -> tuple[int, int]:
        i = k % m
        target.rotation = rotations[(i + 1) % m]
        frame.set_target(target)
        t0 = pc()
        configuration.update(qs[i])
        t1 = pc()
        v = solve_ik(configuration, tasks, dt, solver="daqp", barriers=barriers)
        t2 = pc()
        if k >= 0 and k % 100 == 0:
            pin.framesForwardKinematics(model, after, configuration.integrate(v, dt))
            errors.append(np.linalg.norm(after.oMf[model.getFrameId("tool_tip")].translation - pivot))
        return t2 - t1, t1 - t0
    return tick


def pink_figures(ns: np.ndarray, errors: list) -> dict:
    """pink's statistics from its ticks' (solve_ik, update) ns."""
    return {"solve_ik": stats(ns[:, 0]), "solve_ik_plus_update": stats(ns[:, 0] + ns[:, 1]),
            "tip_error_mm": 1e3 * float(np.max(errors))}


def pink_baseline(ticks: int, dt: float) -> dict:
    """pink's figures timed alone (benchmarks/export_tick.py)."""
    errors: list = []
    return pink_figures(interleaved({"pink": pink_ticks(dt, errors)}, ticks)["pink"], errors)


# ------------------------------------------------------------------------------------------- panda
def load_panda_track():
    """benchmarks/panda_track.vf with its scene benchmarks/panda_track.yaml."""
    task = vfdsl.load(BENCH / "panda_track.vf")
    assert np.allclose(task.start, np.radians(READY_DEG)) and abs(task.scene.period - 0.01) < 1e-12
    return task


def panda_tip_error(task, states, dt) -> float:
    """vfdsl's open-loop tracking: largest distance of the tip from the circle target over the recording (mm)."""
    robot = Robot.load("panda7")
    qs, _ = states
    start, _ = robot.frame_pose(task.start, "tool_tip")
    worst = 0.0
    for k in range(0, len(qs), 100):
        tip, _ = robot.frame_pose(qs[k], "tool_tip")
        worst = max(worst, float(np.linalg.norm(tip - (start + circle_target(k, dt)[0]))))
    return 1e3 * worst
