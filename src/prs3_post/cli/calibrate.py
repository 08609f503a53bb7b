"""The calibration commands: `calibrate plan` (the poses to measure), `calibrate MEASUREMENTS.csv`
(identify the machine as built) and `accuracy` (what the tool's position is worth)."""

from __future__ import annotations

import datetime
import json
from typing import Any

import click

from prs3_post.app.values import LENGTH
from prs3_post.cli.options import (
    QUIET,
    Command,
    Decimal,
    Integer,
    Numbers,
    OutputPath,
    image_format,
    machine_option,
    run_reported,
    verbosity,
    verbosity_options,
)
from prs3_post.core.defaults import DEFAULT_ACTUATOR_RESOLUTION_MM, DEFAULT_MEASUREMENT_NOISE_MM
from prs3_post.core.output_files import is_stdout, write_outputs

#: ``--noise-mm``: a measurement's noise, mm (above 0).
NOISE = Decimal(LENGTH, low=0.0, low_open=True)
_NOISE_HELP = "Measurement noise of a tip coordinate (one standard deviation), mm."


class _CalibrateGroup(click.Group):
    """``calibrate plan ...`` runs the plan; ``calibrate MEASUREMENTS.csv ...`` the identification."""

    command_class = Command

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        lead = 0                                       # the group's own flags (-q, -v) may come first
        while lead < len(args) and args[lead] in ("-q", "--quiet", "-v", "--verbose"):
            lead += 1
        rest = args[lead:]
        if rest and rest[0] not in self.commands and rest[0] not in ("-h", "--help"):
            args = [*args[:lead], "identify", *rest]
        return super().parse_args(ctx, args)


@click.group(cls=_CalibrateGroup)
@verbosity_options
def calibrate() -> None:
    """Calibrate a machine from measured tool poses, and plan the poses to measure.

    \b
    prs3-post calibrate plan --machine M --poses N -o poses.csv
        choose N poses inside every limit that make the geometry observable
    prs3-post calibrate MEASUREMENTS.csv --machine M -o calibrated.toml [--report R.json] [--preview R.png]
        identify the machine as built; calibrated.toml works wherever --machine does

    The CSV: t1,t2,t3 (commanded strokes, mm), optional x,y (stage), px,py,pz (measured tip, machine
    frame, stage applied), optional ax,ay,az (measured axis), optional tool_length_mm.
    `prs3-post calibrate MEASUREMENTS.csv` is `prs3-post calibrate identify MEASUREMENTS.csv`.
    """


def _summary(text: str, to_stderr: bool) -> None:
    """The command's summary: on standard output, or on standard error (not with -q) when that is taken."""
    if not to_stderr or verbosity() > QUIET:
        click.echo(text, nl=False, err=to_stderr)


@calibrate.command("identify", cls=Command)
@verbosity_options
@click.argument("measurements_path", metavar="MEASUREMENTS.csv", type=click.Path(dir_okay=False))
@machine_option
@click.option("-o", "--output", "out_path", type=OutputPath(), required=True,
              help="The calibrated machine file (TOML; - for standard output).")
@click.option("--report", "report_path", type=OutputPath(), help="Write the report as JSON (- for standard output).")
@click.option("--preview", "preview_path", type=OutputPath(),
              help="Draw each pose's tip error before and after (.png or .svg). Needs matplotlib: "
                   "pip install 'prs3-post[plot]'.")
@click.option("--noise-mm", "noise", type=NOISE, default=DEFAULT_MEASUREMENT_NOISE_MM, show_default=True,
              help=_NOISE_HELP + " Combinations the measurements cannot determine to a third of their expected error "
                                 "at this noise are held at nominal.")
@click.option("--fit-frame", is_flag=True,
              help="The tips are in the measuring instrument's own frame: identify its placement too.")
@click.option("--validate", "validate_path", type=click.Path(dir_okay=False), metavar="OTHER.csv",
              help="Other measured poses to check the calibrated machine on (not used to fit it).")
def identify_command(measurements_path: str, machine_name: str, out_path: str, report_path: str | None,
                     preview_path: str | None, noise: float, fit_frame: bool, validate_path: str | None) -> None:
    """Identify the machine as built from measured poses (also: prs3-post calibrate MEASUREMENTS.csv ...).

    Prints the residuals before and after, the hold-out validation, every identified parameter with
    its standard deviation and the ones held at nominal; writes the calibrated machine file.

    \b
    Example:
      prs3-post calibrate measured.csv --machine patel2020 -o calibrated.toml --report calibration.json
    """
    from prs3_post.app.calibrate import calibrate_file
    from prs3_post.app.calibration_report import calibrated_toml, calibration_json, calibration_text

    def body() -> int:
        fmt = image_format(preview_path, "'--preview'") if preview_path else None
        result = calibrate_file(machine_name, measurements_path, noise=noise, fit_frame=fit_frame,
                                validate_path=validate_path)
        date = datetime.datetime.now(datetime.UTC).date().isoformat()
        outputs: list[tuple[str | None, Any]] = [(out_path, calibrated_toml(result, date=date))]
        if report_path:
            outputs.append((report_path, json.dumps(calibration_json(result), indent=2, allow_nan=False) + "\n"))
        if fmt is not None and preview_path:
            from prs3_post.app.calibration_report import residual_picture

            outputs.append((preview_path, residual_picture(result, fmt)))
        write_outputs(outputs)
        _summary(calibration_text(result), is_stdout(out_path) or is_stdout(report_path or ""))
        return 0

    run_reported(body)


