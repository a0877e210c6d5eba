"""The ``vfdsl check`` command: arguments, loading with another scene, output and exit status."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from vfdsl.check import DEFAULT_OVERSHOOT, MAX_OVERSHOOT, Report, checked_overshoot
from vfdsl.check.sampling import DEFAULT_SAMPLES
from vfdsl.pipeline import BACKENDS
from vfdsl.errors import VfError
from vfdsl.files import path_argument
from vfdsl import limits

EPILOG = """\
examples:
  vfdsl check tasks/paper_b_virtual_rcm.vf
  vfdsl check tasks/paper_b_virtual_rcm.vf --overshoot 5% --strict
  vfdsl check tasks/lecture_stay_near_goal.vf --scene other_start.yaml --json > report.json
  vfdsl check tasks/paper_a_follow_curve.vf --backend interpreted

Each finding has a stable code (VF101 polytope-unbounded, VF301 start-infeasible, ...), a severity
(error, warning, note) and the file:line:col of the construct it is about; docs/check.md explains every
code, the math behind it and the --json format. The table of guaranteed bounds gives, per constraint, the
worst error its polytope admits (its circumradius) against the stated tolerance.

exit status: 0 sound (warnings allowed), 1 an error (or a warning under --strict), 2 a usage, parse or
semantic error in the files (with --json, still a report on stdout: the error as finding VF000)."""


def register(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "check", help="prove a fixture sound before it runs: polytopes, tolerances, feasibility, residuals, ...",
        description="Analyse a task without running it on a robot: the polytopes behind its rows, its "
                    "tolerances against the robot's resolution and speeds, feasibility and errors at the "
                    "scene's start, kinematics, the closed loop with the hands off, configurations reached "
                    "under random input, unused or contradictory statements.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", type=path_argument, help="the .vf task file")
    parser.add_argument("--scene", metavar="S.yaml", type=path_argument,
                        help="use this scene file instead of the task's own")
    parser.add_argument("--json", action="store_true", help="print the report as JSON (see docs/check.md)")
    parser.add_argument("--strict", action="store_true", help="exit with status 1 on warnings too")
    parser.add_argument("--overshoot", metavar="PCT", default=DEFAULT_OVERSHOOT, type=_fraction,
                        help="largest accepted excess of a polytope's worst error over its tolerance, in percent: "
                             f"5%% or 5 (default: {DEFAULT_OVERSHOOT * 100:.0f}%%)")
    parser.add_argument("--samples", metavar="N", type=_counter(limits.CHECK_SAMPLES), default=DEFAULT_SAMPLES,
                        help=f"states of the random walk under random input to check (default: {DEFAULT_SAMPLES}; "
                             f"0 skips it; at most {limits.CHECK_SAMPLES:,})")
    parser.add_argument("--seed", metavar="S", type=_counter(limits.SEED), default=0,
                        help=f"seed of the random walk (default: 0; 0 to {limits.SEED:,})")
    parser.add_argument("--backend", choices=BACKENDS, default="auto",
                        help="how the closed-loop analyses run the controller: auto (default: the generated C when a "
                             "C compiler is found, built once per task version, 2-20 s), interpreted (CasADi in this "
                             "process: no build, slower ticks; quick checks while editing) or native (the generated "
                             "C; an error without a compiler)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import vfdsl
    from vfdsl.check import check

    try:
        task = load_with_scene(args.file, args.scene) if args.scene else vfdsl.load(args.file)
        report = check(task, overshoot=args.overshoot, samples=args.samples, seed=args.seed,
                       backend=args.backend)
    except VfError as error:
        if args.json:              # whoever reads the JSON gets a report: the error as its finding (VF000)
            _print_json(Report.input_error(args.file, error).to_json(args.strict))
        raise                      # and, as for every front-end error, the diagnostic on stderr, exit status 2
    if args.json:
        _print_json(report.to_json(args.strict))
    else:
        print(report.render_text(args.strict))
    return report.exit_status(args.strict)


def _print_json(data: dict) -> None:
    json.dump(data, sys.stdout, indent=2)
    sys.stdout.write("\n")


def load_with_scene(path: str | Path, scene: str | Path):
    """As :func:`vfdsl.load`, with the scene read from ``scene`` instead of the task's own."""
    from vfdsl.passes.imports import load_program
    from vfdsl.passes.resolve import Resolver, file_units
    from vfdsl.passes.scene import load_scene

    scene = Path(scene)
    if not scene.is_file():
        raise VfError(f"scene file not found: {scene}")

    class _OtherScene(Resolver):
        def _scene(self, statements):
            return load_scene(scene, self.units, None)

    path = Path(path)
    main, libraries = load_program(path)
    return _OtherScene(main.module, path, [(lib.module, file_units(lib.module)) for lib in libraries]).run(
        [str(lib.path) for lib in libraries])


def _counter(limit: int):
    """An argparse type: a whole number from 0 to ``limit`` (a limit of vfdsl/limits.py)."""
    def count(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if not 0 <= value <= limit:
            raise argparse.ArgumentTypeError(f"expected a whole number from 0 to {limit:,}, got {value:,}")
        return value
    return count


def _fraction(text: str) -> float:
    """'10%' or '10' (a percentage, as the option's PCT says) -> 0.1."""
    try:
        value = float(text.removesuffix("%")) / 100
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a percentage like 10%, got {text!r}") from None
    try:
        return checked_overshoot(value)
    except VfError:
        raise argparse.ArgumentTypeError(f"the overshoot must be between 0% and {MAX_OVERSHOOT:.0%}, got {text}") from None
