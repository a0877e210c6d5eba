"""Build an exported folder and compare its ``replay`` with ``Controller.step()`` on the same closed loop.

    ticks = record(ctrl, count=200)            # q_{k+1} = q_k + dq_k from the start, a user pushing on every input
    build(directory)                           # make (needs make and a C compiler)
    answers = replay(directory, [t.line() for t in ticks], ticks[0].dt)   # [(status or code, dq or message)]

``vfdsl export --self-test`` and tests/test_export.py use these; each tick is one line of numbers written with 17
significant digits, so C reads back the very doubles Python used.
"""

from __future__ import annotations

import math
import shutil
import subprocess
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vfdsl.errors import VfError
from vfdsl.export.writer import Export
from vfdsl.inputs import INPUT_TYPES

MAX_TICKS = 100_000
"""The most ticks ``--self-test`` records and replays: on experiment B, 58 s and 379 MB at most in all (200 ticks:
35 s, 181 MB, the build of the copy included)."""

@dataclass(frozen=True)
class Tick:
    """One recorded tick: the arguments (q, inputs flat in declaration order, dt, the params' numbers when the
    tick sets them) and Python's answer (a teleoperated task's with its readout, as replay prints it)."""

    q: np.ndarray
    u: np.ndarray
    dt: float
    status: int
    dq: np.ndarray
    p: np.ndarray | None = None
    readout: np.ndarray | None = None

    def line(self) -> str:
        """replay's line: q, the inputs, then the params when the tick carries them."""
        return " ".join(f"{x:.17g}" for x in (*self.q, *self.u, *(() if self.p is None else self.p)))


def user_inputs(ctrl, k: int) -> dict[str, np.ndarray]:
    """A hand pushing on every input along a slowly turning direction (different rates per component), each
    component up to its input type's self-test scale (a firm hand, a slow joystick)."""
    types = {d.name: d.type for d in ctrl.task.inputs}
    return {name: np.array([s * math.sin(0.011 * (j + 1) * k + j)
                            for j, s in enumerate(INPUT_TYPES[types[name]].self_test_scale)])
            for name in ctrl.input_sizes}


def record(ctrl, count: int, dt: float | None = None,
           params: dict | Callable[[int], dict] | None = None) -> list[Tick]:
    """``count`` closed-loop ticks of ``ctrl`` (a fresh Controller) from the task's start, dt the scene's period
    (0.01 s when it has none), ``params`` (the run-time params, as ``Controller.step`` takes them) or the
    defaults. ``params`` a function: tick k's params, ``params(k)``, which each tick then carries in its line."""
    dt = dt or ctrl.default_dt or 0.01
    q = np.array(ctrl.task.start if ctrl.task.start is not None else np.zeros(ctrl.nq), dtype=float)
    ticks = []
    for k in range(count):
        inputs = user_inputs(ctrl, k)
        given = params(k) if callable(params) else params
        dq = ctrl.step(q, inputs, given, dt)
        u = np.concatenate([inputs[name] for name in ctrl.input_sizes]) if inputs else np.zeros(0)
        p = ctrl.param_vector(given) if callable(params) else None
        ticks.append(Tick(q.copy(), u, dt, int(ctrl.status), dq.copy(), p, readout_numbers(ctrl.teleop)))
        q = q + dq
    return ticks


READOUT_NUMBERS = 16
"""Numbers of a readout as replay prints it (:func:`readout_numbers`): force 3, set-point 6, goal 3, depth 3,
following 1."""


def readout_numbers(out) -> np.ndarray | None:
    """A teleoperation readout (Controller.teleop) as replay prints it: force, set-point, goal, depth, following
    (None without one)."""
    return None if out is None else np.concatenate([out.force, out.setpoint, out.goal, out.depth,
                                                    [float(out.following)]])


