"""The `linuxcnc-config` job: a LinuxCNC simulation configuration for a machine.

    machine TOML (+ tool table, dialect) ──► INI + HAL + tool table (+ the vismach model) ──► a folder

What LinuxCNC gets, so that our programs run in its own interpreter and motion controller as they
would on the machine:

- One joint per program axis, with trivial kinematics (``trivkins``): stage X and Y (on a machine
  with a stage) and the head's joints (T1, T2, T3), each under the letter the dialect writes it with
  (the default dialect: X Y U V W). The controller interpolates straight in joint space, which is
  what the programs mean (DESIGN.md, "Output").
- Each joint's and axis's limits are the machine file's (``[limits] stroke_mm``, ``[stage]
  travel_x_mm``/``travel_y_mm``); speeds and accelerations its ``[dynamics]`` (in mm/s and mm/s²),
  else :data:`~prs3_post.core.defaults.NOMINAL_RAPID_RATE` and
  :data:`~prs3_post.core.defaults.NOMINAL_ACCEL` (the INI says so).
- Homing needs no switches: every joint homes at once (``HOME_SEQUENCE = 0``, no search) to its home,
  the stroke and stage zero (moved inside the limits where 0 is outside them).
- Simulated drives (the HAL file): each joint's commanded position is its feedback, the E-stop and
  the tool changer answer at once, as LinuxCNC's own sim configurations do.
- The tool table: ``--tool-table``'s tools, else the machine's tool (``tool_length_mm −
  gauge_offset_mm`` long) as T1. LinuxCNC never applies the lengths (there is no Z axis and the
  programs are posted with them): they are there for ``T… M6`` and for the vismach model.
- The vismach model (:mod:`prs3_post.app.linuxcnc_vismach`): the machine drawn at the joints' positions.

Nothing here runs LinuxCNC; the files are text, written whole or not at all.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from pathlib import Path

from prs3_post.app.linuxcnc_vismach import (
    VISMACH_HAL,
    VISMACH_SCRIPT,
    check_drawable,
    one_line,
    vismach_hal,
    vismach_script,
)
from prs3_post.app.requests import DEFAULT_TOOL_DIAMETER
from prs3_post.core.defaults import NOMINAL_ACCEL, NOMINAL_RAPID_RATE
from prs3_post.core.errors import ConfigError, FieldError
from prs3_post.core.numbers import exact_text, fixed
from prs3_post.core.output_folders import FolderFile, write_folder
from prs3_post.core.version import __version__
from prs3_post.kinematics.protocol import joint_letters
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.loading import DEFAULT_DIALECT, load_dialect, load_machine, resolve
from prs3_post.machine.model import Machine
from prs3_post.readers.tooltable import Tool, ToolTable, read_tool_table

__all__ = ["DEFAULT_DISPLAY", "DEFAULT_MAX_FEED_OVERRIDE", "PARAMETER_FILE", "TOOL_TABLE", "ConfigAxis",
           "LinuxcncConfig", "config_axes", "config_files", "homed_at", "tool_table_text", "write_config"]

#: The display program LinuxCNC starts (``[DISPLAY] DISPLAY``) unless another is given.
DEFAULT_DISPLAY = "axis"
#: The largest feed override the display offers (``[DISPLAY] MAX_FEED_OVERRIDE``, 1 = 100 %).
DEFAULT_MAX_FEED_OVERRIDE = 2.0
#: The largest feed override that may be asked for (LinuxCNC's own limit is far above; more is a typo).
MAX_FEED_OVERRIDE_LIMIT = 100.0
#: The files' names in the folder (the INI and HAL files are named after the machine).
TOOL_TABLE = "tool.tbl"
PARAMETER_FILE = "prs3.var"
#: Letters LinuxCNC treats as rotary axes (degrees): a stroke or a stage travel cannot be one.
ROTARY_LETTERS = "ABC"
#: The order LinuxCNC lists its axes in.
AXIS_ORDER = "XYZABCUVW"
#: ns, the motion controller's servo period (1 kHz, as LinuxCNC's sim configurations).
SERVO_PERIOD_NS = 1_000_000


@dataclass(frozen=True, slots=True)
class ConfigAxis:
    """One joint of the configuration, and the axis of the same letter (trivial kinematics).

    Attributes
    ----------
    letter : str — the axis letter (``U``)
    name : str — what moves, for comments (``stroke T1``, ``stage X``)
    low, high : float — mm, the limits (the machine file's)
    home : float — mm, where it homes (inside the limits)
    velocity : float — mm/s, its top speed
    acceleration : float — mm/s², its acceleration
    pin : str — the vismach model's input pin of its position (``stage-x``, ``t1``)
    """

    letter: str
    name: str
    low: float
    high: float
    home: float
    velocity: float
    acceleration: float
    pin: str = ""


@dataclass(frozen=True, slots=True)
class LinuxcncConfig:
    """A configuration written by :func:`write_config`.

    Attributes
    ----------
    folder : Path — the folder (symbolic links resolved)
    ini : Path — its INI file: ``linuxcnc -r INI`` (or ``linuxcnc INI``) starts it
    files : tuple of str — the names of the files in it
    machine : Machine
    axes : tuple of ConfigAxis — joint 0, 1, … in order
    tools : tuple of Tool — the tool table's tools
    """

    folder: Path
    ini: Path
    files: tuple[str, ...]
    machine: Machine
    axes: tuple[ConfigAxis, ...]
    tools: tuple[Tool, ...]


def write_config(machine: str, folder: str, *, tool_table: str | None = None, dialect: str | None = None,
                 display: str | None = None, vismach: bool = True,
                 max_feed_override: float = DEFAULT_MAX_FEED_OVERRIDE, force: bool = False,
                 home: tuple[float, ...] | None = None) -> LinuxcncConfig:
    """Write a LinuxCNC simulation configuration for ``machine`` into the folder ``folder``.

    Parameters
    ----------
    machine : str — a shipped machine's name or a machine TOML file
    folder : str — a new or empty folder (an existing one with files in it only with ``force``)
    tool_table : str | None — a LinuxCNC tool table file (None: the machine's tool as T1)
    dialect : str | None — the dialect the programs are written in, for the axis letters (None: linuxcnc)
    display : str | None — ``[DISPLAY] DISPLAY``: the display program and its arguments (None: ``axis``)
    vismach : bool — load the vismach model of the machine (a window: it needs an X display)
    max_feed_override : float — the largest feed override the display offers (1 = 100 %)
    force : bool — replace an existing folder that has files in it
    home : tuple of float | None — mm, where each joint homes, in the configuration's order (each moved
        inside its limits; None: the stroke and stage zero): `sim` homes at a program's first point

    Raises
    ------
    ConfigError
        The machine or dialect file, or a dialect whose letters LinuxCNC cannot take; with ``vismach``, a
        kinematics the model cannot draw (:class:`~prs3_post.app.linuxcnc_vismach.NoVismachModel`, also a
        NotImplementedError).
    InputError
        The tool table; the folder (not a folder, not empty, holds an input, cannot be written).
    FieldError
        ``display`` empty or more than one line, ``max_feed_override`` out of range.
    """
    loaded = load_machine(machine)
    machine_path = resolve("machines", machine)
    try:
        machine_text = machine_path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:       # it loaded a moment ago: changed since
        raise ConfigError(f"cannot read the file again: {exc}", path=loaded.source) from exc
    table = None if tool_table is None else read_tool_table(tool_table)
    files = config_files(loaded, machine_text, tool_table=table, dialect=dialect, display=display,
                         vismach=vismach, max_feed_override=max_feed_override, home=home)
    inputs = [str(machine_path)] + ([tool_table] if tool_table is not None else [])
    written = write_folder(folder, files, replace=force, inputs=inputs)
    return LinuxcncConfig(folder=written, ini=written / ini_name(loaded), files=tuple(files), machine=loaded,
                          axes=homed_at(config_axes(loaded, dialect), home), tools=_tools(loaded, table))


def ini_name(machine: Machine) -> str:
    """The INI file's name: the machine's (``patel2020.ini``)."""
    return f"{file_stem(machine)}.ini"


def file_stem(machine: Machine) -> str:
    """The machine's name as the configuration's file names use it: letters, digits, ``. _ -`` only (LinuxCNC's
    launcher and HAL files split names at blanks)."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", machine.name) or "machine"


