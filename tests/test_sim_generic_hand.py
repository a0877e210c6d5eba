"""The generic hand of a task without a simulation scene's hand: it drives the tracked frame where the task
guides it (a follows curve, an along line from its first point to its second, else a free world axis), as
fast as the task's speed limits let it (at most an assumed hand speed), says what it assumed, and the run
reports how far the frame moved."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest
from conftest import TASKS_DIR

import vfdsl
from vfdsl.cli import main
from vfdsl.sim.hand import HAND_SPEED
from vfdsl.sim import report
from vfdsl.sim.runner import make_jobs, run
from vfdsl.sim.scene_file import load_settings

NEEDLE = str(TASKS_DIR / "needle_insertion.vf")


def _simulate(tmp_path, *args) -> dict:
    out = tmp_path / "run.json"
    assert main(["simulate", *args, "--quiet", "--json", str(out)]) == 0
    return json.loads(out.read_text())


def test_needle_is_pushed_in_along_its_path_toward_the_target_not_out_of_it():
    """needle_insertion has no .sim.yaml: its needle is held on line(entry, target). The first free world axis
    (+z) would back the needle out; the generic hand pushes it from the entry toward the target."""
    task = vfdsl.load(NEEDLE)
    settings = load_settings(task, None).replace(duration=1.0)
    (result,) = run(make_jobs(NEEDLE, settings, keep_series=True))
    entry, target = (np.asarray(task.param(n).value.xyz) for n in ("entry", "target"))
    np.testing.assert_allclose(result.hand["direction"], (target - entry) / np.linalg.norm(target - entry),
                               atol=1e-12)
    tip = result.series["p"]["tip"]
    advance = np.linalg.norm(tip[0] - target) - np.linalg.norm(tip[-1] - target)
    assert advance > 0.015                       # 1 s at the assumed 20 mm/s, less the start
    assert "along the line of `needle along`" in result.hand["assumed"]
    assert result.motion["net"] == pytest.approx(advance, rel=0.02)


def test_push_speed_is_the_frames_own_speed_limit(tmp_path):
    """A `speed` limit on the tracked frame sets the push: magnitude = limit / gain, and the frame moves at
    the limit (the achieved motion says so)."""
    for name in ("lecture_follow_path.vf", "lecture_follow_path.yaml"):
        shutil.copy(TASKS_DIR / name, tmp_path / name)
    shutil.copytree(TASKS_DIR / "library", tmp_path / "library")
    task_file = tmp_path / "lecture_follow_path.vf"
    task_file.write_text(task_file.read_text() + "require tip speed(8 mm/s)\n")
    doc = _simulate(tmp_path, str(task_file), "--duration", "2s")
    assert doc["hand"]["kind"] == "push" and doc["hand"]["magnitude"] == pytest.approx(8.0)     # N, at 1 mm/s/N
    assert "the `tip speed` limit (lecture_follow_path.vf:" in doc["hand"]["assumed"]
    np.testing.assert_allclose(np.abs(doc["hand"]["direction"]), [math.sqrt(0.5), math.sqrt(0.5), 0], atol=1e-12)
    # 2 s at 8 mm/s; the first tick only starts the motion
    assert 15.5 < doc["motion"]["path_mm"] <= 16.0 + 1e-6
    assert doc["motion"]["net_mm"] == pytest.approx(doc["motion"]["path_mm"], rel=1e-3)


def test_without_a_frame_limit_the_joint_limits_bound_it_and_the_hand_speed_caps_it(tmp_path, capsys):
    """lecture_remote_center: a twist (gain 1) and joint_speed() only; the panda's joints would allow far more
    than a hand moves a tool, so the push is the assumed hand speed, and the output says so."""
    task = str(TASKS_DIR / "lecture_remote_center.vf")
    assert main(["simulate", task, "--duration", "1s"]) == 0
    out = capsys.readouterr().out
    assert "the joint speed limits of `joint_speed` (lecture_remote_center.vf:" in out
    assert f"assumed: a hand moves it at most {HAND_SPEED * 1e3:g} mm/s" in out
    assert "achieved: the hand moved 'tip'" in out
    doc = _simulate(tmp_path, task, "--duration", "1s")
    assert doc["hand"]["magnitude"] == pytest.approx(HAND_SPEED)
    assert doc["motion"]["path_mm"] > 10                    # the old generic push moved it 5 mm in 1 s
    assert doc["metrics"]["tip_passes_through_error_mm"]["max"] <= 0.5 + 1e-9


def test_a_task_whose_frame_follows_a_curve_is_followed(tmp_path):
    doc = _simulate(tmp_path, str(TASKS_DIR / "polyline_guide.vf"), "--duration", "1s")
    assert doc["hand"]["kind"] == "follow" and doc["hand"]["curve"] == "cut"
    assert doc["motion"]["path_mm"] > 10


def test_a_scenes_hand_assumes_nothing_and_the_motion_is_reported_per_trial(tmp_path):
    doc = _simulate(tmp_path, str(TASKS_DIR / "paper_b_virtual_rcm.vf"), "--duration", "1s", "--trials", "2")
    assert doc["hand"]["assumed"] == ""
    rows = doc["trials"]
    assert [set(r) >= {"motion.path_mm", "motion.net_mm", "motion.turn_deg"} for r in rows] == [True, True]
    assert doc["motion"]["turn_deg"] == pytest.approx((rows[0]["motion.turn_deg"] + rows[1]["motion.turn_deg"]) / 2)
    assert doc["motion"]["turn_deg"] > 1                    # the scene's turn: about 6 deg/s of cone motion


@pytest.mark.parametrize("direction, expected", [([1, 0, 0], (0.98, 1.001)), ([0, 0, -1], (0.45, 0.55))])
def test_simulate_reports_the_fraction_of_the_commanded_motion(tmp_path, direction, expected):
    """A 5 N push (5 mm/s) for 4 s on lecture_forbidden_half_space: sideways the robot makes all of it; down, the
    wall 10 mm below the tip stops it after 2 s, half of the 20 mm commanded."""
    scene = tmp_path / "push.sim.yaml"
    scene.write_text(f"units: mm\nduration: 4 s\nperiod: 10 ms\ntrials: 1\n"
                     f"hand: {{input: f, kind: push, direction: {direction}, magnitude: 5 N, tremor: 0 N, drift: 0 N}}\n")
    task_file = TASKS_DIR / "lecture_forbidden_half_space.vf"
    settings = load_settings(vfdsl.load(task_file), scene)
    (result,) = run(make_jobs(str(task_file), settings))
    fraction = result.motion["commanded"]["track(tip) linear"]
    assert expected[0] <= fraction <= expected[1], fraction
    doc = report.document("t", str(task_file), settings, [result], None)
    assert doc["motion"]["commanded_fraction"]["track(tip) linear"] == pytest.approx(fraction)
