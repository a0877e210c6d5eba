"""Every documented call form of Controller.step takes the generated C fast path when its values are plain: q as a
list, tuple or array, inputs as dicts of lists, tuples or arrays, params and dt by position or by keyword. Timings
are benchmarks/tick.py's; here, that the Python checks (the Stepper's ``checked``) were not called."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import TASKS_DIR

import vfdsl


class Spy:
    """Stands for a native controller's ``Stepper.checked`` (the Python checks its C fast path hands a call to):
    counts the calls, then checks as usual, or returns ``answer`` when given (to see that C evaluated nothing)."""

    def __init__(self, ctrl, answer=None):
        self.stepper = ctrl._runner.stepper
        self.original, self.answer, self.calls = self.stepper.checked, answer, 0

    def __call__(self, *args, **kwargs):
        self.calls += 1
        return self.answer if self.answer is not None else self.original(*args, **kwargs)

    def __enter__(self):
        self.stepper.checked = self
        return self

    def __exit__(self, *exc):
        self.stepper.checked = self.original


@pytest.fixture(scope="module")
def task_b():
    return vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf")


@pytest.fixture(scope="module")
def native(task_b):
    ctrl = vfdsl.compile(task_b, backend="native")
    assert ctrl.backend == "native" and ctrl._runner.fast_step is not None
    return ctrl


def _forms(task):
    """(name, call(step)) for every documented call form, with plain values; the last two are left to the checks."""
    q = np.array(task.start)
    tau = np.array([0.01, -0.02, 0.005])
    pivot, axis, dt = [0.0, 0.0, 0.2901], np.array([0.0, -0.19, 1.0]), 0.011
    return [
        ("step(q, inputs)", lambda s: s(q, {"tau": tau})),
        ("q and inputs lists", lambda s: s(q.tolist(), {"tau": tau.tolist()})),
        ("q and inputs tuples", lambda s: s(tuple(q), {"tau": tuple(tau)})),
        ("NumPy float64 scalars", lambda s: s([np.float64(x) for x in q], {"tau": [np.float64(x) for x in tau]})),
        ("inputs by keyword", lambda s: s(q, inputs={"tau": tau})),
        ("q and inputs by keyword", lambda s: s(q=q, inputs={"tau": tau})),
        ("dt by position", lambda s: s(q, {"tau": tau}, None, dt)),
        ("dt by keyword", lambda s: s(q, {"tau": tau}, dt=dt)),
        ("dt a NumPy float64 by keyword", lambda s: s(q, {"tau": tau}, dt=np.float64(dt))),
        ("params None and dt by keyword", lambda s: s(q, {"tau": tau}, params=None, dt=dt)),
        ("params by position", lambda s: s(q, {"tau": tau}, {"pivot": pivot})),
        ("params by keyword", lambda s: s(q, {"tau": tau}, params={"pivot": pivot, "axis": axis})),
        ("params and dt by position", lambda s: s(q, {"tau": tau}, {"axis": tuple(axis)}, dt)),
        ("params and dt by keyword", lambda s: s(q, {"tau": tau}, params={"pivot": pivot}, dt=dt)),
        ("every argument by keyword", lambda s: s(dt=dt, params={"axis": axis}, inputs={"tau": tau}, q=q)),
        ("keywords built at run time", lambda s: s(q, **{"".join(["inp", "uts"]): {"tau": tau}, "d" + "t": dt})),
        ("float32 inputs (checks)", lambda s: s(q, {"tau": tau.astype(np.float32)}, dt=dt)),
        ("a float subclass for dt (checks)", lambda s: s(q, {"tau": tau}, dt=type("F", (float,), {})(dt))),
    ]


def test_every_documented_call_form_takes_the_fast_path(task_b, native):
    """No plain form goes through the Python checks (before, any keyword did: 6-14x slower a tick); each gives the
    answer of the checked path for the same arguments. The forms the fast path leaves to the checks are counted."""
    stepper = native._runner.stepper
    checked = stepper.checked
    for name, call in _forms(task_b):
        with Spy(native) as spy:
            dq = call(native.step)
        assert spy.calls == name.endswith("(checks)"), name
        np.testing.assert_allclose(dq, call(lambda *a, **k: checked(stepper, *a, **k)), rtol=0, atol=1e-10,
                                   err_msg=name)


@pytest.mark.parametrize("call, error", [
    (lambda s, q: s(q, {"tau": [0, 0, 0]}, dtt=0.01), "unexpected keyword argument 'dtt'"),
    (lambda s, q: s(q, {"tau": [0, 0, 0]}, inputs={"tau": [0, 0, 0]}), "multiple values for argument 'inputs'"),
    (lambda s, q: s(inputs={"tau": [0, 0, 0]}), "missing 1 required positional argument: 'q'"),
    (lambda s, q: s(q, {"tau": [0, 0, 0]}, None, 0.01, 0.0), "takes from 2 to 5 positional arguments"),
])
def test_a_wrong_call_is_left_to_python_which_explains_it(task_b, native, call, error):
    with Spy(native) as spy, pytest.raises(TypeError, match=error):
        call(native.step, np.array(task_b.start))
    assert spy.calls == 1
