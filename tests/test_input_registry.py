"""Every registered input type is found by every tool that reads what an input means (vfdsl.inputs); a test id
names the input type and the tool that would miss it. The commanded motion of ``track`` is checked against NumPy."""

from __future__ import annotations

from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import vfdsl
from vfdsl import units as u
from vfdsl.check import lever, sampling
from vfdsl.errors import VfError
from vfdsl.export.selftest import user_inputs
from vfdsl.inputs import INPUT_TYPES, described
from vfdsl.objectives.track import commanded_motion
from vfdsl.primitives.spec import gain_dimension
from vfdsl.runtime.values import INPUT_UNITS, RuntimeValues
from vfdsl.sim import trace
from vfdsl.sim.settings import hand_dimension
from vfdsl.view.live import hand_model
from vfdsl.view.procedure import ProcedurePanel

NAMES = list(INPUT_TYPES)


def _gains(kind) -> str:
    """The track term's gains, written in SI units: ', gain = 2 m/s/N, angular_gain = 3 rad/m/s/N'."""
    out = ""
    for arg, angular, value in (("gain", False, 2.0), ("angular_gain", True, 3.0)):
        dim = kind.gain_dimension(angular)
        if dim is not None:
            out += f", {arg} = {u.DefaultUnits().show(value, dim)}"
    return out


@pytest.fixture(scope="module")
def tasks(tmp_path_factory) -> dict:
    """Per input type, a task that declares one input of it and tracks it with the tool tip (an input that
    commands no motion, a button, is only declared)."""
    folder = tmp_path_factory.mktemp("inputs")
    out = {}
    for name, kind in INPUT_TYPES.items():
        path = folder / f"with_{name}.vf"
        term = f"track(tip, h{_gains(kind)})" if kind.moves else "damping()"
        path.write_text(f'task with_{name}\nrobot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\n'
                        f"input h : {name}\nminimize {term}\n")
        out[name] = vfdsl.load(path)
    return out


class _Controller:
    """What export's self-test reads of a controller."""

    def __init__(self, task):
        self.task = task
        self.input_sizes = {d.name: d.size for d in task.inputs}


def _ir(task, kind):
    assert task.inputs[0].size == kind.size


def _gain_dimensions(task, kind):
    dims = [gain_dimension(kind.name, arg) for arg in ("gain", "angular_gain")]
    assert dims == [kind.gain_dimension(False), kind.gain_dimension(True)]
    assert (dims != [None, None]) == kind.moves


def _units(task, kind):
    assert INPUT_UNITS[kind.name]


def _trace(task, kind):
    assert trace.input_columns(task) == [f"input.h.{c}" for c in kind.columns]
    assert len(kind.columns) == len(set(kind.columns)) == kind.size


def _hand(task, kind):
    for part, hand_kind in ((kind.linear, "push"), (kind.angular, "turn")):
        if part is not None:
            assert hand_dimension(kind.name, hand_kind) == part.dimension


def _self_test(task, kind):
    assert user_inputs(_Controller(task), 3)["h"].shape == (kind.size,)


def _sampling(task, kind):
    scale = sampling.input_scales(task)["h"]
    assert scale.shape == (kind.size,) and np.all(scale > 0)


def _lever(task, kind):
    assert len(lever.tracked(task)) == (kind.linear is not None)


def _runtime_checks(task, kind):
    values = RuntimeValues(task, {"h": (0, kind.size)}, _NoParams(), np.zeros(1), np.ones(1), ["j"])
    assert values.inputs({"h": 0.5 * np.arange(kind.size, dtype=float)}).shape == (kind.size,)
    bad = np.zeros(kind.size)
    bad[-1] = np.nan
    with pytest.raises(VfError, match=rf"input 'h' contains NaN or inf \(index {kind.size - 1}\)"):
        values.inputs({"h": bad})


class _NoParams:
    layout = None


def _viewer(task, kind):
    hand = hand_model(task)
    if not kind.moves:      # an input without a motion part is never the hand's; a button is pressed in the panel
        buttons = ProcedurePanel.buttons.fget(SimpleNamespace(task=task))
        assert hand is None and buttons == ([task.inputs[0].name] if kind.switch else [])
        return
    assert hand.kind is kind and hand.frame == "tip"
    pose = SimpleNamespace(position=np.zeros(3), rotation=np.eye(3), tool_axis=np.array([0.0, 0.0, 1.0]))
    value = hand.value(pose, [0.01, 0.0, 0.0], Rotation.from_rotvec([0.0, 0.0, 0.1]).as_matrix())
    assert value.shape == (kind.size,) and np.any(value != 0) == kind.moves     # the hand leaves a button at 0
    v, w = hand.commanded(value)
    assert v.shape == w.shape == (3,)


TOOLS = {"ir": _ir, "gain dimensions": _gain_dimensions, "units": _units, "trace": _trace, "hand": _hand,
         "self-test": _self_test, "sampling": _sampling, "lever": _lever, "runtime checks": _runtime_checks,
         "viewer": _viewer}


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("tool", list(TOOLS))
def test_every_tool_finds_every_input_type(tasks, name, tool):
    TOOLS[tool](tasks[name], INPUT_TYPES[name])


@pytest.mark.parametrize("name", NAMES)
def test_an_input_is_linear_then_angular_parts(name):
    """[linear; angular] of 3 numbers each, or a level alone (one number), or set-point parts alone."""
    kind = INPUT_TYPES[name]
    assert kind.parts and kind.size == sum(len(p.axes) for p in kind.parts)
    assert [kind.moves, kind.switch, bool(kind.setpoint)].count(True) == 1
    assert (kind.level is None or kind.parts == (kind.level,)) and (not kind.setpoint or kind.parts == kind.setpoint)
    assert [kind.linear_range, kind.angular_range] == [
        slice(0, 3) if kind.linear else None,
        slice(kind.size - 3, kind.size) if kind.angular else None]


