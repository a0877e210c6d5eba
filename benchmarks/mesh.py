"""Tick time of a mesh fixture against the mesh's size, beside the same task without it, in one run.

    python benchmarks/mesh.py            # 1k, 10k, 100k triangles; 3,000 timed ticks each
    python benchmarks/mesh.py --quick    # 1k and 10k, 1,000 ticks

The task is tasks/sinus_channel.vf (the shaft, a capsule, inside a curved channel), with its channel rebuilt at
1k, 10k and 100k triangles (the same tube, finer: tasks/anatomy/make_meshes.py's ``tube``), and without the
``inside_mesh`` line (the baseline: same robot, objectives, speed limits). Each tick is Controller.step on the
generated C path, timed with time.perf_counter_ns after 500 warm-up ticks, GC disabled, over the states of one
closed-loop run recorded beforehand (the hand pushes the shaft into the bend's wall, then toward the target;
the same states for every variant). Also timed: the proximity query alone, the C function called through ctypes
at the same states (about 1 us of the figure is ctypes' call). Progress on stderr, the report on stdout.
"""

from __future__ import annotations

import argparse
import ctypes
import gc
import importlib.util
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import vfdsl
from vfdsl.check.kinematics import frame_pose
from vfdsl.compiler.mesh_rows import K, REACH
from vfdsl.kinematics.robot import Robot
from vfdsl.mesh.external import mesh_query
from vfdsl.mesh.load import read_mesh

ROOT = Path(__file__).resolve().parent.parent
TASK = (ROOT / "tasks" / "sinus_channel.vf").read_text()
SIZES = {1_000: (16, 32), 10_000: (48, 105), 100_000: (128, 390)}   # triangles: (sections, rings), within the limit
WARMUP = 500


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


def _c_calls(mesh, segments) -> list:
    """The query of ``mesh`` at each segment (a, b) (the example's cutoff, keep in) as a ctypes call of its C
    function, all with one work vector (the walk's memory, CasADi's w)."""
    query = mesh_query(mesh, K)
    library = ctypes.CDLL(str(query.source.parent / f"lib{query.name}.so"))
    function = getattr(library, query.name)
    sizes = [ctypes.c_longlong() for _ in range(4)]
    getattr(library, f"{query.name}_work")(*[ctypes.byref(x) for x in sizes])
    double_p = ctypes.POINTER(ctypes.c_double)
    work = np.zeros(sizes[3].value)
    w = work.ctypes.data_as(double_p)
    outputs = [np.zeros(K), np.zeros(K), np.zeros(3 * K)]
    res = (double_p * 3)(*[x.ctypes.data_as(double_p) for x in outputs])

    def call(a, b):
        inputs = [np.array(a, float), np.array(b, float), np.array([0.0015 + REACH, -1.0])]
        arg = (double_p * 3)(*[x.ctypes.data_as(double_p) for x in inputs])
        return lambda: function(arg, res, None, w, 0) or (inputs, outputs, work)   # keeps the arrays alive
    return [call(a, b) for a, b in segments]


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


def line(name: str, us: np.ndarray) -> str:
    return f"| {name} | {np.median(us):.1f} | {np.percentile(us, 99):.1f} |"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
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
            calls = _c_calls(mesh, [(frame_pose(robot, task.frame("tip"), q)[0],
                                     frame_pose(robot, task.frame("shaft"), q)[0]) for q, _ in states])
            q_us = timed(lambda call, _: call(), [(call, None) for call in calls])
            rows.append((len(mesh.triangles), timed(lambda q, u: ctrl.step(q, u), states), q_us, build))
        base_us = timed(lambda q, u: base.step(q, u), states)
    print(f"# mesh fixture tick time ({platform.processor() or platform.machine()}, {ticks} ticks, us)\n")
    print("| variant | median | p99 |\n|---|---|---|")
    print(line("without the mesh", base_us))
    for n, us, q_us, build in rows:
        print(line(f"{n:,} triangles (tick)", us))
        print(line(f"{n:,} triangles (query alone, C through ctypes)", q_us))
    print("\nfirst build (tables, query, task library), s: "
          + ", ".join(f"{n:,}: {build:.1f}" for n, _, _, build in rows))


if __name__ == "__main__":
    main()
