"""`verify` (replay a program and check it) and `preview` (draw it)."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click

from prs3_post.app.requests import AUTO, OPERATION_FIELDS, SETTING_FIELDS
from prs3_post.app.values import ANGLE, FEED
from prs3_post.cli.options import (
    DEPRECATED,
    PART_UNITS_ALIAS,
    QUIET,
    Command,
    Decimal,
    OutputPath,
    detail,
    face_index,
    flag_of,
    image_format,
    machine_option,
    note,
    option_error,
    part_origin_option,
    part_rotation_option,
    part_units_option,
    run_reported,
    say,
    timed,
    up_option,
    verbosity,
    verbosity_options,
    was_given,
)
from prs3_post.cli.progress import ProgressBar
from prs3_post.cli.run import given_options, job_options, job_specs_of
from prs3_post.core.defaults import (
    DEFAULT_ANGLE_TOLERANCE_DEG,
    NOMINAL_RAPID_RATE,
)
from prs3_post.core.errors import FieldError, InputError
from prs3_post.core.output_files import (
    write_atomic,
)

# What only some commands need is imported where it is used (the main job, convert, verify, preview,
# faces: each about 0.1 s of imports), so that `ik`, `fk` and a small `verify` start fast.
if TYPE_CHECKING:
    from prs3_post.app.verify import CamPart, Intended, ProgramContext, ProgramSetting, RebuiltJob

#: What _open_program opens: the whole program, or only what it was made for.
_Opened = TypeVar("_Opened", "ProgramContext", "ProgramSetting")


def _against_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """The main job's options, for `verify --part PART.stl` to rebuild the intended path with:
    the same options and defaults, but --profile not required and without the output-only ones (a
    program with a prs3-post header needs none of them: they may only repeat what it says)."""
    probe = job_options(lambda **_: None)
    skip = {"out_path", "preview_path", "line_numbers", "line_start", "line_step", "tool_table"}
    params = getattr(func, "__click_params__", [])
    borrowed: list[click.Parameter] = probe.__click_params__  # type: ignore[attr-defined]  # click stores them here
    for param in borrowed:                           # in click's stored (reversed) order
        if param.name in skip:
            continue
        if param.name == "profile":
            param.required = False
            param.help = "Operation the program was made with (only with --part PART.stl)."
        if param.name == "tolerance":
            param.help = ("Allowed tip deviation, mm (0.0001 to 1; plus the output rounding against a path); also "
                          "the chordal tolerance the job is rebuilt with for --part PART.stl.")
        params.append(param)
    func.__click_params__ = params                   # type: ignore[attr-defined]
    return func


#: The main job's options that describe the operation: `verify` uses them only with --part PART.stl.
_OPERATION_OPTIONS = (
    "profile", "face_choice", "at_uv", "at_xyz", "units", "up", "depth", "peck", "reapproach_gap", "dwell", "size",
    "corner_radius", "rotation", "diameter", "side", "step_down", "direction", "entry", "ramp_angle", "clearance",
    "retract", "tool_diameter", "tool_number", "feed", "plunge_feed", "spindle", "coolant",
)


def _option_flags(ctx: click.Context, names: list[str]) -> list[str]:
    """The flags as the user spells them (``--face`` for the parameter ``face_choice``)."""
    flags = {f"--{p.name.replace('_', '-')}": p.opts[0] for p in ctx.command.params if p.name}
    return [flags.get(name, name) for name in names]


#: The flag of each value a program header records, for messages about a contradiction.
_HEADER_FLAGS = {"machine": "--machine", "dialect": "--dialect", "part origin": "--part-origin",
                 "part rotation": "--part-rotation", "part": "--part"}


def _open_program(ctx: click.Context, path: str, machine_name: str, dialect_name: str,
                  part_origin: tuple[float, ...] | None, part_rotation: float | None,
                  opener: Callable[..., _Opened]) -> _Opened:
    """The program (``open_program``), or its setting only (``open_setting``), with the machine, dialect and setup
    of its header, or those given."""
    from prs3_post.app.verify import HeaderConflict

    _refuse_auto(part_origin, part_rotation)
    try:
        return opener(path, machine=machine_name if was_given(ctx, "machine_name") else None,
                      dialect=dialect_name if was_given(ctx, "dialect_name") else None,
                      origin=part_origin, rotation_deg=part_rotation)
    except FieldError as error:
        raise option_error(error) from error
    except HeaderConflict as error:
        raise InputError(f"{_HEADER_FLAGS[error.what]}: {error.args[0]}", path=error.path, line=error.line) from error


def _bar_shown() -> bool | None:
    """A progress bar is drawn on a terminal (None: if standard error is one), never with -q."""
    return None if verbosity() > QUIET else False


def _refuse_auto(part_origin: tuple[float, ...] | str | None, part_rotation: float | str | None) -> None:
    """``auto`` chooses a setup when a program is made: reading one, it is a usage error."""
    for value, flag in ((part_origin, "--part-origin"), (part_rotation, "--part-rotation")):
        if value == AUTO:
            raise click.BadParameter("auto chooses the setup when a program is made; a program is read with the "
                                     "setup its header states (or the one given as numbers)", param_hint=f"'{flag}'")


def _refuse_cl_file(path: str, dialect_given: bool = False) -> None:
    """CAM output given where a program for this machine goes (verify, preview): say so, not 'not G-code'.
    Only a file that starts as an APT CL file, or (with the default dialect, whose axes have no A, B or C)
    header-less G-code with rotary words, does; any other problem is the program reader's to name."""
    from prs3_post.app.verify_inputs import is_cl_file, is_five_axis_cam

    if is_cl_file(path):
        raise InputError(f"an APT CL file (CAM output), not a program for this machine: convert it first "
                         f"(prs3-post convert {path} -o PROGRAM.ngc), then give the program, with --against {path} to "
                         "compare them", path=path)
    if not dialect_given and is_five_axis_cam(path):
        raise InputError(f"5-axis CAM output (it turns rotary axes: A, B or C words), not a program for this "
                         f"machine: convert it first with the source machine it was written for (prs3-post convert "
                         f"{path} --source NAME -o PROGRAM.ngc; prs3-post sources lists them), then give the program, "
                         f"with --against {path} to compare them", path=path)


