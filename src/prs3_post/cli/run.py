"""The main job (`run PART.stl`, `demo`) and job files (`job JOB.toml`)."""

from __future__ import annotations

import dataclasses
import math
import os
import re
import stat
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click
import numpy as np

from prs3_post.cli.options import (
    ANGLE,
    CLEARANCE_MIN,
    FEED,
    LENGTH,
    SPEED,
    TIME,
    Command,
    Decimal,
    Integer,
    Numbers,
    OutputPath,
    demo_part,
    dialect_option,
    face_index,
    image_format,
    job_part_origin_option,
    job_part_rotation_option,
    line_number_options,
    machine_option,
    resolve_setup,
    run_reported,
    tolerance_option,
    up_option,
    was_given,
)
from prs3_post.core.defaults import (
    DEFAULT_CLEARANCE_MIN,
    FEED_RANGE_MM_MIN,
    NOMINAL_RAPID_RATE,
)
from prs3_post.core.errors import FeatureError, InputError, quoted
from prs3_post.emit.output_files import (
    is_stdout,
    refuse_overwriting,
    write_outputs,
)
from prs3_post.machine.loading import (
    load_dialect,
    load_machine,
)
from prs3_post.part.setup_transform import AUTO
from prs3_post.toolpaths import (
    Coolant,
    Cutting,
    Direction,
    Entry,
    HoleParams,
    ProfileParams,
    RoundShape,
    Side,
    SquareShape,
)
from prs3_post.toolpaths.common import TOOL_DIAMETER_RANGE
from prs3_post.toolpaths.work import HoleJob, Operation, ProfileJob

# What only some commands need is imported where it is used (the main job, convert, verify, preview,
# faces: each about 0.1 s of imports), so that `ik`, `fk` and a small `verify` start fast.
if TYPE_CHECKING:
    from prs3_post.app.job import JobProgram, JobSpec
    from prs3_post.readers.jobfile import JobFile
    from prs3_post.readers.tooltable import ToolTable


