"""vfdsl: virtual fixtures as short declarative ``.vf`` files, compiled into constrained least-squares controllers.

    task = vfdsl.load("tasks/paper_b_virtual_rcm.vf")       # parse, import, expand, check
    report = vfdsl.check(task)                              # is the fixture sound? (docs/check.md)
    ctrl = vfdsl.compile(task)                              # the tick's QP and its solver
    dq = ctrl.step(task.start, {"tau": [0, 0, 0.01]})
"""

from vfdsl.check import check
from vfdsl.errors import VfError
from vfdsl.ir.model import Task
from vfdsl.loader import load
from vfdsl.pipeline import compile
from vfdsl.runtime.controller import Controller

__all__ = ["Controller", "Task", "VfError", "check", "compile", "load"]
__version__ = "0.1.0"
