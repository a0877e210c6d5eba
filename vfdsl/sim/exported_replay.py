"""An exported controller's replay as a trace (``vfdsl replay-trace``): the ticks a C build was fed (``./replay <
ticks.txt``) and the lines it answered, turned into vfdsl's trace (CSV, Parquet or an MCAP file of ROS 2 messages,
:mod:`vfdsl.sim.mcap_trace`), so that a run of the exported C controller is looked at as a simulation is.

    ticks.txt     one tick a line: q, every input in declaration order, optionally every param (replay.c's input)
    replayed.txt  one line a tick: ``STATUS dq...`` [`` | PHASE``] [`` # force(3) set-point(6) goal(3) depth(3)
                  following``], or ``error CODE MESSAGE`` for a refused tick (replay.c's output)

Tick k is at t = k dt (dt: ``--dt``, else the task's scene period). The params are the task's defaults (or
``--params FILE``) until a tick line sets them, as in the replay (a line whose params the replay refused sets none). A refused tick has the error's code as its status
(negative), ``error CODE MESSAGE`` as its violations, and no dq (NaN).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from types import SimpleNamespace

import numpy as np

import vfdsl
from vfdsl.errors import Span, VfError
from vfdsl.export.selftest import READOUT_NUMBERS, parse_answer
from vfdsl.files import check_outputs, check_writable, path_argument, task_sources
from vfdsl.ir import model as ir
from vfdsl.kinematics.robot import Robot
from vfdsl.objectives.haptics import teleop_terms
from vfdsl.runtime.qp import StepStatus
from vfdsl.runtime.values import ASSUMED_PERIOD, dt_range
from vfdsl.sim import trace as tr

PARAMS_REFUSED = -7
"""VF_ERR_PARAM: the replay refused the line's params and ran no tick; the controller kept the ones before."""
ERROR_CODES = range(-11, 0)
"""The exported API's VF_ERR_* codes (api.h): an ``error CODE`` line's code is one of them."""
STATUSES = range(int(StepStatus(sum(StepStatus))) + 1)
"""A tick's status: its StepStatus bits (api.h's VF_OPTIMAL ... VF_UNCERTIFIED)."""

DESCRIPTION = """\
Turn a run of an exported C controller into a trace: the ticks its replay program was fed (./replay < ticks.txt)
and the lines it answered (> replayed.txt) become the trace `vfdsl simulate --trace` writes: CSV, Parquet, or an
MCAP file of ROS 2 messages for Foxglove, PlotJuggler or RViz (docs/simulate.md), and `vfdsl view --replay`
plays it."""


def add_parser(commands) -> None:
    p = commands.add_parser(
        "replay-trace", help="turn an exported controller's replay (its ticks and its answers) into a trace",
        description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example:\n  vfdsl export tasks/paper_b_virtual_rcm.vf -o vf_b/ && make -C vf_b\n"
               "  vf_b/replay < ticks.txt > replayed.txt\n"
               "  vfdsl replay-trace tasks/paper_b_virtual_rcm.vf ticks.txt replayed.txt -o run.mcap\n\n"
               "The trace has the columns of `vfdsl simulate --trace` that a replay knows (time, q, dq, inputs, params,\n"
               "status, violations; a procedure's phase; a teleoperated task's haptic force, following) and, as MCAP,\n"
               "the topics of docs/simulate.md, the fixtures' markers included.")
    p.add_argument("file", type=path_argument, help="the .vf task file the controller was exported from")
    p.add_argument("ticks", type=path_argument, help="the replay's input: one tick a line (q, inputs[, params])")
    p.add_argument("replayed", type=path_argument, help="the replay's output: one line a tick")
    p.add_argument("-o", "--output", metavar="OUT.csv|OUT.parquet|OUT.mcap", required=True, type=path_argument,
                   help="the trace to write")
    p.add_argument("--dt", metavar="SECONDS", type=float,
                   help="the replay's dt (default: the task's scene period; 1/100 to 10 times it, as the controller)")
    p.add_argument("--params", metavar="FILE", type=path_argument,
                   help="the replay's --params FILE: the params at the start")
    p.set_defaults(run=main)


