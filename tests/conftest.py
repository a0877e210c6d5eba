"""Shared fixtures: where the example tasks live, a scratch copy of them, a private library cache, and a task with
a port on the tool axis above the tip (:func:`port_task`)."""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import subprocess
from pathlib import Path

import pytest

os.environ.setdefault("VFDSL_OPTIMIZE", "O0")   # the tasks' C built ~4x faster, the same answers (vfdsl.codegen.build)
REPO = Path(__file__).resolve().parent.parent
TASKS_DIR = REPO / "tasks"
DOCS_DIR = REPO / "docs"


@pytest.fixture(scope="session")
def tasks_dir() -> Path:
    """The repository's ``tasks/`` directory (example tasks, their YAML scenes, ``library/``)."""
    return TASKS_DIR


@pytest.fixture
def tasks_copy(tmp_path: Path) -> Path:
    """A scratch copy of ``tasks/`` (scenes and ``library/`` included), so a test may edit files in it."""
    target = tmp_path / "tasks"
    shutil.copytree(TASKS_DIR, target)
    return target


@pytest.fixture(scope="session", autouse=True)
def private_cache(tmp_path_factory) -> Path:
    """Generated libraries go to a cache of this test session, never the user's ~/.cache/vfdsl: one for all the
    session's worker processes (pytest-xdist), beside their own temporary folders, so that a task compiled in one
    is not compiled again in the other (the cache publishes each entry with one rename: processes racing on one
    each publish a whole one, tests/test_codegen.py)."""
    base = tmp_path_factory.getbasetemp()
    cache = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "vfdsl-cache"
    cache.mkdir(exist_ok=True)
    previous = os.environ.get("VFDSL_CACHE")
    os.environ["VFDSL_CACHE"] = str(cache)
    yield cache
    if previous is None:
        del os.environ["VFDSL_CACHE"]
    else:
        os.environ["VFDSL_CACHE"] = previous


@pytest.fixture(scope="session", autouse=True)
def solver_ready(private_cache) -> None:
    """DAQP's C sources fetched and its library built in the session's cache, once, before any test: on a fresh
    machine the first controller waits for them (tens of seconds), which must not count against the timeout of any
    test that runs a command in a subprocess (check, simulate, view, the example tasks).
    Without a compiler or the sources the commands run interpreted, as the tests then expect."""
    from vfdsl.codegen import build
    from vfdsl.errors import VfError

    try:
        build.daqp_library(build.find_compiler())
    except VfError:
        pass


def run_cli(*args: str) -> subprocess.CompletedProcess:
    """``vfdsl ARGS`` run in this process (``vfdsl.cli.main``), its stdout, stderr and exit status captured as a
    CompletedProcess: what the command prints and returns, without a new interpreter's 2-3 s of imports per call
    (tests/test_cli.py runs the installed command in a subprocess). An exception that escapes ``main`` fails the
    test, as a traceback would."""
    from vfdsl import cli

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status = cli.main(list(args))
        except SystemExit as stop:          # argparse: --help (0) and usage errors (2)
            status = stop.code if isinstance(stop.code, int) else 1
    return subprocess.CompletedProcess(["vfdsl", *args], status, out.getvalue(), err.getvalue())


PORT_START = {"panda7": (TASKS_DIR / "lecture_remote_center.vf", "[0, -45, 0, -135, 0, 90, 45]"),
              "shr7": (TASKS_DIR / "paper_b_virtual_rcm.vf",
                       "{x: 0, y: -4.432266, z: -1.035904, rcm_a: 26.309932, rcm_b: 0, roll: 0, insert: 10}")}


def port_task(folder: Path, robot_name: str, distance: float, torque: bool = False):
    """A port ``distance`` m above the tip, on the tool axis, at the start of the example task of ``robot_name``
    (panda7: lecture_remote_center, shr7: paper_b_virtual_rcm), ``require tip passes_through(port) within 0.05``,
    a hand force at 1 mm/s/N (or a torque at 1 deg/s/Nmm), joint limits and speeds; written to ``folder``.
    Returns (task, robot, tip position, tip rotation, the tool axis pointing up)."""
    import vfdsl
    from vfdsl.kinematics.robot import Robot

    example = vfdsl.load(PORT_START[robot_name][0])
    robot = Robot.load(example.robots[0].urdf)
    p0, R0 = robot.frame_pose(example.start, "tool_tip")
    up = R0[:, 2] if R0[2, 2] > 0 else -R0[:, 2]
    port = (p0 + distance * up) * 1e3
    (folder / "port.yaml").write_text(f"units: mm, deg\nperiod: 10 ms\nstart: {PORT_START[robot_name][1]}\n"
                                      f"params:\n  port: [{port[0]:.9f}, {port[1]:.9f}, {port[2]:.9f}]\n")
    kind, gain = ("torque", "angular_gain = 1 deg/s/Nmm") if torque else ("force", "gain = 1 mm/s/N")
    (folder / "port.vf").write_text(
        f'task port\nunits mm, deg\nrobot arm = urdf "{robot_name}"\nframe tip = arm.link("tool_tip")\n'
        f"input hand : {kind}\nparam port : point\nminimize track(tip, hand, {gain})\n"
        "minimize damping() weight 1e-6\nrequire tip passes_through(port) within 0.05 resolution 8\n"
        f'require joint_limits()\nrequire joint_speed()\nscene "{folder / "port.yaml"}"\n')
    return vfdsl.load(folder / "port.vf"), robot, p0, R0, up
