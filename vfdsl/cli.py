"""The ``vfdsl`` command line.

User mistakes (syntax, names, units, files) print a diagnostic with file:line:col and a caret, and exit
with status 2; no Python traceback is shown for them. An empty path given for a file or folder is a usage error
(:func:`vfdsl.files.path_argument`).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import yaml

import vfdsl
from vfdsl.check import command as check_command
from vfdsl.errors import EXIT_USER_ERROR, VfError
from vfdsl.files import path_argument

_DESCRIPTION = """\
vfdsl compiles virtual fixtures written as .vf task files into constrained least-squares controllers.

A task file names a robot, task frames on it, the user's inputs, reference parameters, objective terms
(minimize ...) and constraints (require ...). See docs/language.md for the language."""

_EPILOG = """\
a first session:
  vfdsl simulate tasks/paper_b_virtual_rcm.vf    run paper experiment B on a simulated robot and hand
  vfdsl show tasks/paper_b_virtual_rcm.vf        check a task and see what the compiler will see
  vfdsl check tasks/paper_b_virtual_rcm.vf       prove the fixture sound before it touches a robot
  vfdsl compile tasks/paper_b_virtual_rcm.vf     generate and build its controller
  vfdsl view tasks/paper_b_virtual_rcm.vf        see the fixture in 3-D in the browser and push the tool
  python -c "import vfdsl; t = vfdsl.load('tasks/paper_b_virtual_rcm.vf'); \\
             print(vfdsl.compile(t).step(t.start, {'tau': [0, 0, 0.01]}))"

'vfdsl COMMAND --help' explains each command."""

_SHOW_EPILOG = """\
examples:
  vfdsl show tasks/paper_b_virtual_rcm.vf              the checked task, as YAML
  vfdsl show tasks/paper_a_follow_curve.vf --format json > a.json
  vfdsl show tasks/procedures/needle_procedure.vf --statechart dot | dot -Tsvg > machine.svg

Every number is in SI units (m, rad, s, N); every constraint keeps its source line (span) and, when it
comes from a fixture, the use sites it was expanded through (via)."""


class _CompactDumper(yaml.SafeDumper):
    """YAML with number lists and spans on one line each, so a task reads at a glance."""


def _represent_list(dumper: yaml.SafeDumper, data: list):
    flow = all(isinstance(x, (int, float)) for x in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


def _represent_dict(dumper: yaml.SafeDumper, data: dict):
    flow = set(data) == {"file", "line", "column", "end_line", "end_column"}
    return dumper.represent_mapping("tag:yaml.org,2002:map", data.items(), flow_style=flow)


_CompactDumper.add_representer(list, _represent_list)
_CompactDumper.add_representer(dict, _represent_dict)


_COMPILE_EPILOG = """\
examples:
  vfdsl compile tasks/paper_b_virtual_rcm.vf
  vfdsl compile tasks/paper_a_follow_curve.vf -o build/

The build directory holds <prefix>.c and .h (the generated source; C symbol <prefix>), the shared library,
and <prefix>.json (input and param layout, every constraint row with its source line, hashes, compiler and
versions). An unchanged task is not rebuilt; a damaged cache entry is detected and rebuilt."""


def _compile(args: argparse.Namespace) -> int:
    from vfdsl.pipeline import build

    start = time.perf_counter()
    task = vfdsl.load(args.file)
    controller, library = build(task, backend="native", cache_dir=args.output)
    seconds = time.perf_counter() - start
    problem = controller.assembled
    print(f"{task.name}: {'reused cached build' if library.reused else 'compiled'} in {seconds:.2f} s")
    print(f"  variables  {problem.nq} joint increments + {problem.n_slack} slacks")
    print(f"  rows       {len(problem.row_labels)} constraint rows, {problem.nq} joint bounds")
    print(f"  library    {library.so_path}")
    print(f"  source     {library.c_path}  ({len(library.c_path.read_text().splitlines())} lines)")
    print(f"  metadata   {library.meta_path}")
    return 0


_EXPORT_EPILOG = """\
examples:
  vfdsl export tasks/paper_b_virtual_rcm.vf -o vf_rcm/
  cd vf_rcm && make && ./example                 build with a C compiler and make (or: cmake -S . -B build)
  vfdsl export tasks/paper_a_follow_curve.vf -o vf_a/ --self-test

