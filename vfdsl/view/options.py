"""The flags of ``vfdsl view``, checked before the task is loaded and before any server or browser starts: a
flag that cannot work is one line on stderr and exit status 2, never a server left running (docs/view.md,
"Checks")."""

from __future__ import annotations

import argparse
import errno
import math
import re
import socket
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vfdsl import limits
from vfdsl.errors import VfError
from vfdsl.files import check_writable

MAGNIFY = (1.0, 1000.0)          # the tolerances drawn this many times larger: --magnify and the panel's slider
PORTS = 65535


@dataclass(frozen=True)
class Options:
    """The checked flags: the port found free, and the values in SI."""

    port: int
    magnify: float
    size: tuple[int, int]                  # --screenshot: width, height (pixels)
    push: np.ndarray | None                # m, world axes
    seconds: float | None                  # s


def check(args: argparse.Namespace) -> Options:
    """Every flag alone and the flags together; the files they name (the screenshot is writable, Chromium is
    installed) and the address the server will listen on (a trace is read with the task: it needs its joints)."""
    if args.trial is not None and not args.replay:
        raise VfError(f"--trial {args.trial}: a trial is picked from a --replay trace", hint="add --replay FILE")
    if args.size is not None and not args.screenshot:
        raise VfError(f"--size {args.size}: the size of a --screenshot", hint="add --screenshot FILE.png")
    if args.seconds is not None and not (args.screenshot or args.replay):
        raise VfError(f"--seconds {args.seconds:g}: the time a --screenshot runs the controller (or the time of a "
                      "--replay shown)", hint="add --screenshot FILE.png or --replay FILE")
    if args.push is not None and args.replay:
        raise VfError(f"--push {args.push}: a replay has no hand to hold (it plays the recorded joints)",
                      hint="leave --push out, or --replay")
    seconds = None
    if args.seconds is not None:
        seconds = args.seconds
        if not (math.isfinite(seconds) and seconds >= 0):
            raise VfError(f"--seconds {seconds:g}: a time is a finite number of seconds, zero or more")
    magnify = args.magnify
    if not (math.isfinite(magnify) and MAGNIFY[0] <= magnify <= MAGNIFY[1]):
        raise VfError(f"--magnify {magnify:g}: the tolerances are drawn from {MAGNIFY[0]:g} (to scale) to "
                      f"{MAGNIFY[1]:g} times larger")
    size = (1280, 800) if args.size is None else picture_size(args.size)
    push = None if args.push is None else offset(args.push)
    if args.screenshot:
        if Path(args.screenshot).suffix.lower() != ".png":
            raise VfError(f"--screenshot {args.screenshot}: the picture is a PNG file",
                          hint="name it <something>.png")
        check_writable(args.screenshot)
        from vfdsl.view.browser import chromium
        chromium()
    return Options(port=free_port(args.host, args.port), magnify=magnify, size=size, push=push, seconds=seconds)


def free_port(host: str = "127.0.0.1", port: int = 0) -> int:
    """``port`` if a server can listen on it at ``host``, or (``port`` 0) a port it can listen on; found by
    binding it as the server will (SO_REUSEADDR), so a busy port, a port out of range or an address that is
    not this machine's is refused here, before the server starts."""
    if not isinstance(port, int) or not 0 <= port <= PORTS:
        raise VfError(f"--port {port}: a port is a whole number from 0 to {PORTS} (0: any free port)")
    if not host:
        raise VfError("--host: empty", hint="127.0.0.1 (the default) for this machine only, 0.0.0.0 for every "
                                            "network interface")
    try:
        family, kind, proto, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM,
                                                             flags=socket.AI_PASSIVE)[0]
    except (OSError, UnicodeError, ValueError) as err:
        reason = err.strerror if isinstance(err, OSError) and err.strerror else str(err)
        raise VfError(f"--host {host}: not an address ({reason})",
                      hint="an IP address or a host name, e.g. 127.0.0.1 (the default) or 0.0.0.0") from None
    with socket.socket(family, kind, proto) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(address)
        except OSError as err:
            if err.errno == errno.EADDRINUSE:
                raise VfError(f"--port {port}: in use at {host}",
                              hint="choose another port, or leave --port out for a free one") from None
            if err.errno == errno.EADDRNOTAVAIL:
                raise VfError(f"--host {host}: not an address of this machine",
                              hint="127.0.0.1 (the default) for this machine only, 0.0.0.0 for every interface") \
                    from None
            raise VfError(f"cannot listen on {host} port {port}: {err.strerror or err}",
                          hint="ports below 1024 need privileges" if err.errno == errno.EACCES else None) from None
        return s.getsockname()[1]


def picture_size(text: str) -> tuple[int, int]:
    """``WIDTHxHEIGHT`` in pixels, each from 1 to ``limits.PICTURE_SIDE``."""
    match = re.fullmatch(r"\s*(\d{1,9})\s*[xX]\s*(\d{1,9})\s*", text)
    if match is None:
        raise VfError(f"--size {text}: write WIDTHxHEIGHT in pixels, like 1280x800")
    width, height = int(match.group(1)), int(match.group(2))
    if min(width, height) < 1:
        raise VfError(f"--size {text}: a picture is at least 1 pixel wide and high")
    if max(width, height) > limits.PICTURE_SIDE:
        raise limits.exceeded(f"--size {text}: too large a picture", limits.PICTURE_SIDE, None, unit="pixels a side",
                              hint="a smaller size; the page is drawn in software")
    return width, height


def offset(text: str) -> np.ndarray:
    """``--push X,Y,Z``: three finite numbers of millimetres, in metres."""
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3:
        raise VfError(f"--push {text}: three numbers (mm) separated by commas, like 5,0,0")
    if not all(math.isfinite(v) for v in values):
        raise VfError(f"--push {text}: the offset's numbers must be finite")
    return np.array(values) * 1e-3