def main(args: argparse.Namespace) -> int:
    suffix = Path(args.output).suffix.lower()
    if suffix not in tr.FORMATS:
        raise VfError(f"-o {args.output}: write a .csv, a .parquet or an .mcap file")
    tr.check_path(args.output)                 # (Parquet needs pyarrow)
    check_writable(args.output)
    task = vfdsl.load(args.file)
    check_outputs({"-o": args.output}, [*task_sources(task), ("the ticks file", args.ticks),
                                        ("the replayed file", args.replayed), ("the params file", args.params)])
    dt = args.dt if args.dt is not None else (task.scene.period or ASSUMED_PERIOD)
    low, high = dt_range(task.scene.period)
    if not (np.isfinite(dt) and dt > 0):
        raise VfError(f"--dt {args.dt}: a period in seconds, more than 0")
    if not low <= dt <= high:
        raise VfError(f"--dt {args.dt:g}: the exported controller steps at {low:g} s to {high:g} s (1/100 to 10 times "
                      f"its scene's period, {task.scene.period or ASSUMED_PERIOD:g} s); it refuses every other dt",
                      hint="give the --dt the replay ran with, in seconds (e.g. 0.001 for a 1 kHz loop)")
    start = _numbers(Path(args.params), 1, " ".join(_lines(Path(args.params)))) if args.params else None
    trace = read(task, Path(args.ticks), Path(args.replayed), dt, start)
    result = SimpleNamespace(trace=trace, trial=0, seed=0, grid=[])
    out = Path(args.output)
    if suffix == ".mcap":
        from vfdsl.sim.mcap_trace import write_mcap
        write_mcap(out, [result], task)
    else:
        tr.write(out, [result], task.name, str(args.file))
    print(f"{out}: {len(trace['tick'])} ticks of {task.name} at dt {dt:g} s")
    return 0


def read(task: ir.Task, ticks: Path, replayed: Path, dt: float, start_params=None) -> dict:
    """The trace columns (:mod:`vfdsl.sim.trace`) of a replay: ``ticks`` fed to it, ``replayed`` its answers."""
    robot = Robot.load(task.robots[0].urdf)
    nq = len(robot.joint_names)
    nu = len(tr.input_columns(task))
    params = tr.runtime_params(task)
    current = np.concatenate([tr.flat_param(d.value) for d in params]) if params else np.zeros(0)
    if start_params is not None:
        if len(start_params) != len(current):
            raise VfError(f"--params: {len(start_params)} numbers, expected {len(current)} (every param in order)")
        current = np.asarray(start_params, dtype=float)
    fed = [(n, line) for n, line in enumerate(_lines(ticks), start=1) if line.split()]
    answers = [(n, line) for n, line in enumerate(_lines(replayed), start=1) if line.strip()]
    if not fed:
        raise VfError(f"{ticks} holds no tick (it is empty or blank): a trace needs at least one",
                      hint="give the file the replay was fed, one tick a line")
    if len(answers) != len(fed):
        raise VfError(f"{replayed}: {len(answers)} lines for the {len(fed)} ticks of {ticks}: the replay's output of "
                      "another input, or cut short")
    teleop = bool(teleop_terms(task))
    rows = {"q": [], "u": [], "p": [], "dq": [], "status": [], "violations": [], "phase": [], "haptic": [],
            "following": []}
    for (n, line), (m, answer) in zip(fed, answers):
        values = _numbers(ticks, n, line)
        if len(values) not in (nq + nu, nq + nu + len(current)) or (len(values) > nq + nu and not len(current)):
            raise VfError(f"{len(values)} numbers, expected {nq + nu} (q, then every input)"
                          + (f" or {nq + nu + len(current)} (then every param)" if len(current) else ""),
                          _at(ticks, n))
        _answer(rows, replayed, m, answer, nq, teleop, [phase.name for phase in task.phases],
                next((phase.name for phase in task.phases if phase.initial), ""))
        if len(values) > nq + nu and rows["status"][-1] != PARAMS_REFUSED:     # refused params were not set
            current = values[nq + nu:]
        rows["q"].append(values[:nq])
        rows["u"].append(values[nq:nq + nu])
        rows["p"].append(current)
    ticks_n = len(fed)
    trace: dict = {"tick": np.arange(ticks_n), "t_s": np.arange(ticks_n) * dt}
    q, dq = np.array(rows["q"]).reshape(ticks_n, nq), np.array(rows["dq"]).reshape(ticks_n, nq)
    for prefix, table in (("q", q), ("dq", dq)):
        for column, values in zip(tr.joint_columns(prefix, robot.joint_names, robot.joint_types), table.T):
            trace[column] = values
    u = np.array(rows["u"]).reshape(ticks_n, nu)
    for column, values in zip(tr.input_columns(task), u.T):
        trace[column] = values
    p = np.array(rows["p"]).reshape(ticks_n, -1)
    for column, values in zip([c for d in params for c in tr.param_columns(d)], p.T):
        trace[column] = values
    trace["status"] = np.array(rows["status"], dtype=int)
    trace["violations"] = rows["violations"]
    if task.phases:
        trace["phase"] = rows["phase"]
    if teleop:
        force = np.array(rows["haptic"]).reshape(ticks_n, 3)
        trace.update({"haptic_x_N": force[:, 0], "haptic_y_N": force[:, 1], "haptic_z_N": force[:, 2],
                      "following": np.array(rows["following"], dtype=int)})
    return trace


