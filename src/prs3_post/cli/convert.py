"""`convert`: CAM output (APT CL files, 3+2 and 5-axis G-code) into programs for this machine."""

from __future__ import annotations

import dataclasses
import json
import os
import re
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import click

from prs3_post.app.requests import AUTO
from prs3_post.app.values import ANGLE, LENGTH
from prs3_post.cli.options import (
    CLEARANCE_MIN,
    DEPRECATED,
    NORMAL,
    Command,
    Decimal,
    Integer,
    LazyChoice,
    OutputPath,
    clamp_option,
    detail,
    dialect_option,
    flag_of,
    job_part_origin_option,
    job_part_rotation_option,
    line_number_options,
    machine_option,
    note,
    option_error,
    run_reported,
    say,
    tolerance_option,
    up_option,
    verbosity,
    verbosity_options,
    was_given,
)
from prs3_post.cli.progress import ProgressBar
from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE_DEG, DEFAULT_CLEARANCE_MIN
from prs3_post.core.errors import FieldError, quoted, spelled
from prs3_post.core.lexer import code_name
from prs3_post.core.output_files import (
    check_writable,
    refuse_overwriting,
    write_atomic,
)

# What only some commands need is imported where it is used (the main job, convert, verify, preview,
# faces: each about 0.1 s of imports), so that `ik`, `fk` and a small `verify` start fast; so is the
# reader registry (--format's choices, convert's settings).
if TYPE_CHECKING:
    from prs3_post.app.batch import BatchResult, FileOutcome
    from prs3_post.core.types import Progress


def _input_formats() -> tuple[str, ...]:
    """``--format``'s choices: ``auto`` and the registered readers' names."""
    from prs3_post.app.convert_files import INPUT_FORMATS

    return INPUT_FORMATS


def _codes_option(text: str | None, flag: str) -> tuple[str, ...] | None:
    """``G43.4,M428`` → ``("G43.4", "M428")`` (as :func:`~prs3_post.core.lexer.code_name` writes them)."""
    if text is None:
        return None
    codes = []
    for item in text.split(","):
        match = re.fullmatch(r"\s*([GgMm])([0-9]+(?:\.[0-9]+)?)\s*", item)
        if match is None:
            raise click.BadParameter(f"expected G or M codes separated by commas (e.g. G43.4,M428), got {quoted(text)}",
                                     param_hint=f"'{flag}'")
        codes.append(code_name(match[1].upper(), float(match[2])))
    return tuple(codes)


@click.command(cls=Command, aliases={"--units": "--cl-units"})
@click.argument("inputs", nargs=-1, required=True, metavar="INPUT...")
@click.option("-d", "--output-dir", "outdir", type=click.Path(file_okay=False), default=None, metavar="DIR",
              help="Folder for the programs, one per input: DIR/<input stem><dialect extension> (created if "
                   "missing).")
@click.option("-o", "--output", "out_path", type=OutputPath(dir_okay=True), default=None, metavar="FILE",
              help="The program of a single INPUT, as one file (several inputs: -d DIR).")
@click.option("--jobs", type=Integer(1, 1024), default=None, help="Files converted at a time, in worker processes.  "
              "[default: the number of cores]")
@click.option("--fail-fast", is_flag=True, help="Stop at the first file that fails (files under way finish).")
@click.option("--force", is_flag=True,
              help="Replace programs that exist already (default: keep them; that file fails).")
@click.option("--format", "input_format", type=LazyChoice(_input_formats), default="auto", show_default=True,
              help="Input format: by content (CL records or G-code words), or forced.")
@click.option("--report", "report_path", type=OutputPath(), metavar="FILE.json",
              help="Write every file's accounting (records by word, moves, subdivisions, deviations) as JSON.")
@click.option("--tool-length", type=Decimal(LENGTH, low=0.0, low_open=True), default=None, metavar="MM",
              help="Platform centre to tool tip for the IK, mm.  [default: the machine's tool_length_mm]")
@click.option("--angle-tolerance", "angle_tolerance_deg", type=Decimal(ANGLE, low=0.0, low_open=True),
              default=DEFAULT_ANGLE_TOLERANCE_DEG,
              show_default=True, metavar="DEG", help="Allowed tool-axis deviation of axis-changing moves, degrees.")