#: The operation's keys a program's header records, in the order a contradiction names them.
_HEADER_KEYS = (*tuple(OPERATION_FIELDS)[:4], "units", "up", *tuple(OPERATION_FIELDS)[4:])
#: The main job's option of each request key whose name differs.
_OPTION_OF = {"face": "face_choice", "at": "at_uv", "tool": "tool_number"}


def _given_values(ctx: click.Context, opts: dict[str, Any], keys: tuple[str, ...]) -> dict[str, Any]:
    """The values of the request ``keys`` whose options were given (not defaults), a face index checked."""
    given = {key: opts[_OPTION_OF.get(key, key)] for key in keys if was_given(ctx, _OPTION_OF.get(key, key))}
    if "face" in given:
        face_index(given["face"])
    return given


def _refuse_header_contradictions(wrong: list[tuple[str, Any]]) -> None:
    """The options given that say otherwise than the program's header: a usage error naming each."""
    _refuse_contradictions([f"{flag_of(key)} (header: {shown})" for key, shown in wrong])


def _refuse_contradictions(wrong: list[str]) -> None:
    """A usage error for options that say otherwise than the program's header (``--depth (header: 5)``)."""
    if len(wrong) == 1:
        raise click.UsageError(f"{wrong[0]}: contradicts the program's header; leave it out to use the header's value")
    if wrong:
        raise click.UsageError(f"{', '.join(wrong)}: contradict the program's header; leave them out to use the "
                               "header's values")


