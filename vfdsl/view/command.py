"""``vfdsl view``: see a task's fixtures in 3-D in the browser, push its tool, replay a run, take a picture."""

from __future__ import annotations

import argparse
import json
import os
import sys
import threading
import time
import webbrowser
from pathlib import Path

from vfdsl.errors import VfError
from vfdsl.files import path_argument
from vfdsl import limits
from vfdsl.view import options

STATE_PREFIX = "VFDSL-VIEW-STATE "

_EPILOG = """\
examples:
  vfdsl view tasks/paper_b_virtual_rcm.vf                      open the viewer (Ctrl-C stops it)
  vfdsl view tasks/paper_a_follow_curve.vf --port 8090 --no-browser
  vfdsl view tasks/paper_a_follow_curve.vf --replay run.csv    play a per-tick trace with a time slider
  vfdsl view tasks/paper_a_follow_curve.vf --replay run.mcap   the same from an MCAP trace (simulate --trace run.mcap)
  vfdsl view tasks/paper_b_virtual_rcm.vf --screenshot b.png   a picture (headless Chromium), then exit

The scene is in metres, to scale: the robot at the scene's start configuration, each task frame with its
tool axis (magenta), every fixture with its tolerance (polytope, tube, band or cone) and guaranteed bound
(wire). Hard fixtures are blue, soft ones orange, a violated one red. Drag the hand (the transform
controls at the tool) to push the tool: the controller runs live at the task's period. docs/view.md
explains the colours, the hand and the trace format."""


def add_parser(commands) -> None:
    view = commands.add_parser(
        "view", help="show the task's robot and fixtures in 3-D in the browser; push the tool with a handle",
        description="Start a local 3-D viewer (viser) of a task: the robot at its start configuration, the "
                    "task frames, every fixture with its tolerance; a draggable hand drives the compiled "
                    "controller live; --replay plays a recorded run.",
        epilog=_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    view.add_argument("file", type=path_argument, help="the .vf task file")
    view.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1)")
    view.add_argument("--port", type=int, default=0,
                      help="port to listen on, 0 to 65535 (default 0: a free port)")
    view.add_argument("--no-browser", action="store_true", help="do not open a browser")
    view.add_argument("--replay", metavar="FILE", type=path_argument,
                      help="play a per-tick trace (CSV, or the MCAP of vfdsl simulate "
                      "--trace run.mcap; see docs/view.md)")
    view.add_argument("--trial", help="with --replay: the trial to play (default: the first)")
    view.add_argument("--screenshot", metavar="PNG", type=path_argument,
                      help="save a picture of the page (headless Chromium) and exit")
    view.add_argument("--size", help=f"--screenshot: picture size in pixels, at most {limits.PICTURE_SIDE} a side "
                                       "(default 1280x800)")
    view.add_argument("--magnify", type=float, default=1.0,
                      help=f"draw tolerances this many times larger, {options.MAGNIFY[0]:g} to "
                           f"{options.MAGNIFY[1]:g} (default 1: to scale)")
    view.add_argument("--push", metavar="X,Y,Z",
                      help="start with the hand held this far from the tool (mm, world axes), e.g. 5,0,0")
    view.add_argument("--seconds", type=float, default=None,
                      help="with --screenshot: run the controller this long (s) before the picture; with "
                           "--replay: show this time (s after the trace's first row)")
    view.add_argument("--control", action="store_true", help=argparse.SUPPRESS)   # JSON commands on stdin
    view.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import vfdsl
    from vfdsl.view.app import Viewer

    opts = options.check(args)                   # before the task: a wrong flag fails in a second
    task = vfdsl.load(args.file)
    trace = _replay(args, task) if args.replay else None
    ticks = _check_with_task(opts, task, trace)   # and before the compiler
    controller = vfdsl.compile(task)
    viewer = Viewer(task, controller, host=args.host, port=opts.port, replay=trace, magnify=opts.magnify)
    try:
        if opts.push is not None:
            viewer.push(opts.push)
        if trace is not None and opts.seconds is not None:
            viewer.show_time(float(trace.t[0]) + opts.seconds)
        if args.screenshot:
            return _screenshot(viewer, args.screenshot, opts.size, ticks)
        print(f"vfdsl view: {task.name} at {viewer.url}  (Ctrl-C to stop)", flush=True)
        viewer.start_live()
        if not args.no_browser:
            webbrowser.open(viewer.url)
        if args.control:
            threading.Thread(target=_control, args=(viewer,), daemon=True).start()
        while True:
            time.sleep(0.2)
    except KeyboardInterrupt:
        return 0
    finally:
        viewer.close()


