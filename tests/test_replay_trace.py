"""`vfdsl replay-trace` on what a user may hand it (issue 36, the export's replay as a trace): the ticks and answers of
a replay become the trace's rows, params set by a tick line kept for the next, a refused tick kept as its error; and
every mistaken input (a missing or unreadable file, a line of other numbers, answers of other ticks, a bad dt or
params file, an output it cannot write) is refused with a message, exit 2, no traceback. The C build itself is
tested in tests/test_export_teleop.py."""

from __future__ import annotations

import csv

import pytest

from vfdsl.cli import main

from conftest import TASKS_DIR

PAPER_B = TASKS_DIR / "paper_b_virtual_rcm.vf"       # 7 joints, a torque input (3), params pivot and axis (6)
Q = "0.1 0.2 0.3 0.4 0.5 0.6 0.7"


def _files(tmp_path, ticks: str, answers: str):
    t, r = tmp_path / "ticks.txt", tmp_path / "replayed.txt"
    t.write_text(ticks)
    r.write_text(answers)
    return t, r


def test_ticks_and_answers_become_the_traces_rows(tmp_path):
    ticks, answers = _files(tmp_path, f"{Q} 0 0 0.01\n\n{Q} 0 0 0.02 0 0 0.3 0 0 1\n{Q} 0 0 0.03\n",
                            "0 1 2 3 4 5 6 7\n\n1 0 0 0 0 0 0 0\nerror -3 a joint value is not finite\n")
    out = tmp_path / "run.csv"
    assert main(["replay-trace", str(PAPER_B), str(ticks), str(answers), "-o", str(out), "--dt", "0.005"]) == 0
    rows = list(csv.DictReader(out.open()))
    assert [float(r["t_s"]) for r in rows] == [0.0, 0.005, 0.01]
    assert [int(r["status"]) for r in rows] == [0, 1, -3]
    dq = [c for c in rows[0] if c.startswith("dq.")]
    assert rows[2]["violations"] == "error -3 a joint value is not finite" and rows[2][dq[0]] == ""
    assert [float(rows[0][c]) for c in dq] == [1, 2, 3, 4, 5, 6, 7] and float(rows[1]["input.tau.tz_Nm"]) == 0.02
    z = [c for c in rows[0] if c.startswith("param.pivot.") and c.endswith("z_m")][0]
    assert [float(r[z]) for r in rows] == [float(rows[0][z]), 0.3, 0.3]      # set by tick 2, kept for tick 3


def test_params_the_replay_refused_are_not_the_traces_params(tmp_path):
    """A line whose params the replay refused (`error -7`: a zero axis) ran no tick and set nothing: the trace keeps
    the params before it, for that row and the next (it showed the zero axis, which the controller never had)."""
    ticks, answers = _files(tmp_path, f"{Q} 0 0 0.01 0 0 0.3 0 0 1\n{Q} 0 0 0.02 0 0 0.4 0 0 0\n{Q} 0 0 0.03\n",
                            "0 1 2 3 4 5 6 7\nerror -7 a param value is NaN or inf, or fails a check: param 'axis' must "
                            "not be a zero direction\n0 1 2 3 4 5 6 7\n")
    out = tmp_path / "run.csv"
    assert main(["replay-trace", str(PAPER_B), str(ticks), str(answers), "-o", str(out), "--dt", "0.005"]) == 0
    rows = list(csv.DictReader(out.open()))
    assert [int(r["status"]) for r in rows] == [0, -7, 0]
    assert [float(r["param.axis.z"]) for r in rows] == [1.0] * 3
    assert [float(r["param.pivot.z_m"]) for r in rows] == [0.3] * 3


