"""Sound across the motion: configurations the fixture itself reaches, not only the start.

The compiled controller runs a seeded random walk from the start: every HOLD ticks each input gets a new
random direction and a magnitude uniform up to the size that makes its tracked frame move at
SAMPLE_SPEED (or turn at SAMPLE_RATE) through the track term's gains (1 per component for an input no
term tracks). At every state reached, the hard rows' feasibility margin (the LP of :mod:`.lp`) and the
worst conditioning of the Jacobian blocks the constraints use (:mod:`.kinematics`) are measured.

A negative margin at a reached state is VF701 (error), with the state, the tick and an irreducible
infeasible subset there; a conditioning below kinematics.NEAR_SINGULAR is VF702 (warning). VF700 (note)
always gives the worst margin and conditioning found, with their states.
"""

from __future__ import annotations

import numpy as np

from vfdsl.check import feasibility
from vfdsl.check.handsoff import run
from vfdsl.check.kinematics import NEAR_SINGULAR, worst_conditioning
from vfdsl.check.linearized import Linearization
from vfdsl.ir.constraints import describe, value_of, where
from vfdsl.check.lp import FEASIBLE
from vfdsl.check.report import Finding, Severity
from vfdsl.inputs import INPUT_TYPES
from vfdsl.ir import model as ir
from vfdsl.runtime.qp import StepStatus

DEFAULT_SAMPLES = 200
HOLD = 10                        # ticks between changes of the random input
SAMPLE_SPEED = 0.02              # m/s
SAMPLE_RATE = 0.35               # rad/s (20 deg/s)


def input_scales(task: ir.Task) -> dict[str, np.ndarray]:
    """Per input, the magnitude of each component that moves its tracked frame at the sample speeds."""
    scales = {d.name: np.ones(d.size) for d in task.inputs}
    for o in task.objectives:
        if o.term != "track":
            continue
        decl = task.input(o.args["input"].name)
        gain = abs(value_of(o.args["gain"], task).value) if "gain" in o.args else 0.0
        angular = abs(value_of(o.args["angular_gain"], task).value) if "angular_gain" in o.args else 0.0
        linear_size = SAMPLE_SPEED / gain if gain > 0 else 1.0
        angular_size = SAMPLE_RATE / angular if angular > 0 else 1.0
        kind = INPUT_TYPES[decl.type]
        scale = np.empty(kind.size)
        for part, size in ((kind.linear_range, linear_size), (kind.angular_range, angular_size)):
            if part:
                scale[part] = size
        scales[decl.name] = scale
    return scales


def random_inputs(task: ir.Task, ticks: int, seed: int) -> list[dict[str, np.ndarray]]:
    """Piecewise-constant random inputs (a new direction and size every HOLD ticks) in each motion part (a force,
    a torque: 3 numbers); an input that moves nothing (a button) left at 0."""
    rng = np.random.default_rng(seed)
    scales = input_scales(task)
    kinds = {d.name: INPUT_TYPES[d.type] for d in task.inputs}
    out = []
    for t in range(ticks):
        if t % HOLD == 0:
            current = {}
            for name, scale in scales.items():
                value = np.zeros(len(scale))
                for part in (kinds[name].linear_range, kinds[name].angular_range):
                    if part:
                        direction = rng.normal(size=3)
                        value[part] = direction / np.linalg.norm(direction) * rng.uniform(0, 1) * scale[part]
                current[name] = value
        out.append(current)
    return out


def walk(controller, task: ir.Task, linear: Linearization, samples: int, seed: int) -> tuple[list, list]:
    """The seeded random walk: (the states, start first; the controller's status at each tick)."""
    inputs = random_inputs(task, samples, seed)
    statuses: list = []
    trajectory = run(controller, task, task.start, samples, linear.period, inputs.__getitem__, statuses)
    return trajectory, statuses


def analyse(controller, task: ir.Task, linear: Linearization, samples: int, seed: int,
            figures: dict, walked: tuple[list, list] | None = None) -> list[Finding]:
    robot = linear.robot
    trajectory, statuses = walked or walk(controller, task, linear, samples, seed)
    margins, conditioning = [], []
    speed = linear.speed_bound()
    for q in trajectory[1:]:
        margins.append(feasibility.margin(linear.rows(q), robot.nq, speed))
        conditioning.append(worst_conditioning(robot, task, q))
    worst_margin = int(np.argmin(margins))
    worst_conditioned = int(np.argmin([c for c, _ in conditioning]))
    least_violation = sum(bool(s & StepStatus.LEAST_VIOLATION) for s in statuses)
    summary = {"samples": samples, "seed": seed,
               "worst_margin": margins[worst_margin], "worst_margin_tick": worst_margin + 1,
               "worst_margin_q": trajectory[worst_margin + 1].tolist(),
               "worst_conditioning": conditioning[worst_conditioned][0],
               "worst_conditioning_where": conditioning[worst_conditioned][1],
               "worst_conditioning_tick": worst_conditioned + 1,
               "worst_conditioning_q": trajectory[worst_conditioned + 1].tolist(),
               "least_violation_ticks": least_violation}
    figures["sampled"] = summary
    q_text = _q_text(robot, trajectory[worst_margin + 1])
    findings = [Finding(
        "sampled-summary", Severity.NOTE,
        f"{samples} states reached under random input (seed {seed}): worst feasibility margin "
        f"{margins[worst_margin]:.3g} (m or rad) at tick {worst_margin + 1}; worst conditioning "
        f"{conditioning[worst_conditioned][0]:.3g} ({conditioning[worst_conditioned][1]}) at tick "
        f"{worst_conditioned + 1}; {least_violation} least-violation ticks", None, None, "sampled states", summary)]
    if margins[worst_margin] < FEASIBLE:
        q = trajectory[worst_margin + 1]
        conflict = feasibility.irreducible_infeasible_subset(linear.rows(q), robot.nq, speed)
        names = "; ".join(f"{describe(r.constraint)} at {where(r.constraint)}" for r in conflict)
        findings.append(Finding(
            "sampled-infeasible", Severity.ERROR,
            f"after {worst_margin + 1} tick{'s' * (worst_margin > 0)} of random input the hard rows cannot all hold"
            f"{feasibility.within(speed)} (margin "
            f"{margins[worst_margin]:.3g}) at q = {q_text}; conflicting: {names}",
            conflict[0].constraint.span if conflict else None,
            "relax one of the conflicting constraints, or limit the motion that leads there", "sampled states",
            {**summary, "conflict": [where(r.constraint) for r in conflict]}))
    if conditioning[worst_conditioned][0] < NEAR_SINGULAR:
        findings.append(Finding(
            "sampled-ill-conditioned", Severity.WARNING,
            f"after {worst_conditioned + 1} tick{'s' * (worst_conditioned > 0)} of random input "
            f"{conditioning[worst_conditioned][1]} has a "
            f"singular value ratio of {conditioning[worst_conditioned][0]:.3g} at q = "
            f"{_q_text(robot, trajectory[worst_conditioned + 1])}: near a singularity",
            task.frame(conditioning[worst_conditioned][1].split(".")[0]).span,
            "constrain the motion away from it (joint limits, a cone) or accept slow corrections there",
            "sampled states", summary))
    return findings


def _q_text(robot, q) -> str:
    return "{" + ", ".join(f"{n}: {v:.4g}" for n, v in zip(robot.joint_names, q)) + "} (SI)"
