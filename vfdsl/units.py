"""Units and dimensions: every literal becomes an SI number (m, rad, s, N), or a compile error.

A dimension is a vector of exponents over (length, angle, time, force). Angles are a dimension of their
own here, so that a length where an angle belongs (or the reverse) is caught at compile time. A number
written without a unit takes the file's default units (``units mm, deg``), combined with the expected
dimension: a bare ``5`` where a speed is expected means 5 mm/s in a ``units mm`` file.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass

from vfdsl.errors import Span, VfError

Dim = tuple[int, int, int, int]          # exponents of (length, angle, time, force)

DIMENSIONLESS: Dim = (0, 0, 0, 0)
LENGTH: Dim = (1, 0, 0, 0)
ANGLE: Dim = (0, 1, 0, 0)
TIME: Dim = (0, 0, 1, 0)
FORCE: Dim = (0, 0, 0, 1)
TORQUE: Dim = (1, 0, 0, 1)
SPEED: Dim = (1, 0, -1, 0)
ANGULAR_SPEED: Dim = (0, 1, -1, 0)
FREQUENCY: Dim = (0, 0, -1, 0)
STIFFNESS: Dim = (-1, 0, 0, 1)           # N/m: a haptic spring
FORCE_DAMPING: Dim = (-1, 0, 1, 1)       # N s/m: a haptic damper
FORCE_RATE: Dim = (0, 0, -1, 1)          # N/s: how fast a haptic force may change

# name -> (dimension, factor to SI)
UNITS: dict[str, tuple[Dim, float]] = {
    "m": (LENGTH, 1.0), "cm": (LENGTH, 1e-2), "mm": (LENGTH, 1e-3), "um": (LENGTH, 1e-6),
    "rad": (ANGLE, 1.0), "mrad": (ANGLE, 1e-3), "deg": (ANGLE, math.pi / 180.0),
    "s": (TIME, 1.0), "ms": (TIME, 1e-3), "Hz": (FREQUENCY, 1.0),
    "N": (FORCE, 1.0), "Nm": (TORQUE, 1.0), "Nmm": (TORQUE, 1e-3),
}

_BASE_NAMES = ("length", "angle", "time", "force")
_DIM_WORDS = {
    DIMENSIONLESS: "a plain number", LENGTH: "a length", ANGLE: "an angle", TIME: "a time",
    FORCE: "a force", TORQUE: "a torque", SPEED: "a speed", ANGULAR_SPEED: "an angular speed",
    FREQUENCY: "a frequency", STIFFNESS: "a stiffness", FORCE_DAMPING: "a damping coefficient",
    FORCE_RATE: "a force rate",
}
_EXAMPLE_UNIT = {LENGTH: "mm", ANGLE: "deg", TIME: "s", FORCE: "N", TORQUE: "Nmm", SPEED: "mm/s",
                 ANGULAR_SPEED: "deg/s", FREQUENCY: "Hz", DIMENSIONLESS: "",
                 STIFFNESS: "N/mm", FORCE_DAMPING: "N*s/m", FORCE_RATE: "N/s"}


def describe(dim: Dim) -> str:
    """'a length', 'a speed', or the SI formula for other dimensions ('m/s/N')."""
    return _DIM_WORDS.get(dim) or f"a quantity in {si_formula(dim)}"


def example(dim: Dim) -> str:
    """How to write a value of dimension ``dim``: 'a number with a unit, e.g. 5 mm', 'a plain number, e.g. 10'."""
    if dim == DIMENSIONLESS:
        return "a plain number, e.g. 10"
    return f"a number with a unit, e.g. 5 {_EXAMPLE_UNIT.get(dim) or si_formula(dim)}"


def si_formula(dim: Dim) -> str:
    si = ("m", "rad", "s", "N")
    num = "*".join(s if e == 1 else f"{s}^{e}" for s, e in zip(si, dim) if e > 0) or "1"
    den = [s if e == -1 else f"{s}^{-e}" for s, e in zip(si, dim) if e < 0]
    if not den:
        return num
    return f"{num}/{den[0]}" if len(den) == 1 else f"{num}/({'*'.join(den)})"


@dataclass(frozen=True)
class DefaultUnits:
    """The file's ``units`` statement: the unit a bare number takes for each base dimension."""

    length: str = "m"
    angle: str = "rad"
    time: str = "s"
    force: str = "N"

    def factor(self, dim: Dim) -> float:
        """SI factor of a bare number of dimension ``dim``."""
        scale = 1.0
        for base_unit, exponent in zip((self.length, self.angle, self.time, self.force), dim):
            scale *= UNITS[base_unit][1] ** exponent
        return scale

    def show(self, value: float, dim: Dim) -> str:
        """An SI ``value`` of dimension ``dim`` written in these units: 0.003 m -> '3 mm', 0.02 m/s -> '20 mm/s'."""
        names = (self.length, self.angle, self.time, self.force)
        num = "*".join(n if e == 1 else f"{n}^{e}" for n, e in zip(names, dim) if e > 0)
        den = "".join(f"/{n}" if e == -1 else f"/{n}^{-e}" for n, e in zip(names, dim) if e < 0)
        unit = (num or ("1" if den else "")) + den
        return f"{value / self.factor(dim):g} {unit}".rstrip()

    def with_unit(self, name: str, span: Span) -> "DefaultUnits":
        dim, _ = lookup(name, span)
        if dim not in (LENGTH, ANGLE, TIME, FORCE):
            raise VfError(f"'{name}' is not a base unit; a units statement takes units of length, angle, "
                          "time or force", span, hint="e.g. units mm, deg", code="E303")
        field = _BASE_NAMES[(LENGTH, ANGLE, TIME, FORCE).index(dim)]
        return DefaultUnits(**{**self.__dict__, field: name})


