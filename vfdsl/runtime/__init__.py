"""Run time: the tick solver graph and the calling layer for generated or interpreted code."""

from vfdsl.runtime.native import BufferedFunction
from vfdsl.runtime.qp import StepStatus, build_step_function

__all__ = ["BufferedFunction", "StepStatus", "build_step_function"]
