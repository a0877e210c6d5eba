"""The phase machine's semantics (vfdsl.runtime.phase_machine) on hand-written cases: hold times at tick
resolution, release latches, unchanged inputs and elapsed time, the first tick, transitions holding together,
final and self-transitions, blends (interrupted too) and the funnel, NaN values, and malformed tables."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from vfdsl.runtime.phase_machine import (AND, COMPARE, ELAPSED, FALSE, GE, GT, LEAST_VIOLATION, LOGIC, MAX_STACK,
                                         NOT, OR, TRUE, UNCHANGED, UNKNOWN, MachineState, MachineTable, Monitor,
                                         Transition, advance)
from vfdsl.runtime.qp import StepStatus


def machine(monitors, transitions, phases=3, final=(), raw_size=4, u_size=3, watched=()):
    table = MachineTable(0, tuple(p in final for p in range(phases)), tuple(monitors), tuple(watched),
                         tuple(transitions), raw_size, u_size)
    return table, MachineState.initial(table)


def run(table, state, raws, dt=1e-3, u=None, status=0):
    """The fired transitions of ticks over ``raws`` (one list of values per tick, or one value for raw[0])."""
    fired = []
    for k, raw in enumerate(raws):
        raw = raw if isinstance(raw, list) else [raw] + [0.0] * (table.raw_size - 1)
        fired.append(advance(table, state, raw, u[k] if u is not None else [0.0] * table.u_size, dt, status))
    return fired


def ticks_of(fired, transition=0):
    return [k + 1 for k, f in enumerate(fired) if f == transition]


@pytest.mark.parametrize("dt, hold", [(1e-3, 0.05), (1e-4, 0.05), (3e-3, 0.03), (2.5e-4, 0.1), (1e-3, 0.001),
                                      (1e-5, 0.2), (7e-3, 0.7)])
def test_a_hold_of_k_ticks_is_reached_at_the_kth_tick_over_the_limit(dt, hold):
    """``norm(f) > 5 N for 50 ms`` at dt 1 ms: TRUE from the 50th tick over the limit on, not the 49th, whatever
    the rounding of the summed dt (0.003 summed ten times is 0.030000000000000006, 1e-5 twenty thousand times
    0.19999999999990535)."""
    k = round(hold / dt)
    table, state = machine([Monitor(COMPARE, raw=0, hold=hold)], [Transition(0, 1, (0,))])
    fired = run(table, state, [-1.0] * 5 + [2.0] * (k + 5), dt=dt)
    assert ticks_of(fired) == [5 + k]
    table, state = machine([Monitor(COMPARE, raw=0, hold=hold)], [])
    run(table, state, [2.0] * (k - 1), dt=dt)
    assert state.value == [FALSE] and math.isclose(state.held[0], (k - 1) * dt)
    run(table, state, [2.0], dt=dt)
    assert state.value == [TRUE]


def test_a_hold_not_on_a_tick_is_reached_at_the_nearest_tick():
    """Durations compare at tick resolution: 50 ms at dt 3 ms (16.7 ticks) holds at the 17th tick (51 ms), and
    49.4 ms at the 16th (48 ms, within half a tick)."""
    for hold, tick in ((0.05, 17), (0.0494, 16), (0.0496, 17)):
        table, state = machine([Monitor(COMPARE, raw=0, hold=hold)], [Transition(0, 1, (0,))])
        assert ticks_of(run(table, state, [1.0] * 30, dt=3e-3)) == [tick]


def test_the_held_time_restarts_when_the_condition_drops_and_survives_a_transition():
    table, state = machine([Monitor(COMPARE, raw=0, hold=0.005), Monitor(COMPARE, raw=1)],
                           [Transition(0, 1, (1,)), Transition(1, 2, (0,))])
    fired = run(table, state, [[1.0, -1.0, 0, 0]] * 4 + [[-1.0, -1.0, 0, 0]] + [[1.0, -1.0, 0, 0]] * 3
                + [[1.0, 1.0, 0, 0]] + [[1.0, -1.0, 0, 0]] * 3)
    # the held time restarts at tick 6; the transition 0 -> 1 at tick 9 leaves it running: 5 ticks at tick 10
    assert fired == [-1] * 8 + [0, 1, -1, -1]


def test_a_release_latch_does_not_chatter_on_a_noisy_signal():
    """``distance < 1 mm release 1.5 mm`` on a distance crossing 1 mm with 0.2 mm noise: one switch on, and off
    only once the distance goes past 1.5 mm; exactly at a threshold the latch does not switch (on needs > 0)
    and switches off (off at <= 0)."""
    rng = np.random.default_rng(0)
    d = np.r_[np.linspace(2e-3, 0.8e-3, 300), np.linspace(0.8e-3, 1.4e-3, 300), np.linspace(1.4e-3, 2e-3, 300)]
    d = d + rng.uniform(-2e-4, 2e-4, d.size)
    table, state = machine([Monitor(COMPARE, raw=0, release=1), Monitor(COMPARE, raw=0)], [], raw_size=2)
    latched, plain = [], []
    for x in d:
        run(table, state, [[1e-3 - x, 1.5e-3 - x]])
        latched.append(state.value[0])
        plain.append(state.value[1])
    switches = np.flatnonzero(np.diff(latched))
    assert len(switches) == 2 and np.count_nonzero(np.diff(plain)) > 20
    assert d[switches[1] + 1] >= 1.5e-3 and all(d[switches[0] + 1:switches[1] + 1] < 1.5e-3)
    table, state = machine([Monitor(COMPARE, raw=0, release=1)], [], raw_size=2)
    run(table, state, [[0.0, 0.5]])
    assert state.value == [FALSE]
    run(table, state, [[1e-300, 0.5], [-1.0, 0.0]])
    assert state.value == [FALSE] and state.latch == [0]


def test_unchanged_counts_the_time_since_the_input_last_changed():
    """``unchanged(f) for 20 ms`` at dt 1 ms: a value set at tick 1 and kept is stale at tick 21; any change
    (of any component) restarts the count; an input holding a NaN is UNKNOWN."""
    stale = Monitor(UNCHANGED, watch=0, op=GE, threshold=0.02)
    table, state = machine([stale], [Transition(0, 1, (0,))], watched=[(1, 2)])
    u = [[9.0, 1.0, 2.0]] * 10 + [[9.0, 1.0, 2.5]] + [[5.0, 1.0, 2.5]] * 25
    assert ticks_of(run(table, state, [0.0] * 36, u=u)) == [31]
    table, state = machine([stale, Monitor(LOGIC, program=(0, NOT))], [Transition(0, 1, (1,))], watched=[(0, 1)])
    assert run(table, state, [0.0] * 30, u=[[math.nan, 0, 0]] * 30) == [-1] * 30
    assert state.value == [UNKNOWN, UNKNOWN] and state.unchanged == [0.0]


def test_elapsed_is_zero_at_the_entry_tick():
    """``elapsed > 10 ms`` at dt 1 ms after entering at tick 1: elapsed is 10 ms at tick 11, > holds at tick 12 and
    >= at tick 11; a transition restarts it (at 0 in the tick of the transition)."""
    for op, tick in ((GT, 12), (GE, 11)):
        table, state = machine([Monitor(ELAPSED, op=op, threshold=0.01)], [Transition(0, 1, (0,)),
                                                                           Transition(1, 2, (0,))])
        fired = run(table, state, [0.0] * 30)
        assert (ticks_of(fired, 0), ticks_of(fired, 1)) == ([tick], [2 * tick - 1])
        assert state.elapsed == pytest.approx(0.03 - (2 * tick - 1) * 1e-3)


def test_least_violation_reads_the_previous_ticks_status():
    table, state = machine([Monitor(LEAST_VIOLATION, hold=0.002)], [Transition(0, 1, (0,))])
    assert run(table, state, [0.0] * 3, status=int(StepStatus.BOUNDS_CLIPPED)) == [-1] * 3
    assert run(table, state, [0.0] * 2, status=int(StepStatus.LEAST_VIOLATION | StepStatus.FALLBACK)) == [-1, 0]


def test_a_guard_true_at_the_first_tick_fires_at_the_first_tick():
    table, state = machine([Monitor(COMPARE, raw=0)], [Transition(0, 1, (0,), blend=0.01)])
    assert run(table, state, [1.0]) == [0]
    assert state.phase == 1 and state.elapsed == 0.0
    assert state.weight == pytest.approx([0.9, 0.1, 0.0], abs=1e-15) and state.funnel == pytest.approx(0.9)


def test_of_transitions_holding_together_the_first_in_file_order_fires():
    table, state = machine([Monitor(COMPARE, raw=0), Monitor(COMPARE, raw=1)],
                           [Transition(0, 2, (1,)), Transition(-1, 1, (0,)), Transition(0, 2, (0,)),
                            Transition(1, 2, (0, 1, AND))])
    assert run(table, state, [[1.0, -1.0, 0, 0], [1.0, 1.0, 0, 0]]) == [1, 3]     # `*` -> 1 passed over in 1
    table, state = machine([Monitor(COMPARE, raw=0), Monitor(COMPARE, raw=1)],
                           [Transition(0, 2, (1,)), Transition(0, 1, (0,)), Transition(1, 2, (0, 1, AND)),
                            Transition(-1, 0, (1,))])
    assert run(table, state, [[1.0, -1.0, 0, 0], [1.0, 1.0, 0, 0]]) == [1, 2]
    table, state = machine([Monitor(COMPARE, raw=0)], [Transition(0, 1, (0,)), Transition(1, 2, (0,))])
    assert run(table, state, [1.0] * 3) == [0, 1, -1]          # one transition per tick


def test_no_transition_leaves_a_final_phase():
    table, state = machine([Monitor(COMPARE, raw=0)], [Transition(0, 1, (0,)), Transition(-1, 2, (0,)),
                                                       Transition(1, 0, (0,))], final=(1,))
    assert run(table, state, [1.0] * 5) == [0, -1, -1, -1, -1] and state.phase == 1


def test_a_self_transition_restarts_the_phase():
    """A transition into the current phase restarts its elapsed time and its blend (the funnel starts again); the
    weights stay on that phase."""
    table, state = machine([Monitor(COMPARE, raw=0), Monitor(ELAPSED, op=GE, threshold=0.005)],
                           [Transition(0, 0, (0,), blend=0.004)])
    fired = run(table, state, [-1.0] * 8 + [1.0] + [-1.0] * 3)
    assert fired == [-1] * 8 + [0, -1, -1, -1]
    assert state.elapsed == pytest.approx(0.003) and state.value[1] == FALSE
    assert state.weight == [1.0, 0.0, 0.0] and state.funnel == 0.0
    table, state = machine([Monitor(COMPARE, raw=0)], [Transition(0, 0, (0,), blend=0.004)])
    funnels = []
    for raw in [1.0, -1.0, -1.0, 1.0, -1.0]:
        run(table, state, [raw])
        funnels.append(state.funnel)
        assert state.weight == [1.0, 0.0, 0.0]
    assert funnels == pytest.approx([0.75, 0.5, 0.25, 0.75, 0.5])


def test_a_transition_from_any_phase_never_fires_in_its_target():
    """``* -> B`` leaves every other non-final phase, and never restarts B itself (the language's meaning of ``*``):
    with its guard TRUE from the first tick it fires once, then never again."""
    table, state = machine([Monitor(COMPARE, raw=0)], [Transition(-1, 1, (0,), blend=0.004)])
    assert run(table, state, [1.0] * 6) == [0, -1, -1, -1, -1, -1] and state.phase == 1
    assert state.funnel == 0.0 and state.weight == [0.0, 1.0, 0.0]


def test_the_funnel_reaches_zero_exactly_at_the_blend_time():
    """Blend 200 ms at dt 1 ms: the transition tick's step ends at 1 ms (funnel 1 - 1/200), the step of the 199th
    tick after it ends at 200 ms (funnel exactly 0, weights exactly one-hot); linear in between."""
    table, state = machine([Monitor(COMPARE, raw=0)], [Transition(0, 1, (0,), blend=0.2)])
    run(table, state, [-1.0] * 3 + [1.0])
    funnels, weights = [state.funnel], [list(state.weight)]
    for _ in range(205):
        run(table, state, [-1.0])
        funnels.append(state.funnel)
        weights.append(list(state.weight))
    assert funnels[0] == pytest.approx(1 - 1 / 200, abs=1e-15) and funnels[198] == pytest.approx(1 / 200)
    assert funnels[199:] == [0.0] * 7 and weights[199] == [0.0, 1.0, 0.0]
    assert np.allclose(np.diff(funnels[:200]), -1 / 200, atol=1e-12)
    assert np.allclose(np.array(weights)[:200, 1], 1 - np.array(funnels[:200]), atol=1e-15)


def test_without_a_blend_the_switch_is_immediate():
    table, state = machine([Monitor(COMPARE, raw=0)], [Transition(0, 2, (0,))])
    run(table, state, [-1.0, 1.0])
    assert state.weight == [0.0, 0.0, 1.0] and state.funnel == 0.0 and state.phase == 2


def test_an_interrupted_blend_restarts_from_the_current_weights():
    """0 -> 1 (blend 100 ms) interrupted at 40 ms by 1 -> 2 (blend 50 ms): the new blend starts from (0.6, 0.4, 0),
    no weight moves by more than a step of the new blend (dt / 50 ms) in any tick, and the weights sum to 1."""
    table, state = machine([Monitor(COMPARE, raw=0), Monitor(COMPARE, raw=1)],
                           [Transition(0, 1, (0,), blend=0.1), Transition(1, 2, (1,), blend=0.05)])
    weights = []
    for k in range(120):
        run(table, state, [[float(k == 0), float(k == 39), 0.0, 0.0]])
        weights.append(list(state.weight))
    w = np.array(weights)
    assert w[38] == pytest.approx([0.61, 0.39, 0.0], abs=1e-12) and w[39] == pytest.approx(
        [0.61 * 0.98, 0.39 * 0.98, 0.02], abs=1e-12)
    assert np.max(np.abs(np.diff(w, axis=0))) <= 0.02 + 1e-15
    assert np.allclose(w.sum(axis=1), 1.0, atol=1e-15) and list(w[-1]) == [0.0, 0.0, 1.0]


def test_a_nan_value_never_fires_a_transition():
    """A NaN comparison is UNKNOWN (not FALSE): ``not`` it is UNKNOWN too, ``and`` with FALSE is FALSE, ``or`` with
    TRUE is TRUE; it leaves a release latch as it was and restarts a held time."""
    table, state = machine([Monitor(COMPARE, raw=0), Monitor(COMPARE, raw=1), Monitor(LOGIC, program=(0, NOT))],
                           [Transition(0, 1, (2,)), Transition(0, 1, (0, 1, OR, NOT)), Transition(0, 2, (0, 1, OR))])
    assert run(table, state, [[math.nan, -1.0, 0, 0]]) == [-1]
    assert state.value == [UNKNOWN, FALSE, UNKNOWN]
    assert run(table, state, [[math.nan, 1.0, 0, 0]]) == [2]
    table, state = machine([Monitor(COMPARE, raw=0, release=1, hold=0.003)], [], raw_size=2)
    for raw, latch, held in (([1.0, 1.0], 1, 0.001), ([1.0, math.nan], 1, 0.0), ([math.nan, 1.0], 1, 0.001),
                             ([1.0, -1.0], 0, 0.0), ([math.nan, 1.0], 0, 0.0)):
        run(table, state, [raw])
        assert (state.latch[0], state.held[0]) == (latch, pytest.approx(held))


@pytest.mark.parametrize("dt", [math.nan, -1e-3, math.inf, -math.inf])
def test_a_dt_that_is_no_finite_time_counts_as_zero(dt):
    table, state = machine([Monitor(COMPARE, raw=0, hold=0.001)], [Transition(0, 1, (0,), blend=0.01)])
    run(table, state, [1.0] * 3, dt=dt)
    assert (state.phase, state.elapsed, state.held) == (0, 0.0, [0.0])
    run(table, state, [1.0], dt=1e-3)
    run(table, state, [1.0], dt=dt)
    assert state.phase == 1 and state.weight == [1.0, 0.0, 0.0] and state.funnel == 1.0


@pytest.mark.parametrize("monitors, transitions, message", [
    ([Monitor(LOGIC, program=(0,))], [], "no operation or earlier monitor"),
    ([Monitor(COMPARE, raw=0)], [Transition(0, 1, (0, 0))], "leaves 2 values"),
    ([Monitor(COMPARE, raw=0)], [Transition(0, 1, (0, AND))], "malformed"),
    ([Monitor(COMPARE, raw=0)], [Transition(0, 1, (0,) * (MAX_STACK + 1) + (AND,) * MAX_STACK)], "deeper"),
    ([Monitor(COMPARE, raw=0)], [Transition(0, 1, (0, -4))], "no operation"),
    ([Monitor(COMPARE, raw=4)], [], "outside raw"),
    ([Monitor(COMPARE, raw=0, hold=-1.0)], [], "hold"),
    ([Monitor(UNCHANGED, watch=0)], [], "watched input 0 of 0"),
    ([Monitor(7)], [], "unknown kind"),
    ([], [Transition(0, 3, ())], "phases 0 -> 3"),
    ([], [Transition(0, 1, (), blend=math.nan)], "blend"),
])
def test_a_malformed_table_is_refused(monitors, transitions, message):
    with pytest.raises(ValueError, match=message):
        machine(monitors, transitions)


def test_the_docs_example_runs():
    """docs/runtime.md, "Procedures: the tick": its snippet builds a machine that retracts after 50 ticks of push."""
    text = (Path(__file__).parents[1] / "docs" / "runtime.md").read_text().split("## Procedures: the tick")[1]
    snippet = re.search(r"```python\n(.*?)```", text, flags=re.DOTALL).group(1)
    namespace = {"raw": [1.0], "u": [0.0, 0.0, 1.0], "dt": 1e-3, "last_status": 0}      # tick 1: pushing
    exec(compile(snippet, "docs/runtime.md", "exec"), namespace)
    table, state = namespace["table"], namespace["state"]
    fired = [namespace["fired"]] + [advance(table, state, [1.0], [0.0, 0.0, float(k)], 1e-3, 0) for k in range(2, 52)]
    assert ticks_of(fired) == [50] and state.phase == 1 and state.funnel == pytest.approx(1 - 2 / 200)
