#!/usr/bin/python3
"""The display program of `prs3-post sim`: runs one program in LinuxCNC and writes what happened.

LinuxCNC's launcher starts it as the configuration's display (``[DISPLAY] DISPLAY``, with ``-ini
INI PROGRAM`` as arguments) once the motion controller and the task are up, and shuts LinuxCNC down
when it returns. It runs under Debian's ``/usr/bin/python3``, whose ``linuxcnc`` module talks to the
controller, not under prs3-post's environment: the standard library only, and nothing of prs3-post.

What it does, as an operator at a panel would: E-stop reset, machine on, home every joint (the
configuration homes them at the program's first point), set the feed override, move to the
program's first point where homing did not put the joints there (MDI), then open the program and run
it in auto mode, polling the controller every few milliseconds until the interpreter is idle. Every
message of the error channel is kept with its program line. The result (a JSON file, the path in
the settings) has the controller's errors, the joints' final positions, and the times: from cycle
start to the end, and the motion's (from the first sample at which a joint had moved to the last
at which one still moved). With a screenshot asked for, the window of the vismach model (on the X
display LinuxCNC runs under, Xvfb) is saved as a PNG at the end.

The settings come as a JSON file named by the environment variable ``PRS3_SIM_SETTINGS``:
``{"result": PATH, "feed_override": K, "start": "G0 X.. Y..", "start_joints": [..], "timeout_s": S,
"screenshot": PATH|null, "stop": PATH}``. When the ``stop`` file appears (prs3-post stopping the run:
Ctrl-C), or on SIGTERM, the display aborts the program and ends, which lets LinuxCNC's launcher shut
everything down in order.
"""

from __future__ import annotations

import json
import os
import re
import signal
import struct
import sys
import time
import zlib
from typing import Any

#: s, how often the controller's status is read while the program runs, and while waiting for a step.
POLL_S = 0.002
WAIT_POLL_S = 0.01
#: s, how long the steps before the run (machine on, homing, the first point) may take.
SETUP_TIMEOUT_S = 30.0
#: s, how long the error channel is still read after the program ended (late messages).
DRAIN_S = 0.2
#: s, how long the vismach model gets to draw the final pose before the screenshot.
SETTLE_S = 0.5
#: A program line named in a controller message (``Linear move on line 27 would exceed ...``).
LINE_IN_MESSAGE = re.compile(r"\bline (\d+)\b")


class Stopped(Exception):
    """SIGTERM: prs3-post stops the run."""


def _stop(signum: int, frame: Any) -> None:
    raise Stopped


def main(argv: list[str]) -> int:
    import linuxcnc  # Debian's module (linuxcnc-uspace): only under /usr/bin/python3

    with open(os.environ["PRS3_SIM_SETTINGS"], encoding="utf-8") as file:
        settings = json.load(file)
    program = argv[-1]
    result: dict[str, Any] = {"stage": "start", "errors": [], "messages": [], "joints": None, "run_s": None,
                              "motion_s": None, "feed_override": None, "screenshot_error": None,
                              "steps": [["display", time.time()]]}
    signal.signal(signal.SIGTERM, _stop)
    session = _Session(linuxcnc, result)
    try:
        session.run(program, settings)
    except Stopped:
        result["stage"] = "interrupted"
        session.abort()
    except linuxcnc.error as exc:                       # the controller went away
        result["stage"] = f"controller error: {exc}"
    finally:
        _write_json(settings["result"], result)
    return 0