def config_axes(machine: Machine, dialect: str | None = None) -> tuple[ConfigAxis, ...]:
    """The configuration's joints in order: stage X, Y (on a machine with a stage), then the head's joints.

    Raises
    ------
    ConfigError
        The dialect writes a joint with a rotary letter (A, B, C).
    """
    loaded = load_dialect(dialect or DEFAULT_DIALECT)
    kinematics = kinematics_of(machine)
    letters = joint_letters(kinematics.joint_names, kinematics.default_letters, loaded.axes)
    dynamics = machine.dynamics
    stroke_speed = (dynamics.stroke_speed if dynamics else NOMINAL_RAPID_RATE) / 60.0
    stroke_accel = dynamics.stroke_accel if dynamics else NOMINAL_ACCEL
    stage_speed = (dynamics.stage_speed if dynamics else NOMINAL_RAPID_RATE) / 60.0
    stage_accel = dynamics.stage_accel if dynamics else NOMINAL_ACCEL
    axes: list[ConfigAxis] = []
    if machine.stage.present:
        for letter, name, (low, high) in ((loaded.axes.x, "stage X", machine.stage.travel_x),
                                          (loaded.axes.y, "stage Y", machine.stage.travel_y)):
            axes.append(ConfigAxis(letter, name, low, high, _home(low, high), stage_speed, stage_accel,
                                   pin=name.lower().replace(" ", "-")))
    low, high = machine.limits.stroke
    for letter, name in zip(letters, kinematics.joint_names, strict=True):
        axes.append(ConfigAxis(letter, f"stroke {name}", low, high, _home(low, high), stroke_speed, stroke_accel,
                               pin=name.lower()))
    for axis in axes:
        if axis.letter in ROTARY_LETTERS:
            raise ConfigError(f"axes: the dialect writes {axis.name} as {axis.letter!r}, which LinuxCNC treats as a "
                              "rotary axis in degrees: give a dialect that writes the stage and the strokes with X Y "
                              "Z U V W", path=loaded.source)
    return tuple(axes)


