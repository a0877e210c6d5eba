"""What an input type is: one or two 3-vector parts, each a linear or an angular quantity, or a level (one plain
number: a button), or set-point parts (a master's pose: a position and a rotation vector, which no ``track`` reads).

An input u is [linear; angular] (a part it lacks is left out), or [level]: a force f (N), a torque tau (N m), a wrench
[f; tau] or a twist [v; w] (m/s, rad/s). ``minimize track`` turns it into the frame velocity it commands,

    v_d = gain u_linear,    w_d = angular_gain u_angular     (zero for a part the input lacks),

so a part's gain has the dimension of its rate (m/s, rad/s) over its quantity's: m/s per N for a force, a plain
scale for a twist's velocity.

Every value of an input must pass its type's plausibility checks, each one margin per component: check c holds
on u_i iff c.margin(u_i) is finite and >= 0, the rule of the params' column of checks
(:mod:`vfdsl.compiler.margins`). A margin is written with operations that NumPy arrays and CasADi symbols share
(``abs``, arithmetic), so the same expression is evaluated in Python and compiled with the task.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from vfdsl import units as u
from vfdsl.errors import show_vector

AXES = "xyz"


@dataclass(frozen=True)
class Part:
    """One part of an input: its quantity's dimension and SI unit, the prefix of its components' trace
    columns (``f`` -> fx_N, fy_N, fz_N), the size of the export self-test's push on it (SI) and its components'
    names (x, y, z; one unnamed for a level)."""

    dimension: u.Dim
    unit: str
    column: str
    self_test: float
    axes: tuple[str, ...] = tuple(AXES)

    @property
    def rate(self) -> bool:
        """Whether the part is itself a velocity (a twist's), not a force or torque to be turned into one."""
        return self.dimension in (u.SPEED, u.ANGULAR_SPEED)

    def columns(self) -> tuple[str, ...]:
        suffix = self.unit.replace(" ", "").replace("/", "_")
        return tuple(f"{self.column}{axis}_{suffix}" for axis in self.axes)


@dataclass(frozen=True)
class InputCheck:
    """A plausibility check of each component x of an input: it holds iff ``margin(x)`` is finite and >= 0;
    ``message(input name, index, value)`` says what is wrong with a value that fails it."""

    meaning: str
    margin: Callable
    message: Callable[[str, int, np.ndarray], str]


FINITE = InputCheck(
    "every component finite (any finite size: beyond the speed bounds the motion saturates)",
    abs,      # |x| >= 0 always: finite iff x is
    lambda name, i, value: f"input '{name}' contains NaN or inf (index {i}): {show_vector(value)}")


@dataclass(frozen=True)
class InputType:
    """One input type: its name, its parts (``linear`` first, then ``angular``; None where it has none; or a
    ``level`` alone; or ``setpoint`` parts alone), the gain a ``track`` term may leave out (None: the term must give
    it) and its plausibility checks."""

    name: str
    summary: str
    linear: Part | None
    angular: Part | None
    default_gain: float | None = None
    checks: tuple[InputCheck, ...] = (FINITE,)
    level: Part | None = None
    setpoint: tuple[Part, ...] = ()

    @property
    def parts(self) -> tuple[Part, ...]:
        return tuple(p for p in (self.linear, self.angular, self.level, *self.setpoint) if p is not None)

    @property
    def moves(self) -> bool:
        """Whether ``track`` can turn it into a motion (it has a linear or an angular part)."""
        return self.linear is not None or self.angular is not None

    @property
    def switch(self) -> bool:
        """Whether it is a button: one number (its level), read by monitors as pressed above 1/2."""
        return self.level is not None

    @property
    def size(self) -> int:
        return sum(len(p.axes) for p in self.parts)

    @property
    def linear_range(self) -> slice | None:
        """Where the linear part sits in u (None: the input has none)."""
        return slice(0, 3) if self.linear else None

    @property
    def angular_range(self) -> slice | None:
        start = 3 if self.linear else 0
        return slice(start, start + 3) if self.angular else None

    def part_range(self, angular: bool) -> slice | None:
        return self.angular_range if angular else self.linear_range

    @property
    def unit_text(self) -> str:
        """The units as the metadata states them: 'N', or 'N (0-2), N m (3-5)'."""
        if len(self.parts) == 1:
            return self.parts[0].unit
        return ", ".join(f"{p.unit} ({3 * k}-{3 * k + 2})" for k, p in enumerate(self.parts))

    @property
    def columns(self) -> tuple[str, ...]:
        """The trace's column names of its components (``input.<name>.`` before each)."""
        return tuple(c for p in self.parts for c in p.columns())

    @property
    def self_test_scale(self) -> tuple[float, ...]:
        return tuple(p.self_test for p in self.parts for _ in p.axes)

    def gain_dimension(self, angular: bool) -> u.Dim | None:
        """The dimension of ``angular_gain`` (``angular``) or ``gain``: the part's rate over its quantity (a
        velocity = gain * input); None for a part the input lacks."""
        part = self.angular if angular else self.linear
        if part is None:
            return None
        rate = u.ANGULAR_SPEED if angular else u.SPEED
        return tuple(r - d for r, d in zip(rate, part.dimension))

    def first_failure(self, value: np.ndarray) -> tuple[InputCheck, int] | None:
        """The first check that a value fails and the component it fails on, or None."""
        for check in self.checks:
            margin = check.margin(value)
            holds = np.isfinite(margin) & (margin >= 0)
            if not holds.all():
                return check, int(np.argmin(holds))
        return None
