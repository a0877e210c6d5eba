"""Work limits of the commands (vfdsl/limits.py): a value that would fill the memory or run for
days, given as an option or in a scene, exits 2 with a message naming the limit (file:line:col for a
scene value), before any work starts; so does an output that cannot be written and a --cluster address
that answers but is not a Dask scheduler."""

from __future__ import annotations

import os
import socket
import threading
import time

import pytest
from conftest import TASKS_DIR

import vfdsl
from vfdsl.cli import main
from vfdsl.errors import VfError
from vfdsl import limits
from vfdsl.sim import command as sim_command
from vfdsl.sim.cluster import probe

B = str(TASKS_DIR / "paper_b_virtual_rcm.vf")


class _NoRun(Exception):
    """Raised by a stub of the runner: the command got as far as running trials."""


@pytest.fixture
def no_run(monkeypatch):
    """Fail the test's command if it starts running trials (or compiling), recording the call."""
    calls = []

    def run(jobs, workers=1, cluster=None, progress=None):
        calls.append({"jobs": len(jobs), "workers": workers})
        raise _NoRun

    monkeypatch.setattr(sim_command, "run", run)
    return calls


def _refused(capsys, *args) -> str:
    started = time.perf_counter()
    assert main(list(args)) == 2
    assert time.perf_counter() - started < 10
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


@pytest.mark.parametrize("args, message", [
    (["--duration", "1e9s"], "100,000,000,000 control ticks per trial: the limit is 1,000,000"),
    (["--duration", "1e-9s"], "error: a duration of 1e-09 s is not one control tick at a 10 ms period"),
    (["--grid", "duration=1s,4ms"], "--grid duration=0.004: a duration of 0.004 s is not one control tick"),
    (["--period", "1e-9s"], "--period 1e-9s: a period of 1e-09 s is too short: the limit is 1e-05 s"),
    (["--period", "1e-300s"], "a period of 1e-300 s is too short"),
    (["--trials", "1000000000000"], "--trials 1000000000000: 1,000,000,000,000 trials per setting: the limit is 100,000"),
    (["--seed", "-1"], "--seed -1: seed must be a whole number from 0"),
    (["--grid", "duration=1e9s"], "--grid duration=1e+09: 1e+09 s at a 10 ms period"),
    (["--grid", "period=1e-12s,10ms"], "--grid period=1e-12s: a period of 1e-12 s is too short"),
    (["--grid", "period=0.1ms,10ms", "--duration", "200s"], "--grid period=0.0001: 200 s at a 0.1 ms period"),
    (["--trials", "100000", "--duration", "10s"], "this run is 100,000,000 control ticks"),
    (["--grid", "latency=" + ",".join(["0ms"] * 40), "--grid", "noise=" + ",".join(["0mm"] * 40)],
     "the --grid sweep has too many settings: the limit is 1,000"),
])
def test_simulate_options_beyond_a_limit_exit_2_before_any_work(capsys, no_run, args, message):
    err = _refused(capsys, "simulate", B, "--quiet", *args)
    assert message in err
    assert not no_run


@pytest.mark.parametrize("line, column, message", [
    ("duration: 1e9 s", 11, "1e+09 s at a 10 ms period is 100,000,000,000 control ticks per trial"),
    ("duration: 1e-9 s", 11, "a duration of 1e-09 s is not one control tick at a 10 ms period"),
    ("period: 1e-12 s", 9, "a period of 1e-12 s is too short: the limit is 1e-05 s"),
    ("trials: 1000000000000", 9, "1,000,000,000,000 trials per setting"),
    ("seed: -1", 7, "seed must be a whole number from 0"),
    ("duration: 10 s\ntrials: 100000", 9, "100,000 trial(s) of 1,000 control ticks is 100,000,000 ticks: the limit is 20,000,000"),
])
def test_scene_values_beyond_a_limit_point_at_their_line(tmp_path, capsys, no_run, line, column, message):
    scene = tmp_path / "s.sim.yaml"
    scene.write_text(f"units: mm, deg\n{line}\n")
    err = _refused(capsys, "simulate", B, "--scene", str(scene), "--quiet")
    assert f"s.sim.yaml:{1 + line.count(chr(10)) + 1}:{column}: error: {message}" in err