def job_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """The options of the main job (``run`` and ``demo``), grouped as ``--help`` shows them."""
    options = [
        # what to cut
        click.option("--profile", type=click.Choice([o.value for o in Operation]), required=True,
                     help="Operation: hole (drill, optional pecking), square or round (groove or wall)."),
        click.option("--face", "face_choice", default="auto", show_default=True, metavar="auto|N",
                     help="Face to work on: auto = largest upward inclined face; N = index from `prs3-post faces`."),
        click.option("--at", "at_uv", type=Numbers("U,V"), multiple=True,
                     help="Feature position in face coordinates, mm (repeat for several holes). Default: face origin."),
        click.option("--at-xyz", "at_xyz", type=Numbers("X,Y,Z"), multiple=True,
                     help="Feature position in part coordinates, mm: a point on the face "
                          "(within 0.01 mm; repeatable)."),
        click.option("--units", type=click.Choice(["mm", "inch"]), default="mm", show_default=True,
                     help="Length unit of the STL file."),
        up_option,
        # feature geometry
        click.option("--depth", type=Decimal(LENGTH), default=None,
                     help="Depth below the face along the tool axis, mm.  [default: 5 for hole, 2 for square/round]"),
        click.option("--peck", type=Decimal(LENGTH), default=0.0, show_default=True,
                     help="hole: peck depth, mm (0 = drill in one go); each peck retracts to --clearance."),
        click.option("--reapproach-gap", type=Decimal(LENGTH), default=0.5, show_default=True,
                     help="hole: gap above the previous peck bottom where feed resumes, mm."),
        click.option("--dwell", type=Decimal(TIME), default=0.0, show_default=True,
                     help="hole: dwell at the bottom, s."),
        click.option("--size", type=Decimal(LENGTH), default=30.0, show_default=True, help="square: side length, mm."),
        click.option("--corner-radius", type=Decimal(LENGTH), default=0.0, show_default=True,
                     help="square: corner radius, mm."),
        click.option("--rotation", type=Decimal(ANGLE), default=0.0, show_default=True,
                     help="square: rotation about the face normal from the down-slope direction u, degrees."),
        click.option("--diameter", type=Decimal(LENGTH), default=30.0, show_default=True, help="round: diameter, mm."),
        click.option("--side", type=click.Choice([s.value for s in Side]), default="on", show_default=True,
                     help="Tool centre on the outline (a groove), inside it or outside it "
                          "(offset by the tool radius)."),
        click.option("--step-down", type=Decimal(LENGTH), default=1.0, show_default=True,
                     help="square/round: depth per pass, mm."),
        click.option("--direction", type=click.Choice([d.value for d in Direction]), default="climb", show_default=True,
                     help="square/round: climb or conventional milling (spindle clockwise, M3)."),
        click.option("--entry", type=click.Choice([e.value for e in Entry]), default="ramp", show_default=True,
                     help="square/round: how each pass enters the material."),
        click.option("--ramp-angle", type=Decimal(ANGLE), default=3.0, show_default=True,
                     help="Ramp entry angle, degrees."),
        click.option("--clearance", type=Decimal(LENGTH), default=2.0, show_default=True,
                     help="Height above the face where rapids end and feeds begin, mm (along the tool axis)."),
        click.option("--retract", type=Decimal(LENGTH), default=10.0, show_default=True,
                     help="Safe height above the face between features, mm (along the tool axis)."),
        # tool and cutting data
        click.option("--tool-diameter", type=Decimal(LENGTH), default=6.0, show_default=True,
                     help="Tool diameter, mm (0.01 to 500)."),
        click.option("--tool-number", type=Integer(), default=1, show_default=True,
                     help="Tool number (T word), 1 up to the dialect's words.tool_number_max (both shipped: 99999)."),
        click.option("--feed", type=Decimal(FEED, low=FEED_RANGE_MM_MIN[0]), default=300.0, show_default=True,
                     help="Cutting feed at the tool tip, mm/min."),
        click.option("--plunge-feed", type=Decimal(FEED, low=FEED_RANGE_MM_MIN[0]), default=100.0, show_default=True,
                     help="Feed into the material (drilling, plunges, ramps), mm/min."),
        click.option("--spindle", type=Decimal(SPEED, low=0.0, low_open=True), default=3000.0, show_default=True,
                     help="Spindle speed, rpm (clockwise)."),
        click.option("--coolant", type=click.Choice([c.value for c in Coolant]), default=Coolant.FLOOD.value,
                     show_default=True,
                     help="Coolant during cutting: flood (M8), mist (M7) or off."),
        click.option("--tool-table", "tool_table", type=click.Path(dir_okay=False), metavar="TOOL.tbl",
                     help="LinuxCNC tool table (T P D Z ;comment): the IK uses the machine's gauge offset plus the "
                          "tool's Z length, and the tool's D must be --tool-diameter.  [default: the machine's "
                          "tool_length_mm]"),
        # machine, setup and output
        machine_option,
        job_part_origin_option,
        job_part_rotation_option,
        dialect_option,
        *line_number_options,
        tolerance_option,
        click.option("--clamp/--no-clamp", default=True, show_default=True,
                     help="Lower G1 feeds that would drive an axis over its top speed (the machine's [dynamics]); "
                          "--no-clamp refuses such a feed, naming its line."),
        click.option("--collision-check/--no-collision-check", default=True, show_default=True,
                     help="Check that the tool, holder and spindle nose stay clear of the part (the machine's "
                          "[holder]) before writing; the header says when it was skipped."),
        click.option("--clearance-min", type=CLEARANCE_MIN, default=DEFAULT_CLEARANCE_MIN, show_default=True,
                     help="Least distance the tool, holder and spindle nose keep from the part, mm."),
        click.option("-o", "--output", "out_path", type=OutputPath(),
                     help="Program file (written to a temp file, then renamed). Default: standard output."),
        click.option("--preview", "preview_path", type=OutputPath(), metavar="OUT.png|OUT.svg",
                     help="Also draw the program (as `prs3-post preview` does, on this part and face). "
                          "Needs matplotlib: pip install 'prs3-post[plot]'."),
    ]
    for option in reversed(options):
        func = option(func)
    return func