def default_units(names: list[tuple[str, Span]], base: DefaultUnits = DefaultUnits()) -> DefaultUnits:
    """The defaults set by one units statement (``units mm, deg``): at most one unit per base dimension."""
    seen: dict[Dim, str] = {}
    units = base
    for name, span in names:
        dim, _ = lookup(name, span)
        if dim in seen:
            raise VfError(f"two units for {describe(dim)}: '{seen[dim]}' and '{name}'", span, code="E303")
        seen[dim] = name
        units = units.with_unit(name, span)
    return units


def lookup(name: str, span: Span) -> tuple[Dim, float]:
    try:
        return UNITS[name]
    except KeyError:
        close = difflib.get_close_matches(name, UNITS, n=1, cutoff=0.5)
        hint = f"did you mean '{close[0]}'? " if close else ""
        raise VfError(f"unknown unit '{name}'", span,
                      hint=hint + "known units: " + ", ".join(UNITS), code="E301") from None


def parse_unit(text: str, span: Span) -> tuple[Dim, float]:
    """'deg/s/N/mm' -> (dimension, SI factor). Operators apply left to right."""
    dim = [0, 0, 0, 0]
    factor = 1.0
    sign = 1
    token = ""
    for ch in text + "*":
        if ch in "*/":
            unit_dim, unit_factor = lookup(token, span)
            dim = [d + sign * u for d, u in zip(dim, unit_dim)]
            factor *= unit_factor ** sign
            sign = 1 if ch == "*" else -1
            token = ""
        else:
            token += ch
    return tuple(dim), factor


def to_si(number: float, unit: str | None, expected: Dim, defaults: DefaultUnits, span: Span) -> float:
    """Convert one number to SI, checking its unit's dimension against ``expected``."""
    if not math.isfinite(number):
        raise VfError("numbers must be finite", span, code="E304")
    if unit is None:
        return number * defaults.factor(expected)
    dim, factor = parse_unit(unit, span)
    if dim != expected:
        example = _EXAMPLE_UNIT.get(expected)
        hint = f"write it like 5 {example}".rstrip() if example is not None else f"use units of {si_formula(expected)}"
        if expected == DIMENSIONLESS:
            hint = "write a plain number, without a unit"
        raise VfError(f"expected {describe(expected)}, but '{unit}' is {describe(dim)}", span, hint=hint, code="E302")
    value = number * factor
    if not math.isfinite(value):
        raise VfError("this number is too large", span, code="E304")
    return value
