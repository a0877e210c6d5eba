"""Follow a teleoperation master (DESIGN, "Procedures and teleoperation"), as rates:

    linear part:   weight * || J_v dq/dt - (g - p) / tau ||^2               (m/s)
    angular part:  weight * || J_w dq/dt - log(R_g R') / tau ||^2          (rad/s)

with the frame at (p, R), tau = max(time_constant, dt) (never more than the whole gap in one tick), and the goal

    g   = s0 + scale * R_c (m - m0)                          the master's translation since engage, scaled, in the world
    R_g = R_c R_m R_m0' R_c' R_s0     rotation = relative     the master's rotation since engage, unscaled
    R_g = R_c R_m                     rotation = absolute     the master's orientation, seen through the camera
    R_g = R_s0                        rotation = locked       the orientation at engage

(m, R_m) the master's pose (a pose input), (m0, R_m0) its pose at engage and (s0, R_s0) the frame's pose at engage
(two pose captures of the phase that follows: both re-anchored each time it is entered, so nothing jumps at engage
or on clutch release), R_c the camera's rotation (a pose param, world <- master base: a moving camera). A scale
given as a captured param changes only across a clutch. log(R) is the rotation vector (geometry.rotation_vector).

The haptic arguments (stiffness, damping, saturation, rate_limit, ramp) shape the force the master feels:
:mod:`vfdsl.objectives.haptics`.
"""

import casadi as ca

from vfdsl import limits
from vfdsl.compiler.geometry import rotation_vector, rpy_matrix
from vfdsl.compiler.rows import Term, toward
from vfdsl.ir import model as ir
from vfdsl.primitives.spec import POSITIVE, ArgSpec, ObjectiveSpec, Range, choice

ROTATIONS = ("relative", "absolute", "locked")
NONNEGATIVE = Range(low=0.0)

SPEC = ObjectiveSpec(
    name="teleop",
    summary="move the frame as a teleoperation master moves since engage (scaled), and feed back what fixtures stop",
    args=(ArgSpec("frame", "frame", "the task frame the master drives (the slave)"),
          ArgSpec("master", "input", "the master's pose (an input of type pose)"),
          ArgSpec("anchor", "pose", "the frame's pose at engage: capture NAME = FRAME.pose in the following phase"),
          ArgSpec("master_anchor", "pose", "the master's pose at engage: capture NAME = MASTER in the same phase"),
          ArgSpec("scale", "number", "slave motion per master motion (translation only): 0.2 moves the tool 1 mm per "
                  "5 mm of the hand (a ratio 1:5)",
                  default=ir.ScalarValue(dimension="number", value=1.0),
                  range=Range(low=0.0, low_open=True, high=limits.TELEOP_SCALE)),
          ArgSpec("rotation", "choice", "relative: the master's rotation since engage; absolute: its orientation; "
                  "locked: keep the orientation at engage", default=ir.ChoiceValue(value="relative"),
                  choices=ROTATIONS),
          ArgSpec("camera", "pose", "the master's base in the world (a pose param for a moving camera)",
                  default=ir.PoseValue(translation=[0.0] * 3, rpy=[0.0] * 3)),
          ArgSpec("time_constant", "time", "how fast the frame closes the gap to the goal",
                  default=ir.ScalarValue(dimension="time", value=0.01), range=POSITIVE),
          ArgSpec("stiffness", "stiffness", "haptic spring, per metre of master motion the fixtures stopped "
                  "(0: no force fed back)", default=ir.ScalarValue(dimension="stiffness", value=0.0),
                  range=NONNEGATIVE),
          ArgSpec("damping", "force_damping", "haptic damper on the rate of that motion",
                  default=ir.ScalarValue(dimension="force_damping", value=0.0), range=NONNEGATIVE),
          ArgSpec("saturation", "force", "the largest haptic force",
                  default=ir.ScalarValue(dimension="force", value=3.0),
                  range=Range(low=0.0, low_open=True, high=limits.HAPTIC_FORCE)),
          ArgSpec("rate_limit", "force_rate", "how fast the haptic force may change",
                  default=ir.ScalarValue(dimension="force_rate", value=500.0), range=POSITIVE),
          ArgSpec("ramp", "time", "how long the haptic force takes to ramp in after engage",
                  default=ir.ScalarValue(dimension="time", value=0.1), range=POSITIVE),
          ArgSpec("master_damping", "force_damping", "the master's own physical damping, for vfdsl check's "
                  "passivity bound (0: not known)", default=ir.ScalarValue(dimension="force_damping", value=0.0),
                  range=NONNEGATIVE),
          ArgSpec("master_reach", "length", "how far the master moves from its engage pose, for vfdsl check's "
                  "workspace check (0: not known)", default=ir.ScalarValue(dimension="length", value=0.0),
                  range=Range(low=0.0, high=limits.ROW_VALUE))),
    source="dVRK teleoperation (mtsTeleOperationPSM), Li, Kapoor & Taylor 2005 for the fixture",
)


def goal(o, ctx) -> tuple[ca.SX, ca.SX]:
    """(g, R_g): where the master puts the frame this tick (module docstring)."""
    m = ctx.input(o.args["master"])
    R_c, _ = ctx.pose(o.args["camera"])
    R_s0, s0 = ctx.pose(o.args["anchor"])
    R_m0, m0 = ctx.pose(o.args["master_anchor"])
    R_m = rpy_matrix(m[3:6])
    g = s0 + ctx.scalar(o.args["scale"]) * (R_c @ (m[0:3] - m0))
    R_g = {"relative": lambda: R_c @ R_m @ R_m0.T @ R_c.T @ R_s0,
           "absolute": lambda: R_c @ R_m,
           "locked": lambda: R_s0}[choice(o.args, "rotation")]()
    return g, R_g


def commanded(o, ctx) -> tuple[ca.SX, ca.SX, ca.SX]:
    """(v_c, w_c, tau): the linear and angular rate the master asks of the frame, and the time they close the gap in."""
    f = ctx.frame(o.args["frame"].name)
    g, R_g = goal(o, ctx)
    tau = ca.fmax(ctx.scalar(o.args["time_constant"]), ctx.dt)
    return toward(g - f.p, tau, ctx.dt), rotation_vector(R_g @ f.R.T) / tau, tau


def lower(o, ctx) -> tuple[Term, Term]:
    f = ctx.frame(o.args["frame"].name)
    v_c, w_c, _ = commanded(o, ctx)
    return Term(E=f.Jv, f=v_c, part="linear"), Term(E=f.Jw, f=w_c, part="angular")