#: The main job's options that only some profiles use: given with another, they would be ignored.
_PROFILE_ONLY = {
    "peck": ("hole",), "reapproach_gap": ("hole",), "dwell": ("hole",), "size": ("square",),
    "corner_radius": ("square",), "rotation": ("square",), "diameter": ("round",),
    "side": ("square", "round"), "step_down": ("square", "round"), "direction": ("square", "round"),
    "entry": ("square", "round"), "ramp_angle": ("square", "round"),
}


def _unused_by(profile: str, names: list[str]) -> list[str]:
    """Of the option names given, those ``--profile profile`` does not use."""
    return [name for name in names if profile not in _PROFILE_ONLY.get(name, (profile,))]


def _for_profiles(name: str) -> str:
    """``(hole only)``, ``(square and round only)``: the profiles that use an option."""
    return f"({' and '.join(_PROFILE_ONLY[name])} only)"


def refuse_unused_options(profile: str) -> None:
    """A usage error for options the main job was given that ``--profile`` ignores (``--diameter`` on a square)."""
    ctx = click.get_current_context()
    unused = _unused_by(profile, [name for name in _PROFILE_ONLY if was_given(ctx, name)])
    if unused:
        flags = ", ".join(f"--{name.replace('_', '-')} {_for_profiles(name)}" for name in unused)
        raise click.UsageError(f"--profile {profile} does not use {flags}: leave {'it' if len(unused) == 1 else 'them'}"
                               " out")


def _run_job(part: str, **opts: Any) -> int:
    """Build the JobSpec from the options, check the job, write the program (and its preview)."""
    from prs3_post.app.job import check_job
    from prs3_post.app.verify import preview_bytes
    from prs3_post.check.placement import Placement
    from prs3_post.readers.program import read_program

    refuse_unused_options(opts["profile"])
    spec = job_spec(part, opts)
    fmt = image_format(opts["preview_path"], "'--preview'") if opts["preview_path"] else None
    try:
        job = check_job(spec)
    except Placement as error:                         # the library's suggestion, as the option to give
        origin = error.suggested_origin
        hint = ("set by --part-origin X,Y,Z and --part-rotation DEG, or let --part-origin auto --part-rotation "
                "auto search them" if origin is None
                else f"--part-origin={','.join(origin)}")
        raise type(error)(f"{error}: {hint}", setup=error.setup, suggested_origin=origin) from error
    out_path = opts["out_path"]
    text = _ProgramText(job, whole=fmt is not None or not _streamable(out_path))
    image = None
    if fmt is not None:                                # draw before writing anything: no half results
        program = read_program(text.whole, spec.dialect, path=out_path or "<program>",
                               stage=spec.machine.stage.present)
        lengths = None if spec.tool_table is None else {spec.cutting.tool_number: job.tool_lengths[0]}
        image = preview_bytes(program, spec.machine, job.setup, fmt, tolerance=spec.tolerance, tool_lengths=lengths,
                              mesh=job.triangles, face=job.face, title=Path(part).name, dialect=spec.dialect,
                              closest=job.closest, rapid_rate=NOMINAL_RAPID_RATE)
    write_outputs([(out_path, text.data())] + ([] if image is None else [(opts["preview_path"], image)]))
    _report_placement(job)
    if not is_stdout(out_path):
        click.echo(f"prs3-post: wrote {out_path}: {text.lines} lines, "
                   f"{len(job.program)} moves; {job.face_note}", err=True)
        if spec.machine.dynamics is not None:
            click.echo(f"prs3-post: {job.dynamics}", err=True)
    if image is not None:
        click.echo(f"prs3-post: wrote {opts['preview_path']}", err=True)
    return 0


