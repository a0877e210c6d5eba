"""Paper A in closed loop: how far the tool tilts from the plate normal, with vfdsl's controller and with an
independent exact one.

    python benchmarks/closed_loop_tilt.py             # 10 ms and 40 ms periods, 60 s of pushing at most each
    python benchmarks/closed_loop_tilt.py --seconds 5

A hand pushes the tip along the curve (3 N along its tangent, a 0.5 N sideways wobble: tests/test_closed_loop.py's
loop) until the tip reaches the curve's end. Three closed loops run from the task's start: the generated controller,
the interpreted one, and an "exact" controller that steps with the independent reference's lexicographic answer
(tests/levels_reference.py: each level in turn by DAQP's Python package over the null space of the levels above,
held exactly; at a tick where it fails, the generated controller's answer). For each: the largest tilt of the
tool's axis from the plate normal (the tip's distance from the curve: tests/test_closed_loop.py). Also, along the
generated controller's own trajectory, how many ticks the reference judges exact (each level's KKT conditions
within 1e-9, tests/levels_reference.kkt_excess) and the largest
|dq_generated - dq_reference|.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from levels_reference import kkt_excess, level_data, robust  # noqa: E402
from test_closed_loop import plate_and_curve  # noqa: E402

import vfdsl  # noqa: E402
from vfdsl.kinematics.robot import Robot  # noqa: E402

PUSH, WOBBLE = 3.0, 0.5          # N


def run(period: float, seconds: float, step, check=None):
    """(largest tilt in rad, ticks): the closed loop with ``step(q, push, period) -> dq``; ``check(q, push, dq)``
    is called at each tick."""
    task = vfdsl.load(ROOT / "tasks" / "paper_a_follow_curve.vf")
    robot = Robot.load("shr7")
    plate, R_plate, _, s, spline = plate_and_curve(task)
    samples = spline(np.linspace(0.0, s[-1], 4001))
    q = task.start.copy()
    tilt = 0.0
    ticks = 0
    tangent = None
    for k in range(int(seconds / period)):
        p, R = robot.frame_pose(q, "tool_tip")
        tilt = max(tilt, float(np.arccos(np.clip(R[:, 2] @ R_plate[:, 2], -1, 1))))
        if k % 10 == 0:
            nearest = int(np.argmin(np.sum((samples - R_plate.T @ (p - plate.translation)) ** 2, axis=1)))
            if nearest >= len(samples) - 2:
                break
            tangent = R_plate @ spline.derivative()(nearest / (len(samples) - 1) * s[-1])
            tangent /= np.linalg.norm(tangent)
        push = PUSH * tangent + WOBBLE * np.array([np.sin(0.3 * k), np.cos(0.2 * k), 0.0])
        dq = step(q, push, period)
        if check is not None:
            check(q, push, dq)
        q = q + dq
        ticks += 1
    return tilt, ticks


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="longest push per loop (default 60 s)")
    seconds = parser.parse_args().seconds
    task = vfdsl.load(ROOT / "tasks" / "paper_a_follow_curve.vf")
    native = vfdsl.compile(task, backend="native")
    interpreted = vfdsl.compile(task, backend="interpreted")
    damping_last = interpreted.assembled.last_level_is_damping
    print(f"{'period':>7s} {'controller':>12s} {'ticks':>6s} {'tilt (urad)':>12s}")
    for period in (0.01, 0.04):
        failed = [0]

        def exact(q, push, dt):
            levels, A, lba, uba, lbx, ubx = level_data(interpreted, q, {"f": push}, dt=dt)
            x, ok = robust(levels, A, lba, uba, lbx, ubx)
            if not ok:
                failed[0] += 1
                return native.step(q, {"f": push}, dt=dt)
            return x[:len(q)]

        judged = {"exact": 0, "ticks": 0, "dq": 0.0}

        def check(q, push, dq):
            qp = interpreted.problem(q, {"f": push}, dt=period)
            residuals, excess = kkt_excess(qp, np.array(native._runner.x), damping_last)
            judged["ticks"] += 1
            judged["exact"] += max(residuals) <= 1e-9 and excess <= 1e-9
            levels, A, lba, uba, lbx, ubx = level_data(interpreted, q, {"f": push}, dt=period)
            x, ok = robust(levels, A, lba, uba, lbx, ubx)
            if ok:
                judged["dq"] = max(judged["dq"], float(np.max(np.abs(dq - x[:len(q)]))))

        for label, step in (("generated", lambda q, f, dt: native.step(q, {"f": f}, dt=dt)),
                            ("interpreted", lambda q, f, dt: interpreted.step(q, {"f": f}, dt=dt)),
                            ("exact", exact)):
            tilt, ticks = run(period, seconds, step, check if label == "generated" else None)
            note = f"   (reference failed at {failed[0]} ticks: generated's answer)" if label == "exact" else ""
            print(f"{period * 1e3:5.0f}ms {label:>12s} {ticks:6d} {tilt * 1e6:12.3f}{note}", flush=True)
        print(f"        generated's ticks exact by each level's KKT: {judged['exact']} of {judged['ticks']}; "
              f"largest |dq - dq_reference| {judged['dq']:.1e}")


if __name__ == "__main__":
    main()