def _answer(rows: dict, path: Path, n: int, line: str, nq: int, teleop: bool, phases: list[str],
            initial: str) -> None:
    """One line of the replay's output (:func:`vfdsl.export.selftest.parse_answer`) into ``rows``; ``phases``: the
    task's phase names (none without a procedure), ``initial`` the one it starts in (a refused first tick's: the
    machine has not run)."""
    procedure = bool(phases)
    expected = (f"`STATUS` and {nq} dq{' | PHASE' if procedure else ''}"
                f"{f' # and {READOUT_NUMBERS} numbers of readout' if teleop else ''}, or `error CODE MESSAGE`")
    try:
        answer = parse_answer(line)
    except (ValueError, IndexError):
        raise VfError(f"a tick's answer reads {expected}: this line does not", _at(path, n)) from None
    if answer[0] not in (ERROR_CODES if isinstance(answer[1], str) else STATUSES):
        what = (f"an error code is {ERROR_CODES[-1]} to {ERROR_CODES[0]}" if isinstance(answer[1], str)
                else f"a status is {STATUSES[0]} to {STATUSES[-1]} (its bits)")
        raise VfError(f"a tick's answer reads {expected}; {what}, not {answer[0]}", _at(path, n))
    if not all(np.isfinite(part).all() for part in answer[1:] if not isinstance(part, str)):
        raise VfError("a tick's answer holds NaN or inf: the replay writes finite numbers", _at(path, n))
    if isinstance(answer[1], str):                    # a refused tick
        rows["dq"].append(np.full(nq, np.nan))
        rows["status"].append(answer[0])
        rows["violations"].append(f"error {answer[0]} {answer[1]}")
        rows["phase"].append(rows["phase"][-1] if rows["phase"] else initial)
        rows["haptic"].append(np.zeros(3))
        rows["following"].append(0)
        return
    extra = list(answer[2:])
    phase = extra.pop(0).strip() if procedure and extra and isinstance(extra[0], str) else None
    readout = extra.pop(0) if teleop and extra else None
    if len(answer[1]) != nq or extra or (procedure and phase is None) or (teleop and (
            readout is None or len(readout) != READOUT_NUMBERS or readout[-1] not in (0, 1))):
        raise VfError(f"a tick's answer reads {expected}: this line does not", _at(path, n))
    if procedure and phase not in phases:
        raise VfError(f"a tick's answer names phase {phase!r}, which the task lacks: the replay of another task?",
                      _at(path, n), hint=f"its phases: {', '.join(phases)}")
    rows["status"].append(answer[0])
    rows["dq"].append(answer[1])
    rows["violations"].append("")
    rows["phase"].append(phase or "")
    if teleop:
        rows["haptic"].append(readout[:3])
        rows["following"].append(int(readout[-1]))


def _at(path: Path, n: int) -> Span:
    return Span(file=str(path), line=n, column=1, end_line=n, end_column=1)


def _lines(path: Path) -> list[str]:
    try:
        return path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise VfError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") from None


def _numbers(path: Path, n: int, text: str) -> np.ndarray:
    try:
        return np.array([float(x) for x in text.split()], dtype=float)
    except ValueError as exc:
        raise VfError(f"not a number: {exc}", _at(path, n)) from None