@click.option("--cl-units", "units", type=click.Choice(["mm", "inch"]), default=None,
              help="Length unit of CL files without UNITS/.  [default: inch when the feeds are IPM/IPR, else mm]")
@click.option("--work-plane", "work_plane_text", default=None, metavar="PART.stl[:FACE]|OX,OY,OZ,NX,NY,NZ[,XX,XY,XZ]",
              help="Where a G-code program's X, Y, Z are in the part: a face frame (u, v, w) or origin, normal, x.")
@click.option("--ignore", "ignore_words", multiple=True, metavar="WORD",
              help="Skip (and count) this unknown CL major word instead of failing (repeatable).")
@click.option("--source", "source_name", default=None, metavar="NAME|PATH",
              help="Read G-code as a 5-axis program of this source machine (see `prs3-post sources`).")
@click.option("--tcp-on", "tcp_on", default=None, metavar="CODES",
              help="Codes that switch the source's TCP on, comma-separated (e.g. G43.4).  [default: the source's]")
@click.option("--tcp-off", "tcp_off", default=None, metavar="CODES",
              help="Codes that switch the source's TCP off, comma-separated (e.g. G49).  [default: the source's]")
@click.option("--part", "part_path", type=click.Path(exists=True, dir_okay=False), default=None, metavar="PART.stl",
              help="The part: every program is checked against it before it is written (the holder and the "
                   "spindle nose; the tool in the rapids: in the feeds it cuts what the CAM program removes).  "
                   "[default: not checked]")
@click.option("--part-units", type=click.Choice(["mm", "inch"]), default="mm", show_default=True,
              help="Length unit of the --part and --work-plane STL (--cl-units is the CL files').")
@up_option
@click.option("--collision-check/--no-collision-check", default=True, show_default=True,
              help="With --part: check the holder, spindle nose and the tool in the rapids against it; the header "
                   "says when it was skipped.")
@click.option("--clearance-min", type=CLEARANCE_MIN, default=DEFAULT_CLEARANCE_MIN, show_default=True,
              help="With --part: least distance the holder and spindle nose keep from it, mm.")
@click.option("--tool-diameter", "tool_diameter", type=Decimal(LENGTH), default=None, metavar="MM",
              help="With --part: the tool's diameter for its check in the rapids, mm (0.01 to 500).  [default: the "
                   "smallest of a CL file's TLDATA/ diameters; G-code states none: the tool's axis, 0 mm radius]")
