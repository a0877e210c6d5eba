"""Tick time of a mesh fixture against the mesh's size, beside the same task without it, in one run.

    python benchmarks/mesh.py            # 1k, 10k, 100k triangles; 3,000 timed ticks each
    python benchmarks/mesh.py --quick    # 1k and 10k, 1,000 ticks
    python benchmarks/mesh.py --rounds 9 # the query from C called 9 times at each state (5 by default)

The task is tasks/sinus_channel.vf (the shaft, a capsule, inside a curved channel), with its channel rebuilt at
1k, 10k and 100k triangles (the same tube, finer: tasks/anatomy/make_meshes.py's ``tube``), and without the
``inside_mesh`` line (the baseline: same robot, objectives, speed limits). Each tick is Controller.step on the
generated C path, timed with time.perf_counter_ns after 500 warm-up ticks, GC disabled, over the states of one
closed-loop run recorded beforehand (the hand pushes the shaft into the bend's wall, then toward the target;
the same states for every variant). Also timed: the proximity query alone, from C (benchmarks/mesh_query.c, compiled
with the query's source and the task's flags) at the same states' segments, every state in turn, ROUNDS times over:
wall and thread CPU time, over every call and over the states of each state's median over the rounds. Progress on
stderr, the report on stdout.
"""

from __future__ import annotations

import argparse
import gc
import importlib.util
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import vfdsl
from vfdsl.check.kinematics import frame_pose
from vfdsl.codegen.build import FLAGS, find_compiler
from vfdsl.compiler.mesh_rows import K, REACH
from vfdsl.kinematics.robot import Robot
from vfdsl.mesh.external import mesh_query
from vfdsl.mesh.load import read_mesh

ROOT = Path(__file__).resolve().parent.parent
TASK = (ROOT / "tasks" / "sinus_channel.vf").read_text()
SIZES = {1_000: (16, 32), 10_000: (48, 105), 100_000: (128, 390)}   # triangles: (sections, rings), within the limit
WARMUP = 500
ROUNDS = 5