def _intended(ctx: click.Context, against: str | None, part: str | None, context: ProgramContext,
              opts: dict[str, Any]) -> tuple[Intended | None, RebuiltJob | CamPart | None]:
    """The intended path of `verify --part PART.stl`: the job rebuilt from PART.stl and the program's header
    (or, without a header, the options), with that job (for the clearance from the part); or of
    `verify --against POSES.csv`; for a converted program, its CAM input (--against) and its part
    (--part: the clearance only, the path is the CAM input's), either or both."""
    from prs3_post.app.verify import (
        HeaderConflict,
        header_job,
        intended_from_poses,
        intended_from_source,
        rebuild_job,
    )
    from prs3_post.app.verify_inputs import cam_part, is_converted, spec_contradictions

    if is_converted(context.header):                         # a converted program: its CAM source, its part
        try:
            source = intended_from_source(context, against) if against is not None else None
        except HeaderConflict as error:
            raise InputError(f"--against: {error.args[0]}", path=error.path, line=error.line) from error
        return source, None if part is None else cam_part(context, part, units=opts["units"], up=opts["up"])
    if part is not None and against is not None:
        raise click.UsageError(f"--part {part} rebuilds the path the program was made for; --against {against} "
                               "gives another: give one of them (both only for a program converted from CAM output)")
    if part is not None:
        if context.header is not None:
            try:
                specs = header_job(context, part)
            except HeaderConflict as error:
                raise InputError(f"--part: {error.args[0]}", path=error.path, line=error.line) from error
            given = _given_values(ctx, opts, _HEADER_KEYS)
            for spec in specs:                         # an option given must be what every operation says
                _refuse_header_contradictions(spec_contradictions(spec, given))
            rebuilt = rebuild_job(specs)
        elif not opts["profile"]:
            raise click.UsageError("--part PART.stl needs --profile and the other operation options the "
                                   "program was made with (it has no prs3-post header that records them)")
        else:
            rebuilt = rebuild_job(job_specs_of(part, opts, given=given_options())[0])
        return rebuilt.intended, rebuilt
    assert against is not None                               # (verify asks for an intended path only with one)
    if Path(against).suffix.lower() == ".csv":
        return intended_from_poses(against, context.program), None
    raise InputError("--against takes POSES.csv (one pose per motion line) or the CAM file a program was converted "
                     "from (its header names it); the part the program was made from is --part PART.stl",
                     path=against)


@click.command(cls=Command, aliases=PART_UNITS_ALIAS)
@click.argument("program_path", type=click.Path(dir_okay=False), metavar="PROGRAM.ngc")
@click.option("--part", "part_path", type=click.Path(dir_okay=False), metavar="PART.stl",
              help="The part the program was made from: the operation is rebuilt from the program's header (a "
                   "program without one needs the options it was made with: --profile, --at, --depth, ...) as the "
                   "intended path, and the clearance from the part is measured; for a program made by "
                   "`prs3-post convert`, the clearance only.")
@click.option("--against", "against_path", type=click.Path(dir_okay=False), metavar="POSES.csv|INPUT",
              help="The intended path: POSES.csv (the `ik --batch` format, machine frame, one pose per G0/G1 line), "
                   "or for a program made by `prs3-post convert` its CAM input (APT CL or G-code; checked by the "
                   "SHA-256 its header records).")
@click.option("--axis-tolerance", "axis_tolerance_deg", type=Decimal(ANGLE), default=DEFAULT_ANGLE_TOLERANCE_DEG,
              show_default=True,
              help="Allowed tool-axis deviation from the --against path, degrees.")
@click.option("--json", "as_json", is_flag=True,
              help="Print the complete report as JSON: every move, the FK tool-tip path in part coordinates, "
                   "every limit's closest approach, feeds, deviations, problems.")
@click.option("--cross-check", "cross_check", is_flag=True,
              help="Read the program a second time with pygcode (a G-code library we did not write) and report "
                   "every word and move the two readings disagree on (file:line, both readings); any "
                   "disagreement fails the verify. Slow: about 140 CPU s per million lines.")
