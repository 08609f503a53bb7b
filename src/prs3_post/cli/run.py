"""The main job (`run PART.stl`, `demo`) and job files (`job JOB.toml`)."""

from __future__ import annotations

import os
import stat
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from prs3_post.app.requests import (
    DEFAULT_TOOL_DIAMETER,
    OPERATION_FIELDS,
    SETTING_FIELDS,
    choices,
    job_request,
    job_specs,
    used_by,
)
from prs3_post.app.values import ANGLE, FEED, LENGTH, SPEED, SPINDLE_LOW, TIME
from prs3_post.cli.options import (
    CLEARANCE_MIN,
    PART_UNITS_ALIAS,
    Command,
    Decimal,
    Integer,
    Numbers,
    OutputPath,
    clamp_option,
    demo_part,
    detail,
    dialect_option,
    image_format,
    job_part_origin_option,
    job_part_rotation_option,
    line_number_options,
    machine_option,
    option_error,
    part_units_option,
    run_reported,
    say,
    timed,
    tolerance_option,
    up_option,
    verbosity_options,
    was_given,
)
from prs3_post.core.defaults import (
    FEED_RANGE_MM_MIN,
)
from prs3_post.core.errors import FeatureError, FieldError, InputError, UnusedFields
from prs3_post.core.output_files import (
    is_stdout,
    refuse_overwriting,
    write_outputs,
)

# What only some commands need is imported where it is used (the main job, convert, verify, preview,
# faces: each about 0.1 s of imports), so that `ik`, `fk` and a small `verify` start fast.
if TYPE_CHECKING:
    from prs3_post.app.job import JobProgram, JobSpec
    from prs3_post.app.run import JobFile


#: The defaults of the request's keys (shown by --help; the request applies them).
_OP = {key: field.default for key, field in OPERATION_FIELDS.items()}
_SET = {key: field.default for key, field in SETTING_FIELDS.items()}

collision_check_option = click.option(
    "--collision-check/--no-collision-check", default=_SET["collision_check"], show_default=True,
    help="Check that the tool, holder and spindle nose stay clear of the part (the machine's "
         "[holder]) before writing; the header says when it was skipped.")
json_option = click.option(
    "--json", "as_json", is_flag=True,
    help="Print what was written as one JSON object on standard output: the program file (path, lines, "
         "bytes), the setup, the faces, every limit's closest approach (value, margin, line), the collision "
         "check's closest body, the cycle time and the feeds slowed. The program goes to -o FILE.")
preview_option = click.option(
    "--preview", "preview_path", type=OutputPath(), metavar="OUT.png|OUT.svg",
    help="Also draw the program (as `prs3-post preview` does, on this part and face). "
         "Needs matplotlib: pip install 'prs3-post[plot]'.")