@pytest.mark.parametrize("name", NAMES)
def test_the_checks_compile_to_the_column_numpy_evaluates(name):
    """Each check's margin is one expression for NumPy and CasADi: the compiled column agrees, NaN and inf
    included."""
    kind = INPUT_TYPES[name]
    x = ca.SX.sym("x", kind.size)
    for check in kind.checks:
        compiled = ca.Function("margins", [x], [check.margin(x)])
        for value in (np.linspace(-2, 3, kind.size), np.full(kind.size, np.inf), np.full(kind.size, np.nan)):
            np.testing.assert_array_equal(compiled(value).full().ravel(), check.margin(value))


@pytest.mark.parametrize("name", [name for name in NAMES if INPUT_TYPES[name].moves])
def test_the_commanded_motion_is_the_gains_times_the_parts(tasks, name):
    """v_d = gain f (or v), w_d = angular_gain tau (or w), zero for a part the input lacks: the symbolic function
    ``track`` lowers, and the viewer's evaluation of it, against NumPy on the layout [linear; angular]."""
    kind = INPUT_TYPES[name]
    hand = hand_model(tasks[name])
    rng = np.random.default_rng(7)
    for _ in range(5):
        value = rng.normal(size=kind.size)
        hand.gain, hand.angular_gain = rng.uniform(0.1, 2.0, size=2)
        v_numpy = hand.gain * value[:3] if kind.linear else np.zeros(3)
        w_numpy = hand.angular_gain * value[-3:] if kind.angular else np.zeros(3)
        symbolic = (x.full().ravel() for x in commanded_motion(name)(value, hand.gain, hand.angular_gain))
        for v, w in (symbolic, hand.commanded(value)):
            np.testing.assert_allclose(v, v_numpy, rtol=1e-15)
            np.testing.assert_allclose(w, w_numpy, rtol=1e-15)


def test_track_refuses_an_input_that_commands_no_motion(tmp_path):
    path = tmp_path / "t.vf"
    path.write_text('task t\nrobot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\ninput go : button\n'
                    "minimize track(tip, go)\n")
    with pytest.raises(VfError, match="track needs an input that commands a motion; 'go' is a button") as info:
        vfdsl.load(path)
    assert (info.value.code, info.value.line, info.value.column) == ("E503", 5, 10)


def test_a_button_is_checked_between_released_and_pressed(tasks):
    """0 <= x <= 1 (NaN and inf refused by the finite check first), the same margin compiled."""
    kind = INPUT_TYPES["button"]
    values = RuntimeValues(tasks["button"], {"h": (0, 1)}, _NoParams(), np.zeros(1), np.ones(1), ["j"])
    for ok in (0.0, 0.5, 1.0):
        assert values.inputs({"h": [ok]}).tolist() == [ok]
    for bad in (-1e-9, 1.0 + 1e-9, 2.0, -np.inf):
        with pytest.raises(VfError, match="input 'h'"):
            values.inputs({"h": [bad]})
    assert kind.columns == ("pressed_1",) and kind.unit_text == "1" and kind.self_test_scale == (0.0,)


def test_described_names_the_input_types_with_a_part():
    assert described(lambda t: t.angular) == "a torque, wrench or twist input"
    assert described(lambda t: t.linear) == "a force, wrench or twist input"


def test_a_pose_is_a_position_then_roll_pitch_yaw_checked_for_unit_slips(tasks):
    """Finite, the position within 10 m of the master's base on each axis, each angle within pi: a master position
    in millimetres or a rotation in degrees is refused with what it probably is."""
    kind = INPUT_TYPES["pose"]
    assert kind.columns == ("px_m", "py_m", "pz_m", "roll_rad", "pitch_rad", "yaw_rad") and not kind.moves
    assert kind.unit_text == "m (0-2), rad (3-5)" and not kind.switch
    values = RuntimeValues(tasks["pose"], {"h": (0, 6)}, _NoParams(), np.zeros(1), np.ones(1), ["j"])
    for ok in ([0.1, -0.2, 0.3, 0.0, 0.5, -3.0], [10.0, -10.0, 0.0, np.pi, -np.pi, 0.0]):
        assert values.inputs({"h": ok}).tolist() == ok
    for bad, message in (([0.0, 150.0, 0.0, 0, 0, 0], "position is 150 m on axis y, beyond 10 m .millimetres given"),
                         ([0.0, 0.0, 0.0, 0, 0, 90.0], "its yaw is 90 rad, beyond pi .degrees given"),
                         ([0.0, 0.0, np.nan, 0, 0, 0], "contains NaN or inf .index 2.")):
        with pytest.raises(VfError, match=message):
            values.inputs({"h": bad})


def test_a_pose_is_neither_tracked_nor_a_condition(tmp_path):
    head = 'task t\nrobot shr = urdf "shr7"\nframe tip = shr.link("tool_tip")\ninput master : pose\n'
    path = tmp_path / "t.vf"
    path.write_text(head + "minimize track(tip, master)\n")
    with pytest.raises(VfError, match="'master' is a pose") as info:
        vfdsl.load(path)
    assert info.value.code == "E503" and "a pose is read by teleop" in info.value.hint   # (it said "no term yet")
    path.write_text(head + "monitor held = master\nphase a initial final { minimize damping() }\n")
    with pytest.raises(VfError, match="input 'master' is a pose, not a condition") as info:
        vfdsl.load(path)
    assert info.value.code == "E811" and "only a button" in info.value.hint
