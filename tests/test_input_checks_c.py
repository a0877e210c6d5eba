"""The inputs' plausibility checks are compiled with the task, as the params' checks are.

:func:`vfdsl.runtime.values.input_checks` turns every input's type checks (:mod:`vfdsl.inputs`) into one column,
check-major (margin m is check m // nu of u[m % nu]); the build exports it as ``<prefix>_input_checks`` and the C
tick (checked_step.h: the Python extension's fast path and the exported library) refuses an input that fails it.
With today's registry every check is FINITE, so a type with one more check (a bound on the torque) shows that the C
reads the registry's checks rather than a copy of "finite".
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import TASKS_DIR
from test_export import make

import vfdsl
from vfdsl import inputs as input_registry
from vfdsl.errors import VfError
from vfdsl.export import export
from vfdsl.export.selftest import record, replay
from vfdsl.inputs.base import FINITE, InputCheck
from vfdsl.runtime.values import input_checks

BOUND = 50.0
AT_MOST_50 = InputCheck("at most 50 in size", lambda x: BOUND - abs(x),
                        lambda name, i, value: f"input '{name}' is over {BOUND} (index {i})")
ERR_INPUT = -4


def bounded_torque():
    return dataclasses.replace(input_registry.INPUT_TYPES["torque"], checks=(FINITE, AT_MOST_50))


def test_the_column_is_check_major_with_ones_where_a_type_has_fewer_checks():
    types = {"f": input_registry.INPUT_TYPES["force"], "tau": bounded_torque()}
    column = input_checks(types, {"f": (0, 3), "tau": (3, 3)}, 6)
    u = np.array([1.0, -2.0, np.nan, 60.0, -3.0, 0.0])
    margins = column(u).full().ravel()
    assert margins.shape == (12,)
    np.testing.assert_array_equal(margins[:6], np.abs(u))                       # check 0: FINITE, every input
    np.testing.assert_array_equal(margins[6:9], [1.0, 1.0, 1.0])               # the force has no check 1
    np.testing.assert_array_equal(margins[9:], BOUND - np.abs(u[3:]))          # the torque's bound
    failing = [m % 6 for m in range(12) if not (np.isfinite(margins[m]) and margins[m] >= 0)]
    assert failing == [2, 3]                                                   # u[2] NaN, u[3] over the bound


def test_a_task_without_inputs_has_an_empty_column():
    assert input_checks({}, {}, 0).numel_out(0) == 0


@pytest.fixture
def bounded_task(monkeypatch):
    monkeypatch.setitem(input_registry.INPUT_TYPES, "torque", bounded_torque())
    return vfdsl.load(TASKS_DIR / "paper_b_virtual_rcm.vf")


@pytest.fixture(scope="module")
def bounded_cache(tmp_path_factory):
    """A library cache of this module's own: the bounded type changes the generated code, not the task's digest."""
    return tmp_path_factory.mktemp("bounded-cache")


def test_the_generated_check_refuses_on_the_fast_path(bounded_task, bounded_cache):
    """Paper B's torque input over the added bound: the native step refuses it (the C fast path sends it to Python,
    which says which check failed); within the bound it steps as the interpreted path does."""
    native = vfdsl.pipeline.build(bounded_task, backend="native", cache_dir=bounded_cache)[0]
    interpreted = vfdsl.pipeline.build(bounded_task, backend="interpreted")[0]
    q = np.array(bounded_task.start, dtype=float)
    for tau in ([60.0, 0.0, 0.0], [0.0, 0.0, -50.5], np.array([0.0, 51.0, 0.0])):
        for ctrl in (native, interpreted):
            with pytest.raises(VfError, match="over 50"):
                ctrl.step(q, {"tau": tau})
    ok = {"tau": np.array([0.0, 0.0, 49.0])}
    np.testing.assert_allclose(native.step(q, ok), interpreted.step(q, ok), atol=1e-9)


def test_the_exported_library_refuses_an_input_its_type_refuses(bounded_task, bounded_cache, tmp_path):
    exported = export(bounded_task, tmp_path / "b", cache_dir=bounded_cache)
    make(exported.directory)
    tick = record(vfdsl.pipeline.build(bounded_task, backend="native", cache_dir=bounded_cache)[0], 1)[0]
    lines = []
    for k, value in ((0, 49.0), (2, -60.0), (1, np.inf)):
        u = np.zeros(3)
        u[k] = value
        lines.append(" ".join(f"{x:.17g}" for x in (*tick.q, *u)))
    answers = replay(exported.directory, lines, tick.dt)
    assert answers[0][0] >= 0
    assert [code for code, _ in answers[1:]] == [ERR_INPUT, ERR_INPUT]