@machine_option
@job_part_origin_option
@job_part_rotation_option
@dialect_option
@line_number_options[0]
@line_number_options[1]
@line_number_options[2]
@tolerance_option
@clamp_option
@verbosity_options
def convert(inputs: tuple[str, ...], outdir: str | None, out_path: str | None, jobs: int | None, fail_fast: bool,
            force: bool, input_format: str, report_path: str | None, tool_length: float | None,
            angle_tolerance_deg: float, units: str | None,
            work_plane_text: str | None, ignore_words: tuple[str, ...], source_name: str | None,
            tcp_on: str | None, tcp_off: str | None, part_path: str | None, part_units: str, up: str,
            collision_check: bool, clearance_min: float, tool_diameter: float | None, machine_name: str,
            part_origin: tuple[float, ...] | str | None, part_rotation: float | str | None, dialect_name: str,
            line_numbers: bool | None, line_start: int | None, line_step: int | None, tolerance: float,
            clamp: bool) -> None:
    """Convert CAM output (APT CL files, 3+2 G-code) into programs for this machine.

    INPUT is a file, a directory (searched recursively for .cls .clsf .cl .apt .nc .ngc .gcode
    .tap ... files) or a glob pattern. Each file goes through the main job's pipeline: setup, exact
    IK, subdivision of axis-changing moves, every point checked against every limit; its program
    is written whole or not at all. A failing file does not stop the others (unless --fail-fast);
    the summary lists every failure with file:line and reason. Exit status: 0 all converted; else
    the worst failure's: 2 for bad input (a file unreadable or not understood, an output kept
    because it exists) or bad options, 1 for a point outside a limit or out of reach, or files
    not started (--fail-fast).

    -o FILE writes the program of one INPUT to FILE; -d DIR writes each input's program into DIR.

    \b
    Examples:
      prs3-post convert mech491_APT_SimpleMillPlane.cls -o plane.ngc --part-origin 0,-17.2,-856
      prs3-post convert cam/ -d out --part-origin auto --jobs 2 --report out/report.json
    """
    from prs3_post.app.batch import (
        batch_summary,
        collect_inputs,
        convert_batch,
        convert_single,
        default_jobs,
        outcome_line,
        output_path,
        prepare_outdir,
    )

    def body() -> int:
        single, folder = _output(out_path, outdir)
        if folder == "-":                                # it made a folder named '-'
            raise click.BadParameter("'-' is no folder: convert writes one program per input into DIR, standard "
                                     "output cannot take them (a folder named '-' is ./-)",
                                     param_hint="'-d' / '--output-dir'")
        to_stdout = single == "-"                        # one program, to standard output (and not the report:
                                                         # two outputs on it are refused before any work)
        for word in ignore_words:
            if not word.strip():                         # a word no record has: taken, and nothing ignored
                raise click.BadParameter(f"{word!r}: give a CL major word, like PAINT", param_hint="'--ignore'")
        if part_path is None:                            # else taken and ignored: the user believed it checked
            ctx = click.get_current_context()
            for name, flag in (("tool_diameter", "--tool-diameter"), ("clearance_min", "--clearance-min")):
                if was_given(ctx, name):
                    raise click.UsageError(f"{flag} is used only with --part PART.stl (the check against the part): "
                                           "give the part, or leave it out")
        if source_name is None:                          # else taken and ignored: a 3+2 or CL input has no TCP
            for flag, text in (("--tcp-on", tcp_on), ("--tcp-off", tcp_off)):
                if text is not None:
                    raise click.UsageError(f"{flag} is used only with --source (a 5-axis program's TCP codes): "
                                           "give the source machine, or leave it out")
        from prs3_post.app.convert_files import convert_settings

        try:
            settings = convert_settings(
                machine=machine_name, dialect=dialect_name, part_origin=part_origin, part_rotation=part_rotation,
                tolerance=tolerance, angle_tolerance_deg=angle_tolerance_deg, tool_length=tool_length,
                input_format=input_format, units=units, ignore=ignore_words, work_plane=work_plane_text,
                part=part_path, part_units=part_units, part_up=up, source=source_name,
                tcp_on=_codes_option(tcp_on, "--tcp-on"), tcp_off=_codes_option(tcp_off, "--tcp-off"),
                line_numbers=line_numbers, line_start=line_start, line_step=line_step,
                collision_check=collision_check, clearance_min=clearance_min, tool_diameter=tool_diameter, clamp=clamp)
        except FieldError as error:
            raise option_error(error) from error
        dialect = settings.dialect
        repeats: list[tuple[str, str]] = []
        files = collect_inputs(inputs, exclude=folder, exclude_suffix=dialect.extension, repeats=repeats)
        if single is not None and len(files) != 1:
            raise click.UsageError(f"-o FILE writes the program of one input, and {len(files)} files are given: "
                                   "convert them into a folder with -d DIR")
        if report_path is not None and report_path != "-":
            refuse_overwriting({"--report": report_path}, {f"{i + 1} ({f})": f for i, f in enumerate(files)})
            programs = [output_path(file, folder, dialect) for file in files] if folder is not None else []
            for file, program in zip(files, programs, strict=False):   # the report must not replace a program
                refuse_overwriting({f"the program of {file}": program, "--report": report_path}, {})
            # before any work: a report that cannot be written (its folder may be DIR, made by the batch)
            # realpath, not Path.resolve(): a loop of symbolic links is check_writable's clear error, not a RuntimeError
            beside = Path(os.path.realpath(report_path)).parent
            if folder is not None and beside == Path(os.path.realpath(folder)):   # (else no folder made if it fails)
                prepare_outdir(folder)
            check_writable(report_path)
        count = jobs or default_jobs()
        detail(f"{len(files)} file{'s' if len(files) != 1 else ''}, {min(count, len(files))} at a time; machine "
               f"{settings.machine.name}, dialect {dialect.name}, setup "
               f"{_setup_words(settings.setup.describe(), part_origin, part_rotation)}, tolerance "
               f"{settings.tolerance:g} mm, axis tolerance {settings.angle_tolerance_deg:g} deg")
        lines_to_stderr = to_stdout or report_path == "-"   # standard output has the program or the report

        def convert_all(on_done: Callable[[FileOutcome], None], progress: Progress | None = None) -> BatchResult:
            if single is not None:
                return convert_single(files[0], single, settings, force=force, on_done=on_done, progress=progress)
            assert folder is not None                    # (_output gives one of them)
            return convert_batch(files, folder, settings, jobs=count, fail_fast=fail_fast, force=force,
                                 on_done=on_done, progress=progress)

        # bytes read of every input, on a terminal only (-v: a line per file instead; -q: nothing)
        bar = ProgressBar("converting", enabled=None if verbosity() == NORMAL else False)
        if bar.enabled:
            with bar:
                bar(0.0, 1.0)
                result = convert_all(lambda outcome: None, bar)
        else:
            result = convert_all(lambda outcome: _file_done(outcome_line(_flag_named(outcome)), err=lines_to_stderr))
        result = dataclasses.replace(result, outcomes=tuple(_flag_named(o) for o in result.outcomes))
        if report_path is not None:
            write_atomic(report_path, json.dumps(result.record(), indent=1, allow_nan=False) + "\n")
        counts, _, failures = batch_summary(result).partition("\n")   # the failures are errors: said with -q too
        say(counts.removeprefix("prs3-post: "))
        click.echo(failures, err=True, nl=False)
        if repeats:                                  # nothing named is left unsaid
            say(f"{len(repeats)} more name{'s' if len(repeats) > 1 else ''} of files above, each converted once: "
                 + ", ".join(f"{name} (= {same})" for name, same in repeats))
        # the project's exit codes hold for a batch too: 2 when any file was bad input (unreadable, not
        # understood), else 1 when any failed a limit or reach or was not started, else 0
        codes = [outcome.exit_code for outcome in result.failures] + [1] * bool(result.not_started)
        return max(codes, default=0)

    run_reported(body)


