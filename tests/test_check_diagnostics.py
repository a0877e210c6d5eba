"""``vfdsl check`` findings found wanting by new users: frames used only as the base of another frame,
redundancy judged at one degenerate point, implausible speed limits, soft constraints that cannot be met
at the start, and which objective term a hands-off turn is blamed on. Each with a task that triggers the
finding and one that must not."""

from __future__ import annotations

import pytest
from test_check import PROBE, SCENE, codes, probe

from vfdsl.check import hygiene
from vfdsl.check.report import Severity

# ------------------------------------------------------------------------------ D: frames built on frames

BASE_ONLY = PROBE.replace('frame tip = shr.link("tool_tip")',
                          'frame tip = shr.link("tool_tip")\nframe bur = tip axis [0, 0, -1]').replace(
    "track(tip,", "track(bur,").replace("require tip stays_at", "require bur stays_at")


def test_a_frame_used_only_as_the_base_of_another_is_used(tmp_path):
    task = probe(tmp_path, BASE_ONLY)
    assert "tip" not in str(task.constraints) + str(task.objectives)
    assert [f.base for f in task.frames] == [None, "tip"]
    assert hygiene.unused(task) == []


def test_an_unused_frame_built_on_another_is_reported_and_its_base_is_not(tmp_path):
    text = BASE_ONLY.replace("frame bur = tip axis [0, 0, -1]",
                             "frame bur = tip axis [0, 0, -1]\nframe spare = tip offset [0, 0, 5]")
    [finding] = hygiene.unused(probe(tmp_path, text))
    assert finding.data == {"kind": "frame", "name": "spare"} and finding.span.line == 6
