"""`vfdsl export` of a teleoperated task (issue 34): the exported library evaluates the haptic readout after each
tick (codegen/teleop_readout.h over the generated <prefix>_teleop_readout, the function Python's native Controller
evaluates), and ./replay gives Controller.step()'s dq, phase and readout (force, set-point, goal, following) to
1e-12, tick by tick, through contact with the mesh, a clutch and a re-engage; no heap call after _new."""

from __future__ import annotations

import ctypes
import shutil
from pathlib import Path

import numpy as np
import pytest

import vfdsl
from vfdsl.export.selftest import readout_numbers, replay

from test_export import api_caller, built_export, heap_calls

pytestmark = pytest.mark.skipif(shutil.which("make") is None or shutil.which("cc") is None,
                                reason="needs make and a C compiler")
TASK = Path(__file__).resolve().parent.parent / "tasks" / "teleop" / "teleop_keep_out.vf"
DT = 0.001


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    task = vfdsl.load(TASK)
    return task, built_export(task, tmp_path_factory.mktemp("teleop"))


@pytest.fixture(scope="module")
def recorded(exported):
    """The master down onto the bone (contact from ~0.9 s), clutched and brought back, re-engaged and moved aside:
    (replay line, status, dq, phase, readout) per tick of the native controller."""
    task = exported[0]
    ctrl = vfdsl.compile(task, backend="native")
    q = np.array(task.start, dtype=float)
    ticks = []
    for k in range(2200):
        t = k * DT
        down = min(t / 1.0, 1.0) * np.array([0.004, 0.002, -0.03]) * (1.0 if t < 1.4 else max(0.0, 1 - (t - 1.4) / 0.3))
        aside = max(0.0, t - 1.8) / 0.4 * np.array([-0.01, 0.005, 0.0])
        master = np.concatenate([down + aside, [0.0, 0.0, 0.3 * max(0.0, t - 1.8)]])
        clutch = 1.0 if 1.35 <= t < 1.75 else 0.0
        dq = ctrl.step(q, {"master": master, "clutch": [clutch]}, dt=DT)
        line = " ".join(f"{x:.17g}" for x in (*q, *master, clutch))
        ticks.append((line, int(ctrl.status), dq.copy(), ctrl.phase, readout_numbers(ctrl.teleop)))
        q = q + dq
    forces = np.array([np.linalg.norm(t[4][:3]) for t in ticks])
    assert forces.max() > 0.5 and {t[3] for t in ticks} == {"following", "clutched"}    # the run met the bone
    return ticks


def test_replay_gives_the_native_controllers_dq_and_haptic_readout(exported, recorded):
    _, result = exported
    answers = replay(result.directory, [t[0] for t in recorded], DT)
    assert [a[0] for a in answers] == [t[1] for t in recorded]
    assert [a[2] for a in answers] == [t[3] for t in recorded]
    assert max(float(np.max(np.abs(a[1] - t[2]))) for a, t in zip(answers, recorded)) <= 1e-12
    assert max(float(np.max(np.abs(a[3] - t[4]))) for a, t in zip(answers, recorded)) <= 1e-12


def test_no_heap_call_after_new_with_the_readout(exported, recorded, tmp_path):
    at_new, ticked, later = heap_calls(exported[1], [t[0] for t in recorded[:1500]], DT, tmp_path)
    assert at_new > 0 and ticked == 0 and later == 0


class Readout(ctypes.Structure):
    _fields_ = [("force", ctypes.c_double * 3), ("setpoint", ctypes.c_double * 6), ("goal", ctypes.c_double * 3),
                ("depth", ctypes.c_double * 3), ("following", ctypes.c_int)]


def test_the_api_gives_the_readout_and_the_acting_rows(exported, recorded):
    task, result = exported
    call = api_caller(result)

    assert call("is_teleoperated")() == 1
    new, free = call("new", ctypes.c_void_p), call("free", None, ctypes.c_void_p)
    step = call("step", ctypes.c_int, ctypes.c_void_p, ctypes.POINTER(ctypes.c_double),
                ctypes.POINTER(ctypes.c_double), ctypes.c_double, ctypes.POINTER(ctypes.c_double))
    teleop = call("teleop", ctypes.c_int, ctypes.c_void_p, ctypes.POINTER(Readout))
    acting = call("row_acting", ctypes.c_int, ctypes.c_void_p, ctypes.c_int)
    rows = call("num_rows")()
    ctrl = new()
    try:
        out = Readout()
        contact = max(range(len(recorded)), key=lambda k: np.linalg.norm(recorded[k][4][:3]))
        dq = (ctypes.c_double * 6)()
        for k in range(contact + 1):
            numbers = [float(x) for x in recorded[k][0].split()]
            q, u = (ctypes.c_double * 6)(*numbers[:6]), (ctypes.c_double * 7)(*numbers[6:])
            assert step(ctrl, q, u, DT, dq) >= 0
        assert teleop(ctrl, ctypes.byref(out)) == 0
        assert np.allclose(list(out.force), recorded[contact][4][:3], atol=1e-12) and out.following == 1
        assert any(acting(ctrl, i) for i in range(rows)) and acting(ctrl, rows) == 0 and acting(ctrl, -1) == 0
        assert teleop(None, ctypes.byref(out)) < 0 and teleop(ctrl, None) < 0
        assert call("reset", ctypes.c_int, ctypes.c_void_p)(ctrl) == 0
    finally:
        free(ctrl)


