"""``vfdsl view``: see a task's fixtures in 3-D in the browser, push its tool, replay a run, take a picture."""

from __future__ import annotations

import argparse
import json
import os
import socket
import sys
import threading
import time
import webbrowser
from pathlib import Path

from vfdsl.errors import VfError

STATE_PREFIX = "VFDSL-VIEW-STATE "

_EPILOG = """\
examples:
  vfdsl view tasks/paper_b_virtual_rcm.vf                      open the viewer (Ctrl-C stops it)
  vfdsl view tasks/paper_a_follow_curve.vf --port 8090 --no-browser
  vfdsl view tasks/paper_a_follow_curve.vf --replay run.csv    play a per-tick trace with a time slider
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
    view.add_argument("file", help="the .vf task file")
    view.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1)")
    view.add_argument("--port", type=int, default=0,
                      help="port to listen on (default: a free port)")
    view.add_argument("--no-browser", action="store_true", help="do not open a browser")
    view.add_argument("--replay", metavar="FILE", help="play a per-tick trace (CSV; see docs/view.md)")
    view.add_argument("--trial", help="with --replay: the trial to play (default: the first)")
    view.add_argument("--screenshot", metavar="PNG", help="save a picture of the page (headless Chromium) and exit")
    view.add_argument("--size", default="1280x800", help="--screenshot: picture size (default 1280x800)")
    view.add_argument("--magnify", type=float, default=1.0,
                      help="draw tolerances this many times larger (default 1: to scale)")
    view.add_argument("--push", metavar="X,Y,Z",
                      help="start with the hand held this far from the tool (mm, world axes), e.g. 5,0,0")
    view.add_argument("--seconds", type=float, default=None,
                      help="with --screenshot: run the controller this long (s) before the picture (with "
                           "--replay: show this time)")
    view.add_argument("--control", action="store_true", help=argparse.SUPPRESS)   # JSON commands on stdin
    view.set_defaults(run=run)


def free_port(host: str = "127.0.0.1") -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def run(args: argparse.Namespace) -> int:
    import vfdsl
    from vfdsl.view.app import Viewer

    task = vfdsl.load(args.file)
    controller = vfdsl.compile(task)
    trace = None
    if args.replay:
        from vfdsl.view import replay
        from vfdsl.compiler.context import flatten
        from vfdsl.kinematics.robot import Robot
        robot = Robot.load(task.robots[0].urdf)
        sizes = {name: len(flatten(controller.param_defaults[name])) for name in controller.param_names}
        trace = replay.read(args.replay, robot.joint_names, controller.default_dt, args.trial, sizes)
    push = _vector(args.push, "--push") if args.push else None
    port = args.port or free_port(args.host)
    viewer = Viewer(task, controller, host=args.host, port=port, replay=trace, magnify=args.magnify)
    try:
        if push is not None and viewer.hand is not None:
            viewer.push(push * 1e-3)
        if args.screenshot:
            return _screenshot(viewer, args)
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


def _vector(text: str, what: str):
    import numpy as np
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3:
        raise VfError(f"{what} takes three numbers separated by commas, got {text!r}")
    return np.array(values)


def _screenshot(viewer, args) -> int:
    try:
        width, height = (int(x) for x in args.size.lower().split("x"))
    except ValueError:
        raise VfError(f"--size takes WIDTHxHEIGHT, got {args.size!r}") from None
    if args.seconds:
        ticks = int(round(args.seconds / viewer.period))
        if viewer.replay is None and viewer.hand is not None:
            for k in range(ticks):
                viewer.tick(draw=k == ticks - 1)
        elif viewer.replay is not None:
            viewer.show_time(float(viewer.replay.t[0]) + args.seconds)
    for name, node in viewer.nodes.items():          # pictures show the scene, not the handles
        if name == "/hand" or name.startswith("/params/"):
            node.visible = False
    png = take_picture(viewer, width, height)
    Path(args.screenshot).write_bytes(png)
    print(f"vfdsl view: {viewer.task.name}: wrote {args.screenshot} ({width}x{height})")
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
    sets a run-time param; {"cmd": "reset"}."""
    for line in sys.stdin:
        try:
            command = json.loads(line)
            what = command.get("cmd")
            if what == "push":
                viewer.push(command["offset"])
            elif what == "param":
                viewer.set_param(command["name"], command["value"])
            elif what == "reset":
                viewer.reset()
            reply = viewer.state()
        except Exception as err:                 # a bad command is reported, never fatal
            reply = {"error": f"{type(err).__name__}: {err}"}
        print(STATE_PREFIX + json.dumps(reply), flush=True)