def config_files(machine: Machine, machine_text: str, *, tool_table: ToolTable | None = None,
                 dialect: str | None = None, display: str | None = None, vismach: bool = True,
                 max_feed_override: float = DEFAULT_MAX_FEED_OVERRIDE,
                 home: tuple[float, ...] | None = None) -> dict[str, FolderFile]:
    """The configuration's files, {name: file}: the INI, the HAL file, the tool table, the parameter
    file and, with ``vismach``, the vismach model, its HAL file and the machine file it reads
    (``machine_text``, the machine's TOML as loaded). Parameters as :func:`write_config`."""
    shown = DEFAULT_DISPLAY if display is None else display
    if not shown.strip() or not shown.isprintable():                # one line, no control characters
        raise FieldError(f"give the display program on one line, printable (like {DEFAULT_DISPLAY!r}), "
                         f"got {shown!r}",
                         field="display")
    if not (math.isfinite(max_feed_override) and 1.0 <= max_feed_override <= MAX_FEED_OVERRIDE_LIMIT):
        raise FieldError(f"expected 1 to {MAX_FEED_OVERRIDE_LIMIT:g} (1 = 100 %), got {max_feed_override!r}",
                         field="max_feed_override")
    if vismach:
        check_drawable(machine)
    axes = homed_at(config_axes(machine, dialect), home)
    hal = f"{file_stem(machine)}.hal"
    files = {
        ini_name(machine): FolderFile(ini_text(machine, axes, display=shown, hal_files=(hal,) + (
            (VISMACH_HAL,) if vismach else ()), max_feed_override=max_feed_override)),
        hal: FolderFile(hal_text(machine, axes)),
        TOOL_TABLE: FolderFile(tool_table_text(_tools(machine, tool_table))),
        PARAMETER_FILE: FolderFile(""),
    }
    if vismach:
        toml = f"{file_stem(machine)}.toml"
        files[VISMACH_HAL] = FolderFile(vismach_hal([(axis.letter, axis.pin) for axis in axes], machine))
        pins = tuple(axis.pin for axis in axes if not axis.name.startswith("stage"))
        files[VISMACH_SCRIPT] = FolderFile(vismach_script(machine, toml, TOOL_TABLE, pins), executable=True)
        files[toml] = FolderFile(machine_text)
    return files