class _Session:
    """One run: the controller's three channels and what was seen on them."""

    def __init__(self, linuxcnc: Any, result: dict[str, Any]):
        self.lc = linuxcnc
        self.stat = linuxcnc.stat()
        self.command = linuxcnc.command()
        self.errors = linuxcnc.error_channel()
        self.result = result
        self.stop_file = ""
        self.kinds = {linuxcnc.NML_ERROR: "error", linuxcnc.OPERATOR_ERROR: "operator error",
                      linuxcnc.NML_TEXT: "text", linuxcnc.OPERATOR_TEXT: "text",
                      linuxcnc.NML_DISPLAY: "display", linuxcnc.OPERATOR_DISPLAY: "display"}

    def run(self, program: str, settings: dict[str, Any]) -> None:
        lc, cmd, stat = self.lc, self.command, self.stat
        self.stop_file = settings.get("stop") or ""
        self._step("machine on")
        cmd.state(lc.STATE_ESTOP_RESET)
        cmd.wait_complete()
        cmd.state(lc.STATE_ON)
        cmd.wait_complete()
        if not self._wait(lambda: stat.task_state == lc.STATE_ON, SETUP_TIMEOUT_S):
            return self._failed("the machine did not come on (E-stop reset, machine on)")
        self._step("homing")
        cmd.home(-1)
        cmd.wait_complete()
        if not self._wait(lambda: all(stat.homed[: stat.joints]), SETUP_TIMEOUT_S):
            return self._failed("the joints did not home")
        cmd.feedrate(float(settings["feed_override"]))
        cmd.rapidrate(1.0)
        cmd.wait_complete()
        stat.poll()
        there = settings.get("start_joints") is not None and all(
            abs(a - b) < 1e-6 for a, b in zip(stat.joint_actual_position[: stat.joints], settings["start_joints"],
                                              strict=True))
        if settings.get("start") and not there:              # (homed there: nothing to move)
            self._step("first point")
            cmd.mode(lc.MODE_MDI)
            cmd.wait_complete()
            cmd.mdi(settings["start"])
            cmd.wait_complete()
            self._wait(lambda: stat.interp_state != lc.INTERP_IDLE, 0.5)
            if not self._wait(lambda: stat.interp_state == lc.INTERP_IDLE and stat.inpos, SETUP_TIMEOUT_S):
                return self._failed(f"the move to the program's first point did not end ({settings['start']})")
            if self.result["errors"]:
                return None
        self._step("run")
        cmd.mode(lc.MODE_AUTO)
        cmd.wait_complete()
        cmd.program_open(program)
        cmd.wait_complete()
        self._collect()
        if self.result["errors"]:
            return None
        stat.poll()
        self.result["feed_override"] = stat.feedrate
        self._run(settings)
        if settings.get("screenshot"):
            self._screenshot(settings["screenshot"])
        return None

    def _run(self, settings: dict[str, Any]) -> None:
        lc, stat = self.lc, self.stat
        timeout = float(settings["timeout_s"])
        start = time.monotonic()
        self.command.auto(lc.AUTO_RUN, 0)
        before = None
        first_moved = last_moved = None
        started = timed_out = False
        paused = 0.0
        pause_started: float | None = None
        while True:
            self._check_stop()
            stat.poll()
            now = time.monotonic()
            self._collect()
            position = tuple(stat.joint_actual_position[: stat.joints])
            if before is not None and position != before:
                first_moved = now if first_moved is None else first_moved
                last_moved = now
            before = position
            if stat.interp_state == lc.INTERP_PAUSED:     # M0 (or M1 with optional stop on): cycle start
                if pause_started is None:
                    pause_started = now
                    self.result["messages"].append({
                        "kind": "text", "text": "program stop after this line's move: resumed (cycle start)",
                        "line": stat.motion_line or stat.current_line or None, "named": False,
                        "stage": self.result["stage"]})
                    self.command.auto(lc.AUTO_RESUME)
            elif pause_started is not None:
                paused += now - pause_started                # the operator's time, not the program's
                pause_started = None
            busy = stat.interp_state != lc.INTERP_IDLE
            started = started or busy
            if (started or now - start > 1.0) and not busy:
                break
            if now - start > timeout:
                timed_out = True
                self.abort()
                break
            time.sleep(POLL_S)
        end = time.monotonic()
        self._step("timeout" if timed_out else "ended")
        drain = end + DRAIN_S
        while time.monotonic() < drain:
            self._collect()
            time.sleep(POLL_S)
        stat.poll()
        if self.result["stage"] == "ended":
            self.result["stage"] = "done"
        self.result["run_s"] = end - start
        self.result["motion_s"] = None
        if first_moved is not None and last_moved is not None:
            self.result["motion_s"] = last_moved - first_moved - paused
        self.result["paused_s"] = paused
        self.result["joints"] = list(stat.joint_actual_position[: stat.joints])
        self.result["feed_override"] = stat.feedrate

    def _step(self, name: str) -> None:
        """The run has come to step ``name`` (kept with the time, for -v)."""
        self.result["stage"] = name
        self.result["steps"].append([name, time.time()])

    def _check_stop(self) -> None:
        """prs3-post asks the run to stop (Ctrl-C) by making the settings' ``stop`` file."""
        if self.stop_file and os.path.exists(self.stop_file):
            raise Stopped

    def _wait(self, done: Any, timeout: float) -> bool:
        """Poll until ``done()`` (True) or ``timeout`` s (False), keeping the error channel's messages."""
        end = time.monotonic() + timeout
        while True:
            self._check_stop()
            self.stat.poll()
            self._collect()
            if done():
                return True
            if time.monotonic() > end:
                return False
            time.sleep(WAIT_POLL_S)

    def _collect(self) -> None:
        """The error channel's messages so far, each with the program line it names (else the line the
        controller was at)."""
        while True:
            message = self.errors.poll()
            if not message:
                return
            kind, text = message
            text = " ".join(str(text).split())
            named = LINE_IN_MESSAGE.search(text)
            line = int(named.group(1)) if named else (self.stat.motion_line or self.stat.current_line or None)
            entry = {"kind": self.kinds.get(kind, str(kind)), "text": text, "line": line,
                     "named": named is not None, "stage": self.result["stage"]}
            self.result["errors" if entry["kind"].endswith("error") else "messages"].append(entry)

    def _failed(self, why: str) -> None:
        self.result["errors"].append({"kind": "setup", "text": why, "line": None, "stage": self.result["stage"]})

    def abort(self) -> None:
        """Stop the program and the machine (the run ends early)."""
        try:
            self.command.abort()
            self.command.wait_complete(1.0)
            self.command.state(self.lc.STATE_ESTOP)
            self.command.wait_complete(1.0)
        except Exception:                                # the controller is going away: nothing to stop
            pass

    def _screenshot(self, path: str) -> None:
        time.sleep(SETTLE_S)
        try:
            width, height, rgb = grab_window()
            _write_png(path, width, height, rgb)
        except Exception as exc:                         # reported, not fatal: the run itself is the result
            self.result["screenshot_error"] = str(exc) or type(exc).__name__


