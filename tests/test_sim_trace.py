"""``vfdsl simulate --trace``: one row per tick per trial, in SI units, as CSV and Parquet; its values agree
with the run's own summary, the robot's motion, the scene's motions and the controller's status."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from conftest import TASKS_DIR

from vfdsl.cli import main

VESSEL = str(TASKS_DIR / "breathing_vessel.vf")
B = str(TASKS_DIR / "paper_b_virtual_rcm.vf")


def _read_csv(path) -> dict[str, np.ndarray]:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    out = {}
    for i, name in enumerate(header):
        cells = [r[i] for r in body]
        if name == "violations":
            out[name] = np.array(cells, dtype=object)
        else:
            out[name] = np.array([float(c) if c != "" else np.nan for c in cells])
    return out


def _run(tmp_path, *args, trace="t.csv"):
    summary = tmp_path / "run.json"
    assert main(["simulate", *args, "--quiet", "--json", str(summary), "--trace", str(tmp_path / trace)]) == 0
    return json.loads(summary.read_text())


def test_csv_trace_has_a_row_per_tick_per_trial_and_agrees_with_the_summary(tmp_path):
    doc = _run(tmp_path, VESSEL, "--duration", "0.5s", "--trials", "2")
    t = _read_csv(tmp_path / "t.csv")
    assert len(t["tick"]) == 2 * 50
    assert list(t["trial"][:50]) == [0] * 50 and list(t["trial"][50:]) == [1] * 50
    assert list(t["seed"][:1]) == [1] and list(t["seed"][50:51]) == [2]
    assert np.allclose(t["t_s"][:50], np.arange(50) * 0.01)
    for name in ("q.insert_m", "dq.rcm_a_rad", "input.f.fx_N", "param.vessel.p0.z_m", "status", "violations",
                 "metric.vessel_error_m", "metric.joint_speed_rad_s"):
        assert name in t, name
    # every metric of the summary is a column, and pooled over the rows gives the summary's figures
    for name, m in doc["metrics"].items():
        column = "metric." + name.replace("_mm_s", "_m_s").replace("_deg_s", "_rad_s").replace("_mm", "_m") \
            .replace("_deg", "_rad")
        values = t[column][~np.isnan(t[column])]
        scale = 1e-3 if m["unit"].startswith("mm") else math.pi / 180
        assert len(values) == m["samples"], name
        assert np.isclose(values.mean(), m["mean"] * scale, rtol=1e-9, atol=1e-15), name
        assert np.isclose(values.max(), m["max"] * scale, rtol=1e-9, atol=1e-15), name
    # the speed metric of tick k is the step from k - 1 to k: 0 at a trial's first tick, which has no step before it
    assert t["metric.joint_speed_rad_s"][0] == 0 and t["metric.joint_speed_rad_s"][50] == 0


def test_trace_params_are_the_moved_values_and_q_follows_dq(tmp_path):
    """The scene breathes the vessel by 2 mm at 0.25 Hz: every point's z is its scene value plus that sine.
    With no latency, lag or resolution the encoders read the sum of the commands."""
    _run(tmp_path, VESSEL, "--duration", "0.5s", "--trials", "1")
    t = _read_csv(tmp_path / "t.csv")
    breath = 0.002 * np.sin(2 * np.pi * 0.25 * t["t_s"])
    assert np.allclose(t["param.vessel.p0.z_m"] - breath, t["param.vessel.p0.z_m"][0], atol=1e-12)
    assert np.ptp(t["param.vessel.p0.z_m"]) > 1e-3
    for joint in ("x_m", "insert_m", "rcm_a_rad"):
        assert np.allclose(t[f"q.{joint}"][1:], t[f"q.{joint}"][:-1] + t[f"dq.{joint}"][:-1], atol=1e-12)
    # the hand's force: 5 N along the vessel plus tremor and drift, never zero
    force = np.linalg.norm(np.stack([t["input.f.fx_N"], t["input.f.fy_N"], t["input.f.fz_N"]]), axis=0)
    assert 3 < force.mean() < 7


def test_trace_status_and_violations_agree(tmp_path):
    """A 5 mm push of the tool off the pivot: the speed limits cannot undo it in one tick, so the steps that
    follow solve the least-violation problem and name what they leave violated."""
    scene = tmp_path / "push.sim.yaml"
    scene.write_text((TASKS_DIR / "paper_b_virtual_rcm.sim.yaml").read_text()
                     + "disturbances:\n  - {at: 0.1 s, kind: push_tool, frame: tip, by: [5, 0, 0]}\n")
    _run(tmp_path, B, "--scene", str(scene), "--duration", "0.3s", "--trials", "1")
    t = _read_csv(tmp_path / "t.csv")
    failed = t["status"] != 0
    assert failed.any()
    assert all(v for v in t["violations"][failed])
    assert all("stays_at" in v for v in t["violations"][failed] if v)
    assert not t["violations"][:10].any()          # before the push: nothing violated


def test_parquet_trace_holds_the_same_columns_and_values_as_the_csv(tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    _run(tmp_path, VESSEL, "--duration", "0.2s", "--trials", "2", trace="t.csv")
    _run(tmp_path, VESSEL, "--duration", "0.2s", "--trials", "2", trace="t.parquet")
    from_csv = _read_csv(tmp_path / "t.csv")
    table = pq.read_table(tmp_path / "t.parquet")
    assert table.column_names == list(from_csv)
    assert table.schema.metadata[b"vfdsl.task"] == b"breathing_vessel"
    assert str(table.schema.field("tick").type) == "int64" and str(table.schema.field("violations").type) == "string"
    for name, values in from_csv.items():
        column = table.column(name).to_pylist()
        if name == "violations":
            assert column == list(values)
        else:
            assert np.allclose(np.array(column, dtype=float), values, equal_nan=True, rtol=0, atol=0), name


def test_grid_trace_carries_the_grid_settings(tmp_path):
    main(["simulate", VESSEL, "--quiet", "--duration", "0.1s", "--trials", "1", "--grid", "period=10ms,20ms",
          "--trace", str(tmp_path / "g.csv")])
    t = _read_csv(tmp_path / "g.csv")
    assert sorted(set(t["period_s"])) == [0.01, 0.02]
    assert (t["period_s"] == 0.01).sum() == 10 and (t["period_s"] == 0.02).sum() == 5
    assert np.allclose(t["t_s"][t["period_s"] == 0.02], np.arange(5) * 0.02)


@pytest.mark.parametrize("name, message", [("t.txt", "write a .csv, a .parquet or an .mcap file"),
                                           ("missing/t.csv", "no directory")])
def test_bad_trace_path_is_refused_before_the_run(tmp_path, capsys, name, message):
    assert main(["simulate", VESSEL, "--quiet", "--duration", "0.1s", "--trace", str(tmp_path / name)]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_trace_params_carry_a_disturbance_that_moves_a_pose(tmp_path):
    """paper_a_plate_moves: at 6 s the plate moves by (1.5, -1, 1) mm and tilts by (2, -2, 0) deg; the trace's
    plate columns hold the scene value before and the moved pose from that tick on."""
    scene = str(TASKS_DIR / "paper_a_plate_moves.sim.yaml")
    _run(tmp_path, str(TASKS_DIR / "paper_a_follow_curve.vf"), "--scene", scene, "--duration", "6.6s", "--trials", "1")
    t = _read_csv(tmp_path / "t.csv")
    before, after = t["t_s"] < 6 - 1e-9, t["t_s"] >= 6 - 1e-9
    for axis, shift in zip("xyz", (1.5e-3, -1e-3, 1e-3)):
        column = t[f"param.plate.{axis}_m"]
        assert np.ptp(column[before]) == 0 and np.ptp(column[after]) == 0
        assert column[after][0] - column[before][0] == pytest.approx(shift, abs=1e-12)
    yaw = t["param.plate.yaw_rad"]
    assert np.ptp(yaw[before]) == 0 and yaw[after][0] != yaw[0]
    # the tip error jumps at the move
    assert np.nanmax(t["metric.tip_error_m"][after][:1]) > 1e-3