@_against_options
@verbosity_options
def verify(program_path: str, part_path: str | None, against_path: str | None, axis_tolerance_deg: float,
           as_json: bool, cross_check: bool, **opts: Any) -> None:
    """Replay a program through forward kinematics and check it: limits, straightness, feeds, deviation.

    Reads PROGRAM.ngc in --dialect (letters, decimals, comments), samples every move in joint
    space as the controller interpolates it (X, Y, T1..T3 linear; at least 8 samples per move,
    more where the tip path or a link angle curves, so that what falls between samples is below
    --tolerance / 20) and checks every sample:

    \b
    - limits: the closest approach to each limit of --machine (value, margin, line);
    - straightness: a G1's tip stays within --tolerance of the line between its end points;
    - feeds: implied tip feed = chord × F (G93, F = 1/min); with --part it must equal the
      intended feed within the rounding of F and the points; otherwise a G1 whose feed matches
      no other G1 is warned about (a hand edit?), except in a converted program (the CAM's feeds);
    - with --part or --against: tip and axis deviation from the intended path (max, mean, line);
      allowed: --tolerance plus what the output rounding moves the tip, and --axis-tolerance;
    - with --part: the clearance of the tool, holder and spindle nose from the part.

    A program made by prs3-post states in its header the machine, dialect, setup and operation it
    was made with: they are used, and an option that says otherwise is an error (leave it out).
    A program without that header is read with the options given (or their defaults).

    --cross-check: pygcode reads every line again, and its words, motion modes, positions and
    feeds are compared with ours (any difference fails the verify; "cross-check: N lines read by
    pygcode, 0 disagreements" when there is none). It is slow: pygcode reads about 7,000 lines
    per CPU second, so a 1,000,000-line program takes about 140 CPU s against 2 s for a plain
    verify, a 1,357-line golden program 0.46 s against 0.27 s.

    --tolerance (mm; default: the program's, else 0.002) is the allowed tip deviation. The
    operation options (--profile ... --retract) are used only with --part PART.stl, and only
    for a program without a header. Exit status: 0 within every limit and
    tolerance, 1 if not, 2 for a program or option it cannot read.

    \b
    Examples:
      prs3-post demo --profile square -o sq.ngc
      prs3-post verify sq.ngc
      prs3-post verify sq.ngc --part postproc/parts/patel2020-wedge.stl --json
      prs3-post verify paper_2a_2b.ngc --against paper_2a_2b.csv
    """
    from prs3_post.app.verify import HeaderConflict, require_tolerance, verify_steps
    from prs3_post.app.verify_report import report_record, report_text

    if TYPE_CHECKING:
        from prs3_post.app.cross_check import CrossCheck
    checked: list[CrossCheck] = []

    def told(found: CrossCheck) -> None:
        """The cross-check, told before the program is verified (a refusal of our reader comes after it)."""
        checked.append(found)
        if not as_json:
            click.echo(found.text(), nl=False)

    def body() -> int:
        ctx = click.get_current_context()
        part, against = _part_and_against(part_path, against_path)
        _refuse_cl_file(program_path, was_given(ctx, "dialect_name"))
        require_tolerance(opts["tolerance"])
        if not (math.isfinite(axis_tolerance_deg) and axis_tolerance_deg >= 0):
            raise click.BadParameter(f"must be a number ≥ 0 degrees, got {axis_tolerance_deg:g}",
                                     param_hint="'--axis-tolerance'")
        if part is None:
            given = [f"--{name.replace('_', '-')}" for name in (*_OPERATION_OPTIONS, "collision_check", "clearance_min")
                     if was_given(ctx, name)]
            if given:
                raise click.UsageError(f"{', '.join(_option_flags(ctx, given))}: the operation options are only "
                                       "used with --part PART.stl")
        _refuse_auto(opts["part_origin"], opts["part_rotation"])
        bar = ProgressBar("verifying", enabled=_bar_shown())   # bytes read, or rows replayed (on a terminal only)
        try:
            with timed("read and replay" + (" and the clearance" if part is not None else "")):
                verified = verify_steps(
                    program_path, machine=opts["machine_name"] if was_given(ctx, "machine_name") else None,
                    dialect=opts["dialect_name"] if was_given(ctx, "dialect_name") else None,
                    origin=opts["part_origin"], rotation_deg=opts["part_rotation"],
                    tolerance=opts["tolerance"] if was_given(ctx, "tolerance") else None,
                    axis_tolerance_deg=axis_tolerance_deg, whole=as_json,
                    intended_of=((lambda context: _intended(ctx, against, part, context, opts))
                                 if against or part else None),
                    collision_check=opts["collision_check"],
                    clearance_min=opts["clearance_min"] if was_given(ctx, "clearance_min") else None,
                    on_cross_check=told if cross_check else None, progress=bar)
        except FieldError as error:
            raise option_error(error) from error
        except HeaderConflict as error:
            raise InputError(f"{_HEADER_FLAGS[error.what]}: {error.args[0]}", path=error.path,
                             line=error.line) from error
        finally:
            bar.close()
        report, setting, clearance = verified.report, verified.setting, verified.clearance
        _report_setting(setting.header is not None, setting.machine.name, setting.dialect.name,
                        setting.setup.describe())
        dialect = setting.dialect.name
        crossed = checked[0] if checked else None
        agreed = crossed is None or crossed.ok
        if as_json:
            record = report_record(report, path=program_path, dialect=dialect, rapid_rate=NOMINAL_RAPID_RATE,
                                   clearance=clearance)
            record["ok"] = report.ok and agreed
            record["cross_check"] = None if crossed is None else crossed.record()
            click.echo(json.dumps(record, allow_nan=False))
        else:
            click.echo(report_text(report, path=program_path, dialect=dialect, rapid_rate=NOMINAL_RAPID_RATE,
                                   clearance=clearance, all_listed="--json lists all"), nl=False)
            if crossed is not None and not crossed.ok:
                plural = "s" if crossed.count > 1 else ""
                click.echo(f"FAIL: cross-check: {crossed.count} disagreement{plural} with pygcode (listed above)")
        return 0 if report.ok and agreed else 1

    run_reported(body)


