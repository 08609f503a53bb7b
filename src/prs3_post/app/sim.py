"""The `sim` job: a program run in LinuxCNC's own motion controller, headless.

    PROGRAM ──► header (machine, dialect, tools) ──► a LinuxCNC configuration (`linuxcnc-config`'s) in a
    temporary folder ──► linuxcnc -r (milltask + motmod, non-realtime) with our display program ──►
    errors, final joints, run time ──► pass / fail

The configuration homes every joint at the program's first point (the controller starts there, as the
program's cycle time does: not with a long rapid from the stroke zero). The display program
(:mod:`prs3_post.app.sim_display`, run by Debian's python3 and its ``linuxcnc`` module) does what an
operator would: E-stop reset, machine on, home, feed override, (a move to the first point, where
homing could not put it: outside the limits), auto mode, open, run, and read the error channel until
the interpreter is idle. This module prepares the folder, starts LinuxCNC and judges what the display wrote:

- **pass**: the program ran to its end with no controller error, and every joint stopped within
  :data:`POSITION_TOLERANCE_MM` of the words of the program's last motion line;
- **fail** (exit 1): an error of the controller (each with the program line it names) or a joint that
  stopped elsewhere.

The run time is the controller's: the motion's (from when a joint first moved to when the last one
stopped) next to the header's cycle-time estimate. With a feed override K the estimate is worked out
again by the same model (:mod:`prs3_post.post.dynamics`): each G1's inverse-time feed × K, lowered to
the axes' top speeds; rapids at the axes' top speeds (the override does not touch them; LinuxCNC's
rapid override cannot go above 100 %). The motion is real time, so a program takes as long in the
simulation as on the machine, over K where the feeds allow.

LinuxCNC runs one instance per host (its lock ``/tmp/linuxcnc.lock``; a second launch stops the first):
runs of `sim` wait for each other (a lock of their own), and another LinuxCNC that is running is
refused, not stopped. Everything LinuxCNC writes goes to the run's temporary folder (``HOME`` points
there; the launcher's own logs live in ``/tmp`` while it runs and are removed by it); the folder is
removed at the end unless kept. As root, the realtime part (``rtapi_app``) runs as ``nobody``
(``RTAPI_UID``) with its FIFO in a folder of the run that ``nobody`` may write (``RTAPI_FIFO_PATH``).
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import math
import os
import pwd
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from prs3_post.app.linuxcnc_config import ConfigAxis, LinuxcncConfig, write_config
from prs3_post.app.verify import ProgramContext, open_program
from prs3_post.core.errors import FieldError, InputError, MissingDependency, Prs3Error
from prs3_post.core.numbers import fixed
from prs3_post.core.output_files import check_writable, write_atomic
from prs3_post.core.toolpath import EventKind, JointProgram
from prs3_post.emit.header_read import cycle_time
from prs3_post.machine.loading import Dialect
from prs3_post.machine.model import Dynamics, Machine
from prs3_post.post.dynamics import clamp_feeds, joint_columns, joint_deltas, move_times
from prs3_post.readers.tooltable import Tool

__all__ = ["INSTALL_LINUXCNC", "INSTALL_XVFB", "MAX_FEED_OVERRIDE", "POSITION_TOLERANCE_MM", "ControllerMessage",
           "SimError", "SimReport", "estimate_minutes", "simulate"]

#: How to get LinuxCNC (Debian's package: the launcher, milltask, motmod and the Python module).
INSTALL_LINUXCNC = "apt-get install linuxcnc-uspace"
#: How to get the virtual X display a screenshot of the vismach model needs.
INSTALL_XVFB = "apt-get install xvfb"
#: mm, how far a joint may stop from the program's last words (the programs' resolution is 0.0001 mm).
POSITION_TOLERANCE_MM = 0.001
#: The feed override range: more than 0, at most LinuxCNC's configuration's limit (1 = 100 %).
MAX_FEED_OVERRIDE = 100.0
#: The interpreter that runs the display program: Debian's, with the ``linuxcnc`` module.
SYSTEM_PYTHON = "/usr/bin/python3"
#: LinuxCNC's own lock: present while an instance runs (its launcher stops the other one when it starts).
LINUXCNC_LOCK = Path("/tmp/linuxcnc.lock")
#: LinuxCNC's processes (their names in /proc/PID/comm) while an instance runs.
LINUXCNC_PROCESSES = ("linuxcnc", "rtapi_app", "milltask", "linuxcncsvr")
#: The lock runs of `sim` take turns on (in /tmp, where LinuxCNC keeps its own, whatever TMPDIR says).
SIM_LOCK = Path("/tmp/prs3-post-sim.lock")
#: s, how long to wait for another LinuxCNC to end before refusing.
OTHER_WAIT_S = 30.0
#: s, beyond the program's own time limit: LinuxCNC's start (homing, the first point) and shutdown.
LAUNCH_SLACK_S = 120.0
#: s, how long LinuxCNC gets to shut down in order when a run is stopped, before it is made to.
STOP_WAIT_S = 20.0
#: The Xvfb screen a screenshot is taken on.
XVFB_SCREEN = "1024x768x24"
#: The ``dynamics`` header line's number of lines of the launcher's log shown when LinuxCNC fails.
LOG_LINES = 15


class SimError(Prs3Error):
    """LinuxCNC could not run the program at all (it did not start, another instance runs, it ran out
    of time): the message says what happened and what to do. Exit status 1, as a failure."""


@dataclass(frozen=True, slots=True)
class ControllerMessage:
    """A message of the controller's error channel.

    Attributes
    ----------
    kind : str — ``error``, ``operator error`` (failures), ``text``, ``display`` (notes), ``setup``
        (a step before the run failed: the machine did not come on)
    text : str — the controller's words, on one line
    line : int | None — the program line it concerns (the one it names, else the one running)
    """

    kind: str
    text: str
    line: int | None

    @property
    def is_failure(self) -> bool:
        return self.kind in ("error", "operator error", "setup")


@dataclass(frozen=True, slots=True)
class SimReport:
    """What LinuxCNC did with a program.

    Attributes
    ----------
    path : str — the program
    context : ProgramContext — the program read, with its machine and dialect
    config : LinuxcncConfig — the configuration it ran in (its folder gone unless ``kept``)
    stage : str — how the run ended: ``done`` (the program ended), ``timeout``, ``interrupted``, or the
        step before the run that failed (``machine on``, ``homing``, ``first point``)
    messages : tuple of ControllerMessage — errors and notes, in order
    final : (J,) float | None — mm, the joints where they stopped (config order: stage X, Y, strokes)
    expected : (J,) float — mm, the words of the last motion line, in the same order
    last_line : int — that line
    run_s : float | None — s, cycle start to the end (the controller's time, with its tool changes)
    motion_s : float | None — s, the first joint's start to the last one's stop
    feed_override : float — as asked; ``applied``: as the controller reported it
    applied_override : float | None
    header_minutes : float | None — the header's cycle-time estimate (None: not stated); ``header_seconds``:
        the same in seconds as the header writes it
    estimate_s : float | None — s, the same model's estimate at the feed override (None: no [dynamics])
    screenshot : str | None — the PNG written
    screenshot_error : str | None — why it was not
    kept : Path | None — the run's folder, when kept
    steps : tuple of (str, float) — each step of the display program (``display``: it started, ``machine
        on``, ``homing``, ``first point``, ``run``, ``ended``) and when, s after LinuxCNC was launched
    """

    path: str
    context: ProgramContext
    config: LinuxcncConfig
    stage: str
    messages: tuple[ControllerMessage, ...]
    final: np.ndarray | None
    expected: np.ndarray
    last_line: int
    run_s: float | None
    motion_s: float | None
    feed_override: float
    applied_override: float | None
    header_minutes: float | None
    header_seconds: float | None
    estimate_s: float | None
    screenshot: str | None
    screenshot_error: str | None
    kept: Path | None
    steps: tuple[tuple[str, float], ...] = ()

    @property
    def errors(self) -> tuple[ControllerMessage, ...]:
        return tuple(m for m in self.messages if m.is_failure)

    @property
    def deviation(self) -> np.ndarray | None:
        """(J,) mm: |final − expected| (None: no final position)."""
        return None if self.final is None else np.abs(self.final - self.expected)

    @property
    def off_joints(self) -> tuple[int, ...]:
        """The joints that stopped farther than :data:`POSITION_TOLERANCE_MM` from the last words."""
        deviation = self.deviation
        if deviation is None:
            return ()
        return tuple(int(i) for i in np.flatnonzero(~(deviation <= POSITION_TOLERANCE_MM)))

    @property
    def passed(self) -> bool:
        return self.stage == "done" and not self.errors and self.final is not None and not self.off_joints

    @property
    def time_ratio(self) -> float | None:
        """The motion's time over the estimate at the override (None: either is missing)."""
        if self.motion_s is None or not self.estimate_s:
            return None
        return self.motion_s / self.estimate_s


def simulate(path: str, *, machine: str | None = None, feed_override: float = 1.0, screenshot: str | None = None,
             keep: bool = False, progress: Callable[[str], None] | None = None) -> SimReport:
    """Run the program ``path`` in LinuxCNC and report what the controller did.

    Parameters
    ----------
    path : str — a prs3-post program (its header names the machine and dialect)
    machine : str | None — a shipped machine or machine TOML file (None: the header's)
    feed_override : float — the feed override, 1 = 100 % (0 < K ≤ :data:`MAX_FEED_OVERRIDE`)
    screenshot : str | None — a PNG to write of the vismach model at the end (needs xvfb-run)
    keep : bool — keep the run's folder (configuration, LinuxCNC's log, the display's result)
    progress : callable, optional — told each step (``starting LinuxCNC``)

    Raises
    ------
    InputError
        The program (unreadable, not a prs3-post program, a header that contradicts ``machine``), a
        screenshot that cannot be written.
    FieldError
        A feed override out of range.
    MissingDependency
        LinuxCNC (or, for a screenshot, xvfb-run) is not installed: the message says how to install it.
    SimError
        LinuxCNC did not start, or ran past the time the program can take; another LinuxCNC runs.
    """
    tell = progress or (lambda _text: None)
    if not (math.isfinite(feed_override) and 0.0 < feed_override <= MAX_FEED_OVERRIDE):
        raise FieldError(f"expected more than 0 and at most {MAX_FEED_OVERRIDE:g} (1 = 100 %), got {feed_override:g}",
                         field="feed_override")
    context = open_program(path, machine=machine)
    moves = context.program.moves
    if len(moves) == 0:
        raise InputError("no motion line: nothing to run", path=path)
    launcher = linuxcnc_launcher()
    xvfb = None
    if screenshot is not None:
        check_writable(screenshot)
        xvfb = shutil.which("xvfb-run")
        if xvfb is None:
            raise MissingDependency(f"--screenshot needs a virtual X display (xvfb-run), which is not installed: "
                                    f"{INSTALL_XVFB}")
    stated = _header_cycle_time(context)
    dynamics = context.machine.dynamics
    estimate = None if dynamics is None else estimate_minutes(dynamics, moves, feed_override) * 60.0
    isolated = can_isolate()
    with _sim_lock(tell), _run_folder(keep) as folder:
        inside = ISOLATED_ROOT if isolated else folder        # the run folder as LinuxCNC sees it
        if not isolated and os.geteuid() == 0:
            _check_reachable(folder)
        first = config_joints(context.machine, moves, 0)
        config = _configure(context, folder, inside, feed_override, vismach=screenshot is not None,
                            home=tuple(first.tolist()))
        program = folder / "program" / (Path(path).name if path != "-" else "stdin.ngc")
        program.parent.mkdir()
        program.write_text("\n".join(context.program.lines) + "\n", encoding="utf-8")   # as read (and checked)
        time_limit = _time_limit(estimate, moves)
        settings = {
            "result": str(inside / "result.json"),
            "feed_override": feed_override,
            "start": _start_move(config.axes, first),
            "start_joints": first.tolist(),
            "timeout_s": time_limit,
            "screenshot": None if screenshot is None else str(inside / "screenshot.png"),
            "stop": str(inside / "stop"),
        }
        (folder / "settings.json").write_text(json.dumps(settings), encoding="utf-8")
        if not isolated:
            _wait_for_other_linuxcnc(tell)
        tell("starting LinuxCNC" + (" (in a namespace of its own)" if isolated else ""))
        launched = time.time()
        _launch(launcher, xvfb, config, folder, inside, isolated, program.relative_to(folder),
                time_limit + LAUNCH_SLACK_S)
        result = _result(folder)
        shot_error = result.get("screenshot_error")
        written = None
        if screenshot is not None and shot_error is None:
            shot = folder / "screenshot.png"
            if shot.exists():
                write_atomic(screenshot, shot.read_bytes())
                written = screenshot
            else:
                shot_error = "the run ended before the model was drawn"
        report = SimReport(
            path=path, context=context, config=config, stage=str(result.get("stage")),
            messages=_messages(result, moves), final=_final(result, len(config.axes)),
            expected=config_joints(context.machine, moves, -1), last_line=int(moves.source[-1]),
            run_s=result.get("run_s"), motion_s=result.get("motion_s"), feed_override=feed_override,
            applied_override=result.get("feed_override"), header_minutes=None if stated is None else stated[0],
            header_seconds=None if stated is None else stated[1], estimate_s=estimate,
            screenshot=written, screenshot_error=shot_error, kept=folder if keep else None,
            steps=tuple((str(name), float(when) - launched) for name, when in result.get("steps", ())),
        )
    return report


def linuxcnc_launcher() -> str:
    """The ``linuxcnc`` launcher, once the display program's interpreter has LinuxCNC's module.

    Raises
    ------
    MissingDependency
        ``sim needs LinuxCNC ...: apt-get install linuxcnc-uspace``.
    """
    launcher = shutil.which("linuxcnc")
    missing = None
    if launcher is None:
        missing = "the linuxcnc launcher is not on PATH"
    elif not Path(SYSTEM_PYTHON).exists():
        missing = f"{SYSTEM_PYTHON} is missing"
    else:
        probe = subprocess.run([SYSTEM_PYTHON, "-c", "import linuxcnc"], capture_output=True, check=False,
                               env=_system_env({}))
        if probe.returncode != 0:
            missing = f"{SYSTEM_PYTHON} has no linuxcnc module"
    if missing is not None:
        raise MissingDependency(f"sim runs the program in LinuxCNC, which is not installed ({missing}): "
                                f"{INSTALL_LINUXCNC}")
    assert launcher is not None
    return launcher


def estimate_minutes(dynamics: Dynamics, moves: JointProgram, feed_override: float = 1.0) -> float:
    """min: the cycle time of a program's moves and dwells at a feed override, by the header's model
    (:func:`prs3_post.post.dynamics.move_times`): each G1's inverse-time feed × ``feed_override``,
    lowered to the axes' top speeds; rapids at the axes' top speeds. At 1 it is the header's estimate."""
    joints = joint_columns(moves.stage, moves.strokes)
    deltas = joint_deltas(joints)
    inverse_time = np.asarray(moves.inverse_time, dtype=np.float64) * feed_override
    feeds = clamp_feeds(dynamics, moves.kind, deltas, inverse_time).inverse_time
    dwell = sum(e.value for e in moves.events if e.kind is EventKind.DWELL) / 60.0
    return float(move_times(dynamics, moves.kind, deltas, feeds).sum()) + dwell


def _header_cycle_time(context: ProgramContext) -> tuple[float, float] | None:
    """The header's cycle-time estimate, (min, s) (None: no ``dynamics`` entry or the machine had none)."""
    header = context.header
    line = None if header is None else header.line("dynamics")
    if line is None:
        return None
    return cycle_time(context.program.lines[line - 1])


def _time_limit(estimate_s: float | None, moves: JointProgram) -> float:
    """s, how long the program may run before it is stopped: three times the estimate and a minute
    (a program without an estimate: a day, at a G0 a second and a G1's own time, whichever is less)."""
    if estimate_s is not None:
        return 3.0 * estimate_s + 60.0
    feed_minutes = np.where(np.asarray(moves.inverse_time) > 0, 1.0 / np.maximum(moves.inverse_time, 1e-12), 0.0)
    return min(86400.0, float(feed_minutes.sum()) * 60.0 + len(moves) + 60.0)


def config_joints(machine: Machine, moves: JointProgram, row: int) -> np.ndarray:
    """(J,) mm: a program row's joints in the configuration's order (stage X, Y where the machine has a
    stage, then the head's joints)."""
    if machine.stage.present:
        return joint_columns(moves.stage[row], moves.strokes[row])[0]
    return np.asarray(moves.strokes[row], dtype=np.float64).copy()


def _start_move(axes: tuple[ConfigAxis, ...], joints: np.ndarray) -> str:
    """The MDI move to the program's first point (``G90 G0 X1.708000 Y12.070300 U27.280300 ...``)."""
    return "G90 G0 " + " ".join(f"{axis.letter}{value:.6f}" for axis, value in zip(axes, joints, strict=True))


def _configure(context: ProgramContext, folder: Path, inside: Path, feed_override: float, *,
               vismach: bool, home: tuple[float, ...]) -> LinuxcncConfig:
    """The configuration in ``folder/config``, with the display program (``inside``: the run folder as
    LinuxCNC sees it), the program's tools, and the joints homing at ``home`` (the program's first point:
    the controller starts there, as the program's cycle time does)."""
    display = folder / "display.py"
    source = Path(__file__).with_name("sim_display.py")
    display.write_text(source.read_text(encoding="utf-8"), encoding="utf-8")
    display.chmod(0o755)
    if any(ch.isspace() for ch in str(inside)):
        raise SimError(f"the temporary folder {folder} has a space in its name, which LinuxCNC's launcher cannot "
                       "take in [DISPLAY] DISPLAY: set TMPDIR to a folder without one")
    tools = _tool_table(context, folder)
    try:
        return _write(context, folder, inside, feed_override, vismach=vismach, home=home, tools=tools)
    except NotImplementedError as exc:                 # a kinematics without a vismach model
        raise MissingDependency(f"--screenshot needs a vismach model of machine {context.machine.name}, which "
                                f"linuxcnc-config cannot write ({exc}): run without --screenshot") from exc


def _write(context: ProgramContext, folder: Path, inside: Path, feed_override: float, *, vismach: bool,
           home: tuple[float, ...], tools: str | None) -> LinuxcncConfig:
    return write_config(_reference(context.machine), str(folder / "config"), tool_table=tools,
                        dialect=_reference(context.dialect), display=str(inside / "display.py"), vismach=vismach,
                        max_feed_override=max(1.0, feed_override), home=home)


def _reference(loaded: Machine | Dialect) -> str:
    """How to load a machine or dialect again: its file (a given one), else its shipped name."""
    return loaded.source if Path(loaded.source).is_file() else loaded.name


def _tool_table(context: ProgramContext, folder: Path) -> str | None:
    """A tool table with every tool the program changes to (the header's diameters and lengths where it
    states them); None: the program changes no tool other than T1 and states none."""
    from prs3_post.app.linuxcnc_config import tool_table_text

    numbers = sorted({int(e.value) for e in context.program.moves.events if e.kind is EventKind.TOOL_CHANGE})
    recorded = {t.number: t for t in getattr(context.header, "tools", ()) or ()}
    numbers = sorted(set(numbers) | set(recorded))
    if not numbers or (numbers == [1] and not recorded):
        return None
    geometry = context.machine.geometry
    default_length = geometry.tool_length - geometry.gauge_offset
    tools = []
    for number in numbers:
        record = recorded.get(number)
        diameter = record.diameter if record is not None else 6.0
        length = default_length
        if record is not None:
            length = record.length if record.length is not None else record.ik_length - geometry.gauge_offset
        tools.append(Tool(number=number, pocket=number, diameter=diameter, length=length,
                          comment="from the program" if record is None else "the program header's", line=0))
    path = folder / "tools.tbl"
    path.write_text(tool_table_text(tuple(tools)), encoding="utf-8")
    return str(path)


@contextlib.contextmanager
def _run_folder(keep: bool) -> Iterator[Path]:
    """A new temporary folder for the run: HOME, the realtime FIFO, the configuration; removed at the
    end unless ``keep``."""
    folder = Path(tempfile.mkdtemp(prefix="prs3-post-sim-")).resolve()
    try:
        folder.chmod(0o711)                          # rtapi_app (as nobody) reaches its FIFO folder through it
        (folder / "home").mkdir()
        fifo = folder / "fifo"
        fifo.mkdir(mode=0o700)
        if os.geteuid() == 0:
            os.chown(fifo, _unprivileged_uid(), -1)
        yield folder
    finally:
        if not keep:
            shutil.rmtree(folder, ignore_errors=True)


def _check_reachable(folder: Path) -> None:
    """The realtime part, run as an unprivileged user, makes its FIFO in the run's folder: every folder on
    the way there must let others through.

    Raises
    ------
    SimError
        ``the temporary folder /root/tmp/... cannot be entered by nobody ...: set TMPDIR ...``
    """
    for parent in folder.parents:
        if not parent.stat().st_mode & 0o001:
            raise SimError(f"the temporary folder {folder} cannot be entered by the user LinuxCNC's realtime part "
                           f"runs as (uid {_unprivileged_uid()}): {parent} is closed to others; set TMPDIR to a "
                           "folder everyone may enter, like /tmp")


def _unprivileged_uid() -> int:
    """The uid rtapi_app runs as when prs3-post runs as root: the invoking user's under sudo, else nobody's."""
    sudo = os.environ.get("SUDO_UID", "")
    if sudo.isdigit() and int(sudo) != 0:
        return int(sudo)
    try:
        return pwd.getpwnam("nobody").pw_uid
    except KeyError:
        return 65534


@contextlib.contextmanager
def _sim_lock(tell: Callable[[str], None]) -> Iterator[None]:
    """One `sim` at a time on the host (LinuxCNC runs one instance, and runs side by side would slow each
    other's clocks): :data:`SIM_LOCK`, held while LinuxCNC runs."""
    try:                                             # read-only: a lock file another user made is theirs
        handle = os.open(SIM_LOCK, os.O_RDONLY | os.O_CREAT, 0o666)
    except OSError as exc:
        raise SimError(f"cannot open the lock that runs of sim take turns on, {SIM_LOCK}: {exc.strerror}") from exc
    try:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            tell("waiting for another prs3-post sim to finish")
            fcntl.flock(handle, fcntl.LOCK_EX)
        yield
    finally:
        os.close(handle)                             # (closing releases the lock)


def linuxcnc_processes() -> list[tuple[int, str]]:
    """LinuxCNC's processes that are running on the host (pid, name), zombies left out."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            name = (entry / "comm").read_text(encoding="utf-8").strip()
            if name not in LINUXCNC_PROCESSES:
                continue
            state = (entry / "stat").read_text(encoding="utf-8").rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            continue
        if state != "Z":
            found.append((int(entry.name), name))
    return sorted(found)


def _wait_for_other_linuxcnc(tell: Callable[[str], None]) -> None:
    """Wait (up to :data:`OTHER_WAIT_S`) while another LinuxCNC runs on the host; then refuse to start
    (its launcher would stop that one)."""
    deadline = time.monotonic() + OTHER_WAIT_S
    told = False
    while True:
        running = linuxcnc_processes()
        if not running:
            return
        if time.monotonic() > deadline:
            shown = ", ".join(f"{name} (pid {pid})" for pid, name in running)
            raise SimError(f"another LinuxCNC is running on this host ({shown}; lock {LINUXCNC_LOCK}): LinuxCNC runs "
                           "one instance per host and starting one stops the other: close it, then run sim again")
        if not told:
            tell("waiting for another LinuxCNC on this host to end")
            told = True
        time.sleep(0.5)


def _system_env(extra: dict[str, str]) -> dict[str, str]:
    """The environment of LinuxCNC's programs: ours without this Python environment's (its bin folder on
    PATH, VIRTUAL_ENV, PYTHONPATH, PYTHONHOME: LinuxCNC's Python programs are Debian's), plus ``extra``."""
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH", "PYTHONHOME", "DISPLAY")}
    ours = {str(Path(sys.prefix) / "bin"), str(Path(sys.executable).parent)}
    if sys.prefix != sys.base_prefix:
        env["PATH"] = os.pathsep.join(p for p in env.get("PATH", os.defpath).split(os.pathsep) if p not in ours)
    env.update(extra)
    return env


def can_isolate() -> bool:
    """Whether LinuxCNC can run in mount and IPC namespaces of its own (root, or the capability to make
    them): its lock, its temporary files and its shared memory are then the run's, and other LinuxCNC
    instances on the host neither stop it nor are stopped by it."""
    unshare = shutil.which("unshare")
    if unshare is None or os.geteuid() != 0:
        return False
    probe = subprocess.run([unshare, *NAMESPACES, "true"], capture_output=True, check=False)
    return probe.returncode == 0


#: unshare's options: LinuxCNC's own mounts (the run folder over /tmp), shared memory and processes (its
#: launcher stops the processes of its names that it sees, and waits for every rtapi_app to end); all of
#: them end with the namespace.
NAMESPACES = ("--mount", "--ipc", "--pid", "--fork", "--mount-proc", "--kill-child")
#: Where the run folder is mounted in LinuxCNC's own mount namespace: over /tmp, where the launcher
#: keeps its lock and logs.
ISOLATED_ROOT = Path("/tmp")


def _launch(launcher: str, xvfb: str | None, config: LinuxcncConfig, folder: Path, inside: Path, isolated: bool,
            program: Path, time_limit: float) -> None:
    """Run ``linuxcnc -r INI PROGRAM`` (under xvfb-run for a screenshot; with ``isolated``, in namespaces
    of its own with the run folder as /tmp) until it ends; stop it in order on Ctrl-C or past
    ``time_limit`` s. ``program`` and the INI are given relative to the run folder."""
    extra = {"HOME": str(inside / "home"), "RTAPI_FIFO_PATH": str(inside / "fifo" / "rtapi_fifo"),
             "PRS3_SIM_SETTINGS": str(inside / "settings.json"), "TMPDIR": str(inside),
             "PRS3_SIM_RUN": str(folder)}                # marks LinuxCNC's processes as this run's
    if os.geteuid() == 0:
        extra["RTAPI_UID"] = str(_unprivileged_uid())
    ini = inside / config.ini.relative_to(folder)
    command = [launcher, "-r", str(ini), str(inside / program)]
    if xvfb is not None:                             # a server number of its own (-a tries the next ones)
        command = [xvfb, "-a", "-n", str(200 + os.getpid() % 700), "-s", f"-screen 0 {XVFB_SCREEN}", *command]
    if isolated:                                     # sh stays the namespace's init: xvfb-run as init hangs
        command = ["unshare", *NAMESPACES, "--", "/bin/sh", "-c", 'mount --bind "$0" /tmp && cd /tmp && "$@"',
                   str(folder), *command]
    log = folder / "linuxcnc.log"
    with open(log, "wb") as out, _terminate_as_interrupt():
        process = subprocess.Popen(command, cwd=folder, env=_system_env(extra), stdin=subprocess.DEVNULL,
                                   stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            process.wait(timeout=time_limit)
        except subprocess.TimeoutExpired:
            _stop(process, folder)
            raise SimError(f"LinuxCNC did not end within {time_limit:.0f} s: stopped ({_log_tail(log)})") from None
        except BaseException:                        # Ctrl-C, SIGTERM: LinuxCNC shuts down in order before we go
            _stop(process, folder)
            raise


class Terminated(KeyboardInterrupt):
    """SIGTERM while LinuxCNC runs: handled as Ctrl-C is (LinuxCNC is shut down first)."""


def _raise_terminated(signum: int, frame: object) -> None:
    raise Terminated


@contextlib.contextmanager
def _terminate_as_interrupt() -> Iterator[None]:
    """While LinuxCNC runs, SIGTERM stops the run as Ctrl-C does (in the main thread, where signals land)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _stop(process: subprocess.Popen[bytes], folder: Path) -> None:
    """Shut LinuxCNC down: the display first (told by a file: it aborts the program, and the launcher then
    stops the rest in order), and only if that takes too long by signals to the launcher's process group
    (unshare's, in a namespace: the namespace ends with it)."""
    with contextlib.suppress(OSError):
        (folder / "stop").touch()
    for sig in (None, signal.SIGTERM, signal.SIGKILL):
        if sig is not None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(process.pid, sig)
        try:
            process.wait(timeout=STOP_WAIT_S)
            return
        except subprocess.TimeoutExpired:
            continue


def _log_tail(log: Path) -> str:
    """The last lines of LinuxCNC's output, for a message."""
    try:
        lines = log.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return "no output"
    lines = [line for line in lines if line.strip() and "fallback_uid" not in line]
    return "; ".join(lines[-LOG_LINES:]) or "no output"


def _result(folder: Path) -> dict[str, Any]:
    """What the display wrote; a LinuxCNC that never ran it is a :class:`SimError` with its output."""
    path = folder / "result.json"
    try:
        result = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        raise SimError(f"LinuxCNC did not run the program: {_log_tail(folder / 'linuxcnc.log')}") from None
    if not isinstance(result, dict):
        raise SimError(f"LinuxCNC's display wrote no result: {_log_tail(folder / 'linuxcnc.log')}")
    return result


def _messages(result: dict[str, Any], moves: JointProgram) -> tuple[ControllerMessage, ...]:
    """The error channel's messages, each with its program line: the line it names; else, for an error
    that follows one naming a line (``invalid params in linear command`` after ``Linear move on line 27
    would exceed ...``), that line; else the line the controller was at. An error of the move to the
    first point is the first motion line's."""
    out = []
    named: int | None = None
    for entry in result.get("errors", ()):
        line = entry.get("line") if isinstance(entry.get("line"), int) and entry.get("line") > 0 else None
        if entry.get("named"):
            named = line
        elif named is not None:
            line = named
        if entry.get("stage") == "first point" and line is None:
            line = int(moves.source[0])
        out.append(ControllerMessage(kind=str(entry.get("kind")), text=str(entry.get("text")), line=line))
    for entry in result.get("messages", ()):
        line = entry.get("line") if isinstance(entry.get("line"), int) and entry.get("line") > 0 else None
        out.append(ControllerMessage(kind=str(entry.get("kind")), text=str(entry.get("text")), line=line))
    return tuple(out)


def _final(result: dict[str, Any], joints: int) -> np.ndarray | None:
    values = result.get("joints")
    if not isinstance(values, list) or len(values) < joints:
        return None
    return np.asarray(values[:joints], dtype=np.float64)


#: The message of a controller that names a line: ``line 27`` (the report words it once).
_LINE_WORDS = re.compile(r"\s*\b(?:on|near|at) line \d+\b")


def message_text(message: ControllerMessage) -> str:
    """The controller's words, without the line it names (the report puts the line first)."""
    return _LINE_WORDS.sub("", message.text) if message.line is not None else message.text


def seconds(value: float) -> str:
    """``1.18 s``."""
    return f"{fixed(value, 2)} s"


def report_lines(report: SimReport) -> list[str]:
    """The report `sim` prints: what the controller said, where the joints stopped, the times, and the
    verdict (``OK: ...`` or ``FAIL: ...``) last."""
    name = "standard input" if report.path == "-" else Path(report.path).name
    axes = report.config.axes
    k = report.feed_override
    out = [f"{name} in LinuxCNC (machine {report.context.machine.name}, feed override {k:g} = {k * 100:.0f} %)"]
    lines = report.context.program.lines
    for message in report.messages:
        where = f"line {message.line}: " if message.line is not None else ""
        label = "controller" if message.is_failure else "controller note"
        out.append(f"  {label}: {where}{message_text(message)}")
    shown = sorted({m.line for m in report.errors if m.line is not None and 0 < m.line <= len(lines)})
    out += [f"    line {line}: {lines[line - 1].strip()}" for line in shown]
    if report.final is not None:
        words = " ".join(f"{a.letter} {fixed(v, 4)}" for a, v in zip(axes, report.final, strict=True))
        deviation = report.deviation
        assert deviation is not None
        worst = int(np.argmax(deviation))
        if report.errors or report.stage != "done":
            out.append(f"  stopped at: {words} mm")
        else:
            out.append(f"  final joints: {words} mm")
            if report.off_joints:
                off = ", ".join(f"{axes[i].letter} by {fixed(deviation[i], 4)} mm" for i in report.off_joints)
                out.append(f"    line {report.last_line} (the last motion line) says otherwise: {off}")
            else:
                out.append(f"    = line {report.last_line}'s words (the last motion line) within "
                           f"{POSITION_TOLERANCE_MM:g} mm: largest difference {fixed(deviation[worst], 4)} mm "
                           f"({axes[worst].letter})")
    finished = report.stage == "done" and not report.errors
    if report.motion_s is not None and finished:
        total = "" if report.run_s is None else f", {seconds(report.run_s)} from cycle start to the end"
        out.append(f"  run time: {fixed(report.motion_s, 3)} s of motion{total}")
    if report.estimate_s is not None and finished:
        header = ("no estimate in the header" if report.header_seconds is None else
                  f"the header's {fixed(report.header_seconds, 1)} s at 100 %")
        how = "" if k == 1 else f"; each feed × {k:g} up to the axes' top speeds, rapids at their top speeds"
        ratio = report.time_ratio
        versus = "" if ratio is None else f": the motion took {(ratio - 1) * 100:+.1f} %"
        out.append(f"  estimate: {fixed(report.estimate_s, 3)} s at feed override {k:g} ({header}{how}){versus}")
    if report.screenshot is not None:
        out.append(f"  screenshot: {report.screenshot} (the vismach model at the end)")
    elif report.screenshot_error is not None:
        out.append(f"  screenshot: not taken: {report.screenshot_error}")
    if report.kept is not None:
        out.append(f"  run folder kept: {report.kept} (configuration, linuxcnc.log, result.json)")
    out.append(verdict(report))
    return out


def steps_text(report: SimReport) -> str:
    """``LinuxCNC's steps: display 0.72 s, machine on 0.72 s, ...`` (s after the launch), for -v."""
    return "LinuxCNC's steps (s after its launch): " + ", ".join(
        f"{name} {fixed(when, 2)}" for name, when in report.steps)


def verdict(report: SimReport) -> str:
    """``OK: ...`` or ``FAIL: ...``: the last line of the report."""
    if report.passed:
        return "OK: ran to its end with no controller error, every joint at the last line's position"
    errors = report.errors
    if errors:
        first = next((m.line for m in errors if m.line is not None), None)
        at = f" at line {first}" if first is not None else ""
        count = f"{len(errors)} error" + ("s" if len(errors) > 1 else "")
        return f"FAIL: the controller stopped the program{at} ({count}: {message_text(errors[0])})"
    if report.stage == "timeout":
        return "FAIL: the program did not end in the time allowed (three times the estimate and a minute): stopped"
    if report.stage != "done":
        return f"FAIL: the run ended early ({report.stage})"
    if report.final is None:
        return "FAIL: the controller reported no final position"
    return (f"FAIL: the joints stopped away from line {report.last_line}'s words: "
            + ", ".join(report.config.axes[i].letter for i in report.off_joints))