def _streamable(path: str | None) -> bool:
    """The program may be written as it is formatted: ``path`` is a file written to a temp file and
    renamed (a new or regular file), so that an error while formatting leaves nothing. Standard
    output, a FIFO or a device get the whole text once it is complete."""
    if is_stdout(path):
        return False
    try:
        return stat.S_ISREG(os.stat(str(path)).st_mode)
    except FileNotFoundError:
        return True
    except OSError:                                    # the writer says what is wrong with it
        return True


class _ProgramText:
    """A checked job's text for the writer: streamed chunk by chunk, or whole (``whole``: made here),
    counting its lines as it goes."""

    def __init__(self, job: JobProgram, *, whole: bool):
        self.job, self.streamed = job, not whole
        self.whole = "" if self.streamed else "".join(job.chunks())
        self.lines = self.whole.count("\n")

    def data(self) -> str | Iterator[str]:
        return self._counted() if self.streamed else self.whole

    def _counted(self) -> Iterator[str]:
        for chunk in self.job.chunks():
            self.lines += chunk.count("\n")
            yield chunk


def _report_placement(job: JobProgram) -> None:
    """The setup automatic placement chose, and every limit's margin there, on standard error."""
    if job.placement is not None:
        click.echo(f"prs3-post: setup: {job.setup.describe()}; {job.placement.describe()}", err=True)


def job_spec(part: str, opts: dict[str, Any]) -> JobSpec:
    """The JobSpec the main job's options describe (also rebuilt by `verify --against PART.stl`)."""
    from prs3_post.app.job import JobSpec
    from prs3_post.readers.tooltable import read_tool_table

    operation = Operation(opts["profile"])
    depth = opts["depth"] if opts["depth"] is not None else (5.0 if operation is Operation.HOLE else 2.0)
    face = face_index(opts["face_choice"])
    dialect = load_dialect(opts["dialect_name"])
    if not 1 <= opts["tool_number"] <= dialect.tool_number_max:       # both bounds, one message
        raise click.BadParameter(
            f"must be 1..{dialect.tool_number_max} with dialect {dialect.name} (its words.tool_number_max), "
            f"got {opts['tool_number']}", param_hint="'--tool-number'")
    cutting = Cutting(
        tool_diameter=opts["tool_diameter"], feed=opts["feed"], plunge_feed=opts["plunge_feed"],
        spindle_rpm=opts["spindle"], coolant=Coolant(opts["coolant"]), tool_number=opts["tool_number"],
    )
    work: HoleJob | ProfileJob
    if operation is Operation.HOLE:
        work = HoleJob(HoleParams(depth=depth, peck=opts["peck"], dwell=opts["dwell"], clearance=opts["clearance"],
                                  retract=opts["retract"], reapproach_gap=opts["reapproach_gap"]))
    else:
        shape: SquareShape | RoundShape
        if operation is Operation.SQUARE:
            shape = SquareShape(size=opts["size"], corner_radius=opts["corner_radius"],
                                rotation=math.radians(opts["rotation"]))
        else:
            shape = RoundShape(diameter=opts["diameter"])
        work = ProfileJob(shape, ProfileParams(
            side=Side(opts["side"]), depth=depth, step_down=opts["step_down"], direction=Direction(opts["direction"]),
            entry=Entry(opts["entry"]), ramp_angle=math.radians(opts["ramp_angle"]), clearance=opts["clearance"],
            retract=opts["retract"],
        ))
    wrap = dialect.line_numbers.wrap_after
    start = dialect.line_numbers.start if opts.get("line_start") is None else opts["line_start"]
    step = dialect.line_numbers.step if opts.get("line_step") is None else opts["line_step"]
    if start + step > wrap:
        raise click.BadParameter(
            f"--line-start {start} + --line-step {step} passes dialect {dialect.name}'s largest block number "
            f"{wrap}: every block would get the same number", param_hint="'--line-start'")
    machine = load_machine(opts["machine_name"])
    return JobSpec(
        part=part, units=opts["units"], face=face, work=work,
        at_uv=np.array(opts["at_uv"], dtype=np.float64).reshape(-1, 2),
        at_xyz=np.array(opts["at_xyz"], dtype=np.float64).reshape(-1, 3),
        cutting=cutting, machine=machine, dialect=dialect,
        setup=resolve_setup(machine, opts["part_origin"], opts.get("part_rotation")), tolerance=opts["tolerance"],
        line_numbers=opts.get("line_numbers"), line_start=opts.get("line_start"), line_step=opts.get("line_step"),
        up=opts.get("up", "z"), auto_origin=opts["part_origin"] == AUTO,
        auto_rotation=opts.get("part_rotation") == AUTO,
        tool_table=read_tool_table(opts["tool_table"]) if opts.get("tool_table") else None,
        clamp=opts.get("clamp", True), collision_check=opts.get("collision_check", True),
        clearance_min=opts.get("clearance_min", DEFAULT_CLEARANCE_MIN),
    )