def _output(out_path: str | None, outdir: str | None) -> tuple[str | None, str | None]:
    """``(program file, folder)``, one of them None: -o FILE or -d DIR, and -o DIR (a folder that exists, or
    a path that ends in /), the old spelling of -d DIR, with its note."""
    if out_path is not None and outdir is not None:
        raise click.UsageError("-o FILE (the program of one input) and -d DIR (a folder of programs): give one of them")
    if out_path is None and outdir is None:
        raise click.UsageError("give -d DIR (a folder for the programs) or, for a single input, -o FILE (its program)")
    if out_path is not None and out_path != "-" and (os.path.isdir(out_path) or out_path.endswith(("/", os.sep))):
        note(DEPRECATED.format(old=f"-o {out_path} (a folder)", new=f"-d {out_path}"))
        return None, out_path
    return out_path, outdir


def _file_done(line: str, *, err: bool = False) -> None:
    """A file's line (``ok``/``failed``, tab-separated) on standard output (``err``: standard error, when
    standard output has the program or the report), and with ``-v`` on standard error."""
    click.echo(line, err=err)
    if not err:
        detail(line.replace("\t", "  "))


def _setup_words(described: str, part_origin: object, part_rotation: object) -> str:
    """The setup a batch uses, in words: chosen for each file (``auto``), else the one given or the machine's."""
    if AUTO in (part_origin, part_rotation):
        return "chosen for each file (auto)"
    return described + ("" if part_origin is not None or part_rotation is not None else " (the machine file's)")


def _flag_named(outcome: FileOutcome) -> FileOutcome:
    """A kept program's failure says which option replaces it, an error the keys it names as the
    options that set them (the library names no option), and a part origin found to fit as the
    option that gives it (as the main job says it)."""
    from prs3_post.app.batch import EXISTS

    if outcome.suggested_origin is not None:
        error = spelled(outcome.keyed, flag_of, outcome.keys or None) if outcome.keyed else outcome.error
        return dataclasses.replace(outcome, error=f"{error}: --part-origin={','.join(outcome.suggested_origin)}",
                                   keyed="", suggested_origin=None)
    if outcome.keyed:
        return dataclasses.replace(outcome, error=spelled(outcome.keyed, flag_of, outcome.keys or None))
    if not outcome.exists:
        return outcome
    return dataclasses.replace(outcome, error=f"{outcome.output}: {EXISTS} (convert with --force to replace it)")

