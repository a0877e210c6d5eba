"""vfdsl: virtual fixtures as short declarative ``.vf`` files, compiled into constrained least-squares controllers."""

from vfdsl.errors import VfError

__all__ = ["VfError"]
__version__ = "0.1.0"