@click.command(cls=Command)
@click.argument("part", type=click.Path(dir_okay=False), metavar="PART.stl")
@job_options
def run(part: str, **opts: Any) -> None:
    """The main job: cut a hole, square or round profile on a part's inclined face.

    Loads PART.stl, picks the inclined face (--face), places the feature (--at / --at-xyz, default
    the face centre), plans it with the tool normal to the face, runs the exact inverse kinematics
    and writes the program in actuator space. Nothing is written if any point breaks a limit.
    `prs3-post PART.stl ...` is short for `prs3-post run PART.stl ...`.

    \b
    Examples:
      prs3-post part.stl --profile hole --at 10,0 --at -10,0 --depth 8 --peck 2 -o holes.ngc
      prs3-post part.stl --profile square --size 40 --corner-radius 5 --side inside -o pocket.ngc
      prs3-post part.stl --profile round --diameter 25 --dialect fanuc --line-numbers -o round.nc
    """
    run_reported(lambda: _run_job(part, **opts))


@click.command(cls=Command)
@job_options
def demo(**opts: Any) -> None:
    """The main job on the bundled demo part: the paper's wedge (26.57° face, Patel 2020).

    Same options as `run`. The wedge spans x −50…50, y 150…250 mm with its top face
    z = 300 − x/2, placed at machine (−100, −200, −970) by the default setup.

    \b
    Examples:
      prs3-post demo --profile square -o demo-square.ngc
      prs3-post demo --profile hole --at-xyz 18.9736,221.2132,290.5135      (the paper's case 2a)
    """
    run_reported(lambda: _run_job(str(demo_part()), **opts))


#: Keys of a job file's ``[[operation]]`` whose main-job option has another name.
_JOB_KEY_OPTION = {"face": "face_choice", "at": "at_uv", "tool": "tool_number"}
#: The job file's key of a main-job flag whose name differs (``--tool-number`` → ``tool``).
_JOB_KEY_OF = {"tool-number": "tool"}
#: Top-level keys of a job file and the main-job option each sets.
_JOB_SETTING_OPTION = {"units": "units", "up": "up", "machine": "machine_name", "dialect": "dialect_name",
                       "tolerance": "tolerance", "line_numbers": "line_numbers", "line_start": "line_start",
                       "line_step": "line_step"}