def grab_window() -> tuple[int, int, bytes]:
    """The largest window on the X display ``$DISPLAY`` (the vismach model's): width, height, RGB rows."""
    import ctypes
    import ctypes.util

    name = ctypes.util.find_library("X11")
    if name is None:
        raise RuntimeError("libX11 not found")
    x11 = ctypes.CDLL(name)
    x11.XOpenDisplay.restype = ctypes.c_void_p
    x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x11.XDefaultRootWindow.restype = ctypes.c_ulong
    x11.XDefaultRootWindow.argtypes = [ctypes.c_void_p]
    x11.XQueryTree.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.POINTER(ctypes.c_ulong),
                               ctypes.POINTER(ctypes.c_ulong), ctypes.POINTER(ctypes.POINTER(ctypes.c_ulong)),
                               ctypes.POINTER(ctypes.c_uint)]
    x11.XGetGeometry.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.POINTER(ctypes.c_ulong),
                                 ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_int),
                                 ctypes.POINTER(ctypes.c_uint), ctypes.POINTER(ctypes.c_uint),
                                 ctypes.POINTER(ctypes.c_uint), ctypes.POINTER(ctypes.c_uint)]
    x11.XGetImage.restype = ctypes.c_void_p
    x11.XGetImage.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.c_int, ctypes.c_int, ctypes.c_uint,
                              ctypes.c_uint, ctypes.c_ulong, ctypes.c_int]
    x11.XFree.argtypes = [ctypes.c_void_p]
    x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    display = x11.XOpenDisplay(None)
    if not display:
        raise RuntimeError(f"cannot open the X display {os.environ.get('DISPLAY', '(DISPLAY not set)')}")
    try:
        root = x11.XDefaultRootWindow(display)
        parent, root_back = ctypes.c_ulong(), ctypes.c_ulong()
        children, count = ctypes.POINTER(ctypes.c_ulong)(), ctypes.c_uint()
        x11.XQueryTree(display, root, ctypes.byref(root_back), ctypes.byref(parent), ctypes.byref(children),
                       ctypes.byref(count))
        best = (0, root, 0, 0)
        for index in range(count.value):
            window = children[index]
            x, y = ctypes.c_int(), ctypes.c_int()
            w, h, border, depth = ctypes.c_uint(), ctypes.c_uint(), ctypes.c_uint(), ctypes.c_uint()
            x11.XGetGeometry(display, window, ctypes.byref(root_back), ctypes.byref(x), ctypes.byref(y),
                             ctypes.byref(w), ctypes.byref(h), ctypes.byref(border), ctypes.byref(depth))
            if w.value * h.value > best[0] and w.value > 1 and h.value > 1:
                best = (w.value * h.value, window, w.value, h.value)
        if count.value:
            x11.XFree(children)
        _, window, width, height = best
        if window == root or not width:
            raise RuntimeError("no window on the X display (did the vismach model start?)")
        image = x11.XGetImage(display, window, 0, 0, width, height, 0xFFFFFFFF, 2)   # 2: ZPixmap
        if not image:
            raise RuntimeError("cannot read the window's pixels (is it mapped?)")
        try:
            shape: Any = _ximage().from_address(image)
            if shape.bits_per_pixel != 32 or (shape.red_mask, shape.green_mask, shape.blue_mask) != (
                    0xFF0000, 0xFF00, 0xFF):
                raise RuntimeError(f"a {shape.bits_per_pixel}-bit display: run it on a 24-bit one "
                                   "(Xvfb -screen 0 WxHx24)")
            data = ctypes.string_at(shape.data, shape.bytes_per_line * height)
        finally:
            x11.XFree(image)
        rows = bytearray()
        for top in range(0, height * shape.bytes_per_line, shape.bytes_per_line):   # BGRX pixels to RGB rows
            row = data[top: top + 4 * width]
            rgb = bytearray(3 * width)
            rgb[0::3], rgb[1::3], rgb[2::3] = row[2::4], row[1::4], row[0::4]
            rows += b"\x00" + rgb                 # the PNG row's filter byte: none
        return width, height, bytes(rows)
    finally:
        x11.XCloseDisplay(display)