def test_a_short_period_in_the_task_scene_points_at_its_line(tmp_path, capsys):
    (tmp_path / "t.vf").write_text((TASKS_DIR / "paper_b_virtual_rcm.vf").read_text().replace(
        'import "library/', f'import "{TASKS_DIR}/library/'))
    (tmp_path / "t.yaml").write_text((TASKS_DIR / "paper_b_virtual_rcm.yaml").read_text().replace(
        "period: 10 ms", "period: 1e-9 s"))
    err = _refused(capsys, "check", str(tmp_path / "t.vf"))
    assert "t.yaml:" in err and "a period of 1e-09 s is too short" in err


def test_workers_are_capped_at_the_trials_and_the_cores(capsys, no_run):
    with pytest.raises(_NoRun):
        main(["simulate", B, "--quiet", "--duration", "0.1s", "--trials", "2", "--workers", "64"])
    assert no_run == [{"jobs": 2, "workers": 2}] or no_run[0]["workers"] <= 2


@pytest.mark.parametrize("name", ["DIR", "x" * 300 + ".png", "plot.xyz"])
def test_an_unwritable_plot_is_refused_before_the_run(tmp_path, capsys, no_run, name):
    target = tmp_path if name == "DIR" else tmp_path / name
    err = _refused(capsys, "simulate", B, "--quiet", "--duration", "0.1s", "--plot", str(target))
    assert f"cannot write {target}" in err
    assert not no_run and os.listdir(tmp_path) == []


def test_a_writable_plot_path_is_not_left_behind_by_the_check(tmp_path, capsys, no_run):
    with pytest.raises(_NoRun):
        main(["simulate", B, "--quiet", "--duration", "0.1s", "--plot", str(tmp_path / "p.png")])
    assert no_run and not (tmp_path / "p.png").exists()


class _Foreign:
    """A TCP server on 127.0.0.1 that answers every connection with ``reply`` (or nothing) and then holds
    it open; it stops itself after ``lifetime`` seconds at the latest."""

    def __init__(self, reply: bytes | None, lifetime: float = 20.0):
        self.reply = reply
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.sock.settimeout(0.1)
        self.address = f"tcp://127.0.0.1:{self.sock.getsockname()[1]}"
        self.deadline = time.monotonic() + lifetime
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)

    def _serve(self):
        open_conns = []
        while not self.stop.is_set() and time.monotonic() < self.deadline:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                continue
            open_conns.append(conn)
            if self.reply is not None:
                try:
                    conn.sendall(self.reply)
                except OSError:
                    pass
        for conn in open_conns:
            conn.close()
        self.sock.close()

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join(5)


HTTP = b"HTTP/1.1 400 Bad Request\r\nContent-Type: text/plain\r\nContent-Length: 11\r\n\r\nBad Request" * 4


def test_cluster_at_a_server_that_is_not_dask_exits_2_quickly(capsys, no_run):
    with _Foreign(HTTP) as server:
        err = _refused(capsys, "simulate", B, "--quiet", "--duration", "0.1s", "--cluster", server.address)
    assert f"'{server.address}' answers, but not as a Dask scheduler" in err
    assert not no_run


def test_cluster_at_a_silent_server_times_out_within_the_limit():
    with _Foreign(None) as server:
        started = time.perf_counter()
        with pytest.raises(VfError, match="cannot reach a Dask scheduler at .*: no answer within 1 s"):
            probe(server.address, timeout=1.0)
        assert time.perf_counter() - started < 5