def _job_value(param: click.Parameter, value: Any) -> Any:
    """A job file's value for the main job's option ``param``, checked as the option's own value is."""
    if isinstance(value, bool) and not isinstance(param.type, click.types.BoolParamType):
        raise click.BadParameter(f"expected {param.type.name}, got {str(value).lower()}")
    if param.multiple:                                 # at, at_xyz: a list of points
        if not (isinstance(value, list) and value and all(isinstance(v, list) for v in value)):   # [] is no point
            like = "[[1.0, 2.0, 3.0]]" if param.name == "at_xyz" else "[[1.0, 2.0]]"
            raise click.BadParameter(f"expected a list of points like {like}, got {quoted(value)}")
        return tuple(param.type.convert(",".join(str(x) for x in point), None, None) for point in value)
    if param.name == "face_choice":
        if not (isinstance(value, str) or isinstance(value, int)):
            raise click.BadParameter(f'expected "auto" or a face index, got {quoted(value)}')
        return str(value)
    if isinstance(param.type, (Decimal, Integer)) and isinstance(value, str):
        raise click.BadParameter(f"expected a number, got {quoted(value)}")
    if isinstance(param.type, click.Choice) and value not in param.type.choices:
        raise click.BadParameter(f"expected one of {', '.join(map(str, param.type.choices))}, got {quoted(value)}")
    return param.type.convert(value, None, None)


#: The job file's keys of the setup options (a job's one setup, not an operation's).
_JOB_SETUP_KEYS = {"--part-origin": "setup.part_origin", "--part-rotation": "setup.part_rotation_deg"}


def _job_specs(job: JobFile) -> tuple[JobSpec, ...]:
    """Each operation of a job file as the JobSpec its options make (the main job's defaults, then the
    file's top-level settings, then the operation's keys)."""
    from prs3_post.readers.jobfile import OPERATION_KEYS
    from prs3_post.readers.tooltable import read_tool_table

    params = {p.name: p for p in job_options(lambda **_: None).__click_params__}  # type: ignore[attr-defined]
    table: ToolTable | None = read_tool_table(job.settings["tool_table"]) if "tool_table" in job.settings else None
    ctx = click.Context(run)
    base = {name: _option_default(ctx, param) for name, param in params.items() if name is not None}
    base |= {"part_origin": job.part_origin, "part_rotation": job.part_rotation_deg, "tool_table": None,
             "out_path": None, "preview_path": None}
    for key, name in _JOB_SETTING_OPTION.items():
        if key in job.settings:
            base[name] = _job_setting(job, key, params[name])
    specs = []
    for number, operation in enumerate(job.operations, start=1):
        opts = dict(base)
        where = f"operation[{number}]"
        try:                                           # a profile that is none: say so, not which keys it lacks
            _job_value(params["profile"], operation["profile"])
        except click.BadParameter as error:
            raise InputError(f"{where}.profile: {error.message}", path=job.path) from error
        unused = _unused_by(str(operation["profile"]), [key for key in operation if key in _PROFILE_ONLY])
        if unused:
            raise InputError(f"{where}: profile {operation['profile']} does not use "
                             f"{', '.join(f'{key} {_for_profiles(key)}' for key in unused)}: remove "
                             f"{'it' if len(unused) == 1 else 'them'}", path=job.path)
        for key, value in operation.items():
            name = _JOB_KEY_OPTION.get(key, key)
            try:
                opts[name] = _job_value(params[name], value)
            except click.BadParameter as error:
                raise InputError(f"{where}.{key}: {error.message}", path=job.path) from error
        if table is not None and "tool_diameter" not in operation:     # the table says the diameter
            tool = table.find(opts["tool_number"])
            if tool is not None:
                low, high = TOOL_DIAMETER_RANGE          # its line, not the operation's tool_diameter (not given)
                if not low <= tool.diameter <= high:
                    raise InputError(f"T{tool.number} has diameter {tool.diameter:g} mm in the tool table: a job "
                                     f"takes a diameter from {low:g} to {high:g} mm (or give tool_diameter in the "
                                     "operation)", path=table.path, line=tool.line)
                opts["tool_diameter"] = tool.diameter
        try:
            spec = job_spec(job.part, opts)
        except click.BadParameter as error:            # one option's value: name the job file's key
            hint = error.param_hint.strip("'") if isinstance(error.param_hint, str) else ""
            key = _job_keys(hint)
            at = (f"{where}.{key}" if key in OPERATION_KEYS else key if key in _JOB_SETTING_OPTION
                  else _JOB_SETUP_KEYS.get(hint, ""))     # the file's [setup], not an operation's
            if at:
                raise InputError(f"{at}: {_job_keys(error.message)}", path=job.path) from error
            raise InputError(f"{where}: {error.format_message()}", path=job.path) from error
        except click.ClickException as error:
            raise InputError(f"{where}: {error.format_message()}", path=job.path) from error
        except FeatureError as error:                  # worded for the options: say the job file's keys
            raise InputError(f"{where}: {_job_keys(str(error))}", path=job.path) from error
        specs.append(dataclasses.replace(spec, tool_table=table))
    return tuple(specs)