def homed_at(axes: tuple[ConfigAxis, ...], home: tuple[float, ...] | None) -> tuple[ConfigAxis, ...]:
    """The axes homing at ``home`` (mm, one per joint in order, each moved inside its limits); None: as they are.

    Raises
    ------
    FieldError
        Not one position per joint.
    """
    if home is None:
        return axes
    if len(home) != len(axes):
        raise FieldError(f"expected {len(axes)} positions (one per joint: {''.join(a.letter for a in axes)}), got "
                         f"{len(home)}", field="home")
    return tuple(replace(axis, home=min(max(float(value), axis.low), axis.high))
                 for axis, value in zip(axes, home, strict=True))


def _home(low: float, high: float) -> float:
    """The zero, moved inside [low, high] where it is outside."""
    return min(max(0.0, low), high)


def _tools(machine: Machine, table: ToolTable | None) -> tuple[Tool, ...]:
    """The table's tools, else the machine's own tool as T1."""
    if table is not None:
        return table.tools
    length = machine.geometry.tool_length - machine.geometry.gauge_offset
    return (Tool(number=1, pocket=1, diameter=DEFAULT_TOOL_DIAMETER, length=length,
                 comment=f"the machine's tool: tool_length_mm - gauge_offset_mm of {one_line(machine.name)}"),)


def tool_table_text(tools: tuple[Tool, ...]) -> str:
    """A LinuxCNC tool table: ``T1 P1 D6.000 Z55.000 ;comment``, one tool a line (a tool without a
    pocket gets its number as pocket, which LinuxCNC needs)."""
    lines = []
    for tool in tools:
        pocket = tool.number if tool.pocket is None else tool.pocket
        comment = " ".join(tool.comment.split())
        lines.append(f"T{tool.number} P{pocket} D{exact_text(tool.diameter, 3)} Z{exact_text(tool.length, 3)}"
                     + (f" ;{comment}" if comment else ""))
    return "\n".join(lines) + "\n"


def _number(value: float) -> str:
    """A number of the INI: exact (it reads back as the same float), at least three decimals."""
    return exact_text(value, 3)


def _norm(values: list[float]) -> float:
    return math.sqrt(sum(v * v for v in values))