def build(directory: Path, *targets: str, jobs: int = 2, **variables: str) -> None:
    """``make`` in ``directory`` (VAR=value for each of ``variables``); VfError naming what is missing or failed."""
    make = shutil.which("make")
    if make is None:
        raise VfError("make not found: the self-test builds the export with make",
                      hint="install make and a C compiler (e.g. apt install build-essential), or drop --self-test")
    argv = [make, "-s", f"-j{jobs}", *targets, *(f"{k}={v}" for k, v in variables.items())]
    result = subprocess.run(argv, cwd=directory, capture_output=True, text=True)
    if result.returncode != 0:
        tail = "\n".join((result.stderr or result.stdout).strip().splitlines()[-15:])
        missing = "not found" in tail or "No such file" in tail
        raise VfError(f"building the export in {directory} failed ({' '.join(argv[1:])}):\n{tail}",
                      hint="install a C compiler (cc) or set CC" if missing else None)


def replay(directory: Path, lines: list[str], dt: float, params: Path | None = None) -> list[tuple]:
    """Run ``directory/replay`` on ``lines``: per line (status, dq) or (error code, message); a procedure's
    (status, dq, phase) for a tick it ran; a teleoperated task's with its readout last (force, set-point, goal,
    depth, following: 16 numbers)."""
    argv = [str(Path(directory) / "replay"), "--dt", repr(dt)] + (["--params", str(params)] if params else [])
    result = subprocess.run(argv, input="\n".join(lines) + "\n", capture_output=True, text=True)
    if result.returncode != 0:
        raise VfError(f"replay failed with status {result.returncode}: {result.stderr.strip()}")
    return [parse_answer(out) for out in result.stdout.splitlines()]


def parse_answer(line: str) -> tuple:
    """One line of the replay's output: (error code, message) for a refused tick, else (status, dq) with a
    procedure's phase and a teleoperated task's readout after them; ValueError when it is neither."""
    words = line.split()
    if not words:
        raise ValueError("an empty line")
    if words[0] == "error":
        return int(words[1]), " ".join(words[2:])
    line, hashed, readout = line.partition(" # ")
    numbers, bar, phase = line.partition(" | ")
    words = numbers.split()
    return (int(words[0]), np.array([float(x) for x in words[1:]]), *([phase] if bar else []),
            *([np.array([float(x) for x in readout.split()])] if hashed else []))


def check_count(count: int) -> int:
    """``count``, the ticks of a self-test, or VfError when it is not in [1, MAX_TICKS]."""
    if not 1 <= count <= MAX_TICKS:
        raise VfError(f"a self-test replays 1 to {MAX_TICKS:,} ticks, not {count:,}",
                      hint=f"give --self-test a number of ticks up to {MAX_TICKS:,} (default 200)")
    return count


def self_test(ctrl, exported: Export, count: int) -> float:
    """Build a copy of the files of ``exported`` (the folder itself stays as written; other files in it are not
    read) and replay ``count`` ticks (at most :data:`MAX_TICKS`) recorded from ``ctrl``: the largest |dq|
    difference; VfError when a status differs or a tick is refused."""
    ticks = record(ctrl, check_count(count))
    with tempfile.TemporaryDirectory(prefix="vfdsl-export-test-") as tmp:
        copy = Path(tmp) / "export"
        for path in exported.files:
            target = copy / path.relative_to(exported.directory)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, target, follow_symlinks=False)
        build(copy, "replay")
        answers = replay(copy, [t.line() for t in ticks], ticks[0].dt)
    worst = 0.0
    for k, (tick, (status, dq, *rest)) in enumerate(zip(ticks, answers, strict=True)):
        if status != tick.status:
            raise VfError(f"self-test: tick {k}: the C library answered {status} ({dq if status < 0 else 'status'}), "
                          f"Python's step() status {tick.status}")
        worst = max(worst, float(np.max(np.abs(dq - tick.dq), initial=0.0)))
        if tick.readout is not None:     # the haptic readout too (N and m: compared as dq is)
            worst = max(worst, float(np.max(np.abs(rest[-1] - tick.readout))))
    return worst