def _job_keys(text: str) -> str:
    """A message worded for the options, with the job file's keys instead (``--tool-number`` → ``tool``)."""
    return re.sub(r"--([a-z-]+)", lambda m: _JOB_KEY_OF.get(m.group(1), m.group(1).replace("-", "_")), text)


def _option_default(ctx: click.Context, param: click.Parameter) -> Any:
    """An option's default value as the command receives it (``()`` for a repeatable option)."""
    value = param.get_default(ctx)
    if value is None or value is getattr(click.core, "UNSET", None):   # click ≥ 8.3 marks "no default" so
        return () if param.multiple else None
    return param.type_cast_value(ctx, value)


def _job_setting(job: JobFile, key: str, param: click.Parameter) -> Any:
    value = job.settings[key]
    if key in ("machine", "dialect", "line_numbers"):
        return value
    try:
        return _job_value(param, value)
    except click.BadParameter as error:
        raise InputError(f"{key}: {error.message}", path=job.path) from error


@click.command(cls=Command)
@click.argument("job_path", type=click.Path(dir_okay=False), metavar="JOB.toml")
@click.option("-o", "--output", "out_path", type=OutputPath(),
              help="Program file (written to a temp file, then renamed). Default: standard output.")
def job(job_path: str, out_path: str | None) -> None:
    """Run a job file: several operations on one part, on one or more faces, with one or more tools.

    JOB.toml names the part (part, units, up), the setup ([setup] part_origin, part_rotation_deg),
    a tool table (tool_table, LinuxCNC format) and one [[operation]] table per operation, in order:
    profile, face, tool and the main job's options with _ for - (at, depth, step_down, side ...).
    Paths are relative to the job file. One program: between operations the tool rises along its
    axis to a safe height above the part, the spindle and coolant stop, the tool changes where it
    changes, the axis turns at that height (checked like any move) and the tool goes to the next face.
    Each operation's IK uses its tool's length (the machine's gauge offset plus the table's Z).

    \b
    Example:
      prs3-post job fixtures/jobs/example.toml -o example.ngc
    """
    from prs3_post.app.job import check_operations
    from prs3_post.readers.jobfile import read_job_file


    def body() -> int:
        job_file = read_job_file(job_path)
        named = {"part": job_file.part} | {key: job_file.settings.get(key)
                                            for key in ("tool_table", "machine", "dialect")}
        refuse_overwriting({"--output": out_path}, {f"{key} of {job_path}": path for key, path in named.items()
                                                    if isinstance(path, str)})
        specs = _job_specs(job_file)
        try:
            job = check_operations(specs)
        except FeatureError as error:                  # worded for the options: say the job file and its key
            where = "" if error.operation is None else f"operation[{error.operation}]"
            where += f".{error.key}" if where and error.key else ""
            raise InputError(f"{where}: {_job_keys(str(error))}" if where else _job_keys(str(error)),
                             path=job_path) from error
        text = _ProgramText(job, whole=not _streamable(out_path))
        write_outputs([(out_path, text.data())])
        _report_placement(job)
        if not is_stdout(out_path):
            click.echo(f"prs3-post: wrote {out_path}: {text.lines} lines, "
                       f"{len(job.program)} moves, {len(specs)} operations", err=True)
            if specs[0].machine.dynamics is not None:
                click.echo(f"prs3-post: {job.dynamics}", err=True)
        return 0

    run_reported(body)

