"""The input types a task may declare (``input NAME : TYPE``), one module each; adding one is its module and one
line below. Every tool reads what an input means from here (:class:`~vfdsl.inputs.base.InputType`)."""

from vfdsl.inputs import button, force, pose, torque, twist, wrench
from vfdsl.inputs.base import InputType

INPUT_TYPES: dict[str, InputType] = {m.INPUT.name: m.INPUT for m in (force, torque, wrench, twist, button, pose)}


def input_type(name: str) -> InputType:
    return INPUT_TYPES[name]


def described(test) -> str:
    """'a torque, wrench or twist input': the types for which ``test(type)`` holds, in registry order."""
    names = [t.name for t in INPUT_TYPES.values() if test(t)]
    return "a " + (f"{', '.join(names[:-1])} or {names[-1]}" if len(names) > 1 else names[0]) + " input"