def _report_setting(header: bool, machine: str, dialect: str, setup: str) -> None:
    """With ``-v``: the machine, dialect and setup a program was read with, and where they came from."""
    origin = "as the program's header states them" if header else "as given, or the defaults"
    detail(f"read with machine {machine}, dialect {dialect} ({origin}); setup: {setup}")


def _part_and_against(part: str | None, against: str | None) -> tuple[str | None, str | None]:
    """``--part`` and ``--against``, with ``--against PART.stl`` (the old spelling) read as ``--part``."""
    if against is None or Path(against).suffix.lower() != ".stl":
        return part, against
    if part is not None:
        raise click.UsageError(f"--against {against} is the old spelling of --part, and --part {part} is given: "
                               "give the part once, as --part")
    note(DEPRECATED.format(old="--against PART.stl", new="--part PART.stl"))
    return against, None


@click.command(cls=Command, aliases=PART_UNITS_ALIAS)
@click.argument("program_path", type=click.Path(dir_okay=False), metavar="PROGRAM.ngc")
@click.option("-o", "--output", "out_path", type=OutputPath(), required=True,
              metavar="OUT.png|OUT.svg|OUT.html",
              help="Image file (PNG or SVG), or the interactive HTML view, by suffix; written to a temp file, "
                   "then renamed.")
@click.option("--part", "part_path", type=click.Path(dir_okay=False), metavar="PART.stl",
              help="Draw the part (part coordinates) and highlight its face (--face). Without it, the part a "
                   "program's header names is found by itself (beside the program, here, or shipped). A main "
                   "job's program: the part it was made from (SHA-256); a converted program, or one without a "
                   "header: any part, drawn at the program's setup, no face unless --face (a converted one: with "
                   "the holder's closest approach as verify --part measures it).")
@click.option("--face", "face_choice", default="auto", show_default=True, metavar="auto|N",
              help="Face to highlight: auto = the main job's automatic choice; N = index from `prs3-post faces`.")
@part_units_option("Length unit of the --part STL.")
@up_option
@machine_option
@click.option("--dialect", "dialect_name", default=SETTING_FIELDS["dialect"].default, show_default=True,
              metavar="NAME|PATH",
              help="G-code dialect of the program: linuxcnc, fanuc, or a dialect TOML file.")
@part_origin_option
@part_rotation_option
@click.option("--rapid-rate", type=Decimal(FEED, low=0.0, low_open=True), default=NOMINAL_RAPID_RATE, show_default=True,
              help="Joint-space rate of G0 moves for the time axis, mm/min (the longest joint travel at this rate), "
                   "for a machine without [dynamics]; with them the axis shows the cycle time.")