def ini_text(machine: Machine, axes: tuple[ConfigAxis, ...], *, display: str, hal_files: tuple[str, ...],
             max_feed_override: float) -> str:
    """The INI file."""
    letters = "".join(axis.letter for axis in axes)
    # a move of several axes may reach each axis's speed at once: the vector limits must not slow it
    top_speed = _norm([axis.velocity for axis in axes])
    top_accel = _norm([axis.acceleration for axis in axes])
    slowest = min(axis.velocity for axis in axes)
    dynamics = ("its [dynamics]" if machine.dynamics is not None else
                f"no [dynamics] in the machine file: the nominal {fixed(NOMINAL_RAPID_RATE, 0)} mm/min and "
                f"{fixed(NOMINAL_ACCEL, 0)} mm/s²")
    out = [
        f"# LinuxCNC configuration of the machine {one_line(machine.name)} ({one_line(machine.description)}),",
        f"# written by prs3-post {__version__} linuxcnc-config from {one_line(Path(machine.source).name)}.",
        "# Joints (trivial kinematics, one per program axis): "
        + ", ".join(f"{i} = {axis.letter} ({axis.name})" for i, axis in enumerate(axes)) + ".",
        "# Limits are the machine file's; speeds and accelerations " + dynamics + ".",
        "# Simulated drives (no hardware): start it with  linuxcnc " + ini_name(machine),
        "",
        "[EMC]",
        "VERSION = 1.1",
        f"MACHINE = prs3-post {one_line(machine.name)}",
        "DEBUG = 0",
        "",
        "[DISPLAY]",
        f"DISPLAY = {display}",
        "CYCLE_TIME = 0.100",
        "POSITION_OFFSET = RELATIVE",
        "POSITION_FEEDBACK = ACTUAL",
        "# the feed override range the display offers (1 = 100 %)",
        f"MAX_FEED_OVERRIDE = {_number(max_feed_override)}",
        f"DEFAULT_LINEAR_VELOCITY = {fixed(slowest / 10.0, 3)}",
        f"MAX_LINEAR_VELOCITY = {_number(top_speed)}",
        "INCREMENTS = 10mm 1mm 0.1mm 0.01mm 0.001mm",
        "",
        "[TASK]",
        "TASK = milltask",
        "CYCLE_TIME = 0.010",
        "",
        "[RS274NGC]",
        f"PARAMETER_FILE = {PARAMETER_FILE}",
        "RS274NGC_STARTUP_CODE = G17 G21 G40 G49 G54 G80 G90 G94 G61",
        "",
        "[EMCMOT]",
        "EMCMOT = motmod",
        "COMM_TIMEOUT = 1.0",
        f"SERVO_PERIOD = {SERVO_PERIOD_NS}",
        "",
        "[EMCIO]",
        "EMCIO = io",
        "CYCLE_TIME = 0.100",
        "# T… M6 takes these tools; their Z lengths are not applied (no Z axis; the programs are posted with them)",
        f"TOOL_TABLE = {TOOL_TABLE}",
        "",
        "[HAL]",
        *(f"HALFILE = {name}" for name in hal_files),
        "",
        "[KINS]",
        f"KINEMATICS = trivkins coordinates={letters}",
        f"JOINTS = {len(axes)}",
        "",
        "[TRAJ]",
        f"COORDINATES = {letters}",
        "LINEAR_UNITS = mm",
        "ANGULAR_UNITS = degree",
        f"DEFAULT_LINEAR_VELOCITY = {fixed(slowest / 10.0, 3)}",
        "# the vector limits: every axis at its own top speed and acceleration at once",
        f"MAX_LINEAR_VELOCITY = {_number(top_speed)}",
        f"MAX_LINEAR_ACCELERATION = {_number(top_accel)}",
    ]
    for axis in axes:
        out += ["", f"# {axis.name}", f"[AXIS_{axis.letter}]",
                f"MIN_LIMIT = {_number(axis.low)}", f"MAX_LIMIT = {_number(axis.high)}",
                f"MAX_VELOCITY = {_number(axis.velocity)}", f"MAX_ACCELERATION = {_number(axis.acceleration)}"]
    for index, axis in enumerate(axes):
        out += ["", f"# {axis.name}, homed where it stands (no switches), all joints at once",
                f"[JOINT_{index}]", "TYPE = LINEAR",
                f"MIN_LIMIT = {_number(axis.low)}", f"MAX_LIMIT = {_number(axis.high)}",
                f"MAX_VELOCITY = {_number(axis.velocity)}", f"MAX_ACCELERATION = {_number(axis.acceleration)}",
                "FERROR = 1.0", "MIN_FERROR = 0.25",
                f"HOME = {_number(axis.home)}", f"HOME_OFFSET = {_number(axis.home)}",
                "HOME_SEARCH_VEL = 0", "HOME_LATCH_VEL = 0", "HOME_USE_INDEX = NO", "HOME_SEQUENCE = 0"]
    return "\n".join(out) + "\n"


def hal_text(machine: Machine, axes: tuple[ConfigAxis, ...]) -> str:
    """The HAL file: the motion controller with simulated drives (each joint's command is its feedback)."""
    out = [
        f"# Simulated drives of {one_line(machine.name)}: the motion controller, each joint's commanded position",
        "# looped back as its feedback, the E-stop and the tool changer answering at once (as LinuxCNC's sim configs).",
        "loadrt [KINS]KINEMATICS",
        "loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS",
        "addf motion-command-handler servo-thread",
        "addf motion-controller servo-thread",
        "",
    ]
    for index, axis in enumerate(axes):
        out += [f"# joint {index}: {axis.name}",
                f"net {axis.letter.lower()}-pos-cmd joint.{index}.motor-pos-cmd => joint.{index}.motor-pos-fb"]
    out += [
        "",
        "net estop-loop iocontrol.0.user-enable-out => iocontrol.0.emc-enable-in",
        "net tool-prepare-loop iocontrol.0.tool-prepare => iocontrol.0.tool-prepared",
        "net tool-change-loop iocontrol.0.tool-change => iocontrol.0.tool-changed",
    ]
    return "\n".join(out) + "\n"