def job_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """The options of the main job (``run`` and ``demo``), grouped as ``--help`` shows them."""
    options = [
        # what to cut
        click.option("--profile", type=click.Choice(list(choices("profile"))), required=True,
                     help="Operation: hole (drill, optional pecking), square or round (groove or wall)."),
        click.option("--face", "face_choice", default=_OP["face"], show_default=True, metavar="auto|N",
                     help="Face to work on: auto = largest upward inclined face; N = index from `prs3-post faces`."),
        click.option("--at", "at_uv", type=Numbers("U,V"), multiple=True,
                     help="Feature position in face coordinates, mm (repeat for several holes). Default: face origin."),
        click.option("--at-xyz", "at_xyz", type=Numbers("X,Y,Z"), multiple=True,
                     help="Feature position in part coordinates, mm: a point on the face "
                          "(within 0.01 mm; repeatable)."),
        part_units_option(),
        up_option,
        # feature geometry
        click.option("--depth", type=Decimal(LENGTH), default=None,
                     help="Depth below the face along the tool axis, mm.  [default: 5 for hole, 2 for square/round]"),
        click.option("--peck", type=Decimal(LENGTH), default=_OP["peck"], show_default=True,
                     help="hole: peck depth, mm (0 = drill in one go); each peck retracts to --clearance."),
        click.option("--reapproach-gap", type=Decimal(LENGTH), default=_OP["reapproach_gap"], show_default=True,
                     help="hole: gap above the previous peck bottom where feed resumes, mm."),
        click.option("--dwell", type=Decimal(TIME), default=_OP["dwell"], show_default=True,
                     help="hole: dwell at the bottom, s."),
        click.option("--size", type=Decimal(LENGTH), default=_OP["size"],
                     show_default=True, help="square: side length, mm."),
        click.option("--corner-radius", type=Decimal(LENGTH), default=_OP["corner_radius"], show_default=True,
                     help="square: corner radius, mm."),
        click.option("--rotation", type=Decimal(ANGLE), default=_OP["rotation"], show_default=True,
                     help="square: rotation about the face normal from the down-slope direction u, degrees."),
        click.option("--diameter", type=Decimal(LENGTH), default=_OP["diameter"],
                     show_default=True, help="round: diameter, mm."),
        click.option("--side", type=click.Choice(list(choices("side"))), default=_OP["side"], show_default=True,
                     help="Tool centre on the outline (a groove), inside it or outside it "
                          "(offset by the tool radius)."),
        click.option("--step-down", type=Decimal(LENGTH), default=_OP["step_down"], show_default=True,
                     help="square/round: depth per pass, mm."),
        click.option("--direction", type=click.Choice(list(choices("direction"))), default=_OP["direction"],
                     show_default=True,
                     help="square/round: climb or conventional milling (spindle clockwise, M3)."),
        click.option("--entry", type=click.Choice(list(choices("entry"))), default=_OP["entry"], show_default=True,
                     help="square/round: how each pass enters the material."),
        click.option("--ramp-angle", type=Decimal(ANGLE), default=_OP["ramp_angle"], show_default=True,
                     help="Ramp entry angle, degrees."),
        click.option("--clearance", type=Decimal(LENGTH), default=_OP["clearance"], show_default=True,
                     help="Height above the face where rapids end and feeds begin, mm (along the tool axis)."),
        click.option("--retract", type=Decimal(LENGTH), default=_OP["retract"], show_default=True,
                     help="Safe height above the face between features, mm (along the tool axis)."),
        # tool and cutting data
        click.option("--tool-diameter", type=Decimal(LENGTH), default=DEFAULT_TOOL_DIAMETER, show_default=True,
                     help="Tool diameter, mm (0.01 to 500)."),
        click.option("--tool-number", type=Integer(), default=_OP["tool"], show_default=True,
                     help="Tool number (T word), 1 up to the dialect's words.tool_number_max (both shipped: 99999)."),
        click.option("--feed", type=Decimal(FEED, low=FEED_RANGE_MM_MIN[0]), default=_OP["feed"], show_default=True,
                     help="Cutting feed at the tool tip, mm/min."),
        click.option("--plunge-feed", type=Decimal(FEED, low=FEED_RANGE_MM_MIN[0]), default=_OP["plunge_feed"],
                     show_default=True,
                     help="Feed into the material (drilling, plunges, ramps), mm/min."),
        click.option("--spindle", type=Decimal(SPEED, low=SPINDLE_LOW), default=_OP["spindle"],
                     show_default=True,
                     help="Spindle speed, rpm (clockwise)."),
        click.option("--coolant", type=click.Choice(list(choices("coolant"))), default=_OP["coolant"],
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
        clamp_option,
        collision_check_option,
        click.option("--clearance-min", type=CLEARANCE_MIN, default=_SET["clearance_min"], show_default=True,
                     help="Least distance the tool, holder and spindle nose keep from the part, mm."),
        click.option("-o", "--output", "out_path", type=OutputPath(),
                     help="Program file (written to a temp file, then renamed). Default: standard output."),
        preview_option,
    ]
    for option in reversed(options):
        func = option(func)
    return func


#: The main job's option of each request key whose name differs (``--tool-number`` is ``tool``).
_OPTION_OF = {"face": "face_choice", "at": "at_uv", "tool": "tool_number", "machine": "machine_name",
              "dialect": "dialect_name"}
def request_data(part: str, opts: dict[str, Any], *, given: tuple[str, ...] = ()) -> dict[str, Any]:
    """The main job's options as a request's plain data (shaped as a job file: settings, ``setup``, one
    ``operation``): the values of the keys the profile uses, and of any other option in ``given`` (the
    options the user gave: the request refuses those the profile does not use)."""
    profile = opts["profile"]
    operation: dict[str, Any] = {}
    data: dict[str, Any] = {"part": part}
    for key, field in OPERATION_FIELDS.items():
        name = _OPTION_OF.get(key, key)
        value = opts.get(name)
        if value is None or (field.points and not value) or not (used_by(profile, key) or name in given):
            continue
        operation[key] = [list(point) for point in value] if field.points else value
    for key in SETTING_FIELDS:
        value = opts.get(_OPTION_OF.get(key, key))
        if value is not None:
            data[key] = value
    data["setup"] = {"part_origin": opts.get("part_origin"), "part_rotation_deg": opts.get("part_rotation")}
    data["operation"] = [operation]
    return data


def job_specs_of(part: str, opts: dict[str, Any], *, given: tuple[str, ...] = ()) -> tuple[JobSpec, ...]:
    """The JobSpec the main job's options describe (also rebuilt by `verify --against PART.stl`)."""
    try:
        return job_specs(job_request(request_data(part, opts, given=given)))
    except FieldError as error:
        raise option_error(error) from error


def job_spec(part: str, opts: dict[str, Any]) -> JobSpec:
    """:func:`job_specs_of` of the options of one operation (none refused: those its profile does not use are
    left out)."""
    return job_specs_of(part, opts)[0]


def given_options() -> tuple[str, ...]:
    """The options of the current command the user gave (not their defaults)."""
    ctx = click.get_current_context()
    return tuple(name for name in ctx.params if was_given(ctx, name))


def _placement_hint(origin: tuple[str, str, str] | None) -> str:
    """The library's suggestion for a job that does not fit its setup, as the options to give."""
    if origin is None:
        return ("set by --part-origin X,Y,Z and --part-rotation DEG, or let --part-origin auto --part-rotation "
                "auto search them")
    return f"--part-origin={','.join(origin)}"


def _run_job(part: str, **opts: Any) -> int:
    """Build the request from the options, check the job, write the program (and its preview)."""
    from prs3_post.app.run import check_specs  # the job's modules: only the commands that run one

    out_path, as_json = opts["out_path"], opts["as_json"]
    _refuse_json_to_stdout(as_json, out_path)
    with timed("options, machine and dialect"):
        specs = job_specs_of(part, opts, given=given_options())
    fmt = image_format(opts["preview_path"], "'--preview'") if opts["preview_path"] else None
    if fmt is not None:
        from prs3_post.app.preview import require_plotting

        require_plotting()
    with timed("post and check"):
        job = check_specs(specs, placement_hint=_placement_hint, margins=as_json)
    _write_job(job, specs, out_path, opts["preview_path"], fmt, title=Path(part).name, what=f"; {job.face_note}",
               as_json=as_json)
    return 0


def _refuse_json_to_stdout(as_json: bool, out_path: str | None) -> None:
    """``--json`` takes standard output: the program must go to a file."""
    if as_json and is_stdout(out_path):
        raise click.UsageError("--json prints its report on standard output: write the program to a file "
                               "with -o FILE")


def _write_job(job: JobProgram, specs: tuple[JobSpec, ...], out_path: str | None, preview_path: str | None,
               fmt: str | None, *, title: str, what: str, as_json: bool = False) -> None:
    """Write the checked job's program (and its preview, drawn first: no half results) and say what was
    written; ``what`` ends the summary line (the main job's face, a job file's operation count).
    ``as_json``: then print the JSON record of what was written (:func:`~prs3_post.app.run.job_json`)."""
    from prs3_post.app.run import job_json, job_preview

    text = _ProgramText(job, whole=as_json or fmt is not None or not _streamable(out_path))
    image = None
    if fmt is not None:
        with timed("preview"):
            image = job_preview(job, specs, fmt, text=text.whole, path=out_path or "<program>", title=title)
    with timed("write"):
        write_outputs([(out_path, text.data())] + ([] if image is None else [(preview_path, image)]))
    _report_placement(job)
    _report_details(job, specs)
    if not is_stdout(out_path):
        say(f"wrote {out_path}: {text.lines} lines, {len(job.program)} moves{what}")
        if specs[0].machine.dynamics is not None:
            say(job.dynamics)
    if image is not None:
        say(f"wrote {preview_path}")
    if as_json:
        click.echo(job_json(job, specs, str(out_path), text.whole))


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
        say(f"setup: {job.setup.describe()}; {job.placement.describe()}")


#: The header's entries that ``-v`` repeats on standard error (the setup: when it was not chosen automatically).
_DETAILED = ("machine", "part", "face", "faces", "setup", "tool", "tools", "tolerance", "collision")


def _report_details(job: JobProgram, specs: tuple[JobSpec, ...]) -> None:
    """With ``-v``: what the program was made with, as its header states it (machine, part, face, setup, tools,
    tolerance, the clearance from the part), and the tool lengths the IK used."""
    for key, value in job.header:
        if key in _DETAILED and not (key == "setup" and job.placement is not None):
            detail(f"{key}: {value}")
    lengths = ", ".join(f"T{spec.cutting.tool_number} {length:.3f} mm" for spec, length in
                        zip(specs, job.tool_lengths, strict=True))
    detail(f"tool length{'s' if len(specs) > 1 else ''} (platform centre to tip, for the IK): {lengths}")


@click.command(cls=Command, aliases=PART_UNITS_ALIAS)
@click.argument("part", type=click.Path(dir_okay=False), metavar="PART.stl")
@job_options
@verbosity_options
@json_option
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


@click.command(cls=Command, aliases=PART_UNITS_ALIAS)
@job_options
@verbosity_options
@json_option
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


def job_file_key(error: FieldError) -> str:
    """Where in a job file a request's error is: ``operation[2].depth``, ``tolerance``, ``setup.part_origin``."""
    return error.field if error.operation is None else f"operation[{error.operation}].{error.field}"


def _job_specs(job: JobFile, overrides: dict[str, Any] | None = None) -> tuple[JobSpec, ...]:
    """Each operation of a job file as its JobSpec (the defaults, then the file's settings and the
    command line's ``overrides`` (a request's keys), then each operation's keys)."""
    data = job.as_data()
    for key, value in (overrides or {}).items():
        if key.startswith("setup."):
            data["setup"][key.removeprefix("setup.")] = value
        else:
            data[key] = value
    try:
        return job_specs(job_request(data))
    except UnusedFields as error:
        raise InputError(f"operation[{error.operation}]: {error}: remove {'it' if len(error.keys) == 1 else 'them'}",
                         path=job.path) from error
    except FieldError as error:
        raise InputError(f"{job_file_key(error)}: {error}", path=job.path) from error
    except FeatureError as error:                  # its keys, as the job file spells them
        where = "" if error.operation is None else f"operation[{error.operation}]"
        raise InputError(f"{where}: {error!s}" if where else str(error),
                         path=job.path) from error


#: The main job's options that `job` takes too (they replace the job file's): option name → request key.
_JOB_OVERRIDES = {"machine_name": "machine", "dialect_name": "dialect", "part_origin": "setup.part_origin",
                  "part_rotation": "setup.part_rotation_deg", "collision_check": "collision_check", "units": "units"}


@click.command(cls=Command)
@click.argument("job_path", type=click.Path(dir_okay=False), metavar="JOB.toml")
@click.option("-o", "--output", "out_path", type=OutputPath(),
              help="Program file (written to a temp file, then renamed). Default: standard output.")
@machine_option
@job_part_origin_option
@job_part_rotation_option
@dialect_option
@part_units_option("Length unit of the job file's part (replaces its units).  [default: the job file's, else mm]",
                   default=None)
@collision_check_option
@preview_option
@verbosity_options
@json_option
def job(job_path: str, out_path: str | None, machine_name: str, part_origin: tuple[float, ...] | str | None,
        part_rotation: float | str | None, dialect_name: str, units: str, collision_check: bool,
        preview_path: str | None, as_json: bool) -> None:
    """Run a job file: several operations on one part, on one or more faces, with one or more tools.

    JOB.toml names the part (part, units, up), the setup ([setup] part_origin, part_rotation_deg),
    a tool table (tool_table, LinuxCNC format) and one [[operation]] table per operation, in order:
    profile, face, tool and the main job's options with _ for - (at, depth, step_down, side ...).
    Paths are relative to the job file. One program: between operations the tool rises along its
    axis to a safe height above the part, the spindle and coolant stop, the tool changes where it
    changes, the axis turns at that height (checked like any move) and the tool goes to the next face.
    Each operation's IK uses its tool's length (the machine's gauge offset plus the table's Z).
    --machine, --dialect, --part-origin, --part-rotation, --part-units and --no-collision-check
    replace what the job file says.

    \b
    Example:
      prs3-post job fixtures/jobs/example.toml -o example.ngc
    """

    def body() -> int:
        from prs3_post.app.run import check_specs, read_job

        ctx = click.get_current_context()
        _refuse_json_to_stdout(as_json, out_path)
        job_file = read_job(job_path)
        named = {"part": job_file.part} | {key: job_file.settings.get(key)
                                            for key in ("tool_table", "machine", "dialect")}
        refuse_overwriting({"--output": out_path}, {f"{key} of {job_path}": path for key, path in named.items()
                                                    if isinstance(path, str)})
        overrides = {key: ctx.params[name] for name, key in _JOB_OVERRIDES.items() if was_given(ctx, name)}
        with timed("options, machine and dialect"):
            specs = _job_specs(job_file, overrides)
        fmt = image_format(preview_path, "'--preview'") if preview_path else None
        if fmt is not None:
            from prs3_post.app.preview import require_plotting

            require_plotting()
        try:
            with timed("post and check"):
                job = check_specs(specs, margins=as_json)
        except FeatureError as error:                  # the job file, the operation and its key
            where = "" if error.operation is None else f"operation[{error.operation}]"
            where += f".{error.key}" if where and error.key else ""
            raise InputError(f"{where}: {error!s}" if where else str(error),
                             path=job_path) from error
        _write_job(job, specs, out_path, preview_path, fmt, title=Path(job_file.part).name,
                   what=f", {len(specs)} operations", as_json=as_json)
        return 0

    run_reported(body)

