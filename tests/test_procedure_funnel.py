"""The funnel of a hard fixture entered violated (issue 33, item 3): its rows' bounds widened by e x the machine's
funnel factor over the blend (values in the activity argument, never structure), e measured at the transition tick;
the joint accelerations at the example's transitions with and without a blend (benchmarks/procedure_transitions.py);
the tracking readout of the current phase's `track` terms."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

import vfdsl
from vfdsl.runtime.qp import StepStatus

REPO = Path(__file__).resolve().parent.parent
DT = 0.001
TOLERANCE = 0.5e-3

TASK = """\
task funnel
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
input f : force
input go : button
param goal : point = [0, 0, 0]
monitor pressed = go
minimize damping() weight 1e-6
phase free initial { minimize track(tip, f, gain = 1 mm/s/N) }
phase held final { require tip stays_at(goal) within 0.5 mm }
transition free -> held when pressed
blend BLEND ms
"""


def compiled(tmp_path, blend_ms):
    path = tmp_path / f"funnel_{blend_ms}.vf"
    path.write_text(TASK.replace("BLEND", str(blend_ms)))
    return vfdsl.compile(vfdsl.load(path), backend="interpreted")


class Entry:
    """The tool at rest at q = 0, the goal ``offset`` m along +x from the tip; the button at tick 2."""

    def __init__(self, ctrl, offset):
        self.ctrl = ctrl
        self.q = np.zeros(ctrl.nq)
        self.goal = ctrl.frames(self.q)["tip"].position + np.array([offset, 0.0, 0.0])
        self.distance, self.status, self.widths = [], [], []

    def tick(self, go=0.0):
        self.q = self.q + self.ctrl.step(self.q, {"f": [0.0, 0.0, 0.0], "go": [go]}, {"goal": self.goal}, dt=DT)
        self.distance.append(float(np.linalg.norm(self.ctrl.frames(self.q)["tip"].position - self.goal)))
        self.status.append(int(self.ctrl.status))
        self.widths.append(self.ctrl._procedure.activity[4:].copy())

    def enter(self, after):
        self.tick()
        self.tick(go=1.0)
        assert self.ctrl.phase == "held" and self.ctrl.events
        for _ in range(after):
            self.tick()


def test_a_fixture_entered_2_mm_off_returns_monotonically_within_the_blend(tmp_path):
    run = Entry(compiled(tmp_path, 200), TOLERANCE + 2e-3)
    run.enter(260)
    proc = run.ctrl._procedure
    assert proc.entry_error == pytest.approx([2e-3], abs=1e-9)      # beyond the 0.5 mm, along a facet's normal
    d = np.array(run.distance[1:])                                   # from the transition tick on
    assert np.all(np.diff(d) <= 1e-12)                               # monotone
    ticks = np.arange(1, len(d) + 1)
    funnel = TOLERANCE + 2e-3 * np.clip(1 - ticks * DT / 0.2, 0, 1)
    assert np.all(d <= funnel + 1e-9)                                # inside the funnel at every tick
    assert d[0] > 2.4e-3 and d[100] > 1.4e-3                         # asked back over the blend, not snapped
    assert d[199] <= TOLERANCE + 1e-9                                # at the declared tolerance at t = B
    widths = np.array(run.widths[1:])[:, 0]
    assert widths[0] == pytest.approx(2e-3 * (1 - DT / 0.2)) and np.all(np.diff(widths[:200]) < 0)
    assert np.all(widths[199:] == 0.0)                               # exactly 0 from the tick whose step ends at B
    assert not any(s & StepStatus.LEAST_VIOLATION for s in run.status)


def test_a_width_widens_every_row_of_the_fixture_by_exactly_itself(tmp_path):
    run = Entry(compiled(tmp_path, 200), TOLERANCE + 2e-3)
    run.enter(0)
    proc, inputs = run.ctrl._procedure, ({"f": [0, 0, 0], "go": [0]}, {"goal": run.goal})
    rows = [k for k, label in enumerate(run.ctrl.row_labels) if label.phase == "held"]
    proc.activity[4] = 0.0
    declared = run.ctrl.problem(run.q, *inputs, dt=DT)
    proc.activity[4] = 1.25e-3
    widened = run.ctrl.problem(run.q, *inputs, dt=DT)
    n = declared.P.shape[0]
    assert len(rows) == 6                                            # the box of stays_at's default facets
    assert np.allclose(declared.lb[n:][rows] - widened.lb[n:][rows], 1.25e-3, rtol=0, atol=1e-15)  # k = 1
    assert np.array_equal(declared.A, widened.A) and np.array_equal(declared.ub, widened.ub)


def test_without_a_blend_the_fixture_applies_at_once(tmp_path):
    run = Entry(compiled(tmp_path, 0), TOLERANCE + 2e-3)
    run.enter(150)
    assert run.ctrl._procedure.entry_error == pytest.approx([2e-3], abs=1e-9)    # measured, but no funnel
    assert all(np.all(w == 0.0) for w in run.widths)
    least_violation = sum(bool(s & StepStatus.LEAST_VIOLATION) for s in run.status)
    inside = next(k for k, d in enumerate(run.distance) if d <= TOLERANCE + 1e-9)
    print(f"blend 0: {least_violation} least-violation ticks, back within the tolerance at tick {inside + 1} "
          f"(the transition at tick 2)")
    assert least_violation > 0 and inside > 50      # shr7's x joint at its speed limit (20 mm/s), in least violation


def test_a_fixture_met_at_entry_gets_no_funnel(tmp_path):
    run = Entry(compiled(tmp_path, 200), 0.3e-3)
    run.enter(5)
    assert np.all(run.ctrl._procedure.entry_error == 0.0) and all(np.all(w == 0.0) for w in run.widths)


def test_a_phase_less_fixture_is_never_funnelled(tmp_path):
    path = tmp_path / "phaseless.vf"
    path.write_text(TASK.replace("BLEND", "200").replace("phase held final { require tip stays_at(goal) within "
                                                         "0.5 mm }", "phase held final { }")
                    .replace("minimize damping() weight 1e-6", "require tip stays_at(goal) within 5 mm"))
    ctrl = vfdsl.compile(vfdsl.load(path), backend="interpreted")
    assert ctrl._procedure.activity.size == 4 and ctrl._procedure.entry_error.size == 0


def test_nan_never_enters_a_width(tmp_path):
    ctrl = compiled(tmp_path, 200)
    proc = ctrl._procedure
    real = proc._captures

    class Degenerate:                      # a capture gone NaN (a zero vector normalized) makes e NaN
        def call(self, args):
            out = real.call(args)
            return out[:3] + [np.array([[np.nan]])]             # held's entry error

        def numel_out(self, k):
            return real.numel_out(k)

    proc._captures = Degenerate()
    run = Entry(ctrl, TOLERANCE + 2e-3)
    run.enter(3)
    assert np.all(proc.entry_error == 0.0) and np.all(np.isfinite(proc.activity))
    assert all(np.all(w == 0.0) for w in run.widths)


def bench():
    spec = importlib.util.spec_from_file_location("vfdsl_bench_transitions",
                                                  REPO / "benchmarks" / "procedure_transitions.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module             # (its dataclass looks its module up there)
    spec.loader.exec_module(module)
    return module


def test_the_blended_example_stays_under_the_documented_bound():
    b = bench()
    task = vfdsl.load(b.EXAMPLE)
    blended = b.run(task)
    assert [t.target for t in blended] == ["align", "insert", "retract", "done"]
    assert max(t.max_acceleration for t in blended) < b.BOUND
    assert sum(t.least_violation for t in blended) == 0
    funnelled = b.run(task, misplaced=True)
    entry = funnelled[0]
    assert len(entry.entry_errors) == 2 and entry.least_violation == 0
    assert entry.max_acceleration < b.funnel_bound(entry.entry_errors, task.blend)
    plain, snapped = b.run(b.unblended(task)), b.run(b.unblended(task), misplaced=True)
    print("blend 0, max |ddq| per transition (rad/s^2):", [round(t.max_acceleration, 3) for t in plain],
          "; entered violated:", [round(t.max_acceleration, 3) for t in snapped],
          f"with {snapped[0].least_violation} least-violation ticks")


def test_tracking_reads_the_current_phase_track_terms():
    task = vfdsl.load(REPO / "tasks" / "procedures" / "needle_procedure.vf")
    ctrl = vfdsl.compile(task, backend="interpreted")
    q = np.array(task.start, dtype=float)
    names, _ = ctrl.tracked_parts
    assert "track(tip) linear in phase approach" in names and "track(tip) linear in phase insert" in names
    readout = ctrl.tracking(q, {"hand": [2.0, 0.0, 0.0], "go": [0]}, dt=DT)
    assert ctrl.phase == "approach"
    assert [t.term for t in readout] == ["track(tip) linear in phase approach", "track(tip) angular in phase approach"]
    assert np.allclose(readout[0].commanded, [4e-3, 0, 0]) and readout[0].fraction > 0.99    # 2 mm/s/N x 2 N
    readout = ctrl.tracking(q, {"hand": [2.0, 0.0, 0.0], "go": [1]}, dt=DT)
    assert ctrl.phase == "align" and readout == []                   # align tracks nothing


def test_only_the_rows_the_tolerance_enters_are_widened(tmp_path):
    path = tmp_path / "plane.vf"
    path.write_text("""\