def test_replay_trace_turns_the_exported_replay_into_an_mcap_trace(exported, recorded, tmp_path, capsys):
    """`vfdsl replay-trace`: the ticks fed to ./replay and its answers become an MCAP trace whose joints, master,
    haptic force, phase and status are the replay's own (the native controller's to 1e-12), with the fixtures'
    markers; a refused tick (a NaN joint) keeps its error as its status; a cut answer file is refused at its line."""
    import subprocess
    from rosbags.highlevel import AnyReader
    from vfdsl.cli import main
    _, result = exported
    lines = [t[0] for t in recorded[:1500]] + ["nan" + recorded[0][0][recorded[0][0].index(" "):]]
    ticks, replayed, out = tmp_path / "ticks.txt", tmp_path / "replayed.txt", tmp_path / "run.mcap"
    ticks.write_text("\n".join(lines) + "\n")
    with ticks.open() as stdin, replayed.open("w") as stdout:
        subprocess.run([str(result.directory / "replay"), "--dt", repr(DT)], stdin=stdin, stdout=stdout, check=True)
    assert main(["replay-trace", str(TASK), str(ticks), str(replayed), "-o", str(out), "--dt", repr(DT)]) == 0
    found = {}
    with AnyReader([out]) as reader:
        for connection, stamp, raw in reader.messages():
            found.setdefault(connection.topic, []).append((stamp, reader.deserialize(raw, connection.msgtype)))
    assert {"/joint_states", "/tf", "/vfdsl/input/master", "/vfdsl/input/clutch", "/vfdsl/status", "/vfdsl/phase",
            "/vfdsl/haptic", "/vfdsl/fixtures"} <= set(found)
    states = found["/joint_states"]
    assert len(states) == len(lines) and [s for s, _ in states] == [round(k * DT * 1e9) for k in range(len(lines))]
    for k, tick in enumerate(recorded[:1500]):
        numbers = np.array([float(x) for x in tick[0].split()])
        assert np.array_equal(states[k][1].position, numbers[:len(states[k][1].position)])
        assert np.allclose(states[k][1].velocity * DT, tick[2], rtol=0, atol=1e-12)
        force = found["/vfdsl/haptic"][k][1].wrench.force
        assert np.allclose([force.x, force.y, force.z], tick[4][:3], rtol=0, atol=1e-12)
        assert found["/vfdsl/phase"][k][1].data == tick[3] and found["/vfdsl/status"][k][1].data == tick[1]
    assert found["/vfdsl/status"][-1][1].data < 0 and found["/vfdsl/violations"][-1][1].data.startswith("error ")
    replayed.write_text("\n".join(replayed.read_text().splitlines()[:20] + ["0 1 2"] +
                                  replayed.read_text().splitlines()[21:]) + "\n")
    assert main(["replay-trace", str(TASK), str(ticks), str(replayed), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "replayed.txt:21:1" in err and "a tick's answer reads `STATUS` and" in err and "Traceback" not in err


def test_an_input_its_type_refuses_is_named_by_the_error_message(exported):
    """A clutch of 2 or a master 50 m away: the C step refuses them as Controller.step() does, and its message says
    what the inputs' checks ask (it said "an input contains NaN or inf", which these numbers are not)."""
    task, result = exported
    call = api_caller(result)
    new, free = call("new", ctypes.c_void_p), call("free", None, ctypes.c_void_p)
    step = call("step", ctypes.c_int, ctypes.c_void_p, ctypes.POINTER(ctypes.c_double),
                ctypes.POINTER(ctypes.c_double), ctypes.c_double, ctypes.POINTER(ctypes.c_double))
    message = call("error_message", ctypes.c_char_p, ctypes.c_int)(-4).decode()
    assert message.startswith("an input contains NaN or inf, or fails its type's check: ")
    assert "'master' (pose): the position within 10 m" in message and "'clutch' (button): " in message
    python = vfdsl.compile(task, backend="native")
    ctrl = new()
    try:
        q, dq = (ctypes.c_double * 6)(*task.start), (ctypes.c_double * 6)()
        for master, clutch, said in (([0.0] * 6, 2.0, "is a button"), ([50.0] + [0.0] * 5, 0.0, "is a pose")):
            assert step(ctrl, q, (ctypes.c_double * 7)(*master, clutch), DT, dq) == -4 and not any(dq)
            with pytest.raises(vfdsl.VfError, match=said):
                python.step(np.array(task.start), {"master": master, "clutch": [clutch]}, dt=DT)
    finally:
        free(ctrl)
