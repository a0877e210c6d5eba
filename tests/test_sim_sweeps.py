"""Sweeps: a grid of settings times trials gives the same aggregate in this process, in a local process pool
and on a Dask cluster (a LocalCluster of two workers), for the same seeds; the CSV has one row per trial."""

from __future__ import annotations

import csv
import io
import json

import distributed
import pytest
from conftest import TASKS_DIR

import vfdsl
from vfdsl.cli import main
from vfdsl.sim import report
from vfdsl.sim.runner import make_jobs, run
from vfdsl.sim.scene_file import load_settings

B = str(TASKS_DIR / "paper_b_virtual_rcm.vf")
GRID = [("period", [0.01, 0.02]), ("latency", [0.0, 0.03])]


@pytest.fixture(scope="module")
def sweep():
    task = vfdsl.load(B)
    settings = load_settings(task, TASKS_DIR / "paper_b_virtual_rcm.sim.yaml").replace(trials=3, duration=0.5)
    jobs = make_jobs(B, settings, GRID)
    sequential = report.to_json(report.document(task.name, B, settings, run(jobs), GRID))
    return task, settings, jobs, sequential


def test_grid_times_trials_in_order_with_seeds(sweep):
    _, _, jobs, sequential = sweep
    assert len(jobs) == 2 * 2 * 3
    assert [dict(j.grid) for j in jobs[:4]] == [{"period": 0.01, "latency": 0.0}] * 3 + [{"period": 0.01, "latency": 0.03}]
    assert [j.seed for j in jobs[:3]] == [1, 2, 3] and [j.seed for j in jobs[3:6]] == [1, 2, 3]
    rows = list(csv.DictReader(io.StringIO(report.to_csv(json.loads(sequential)))))
    assert len(rows) == 12
    assert rows[4]["seed"] == "2" and rows[4]["latency"] == "0.03" and float(rows[4]["pivot_error_mm.max"]) > 0


@pytest.mark.slow
def test_process_pool_gives_the_sequential_aggregate(sweep):
    task, settings, jobs, sequential = sweep
    pooled = report.to_json(report.document(task.name, B, settings, run(jobs, workers=2), GRID))
    assert pooled == sequential


@pytest.mark.slow
def test_dask_local_cluster_gives_the_sequential_aggregate(sweep, tmp_path):
    """Through the API (a Client) and through the command line (--cluster ADDRESS)."""
    task, settings, jobs, sequential = sweep
    args = ["simulate", B, "--trials", "2", "--duration", "0.5s", "--grid", "period=10ms,20ms", "--quiet", "--json"]
    assert main([*args, str(tmp_path / "local.json")]) == 0
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        on_dask = report.to_json(report.document(task.name, B, settings, run(jobs, cluster=client), GRID))
        assert main([*args, str(tmp_path / "dask.json"), "--cluster", cluster.scheduler_address]) == 0
    assert on_dask == sequential
    assert (tmp_path / "dask.json").read_text() == (tmp_path / "local.json").read_text()


def test_the_api_probes_a_cluster_address_as_the_command_does(sweep, monkeypatch):
    """run(jobs, cluster=ADDRESS) from Python: a port where nothing listens and a server that is not a Dask
    scheduler are each one clear error before any trial runs, within the connect timeout."""
    import socket
    import threading

    from vfdsl import limits
    from vfdsl.errors import VfError

    monkeypatch.setattr(limits, "CONNECT_TIMEOUT", 2.0)
    _, _, jobs, _ = sweep
    with pytest.raises(VfError, match="cannot reach a Dask scheduler at 'tcp://127.0.0.1:9'"):
        run(jobs[:1], cluster="tcp://127.0.0.1:9")
    with socket.socket() as server:         # answers like an HTTP server, whatever it is sent
        server.bind(("127.0.0.1", 0))
        server.listen()

        def answer():
            conn, _ = server.accept()
            with conn:
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 4)
                conn.recv(1024)

        threading.Thread(target=answer, daemon=True).start()
        with pytest.raises(VfError, match="answers, but not as a Dask scheduler|cannot reach a Dask scheduler"):
            run(jobs[:1], cluster=f"tcp://127.0.0.1:{server.getsockname()[1]}")


def test_the_probe_works_inside_a_running_event_loop(monkeypatch):
    """As in a notebook: the address is probed from a coroutine, and the error is the same clear one."""
    import asyncio

    from vfdsl import limits
    from vfdsl.errors import VfError
    from vfdsl.sim.cluster import probe

    monkeypatch.setattr(limits, "CONNECT_TIMEOUT", 2.0)

    async def inside():
        with pytest.raises(VfError, match="cannot reach a Dask scheduler at 'tcp://127.0.0.1:9'"):
            probe("tcp://127.0.0.1:9")

    asyncio.run(inside())


def test_a_grid_point_without_the_trackers_metrics_first(tmp_path, capsys):
    """--grid noise=0,0.2mm: the first grid point has no tracker, so none of the tracker_* metrics the second has (they
    were looked up in the first trial's units: KeyError). Every output holds the union: the first point's JSON group
    has no tracker metric, its CSV row and trace rows empty tracker cells."""
    out = {suffix: tmp_path / f"run{suffix}" for suffix in (".json", ".csv", ".trace.csv")}
    assert main(["simulate", B, "--trials", "1", "--duration", "0.2s", "--grid", "noise=0,0.2mm", "--quiet",
                 "--json", str(out[".json"]), "--csv", str(out[".csv"]), "--trace", str(out[".trace.csv"])]) == 0
    quiet, noisy = json.loads(out[".json"].read_text())["groups"]
    assert "tracker_pivot_error_mm" not in quiet["metrics"]
    assert noisy["metrics"]["tracker_pivot_error_mm"]["unit"] == "mm"
    rows = list(csv.DictReader(out[".csv"].open()))
    assert rows[0]["tracker_pivot_error_mm.max"] == "" and float(rows[1]["tracker_pivot_error_mm.max"]) > 0
    ticks = list(csv.DictReader(out[".trace.csv"].open()))
    assert len(ticks) == 40 and ticks[0]["tracker.pivot_error_m"] == ""
    assert float(ticks[-1]["tracker.pivot_error_m"]) > 0
    assert "Traceback" not in capsys.readouterr().err