task plane
units mm, deg
robot shr = urdf "shr7"
frame tip = shr.link("tool_tip")
frame scope = tip axis [0, 0, -1]
input go : button
param wall : plane = plane([0, 0, 200], [0, 0, 1])
param port : point = [0, 0, 250]
monitor pressed = go
phase a initial { }
phase b final {
    require tip on_plane(wall) within 0.1 mm
    require scope passes_through(port) within 0.5 mm resolution 8
}
transition a -> b when pressed
blend 100 ms
""")
    ctrl = vfdsl.compile(vfdsl.load(path), backend="interpreted")
    proc = ctrl._procedure
    assert proc.activity.size == 2 * 2 + 2
    q = np.zeros(ctrl.nq)
    proc.activity[:] = [0, 1, 0, 1, 0, 0]
    declared = ctrl.problem(q, {"go": [0]}, dt=DT)
    proc.activity[4:] = [1e-3, 2e-3]
    widened = ctrl.problem(q, {"go": [0]}, dt=DT)
    n = declared.P.shape[0]
    shift = (declared.lb - widened.lb)[n:]
    labels = [str(label) for label in ctrl.row_labels]
    below = [k for k, text in enumerate(labels) if "not below" in text]
    above = [k for k, text in enumerate(labels) if "not above" in text]
    port = [k for k, text in enumerate(labels) if text.startswith("passes_through")]
    assert len(below) == len(above) == 1 and len(port) == 8
    assert shift[below] == pytest.approx([0.0], abs=1e-15) and shift[above] == pytest.approx([1e-3], abs=1e-15)
    assert np.allclose(shift[port], 2e-3, rtol=0, atol=1e-15)