def _lengths(value: str | None) -> tuple[float, ...]:
    if not value:
        return ()
    try:
        lengths = tuple(float(v) for v in value.split(","))
    except ValueError:
        raise click.BadParameter(f"expected tool lengths in mm separated by commas (175,225), got {value!r}",
                                 param_hint="'--tool-lengths'") from None
    if not all(0 < v < 1e4 for v in lengths) or len(set(lengths)) != len(lengths):
        raise click.BadParameter(f"expected distinct tool lengths above 0 mm, got {value!r}",
                                 param_hint="'--tool-lengths'")
    return lengths


@calibrate.command("plan", cls=Command)
@verbosity_options
@machine_option
@click.option("--poses", type=Integer(1, 500), default=60, show_default=True, help="How many poses to measure.")
@click.option("-o", "--output", "out_path", type=OutputPath(), required=True,
              help="The poses as a measurement CSV with the measured columns empty (- for standard output).")
@click.option("--report", "report_path", type=OutputPath(),
              help="Write the plan's report as JSON (- for standard output).")
@click.option("--noise-mm", "noise", type=NOISE, default=DEFAULT_MEASUREMENT_NOISE_MM, show_default=True,
              help=_NOISE_HELP + " The expected standard deviations are for this noise.")
@click.option("--axes/--no-axes", default=True, show_default=True,
              help="The tool axis will be measured too (ax, ay, az), or only the tip.")
@click.option("--tool-lengths", metavar="TL1,TL2,...", default=None,
              help="Measure with these tools (tool length TL, mm, platform centre to tip): adds tool_length_mm.  "
                   "[default: the machine file's]")
@click.option("--fit-frame", is_flag=True, help="The measurements will be in the instrument's own frame.")
@click.option("--seed", type=Integer(0, 2**31), default=0, show_default=True,
              help="Seed of the random candidate poses (the same seed gives the same plan).")
def plan(machine_name: str, poses: int, out_path: str, report_path: str | None, noise: float, axes: bool,
         tool_lengths: str | None, fit_frame: bool, seed: int) -> None:
    """Choose the poses to measure: inside every limit, D-optimal for the machine's geometry.

    The criterion: the chosen poses maximise det(I + JᵀJ/σ²) of the scaled identification Jacobian
    J (each parameter in units of its expected error, σ the noise). Prints each parameter's expected
    standard deviation and the ones no measurement of this kind can separate.

    \b
    Example:
      prs3-post calibrate plan --machine patel2020 --poses 60 -o poses.csv
    """
    from prs3_post.app.calibrate import plan_calibration
    from prs3_post.app.calibration_report import plan_csv, plan_json, plan_text
    from prs3_post.app.kinematics import machine_of

    def body() -> int:
        machine = machine_of(machine_name)
        chosen = plan_calibration(machine, poses, noise=noise, axes=axes, tool_lengths=_lengths(tool_lengths),
                                  fit_frame=fit_frame, seed=seed)
        outputs: list[tuple[str | None, Any]] = [(out_path, plan_csv(chosen))]
        if report_path:
            outputs.append((report_path, json.dumps(plan_json(chosen), indent=2, allow_nan=False) + "\n"))
        write_outputs(outputs)
        _summary(plan_text(chosen), is_stdout(out_path) or is_stdout(report_path or ""))
        return 0

    run_reported(body)


@click.command(cls=Command)
@machine_option
@click.option("--noise-mm", "noise", type=NOISE, default=None,
              help="Show what a planned calibration (60 poses) measured with this noise would give, instead of "
                   "the machine file's calibration.")
@click.option("--resolution-mm", "resolution", type=Decimal(LENGTH, low=0.0), default=DEFAULT_ACTUATOR_RESOLUTION_MM,
              show_default=True, help="The step each actuator is set to within, mm.")
@click.option("--at", "where", type=Numbers("X,Y,Z"), default=None,
              help="The tool tip's position, machine frame, mm.  [default: the part origin's x, y at the height "
                   "of the untilted tool at mid-stroke]")
@click.option("--preview", "preview_path", type=OutputPath(),
              help="Draw the map (.png or .svg). Needs matplotlib: pip install 'prs3-post[plot]'.")
@click.option("--json", "as_json", is_flag=True, help="Print the map as JSON.")
@verbosity_options
def accuracy(machine_name: str, noise: float | None, resolution: float, where: tuple[float, float, float] | None,
             preview_path: str | None, as_json: bool) -> None:
    """How accurate the tool is: actuator resolution and the geometry's uncertainty at the tool tip.

    First order (through the Jacobian), over every tilt and azimuth of the tool axis at one tip
    position (--at; by default over the part's placement, at mid-stroke height): the tip's
    uncertainty (mm, one standard deviation of its 3D error) and the axis's
    (deg). The geometry's uncertainty is the machine file's calibration ([calibration], written by
    `prs3-post calibrate`), or with --noise-mm a planned calibration's, or for a machine nobody
    calibrated each parameter's expected error.

    \b
    Example:
      prs3-post accuracy --machine calibrated.toml --preview accuracy.png
    """
    from prs3_post.app.accuracy import accuracy_json, accuracy_map, accuracy_picture, accuracy_text
    from prs3_post.app.kinematics import machine_of

    def body() -> int:
        fmt = image_format(preview_path, "'--preview'") if preview_path else None
        found = accuracy_map(machine_of(machine_name), resolution=resolution, noise=noise, where=where)
        if fmt is not None and preview_path:
            write_outputs([(preview_path, accuracy_picture(found, fmt))])
        click.echo(json.dumps(accuracy_json(found), indent=2, allow_nan=False) if as_json else accuracy_text(found),
                   nl=as_json)
        return 0

    run_reported(body)