@verbosity_options
def preview(program_path: str, out_path: str, part_path: str | None, face_choice: str, units: str, up: str,
            machine_name: str, dialect_name: str, part_origin: tuple[float, ...] | None, part_rotation: float | None,
            rapid_rate: float) -> None:
    """Draw a program: the machine at its worst pose, the FK tool path on the part, every limit over time.

    One figure: (a) the machine (base, rails, sliders, links, platform, spindle, holder, tool) at the
    sample with the smallest margin to any limit, with the part at its setup; (b) 3D view in part
    coordinates of the part mesh (--part, else the part the header names when it is beside the program,
    here or among the shipped parts), each operation's face and the tool-tip path replayed
    through forward kinematics in the operation's colour (G1 solid, G0 dashed); (c)-(g) the strokes,
    stage X, Y, tilt, link angles and axis speeds over program time (the cycle time of the
    machine's [dynamics]; without them G1: 1/F min, G0: the longest joint travel at --rapid-rate),
    each limit a red line in view, operations and tool changes marked with their lines; (h) the
    worst margin of every limit as a fraction of its range. Needs matplotlib: pip install 'prs3-post[plot]'.
    The machine, dialect and setup (and the part's units, up axis and faces) come from the program's
    header when it has one; an option that says otherwise is an error.
    `prs3-post PART.stl ... --preview OUT.png` makes a program and its picture in one step.

    -o OUT.html writes one self-contained page instead (plotly embedded: it opens offline, by
    double-click): the machine drawn by forward kinematics at the slider's line over the part, its
    faces and the tool path by operation, a play button, and every limit over time with its bounds.
    Needs plotly: pip install 'prs3-post[plot]'. A long program is decimated (the extremes kept).

    \b
    Examples:
      prs3-post demo --profile square -o sq.ngc
      prs3-post preview sq.ngc --part postproc/parts/patel2020-wedge.stl -o sq.png
      prs3-post preview sq.ngc -o sq.html
      prs3-post demo --profile round -o round.ngc --preview round.svg
    """
    from prs3_post.app.preview import HeaderContradiction, preview_bytes, preview_part_of, require_plotting
    from prs3_post.app.preview_html import PREVIEW_SUFFIXES, require_view, view_html, view_part
    from prs3_post.app.verify import HeaderConflict, open_program, tool_lengths_of

    def body() -> int:
        ctx = click.get_current_context()
        fmt = image_format(out_path, "'-o' / '--output'", tuple(PREVIEW_SUFFIXES), what="preview")
        html = fmt == "html"
        require_view() if html else require_plotting()
        _refuse_cl_file(program_path, was_given(ctx, "dialect_name"))
        with timed("read"):
            context = _open_program(ctx, program_path, machine_name, dialect_name, part_origin, part_rotation,
                                    open_program)
        _report_setting(context.header is not None, context.machine.name, context.dialect.name,
                        context.setup.describe())
        if context.machine.dynamics is not None and was_given(ctx, "rapid_rate"):
            raise click.BadParameter(f"machine {context.machine.name} has [dynamics]: the time axis shows its cycle "
                                     "time (each axis's top speed); leave it out", param_hint="'--rapid-rate'")
        given = _given_values(ctx, {"face_choice": face_choice, "units": units, "up": up}, ("face", "units", "up"))
        with timed("the part"):
            try:
                drawn = preview_part_of(context, part_path, face=face_index(face_choice), units=units, up=up,
                                        given=given, html=html)
            except HeaderConflict as error:
                raise InputError(f"--part: {error.args[0]}", path=error.path, line=error.line) from error
            except HeaderContradiction as error:
                _refuse_header_contradictions(error.wrong)
                raise
        part, mesh, faces, rebuilt = drawn.path, drawn.mesh, drawn.faces, drawn.against
        if drawn.from_header:
            detail(f"the part: {part} (the header's)")
        elif drawn.named:
            note(f"the part the header names ({drawn.named}) is not beside the program, here or among the shipped "
                 f"parts: the {'view' if html else 'picture'} has no part (give it with --part)")
        if html:
            with timed("replay and draw"), ProgressBar("replaying", after="drawing", enabled=_bar_shown()) as bar:
                page = view_html(context.program, context.machine, context.setup, dialect=context.dialect,
                                 header=context.header,
                                 part=None if mesh is None else view_part(mesh, faces[0] if faces else None, rebuilt),
                                 rapid_rate=rapid_rate, tool_lengths=tool_lengths_of(context.header), rebuilt=rebuilt,
                                 progress=bar)
            write_atomic(out_path, page)
            say(f"wrote {out_path}")
            return 0
        with timed("replay and draw"), ProgressBar("replaying", after="drawing", enabled=_bar_shown()) as bar:
            image = preview_bytes(context.program, context.machine, context.setup, fmt, dialect=context.dialect,
                                  mesh=mesh, faces=faces, rapid_rate=rapid_rate, header=context.header,
                                  tool_lengths=tool_lengths_of(context.header),
                                  title=Path(part).name if part else "", rebuilt=rebuilt, progress=bar)
        write_atomic(out_path, image)
        say(f"wrote {out_path}")
        return 0

    run_reported(body)