def _tube_module():
    spec = importlib.util.spec_from_file_location("make_meshes", ROOT / "tasks" / "anatomy" / "make_meshes.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def channel(folder: Path, sections: int, rings: int) -> Path:
    make = _tube_module()
    z = np.linspace(320.0, 228.0, rings)
    x = make.BEND * (np.clip(295.0 - z, 0, None) / 65.0) ** 2
    mesh = make.tube(np.column_stack([x, np.zeros_like(z), z]), make.RADIUS, sections)
    path = folder / f"channel_{len(mesh.faces)}.stl"
    mesh.export(path)
    return path


def task_file(folder: Path, stl: Path | None) -> Path:
    text = TASK.replace('import "library/fixtures.vf"', f'import "{ROOT / "tasks" / "library" / "fixtures.vf"}"')
    if stl is None:
        text = "\n".join(line for line in text.splitlines()
                         if not line.startswith(("param channel", "require tip inside_mesh"))) + "\n"
    else:
        text = text.replace('"anatomy/channel.stl"', f'"{stl.name}"')
    name = f"t_{stl.stem if stl else 'none'}"
    path = folder / f"{name}.vf"
    path.write_text(text.replace("task sinus_channel", f"task {name}"))
    (folder / f"{name}.yaml").write_text((ROOT / "tasks" / "sinus_channel.yaml").read_text())
    return path


def record(ctrl, task, ticks: int) -> list:
    """Joint states of a closed loop: 1 s pushing into the bend's wall, then toward the target."""
    q, states = task.start.copy(), []
    target = np.array([0.0096, 0.0, 0.236])
    for k in range(ticks):
        p = ctrl.frames(q)["tip"].position
        e = target - p
        f = np.array([20.0, 0.0, -2.0]) if k < 100 else 10 * e / max(np.linalg.norm(e), 2e-3)
        states.append((q.copy(), {"f": f}))
        q = q + ctrl.step(q, {"f": f})
    return states


def query_from_c(mesh, segments, folder: Path, rounds: int) -> tuple[np.ndarray, np.ndarray]:
    """The query of ``mesh`` (the example's cutoff, keep in) timed from C at each segment (a, b), every segment in
    turn, ``rounds`` times over: (wall median, p99, p99.9, max, then the same of CPU time, us) over every call, and
    over the states of each state's median over the rounds."""
    query = mesh_query(mesh, K)
    program = folder / f"time_{query.name}"
    subprocess.run([*find_compiler().command, *FLAGS, f"-DQUERY={query.name}", f"-DROWS={K}",
                    str(ROOT / "benchmarks" / "mesh_query.c"), str(query.source), "-o", str(program), "-lm"],
                   check=True, capture_output=True)
    text = "".join(" ".join(f"{x:.17g}" for x in (*a, *b)) + "\n" for a, b in segments)
    out = subprocess.run([str(program), str(rounds), f"{0.0015 + REACH!r}", "-1"], input=text, check=True,
                         capture_output=True, text=True).stdout.split("\n")
    return np.array(out[0].split(), float), np.array(out[1].split(), float)


def timed(call, states) -> np.ndarray:
    for q, u in states[:WARMUP]:
        call(q, u)
    gc.disable()
    try:
        out = np.empty(len(states))
        for i, (q, u) in enumerate(states):
            begin = time.perf_counter_ns()
            call(q, u)
            out[i] = time.perf_counter_ns() - begin
    finally:
        gc.enable()
    return out / 1e3


def c_line(name: str, figures: np.ndarray) -> str:
    return f"| {name} | " + " | ".join(f"{x:.1f}" for x in figures) + " |"


def line(name: str, us: np.ndarray) -> str:
    return c_line(name, np.percentile(us, [50, 99, 99.9, 100]))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--rounds", type=int, default=ROUNDS, help="calls of the query from C at each state")
    args = parser.parse_args()
    sizes = [1_000, 10_000] if args.quick else list(SIZES)
    ticks = 1_000 if args.quick else 3_000
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        base_task = vfdsl.load(task_file(folder, None))
        base = vfdsl.compile(base_task, backend="native")
        states = None
        for n in sizes:
            stl = channel(folder, *SIZES[n])
            print(f"{stl.name}: compiling", file=sys.stderr)
            begin = time.perf_counter()
            task = vfdsl.load(task_file(folder, stl))
            ctrl = vfdsl.compile(task, backend="native")
            build = time.perf_counter() - begin
            if states is None:
                states = record(ctrl, task, ticks)
            mesh = read_mesh(stl, 1e-3)
            robot = Robot.load(task.robots[0].urdf)
            segments = [(frame_pose(robot, task.frame("tip"), q)[0], frame_pose(robot, task.frame("shaft"), q)[0])
                        for q, _ in states]
            print(f"{stl.name}: the query from C, {args.rounds} rounds", file=sys.stderr)
            from_c = query_from_c(mesh, segments, folder, args.rounds)
            rows.append((len(mesh.triangles), timed(lambda q, u: ctrl.step(q, u), states), from_c, build))
        base_us = timed(lambda q, u: base.step(q, u), states)
    print(f"# mesh fixture tick time ({platform.processor() or platform.machine()}, {ticks} ticks, us)\n")
    print("| variant | median | p99 | p99.9 | max |\n|---|---|---|---|---|")
    print(line("without the mesh", base_us))
    for n, us, _, _ in rows:
        print(line(f"{n:,} triangles (tick)", us))
    print(f"\n# the query alone, from C ({ticks} states x {args.rounds} rounds, us)\n")
    print("| query | wall: median | p99 | p99.9 | max | CPU: median | p99 | p99.9 | max |\n" + "|---" * 9 + "|")
    for n, _, (calls, per_state), _ in rows:
        print(c_line(f"{n:,} triangles, every call", calls))
        print(c_line(f"{n:,} triangles, each state's median", per_state))
    print("\nfirst build (tables, query, task library), s: "
          + ", ".join(f"{n:,}: {build:.1f}" for n, _, _, build in rows))


if __name__ == "__main__":
    main()