@pytest.mark.parametrize("ticks, answers, extra, message", [
    (None, "0 0 0 0 0 0 0 0\n", [], "cannot read"),
    (f"{Q} 0 0\n", "0 0 0 0 0 0 0 0\n", [], "ticks.txt:1:1: error: 9 numbers, expected 10"),
    (f"{Q} 0 0 x\n", "0 0 0 0 0 0 0 0\n", [], "ticks.txt:1:1: error: not a number"),
    (f"{Q} 0 0 0\n{Q} 0 0 0\n", "0 0 0 0 0 0 0 0\n", [], "1 lines for the 2 ticks"),
    (f"{Q} 0 0 0\n", "0 0 0\n", [], "replayed.txt:1:1: error: a tick's answer reads `STATUS` and 7 dq"),
    (f"{Q} 0 0 0\n", "0 0 0 0 0 0 0 0\n", ["--dt", "nan"], "--dt nan: a period in seconds"),
    (f"{Q} 0 0 0\n", "0 0 0 0 0 0 0 0\n", ["--dt", "1e308"], "--dt 1e+308: the exported controller steps at 0.0001 s"),
    (f"{Q} 0 0 0\n", "0 0 0 0 0 0 0 0\n", ["--dt", "1e-320"], "--dt 9.99989e-321: the exported controller steps"),
    (f"{Q} 0 0 0\n", "99999999999999999999 0 0 0 0 0 0 0\n", [], "a status is 0 to 15 (its bits), not 999"),
    (f"{Q} 0 0 0\n", "-7 0 0 0 0 0 0 0\n", [], ("replayed.txt:1:1: error: a tick's answer reads `STATUS` and 7 dq, "
                                                "or `error CODE MESSAGE`; a status is 0 to 15 (its bits), not -7")),
    (f"{Q} 0 0 0\n", "error 99999999999999999999 x\n", [], "an error code is -1 to -11, not 999"),
    (f"{Q} 0 0 0\n", "error 3 x\n", [], "an error code is -1 to -11, not 3"),
    (f"{Q} 0 0 0\n", "0 nan 0 0 0 0 0 inf\n", [], "replayed.txt:1:1: error: a tick's answer holds NaN or inf"),
    (f"{Q} 0 0 0\n", "0 0 0 0 0 0 0 0\n", ["--params", "PARAMS"], "--params: 2 numbers, expected 6"),
    (f"{Q} 0 0 0\n", "0 0 0 0 0 0 0 0\n", ["--params", "missing.txt"], "cannot read missing.txt"),
    (f"{Q} 0 0 0\n", "0 0 0 0 0 0 0 0\n", ["-o", "/nonexistent/run.csv"], "cannot write /nonexistent/run.csv"),
    ("", "", [], "ticks.txt holds no tick (it is empty or blank)"),       # a reshape of no rows: ValueError
    (" \n\n", "\n", ["-o", "run.mcap"], "ticks.txt holds no tick"),
    (f"{Q} 0 0 0\n", "0 0 0 0 0 0 0 0\n", ["-o", "run.txt"], "-o run.txt: write a .csv, a .parquet or an .mcap"),
    (f"{Q} 0 0 0\n", "0 0 0 0 0 0 0 0\n", ["-o", "PARAMS.csv", "--params", "PARAMS.csv"],
     "-o PARAMS.csv is the params file: writing the output there would destroy it"),
])
def test_mistaken_input_is_refused_without_a_traceback(tmp_path, capsys, monkeypatch, ticks, answers, extra, message):
    monkeypatch.chdir(tmp_path)
    t, r = _files(tmp_path, ticks or "", answers)
    if ticks is None:
        t.unlink()
    (tmp_path / "PARAMS").write_text("1 2\n")
    (tmp_path / "PARAMS.csv").write_text("1 2\n")
    args = ["replay-trace", str(PAPER_B), str(t), str(r)] + (["-o", "run.csv"] if "-o" not in extra else []) + extra
    assert main(args) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err, err
    assert (tmp_path / "PARAMS.csv").read_text() == "1 2\n"


@pytest.mark.parametrize("answer, message", [
    ("0 0 0 0 0 0 0 0 | nowhere", "a tick's answer names phase 'nowhere', which the task lacks"),
    ("0 0 0 0 0 0 0 0 | ", "a tick's answer names phase '', which the task lacks"),
])
def test_a_phase_the_task_lacks_is_refused(tmp_path, capsys, answer, message):
    """A procedure's answer names one of its phases (an answer of another task's replay named any word)."""
    ticks, answers = _files(tmp_path, "0 0 0 0 0 0 0.005 0 0 0 0\n", answer + "\n")
    task = TASKS_DIR / "procedures" / "needle_procedure.vf"
    assert main(["replay-trace", str(task), str(ticks), str(answers), "-o", str(tmp_path / "run.csv")]) == 2
    err = capsys.readouterr().err
    assert message in err and "replayed.txt:1:1" in err and "Traceback" not in err, err
    assert not (tmp_path / "run.csv").exists()


def test_an_output_that_is_an_input_is_refused_and_the_file_kept(tmp_path, capsys):
    """-o naming the ticks, the answers or the task would replace what the trace is made from."""
    ticks, answers = _files(tmp_path, f"{Q} 0 0 0\n", "0 0 0 0 0 0 0 0\n")
    for out, what in ((tmp_path / "ticks.csv", "the ticks file"), (tmp_path / "replayed.csv", "the replayed file")):
        out.symlink_to(ticks if what == "the ticks file" else answers)
        assert main(["replay-trace", str(PAPER_B), str(ticks), str(answers), "-o", str(out)]) == 2
        err = capsys.readouterr().err
        assert f"-o {out} is {what}" in err and "Traceback" not in err, err
    assert ticks.read_text() == f"{Q} 0 0 0\n" and answers.read_text() == "0 0 0 0 0 0 0 0\n"


def test_a_refused_first_tick_of_a_procedure_is_in_its_initial_phase(tmp_path):
    """A tick the replay refused before any other ran no machine: the trace's phase is the one the procedure starts
    in (it was '', no phase of the task), and the next tick's is its answer's."""
    ticks, answers = _files(tmp_path, "0 0 0 0 0 0 0.005 0 0 0 0\n0 0 0 0 0 0 0.005 0 0 0 0\n",
                            "error -3 a joint value is not finite\n0 0 0 0 0 0 0 0 | insert\n")
    task = TASKS_DIR / "procedures" / "needle_procedure.vf"
    out = tmp_path / "run.csv"
    assert main(["replay-trace", str(task), str(ticks), str(answers), "-o", str(out)]) == 0
    rows = list(csv.DictReader(out.open()))
    assert [r["phase"] for r in rows] == ["approach", "insert"]