def _replay(args: argparse.Namespace, task):
    """The trace of ``--replay``, with the run-time params of the task (those with numbers at run time)."""
    from vfdsl.view import replay
    from vfdsl.compiler.context import flatten
    from vfdsl.kinematics.robot import Robot
    robot = Robot.load(task.robots[0].urdf)
    sizes = {d.name: size for d in task.params if (size := len(flatten(d.value)))}
    return replay.read(args.replay, robot.joint_names, task.scene.period, args.trial, sizes)


def _check_with_task(opts: options.Options, task, trace) -> int:
    """The flags that depend on the task: ``--push`` needs a hand (an input), ``--seconds`` a run within the
    limits or a time the trace has. The ticks to run before a picture."""
    from vfdsl.sim.settings import check_ticks
    from vfdsl.view.live import control_period, hand_model
    if opts.push is not None and hand_model(task) is None:
        what = "no input but buttons" if task.inputs else "no input"
        raise VfError(f"--push: task '{task.name}' has {what}, so no hand to hold",
                      hint="leave --push out: the task runs hands off")
    if opts.seconds is None or opts.seconds == 0:
        return 0
    if trace is not None:
        length = float(trace.t[-1] - trace.t[0])
        if opts.seconds > length + 1e-9:
            raise VfError(f"--seconds {opts.seconds:g}: the trace lasts {length:g} s",
                          hint=f"a time from 0 to {length:g} s after its first row")
        return 0
    return check_ticks(opts.seconds, control_period(task), what=f"--seconds {opts.seconds:g}: ")


def _screenshot(viewer, path: str, size: tuple[int, int], ticks: int) -> int:
    for k in range(ticks):
        viewer.tick(draw=k == ticks - 1)
    for name, node in viewer.nodes.items():          # pictures show the scene, not the handles
        if name == "/hand" or name.startswith("/params/"):
            node.visible = False
    png = take_picture(viewer, *size)
    try:
        Path(path).write_bytes(png)
    except OSError as err:
        raise VfError(f"cannot write {path}: {err.strerror or err}") from None
    print(f"vfdsl view: {viewer.task.name}: wrote {path} ({size[0]}x{size[1]})")
    return 0


def take_picture(viewer, width: int = 1280, height: int = 800, settle: float = 3.0, timeout: float = 30.0) -> bytes:
    """Load the viewer's page in headless Chromium, wait until it is connected and drawn, and return a PNG."""
    from vfdsl.view.browser import Browser
    start = time.monotonic()
    with Browser(width, height, timeout=timeout) as browser:
        browser.open(viewer.url)
        deadline = time.monotonic() + timeout
        while not viewer.server.get_clients():
            if time.monotonic() > deadline:
                raise VfError(f"the page at {viewer.url} did not connect within {timeout:g} s")
            time.sleep(0.1)
        connected = time.monotonic()
        time.sleep(settle)
        browser.evaluate(_HIDE_NOTICES)
        time.sleep(0.2)
        shot = time.monotonic()
        png = browser.screenshot()
        if os.environ.get("VFDSL_VIEW_TIMING"):
            print(f"connect {connected - start:.1f} s, capture {time.monotonic() - shot:.1f} s", file=sys.stderr)
        return png


# Chromium renders WebGL in software here; the viewer's notice saying so is hidden in pictures.
_HIDE_NOTICES = """
for (const el of document.querySelectorAll('[class*="Notification"]')) {
  if (el.textContent.includes('Software WebGL')) el.style.display = 'none';
}
"""


def _control(viewer) -> None:
    """JSON commands, one per line on stdin (tests and scripts): {"cmd": "state"} prints a state line;
    {"cmd": "push", "offset": [x, y, z]} (m) holds the hand there; {"cmd": "param", "name": n, "value": v}
    sets a run-time param; {"cmd": "press", "name": b} presses a button input (100 ms); {"cmd": "reset"}."""
    for line in sys.stdin:
        try:
            command = json.loads(line)
            what = command.get("cmd")
            if what == "push":
                viewer.push(command["offset"])
            elif what == "param":
                viewer.set_param(command["name"], command["value"])
            elif what == "press":
                viewer.press(command["name"])
            elif what == "reset":
                viewer.reset()
            reply = viewer.state()
        except Exception as err:                 # a bad command is reported, never fatal
            reply = {"error": f"{type(err).__name__}: {err}"}
        print(STATE_PREFIX + json.dumps(reply), flush=True)