The folder holds vf_<task>.h (the C API: _new, _step, _set_param, _violations, _error_message, the names,
sizes and units of joints, inputs and params), vf_<task>.hpp (a C++ owner), the generated tick, DAQP's
sources and licence, a Makefile and a CMakeLists.txt (static and shared library, ./example, ./replay) and a
README. It needs no Python or CasADi to build. The C step checks its arguments as Controller.step() does,
with the same code, and allocates nothing after _new. Exporting an unchanged task again writes the same
bytes. docs/embedding.md shows a 1 kHz C++ loop, ros2_control and cisst."""


def _export(args: argparse.Namespace) -> int:
    from vfdsl import pipeline
    from vfdsl.export import export
    from vfdsl.export.selftest import self_test

    task = vfdsl.load(args.file)
    written = export(task, args.output, cache_dir=args.cache)
    print(f"{task.name}: exported {written.api} ({len(written.files)} files) to {written.directory}")
    print(f"  build      cd {written.directory} && make      (or: cmake -S . -B build && cmake --build build)")
    print(f"  API        {written.directory / (written.api + '.h')}")
    if args.self_test:
        controller, _ = pipeline.build(task, backend="native", cache_dir=args.cache)
        worst = self_test(controller, written, args.self_test)
        what = "|dq| and haptic readout" if controller.teleop is not None else "|dq|"
        print(f"  self-test  built with make; {args.self_test} closed-loop ticks replayed: statuses equal, "
              f"largest {what} difference from Controller.step() {worst:.3g}")
    return 0


def _ticks(text: str) -> int:
    from vfdsl.export.selftest import MAX_TICKS, check_count
    try:
        return check_count(int(text))
    except (ValueError, VfError):
        raise argparse.ArgumentTypeError(f"give a whole number of ticks from 1 to {MAX_TICKS:,}, not {text!r}") \
            from None


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="vfdsl", description=_DESCRIPTION, epilog=_EPILOG,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"vfdsl {vfdsl.__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    commands.required = True
    show = commands.add_parser("show", help="print the checked task (the IR the compiler sees)",
                               description="Load, check and print a task file's IR.", epilog=_SHOW_EPILOG,
                               formatter_class=argparse.RawDescriptionHelpFormatter)
    show.add_argument("file", type=path_argument, help="the .vf task file")
    show.add_argument("--format", choices=("yaml", "json"), default="yaml", help="output format (default: yaml)")
    show.add_argument("--statechart", choices=("dot", "mermaid"),
                      help="print the task's phase machine instead: states, initial and final marks, transitions "
                           "labelled with their guards (Graphviz DOT or Mermaid)")
    show.set_defaults(run=_show)

    build = commands.add_parser(
        "compile", help="generate, compile and cache the task's controller (C source, library, metadata)",
        description="Compile a task into a shared library: generated C for the whole tick (kinematics, "
                    "constraint rows, QP assembly, DAQP solve, least-violation fallback), built with the "
                    "system C compiler ($CC, default cc) and cached by content hash.",
        epilog=_COMPILE_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    build.add_argument("file", type=path_argument, help="the .vf task file")
    build.add_argument("-o", "--output", type=path_argument, metavar="DIR",
                       help="where to put the build (default: $VFDSL_CACHE or ~/.cache/vfdsl)")
    build.set_defaults(run=_compile)
    from vfdsl.export.selftest import MAX_TICKS
    export = commands.add_parser(
        "export", help="write the task's controller as a C library folder (builds with a C compiler and make)",
        description="Write a self-contained folder with the task's controller as C: the generated tick, DAQP's "
                    "sources, a small stable API (vf_<task>.h, and .hpp for C++), a Makefile and a CMakeLists.txt, "
                    "an example and a replay program. For C and C++ control loops without Python.",
        epilog=_EXPORT_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    export.add_argument("file", type=path_argument, help="the .vf task file")
    export.add_argument("-o", "--output", type=path_argument, metavar="DIR", required=True,
                        help="the folder to write (created if missing; files of the same names are replaced)")
    export.add_argument("--self-test", metavar="TICKS", type=_ticks, nargs="?", const=200, default=None,
                        help="then build a copy of the written files with make and replay TICKS (default 200, at most "
                             f"{MAX_TICKS:,}) closed-loop ticks recorded from Controller.step(): statuses must be "
                             "equal; prints the largest dq difference")
    export.add_argument("--cache", type=path_argument, metavar="DIR",
                        help="the build cache of the generated library (default: $VFDSL_CACHE or ~/.cache/vfdsl)")
    export.set_defaults(run=_export)
    reference = commands.add_parser(
        "primitives", help="list every constraint primitive and objective term, its arguments and their ranges",
        description="The signatures of `require` primitives and `minimize` terms, from their specs: argument "
                    "kinds, defaults and allowed ranges (the same table the loader checks and docs/language.md shows).")
    reference.add_argument("name", nargs="?", help="only this primitive or term")
    reference.set_defaults(run=_primitives)
    check_command.register(commands)
    from vfdsl.sim.command import add_parser as add_simulate
    add_simulate(commands)
    from vfdsl.sim.exported_replay import add_parser as add_replay_trace
    add_replay_trace(commands)
    from vfdsl.view.command import add_parser as add_view
    add_view(commands)
    return parser


def _show(args: argparse.Namespace) -> int:
    from vfdsl.ir import statechart

    task = vfdsl.load(args.file)
    if args.statechart:
        if not task.phases:
            raise VfError(f"task '{task.name}' has no phases: there is no statechart to show",
                          hint="a procedure is written with `phase NAME { ... }` and `transition A -> B when ...` "
                               "(docs/language.md, \"Procedures\")")
        sys.stdout.write(getattr(statechart, args.statechart)(task))
        return 0
    data = task.model_dump(mode="json")
    if args.format == "json":
        json.dump(data, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        yaml.dump(data, sys.stdout, Dumper=_CompactDumper, sort_keys=False, width=110)
    return 0


def _primitives(args: argparse.Namespace) -> int:
    from vfdsl.objectives import OBJECTIVES
    from vfdsl.primitives import CONSTRAINTS
    from vfdsl.primitives.spec import REQUIRED
    from vfdsl.errors import suggest
    specs = [("require", s) for s in CONSTRAINTS.values()] + [("minimize", s) for s in OBJECTIVES.values()]
    if args.name is not None:
        specs = [(k, s) for k, s in specs if s.name == args.name]
        if not specs:
            known = [*CONSTRAINTS, *OBJECTIVES]
            raise VfError(f"no primitive or objective term '{args.name}'", hint=suggest(args.name, known, "names"))
    for keyword, spec in specs:
        print(f"{keyword} {'FRAME ' if getattr(spec, 'subject', False) else ''}{spec.name}(...)  {spec.summary}")
        for arg in spec.args:
            default = "required" if arg.default is REQUIRED else "optional"
            allowed = f", allowed {arg.range.describe()}" if arg.range is not None else ""
            print(f"    {arg.name:<14} {arg.kind:<14} {default}{allowed}  {arg.doc}")
        if getattr(spec, "tolerance", None):
            print(f"    within         {spec.tolerance:<14} default {spec.default_tolerance:g} (SI)")
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return args.run(args)
    except VfError as err:
        print(err.render(), file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:                      # e.g. `vfdsl show x.vf | head`: stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
