"""vfdsl: virtual fixtures as short declarative ``.vf`` files, compiled into constrained least-squares controllers."""

from vfdsl.errors import VfError
from vfdsl.ir.model import Task
from vfdsl.loader import load

__all__ = ["Task", "VfError", "load"]
__version__ = "0.1.0"