def _ximage() -> Any:
    import ctypes

    class XImage(ctypes.Structure):
        """The leading fields of Xlib's XImage."""
        _fields_ = [("width", ctypes.c_int), ("height", ctypes.c_int), ("xoffset", ctypes.c_int),
                    ("format", ctypes.c_int), ("data", ctypes.c_void_p), ("byte_order", ctypes.c_int),
                    ("bitmap_unit", ctypes.c_int), ("bitmap_bit_order", ctypes.c_int), ("bitmap_pad", ctypes.c_int),
                    ("depth", ctypes.c_int), ("bytes_per_line", ctypes.c_int), ("bits_per_pixel", ctypes.c_int),
                    ("red_mask", ctypes.c_ulong), ("green_mask", ctypes.c_ulong), ("blue_mask", ctypes.c_ulong)]
    return XImage


def _write_png(path: str, width: int, height: int, rows: bytes) -> None:
    """An RGB PNG of ``rows`` (each a filter byte and ``width`` RGB pixels)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    data = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows, 6)) + chunk(b"IEND", b"")
    temporary = path + ".part"
    with open(temporary, "wb") as file:
        file.write(data)
    os.replace(temporary, path)


def _write_json(path: str, value: dict[str, Any]) -> None:
    temporary = path + ".part"
    with open(temporary, "w", encoding="utf-8") as file:
        json.dump(value, file)
    os.replace(temporary, path)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