@pytest.mark.parametrize("args, message", [
    (["--samples", "1000000000"], "argument --samples: expected a whole number from 0 to 5,000, got 1,000,000,000"),
    (["--seed", "-1"], "argument --seed: expected a whole number from 0 to 4,294,967,295, got -1"),
])
def test_check_options_beyond_a_limit_exit_2(capsys, args, message):
    with pytest.raises(SystemExit) as exit_:
        main(["check", B, *args])
    assert exit_.value.code == 2
    assert message in capsys.readouterr().err


def test_check_through_the_api_refuses_the_same_values():
    task = vfdsl.load(B)
    with pytest.raises(VfError, match="samples must be a whole number from 0 to 5,000"):
        vfdsl.check(task, samples=limits.CHECK_SAMPLES + 1)
    with pytest.raises(VfError, match="seed must be a whole number"):
        vfdsl.check(task, seed=-1)


@pytest.mark.parametrize("overshoot", [float("nan"), -0.1, 0, 10, float("inf"), "10%", True, None])
def test_check_through_the_api_refuses_an_overshoot_the_option_refuses(overshoot):
    # NaN passed every polytope silently (no overshoot warning), a negative one failed them all.
    with pytest.raises(VfError, match="the overshoot must be"):
        vfdsl.check(vfdsl.load(B), overshoot=overshoot, samples=0)


def test_check_through_the_api_refuses_booleans_as_counts():
    with pytest.raises(VfError, match="samples must be a whole number"):
        vfdsl.check(vfdsl.load(B), samples=True)


FAR = ("task far\nunits mm, deg\nrobot shr = urdf \"shr7\"\nframe tip = shr.link(\"tool_tip\")OFFSET\n"
       "input f : force\nparam p : point = POINT\nminimize track(tip, f, gain = 1 mm/s/N)\n"
       "require tip stays_at(p) within 0.1\n")


def _far(tmp_path, offset: str = "", point: str = "[0, 0, 290]"):
    task = tmp_path / "far.vf"
    task.write_text(FAR.replace("OFFSET", offset).replace("POINT", point))
    (tmp_path / "far.yaml").write_text("units: mm, deg\nperiod: 10 ms\n"
                                       "start: {x: 0, y: 0, z: 0, rcm_a: 0, rcm_b: 0, roll: 0, insert: 10}\n")
    return task


@pytest.mark.parametrize("offset, shown", [("[1e300, 0, 0]", "1e+297 m"), ("[0, 2000, 0] m", "2000 m")])
def test_a_frame_a_kilometre_from_its_link_is_refused_at_its_offset(tmp_path, capsys, offset, shown):
    task = _far(tmp_path, f" offset {offset}")
    for command in ("check", "show"):
        err = _refused(capsys, command, str(task))
        assert f"far.vf:4:41: error: frame 'tip' is {shown} from its link: the limit is 1000 m" in err


def test_check_refuses_rows_beyond_the_linear_programs_range_at_the_constraint(tmp_path, capsys):
    """A point 1e300 m away: the rows hold numbers HiGHS refuses (it was a 'Model error' traceback). A param
    point (or vector) that far is refused at its value already (implausible); one computed from a run-time number,
    which has no plausible size, reaches the rows."""
    err = _refused(capsys, "check", str(_far(tmp_path, point="[1e300, 0, 0]")))
    assert "far.vf:6:19: error: param 'p' is [1e+297, 0, 0] m: beyond 1.86 m" in err
    task = _far(tmp_path)
    task.write_text(task.read_text().replace("param p : point = [0, 0, 290]", "param k : number = 1e300")
                    .replace("stays_at(p)", "stays_at([0, 0, 290] + k * [1, 0, 0] mm)"))
    err = _refused(capsys, "check", str(task))
    assert "far.vf:8:1: error: at the start, the rows of stays_at(tip) hold 1e+297 (m or rad): the limit is 1e+06" in err
    assert main(["show", str(task)]) == 0
