"""The kinematics commands: `ik` (tool poses → actuator settings) and `fk` (actuator settings → tool pose)."""

from __future__ import annotations

import json

import click

from prs3_post.app.kinematics import IK_MODELS, IKModel, machine_of
from prs3_post.app.values import RATIO
from prs3_post.cli.options import (
    Command,
    Numbers,
    OutputPath,
    detail,
    machine_option,
    run_reported,
    timed,
    verbosity_options,
    was_given,
)
from prs3_post.core.output_files import (
    write_outputs,
)


@click.command(cls=Command)
@click.option("--tip", type=Numbers("X,Y,Z"), help="Tool tip in the machine frame, mm (part-relative, stage included).")
@click.option("--axis", type=Numbers("I,J,K", RATIO),
              help="Tool axis from the tip toward the spindle (normalized; K > 0).")
@click.option(
    "--batch", "batch_path", type=click.Path(dir_okay=False), metavar="POSES.csv",
    help="Many poses: CSV with header tip_x,tip_y,tip_z,axis_x,axis_y,axis_z.",
)
@click.option("-o", "--output", "out_path", type=OutputPath(), help="Batch output CSV (default: standard output).")
@click.option(
    "--model", type=click.Choice(list(IK_MODELS)), default="exact", show_default=True,
    help="exact: rigid platform + XY stage; head: no stage; paper: the paper's per-leg method (validation).",
)
@machine_option
@click.option("--json", "as_json", is_flag=True, help="Print the single-pose result as JSON (keys = CSV columns).")
@verbosity_options
def ik(tip: tuple[float, ...] | None, axis: tuple[float, ...] | None, batch_path: str | None, out_path: str | None,
       model: str, machine_name: str, as_json: bool) -> None:
    """Inverse kinematics: tool pose(s) → stage X, Y, strokes T1..T3, link angles, condition number.

    Every result is checked against the machine's limits (ok = all respected; violations are
    listed with their margins). The exit status is 1 when a pose is outside a limit or unreachable.

    \b
    Examples:
      prs3-post ik --tip -81.0264,21.2132,-679.4865 --axis 0.447214,0,0.894427 --json
      prs3-post ik --batch poses.csv -o strokes.csv
    """
    from prs3_post.app.kinematics import pose_record
    from prs3_post.app.pose_tables import ik_text

    def body() -> int:
        machine = machine_of(machine_name)
        detail(f"machine {machine.name}: {machine.source}")
        if batch_path is not None:
            if tip is not None or axis is not None:
                raise click.UsageError("--batch cannot be combined with --tip/--axis")
            from prs3_post.app.ik_batch import IKBatch

            batch = IKBatch(machine, batch_path, model=IKModel(model))
            with timed("read, solve and write"):
                write_outputs([(out_path, batch.chunks())])
            if batch.summary():
                click.echo(f"prs3-post: {batch.summary()}", err=True)
                return 1
            return 0
        if tip is None or axis is None:
            raise click.UsageError("give --tip and --axis, or --batch POSES.csv")
        record = pose_record(machine, tip, axis, model=IKModel(model))
        click.echo(json.dumps(record, indent=2, allow_nan=False) if as_json else ik_text(record), nl=as_json)
        return 0 if record["ok"] else 1

    run_reported(body)


@click.command(cls=Command)
@click.option("--strokes", type=Numbers("T1,T2,T3"), required=True,
              help="Actuator strokes, mm (downward from the base).")
@click.option("--xy", type=Numbers("X,Y"), default="0,0", show_default=True, help="Stage position X, Y, mm.")
@machine_option
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@verbosity_options
def fk(strokes: tuple[float, ...], xy: tuple[float, ...], machine_name: str, as_json: bool) -> None:
    """Forward kinematics: strokes T1..T3 (and stage X, Y) → tool tip, tool axis and link angles.

    The setting is checked against the machine's limits, as `ik` checks a pose (violations are
    listed with their margins); the exit status is 1 when it is outside a limit.

    \b
    Example:
      prs3-post fk --strokes 36.2244,170.3886,88.9519 --xy -2.7640,12.0703
    """
    from prs3_post.app.kinematics import setting_record
    from prs3_post.app.pose_tables import fk_text

    def body() -> int:
        machine = machine_of(machine_name)
        detail(f"machine {machine.name}: {machine.source}")
        if not machine.stage.present and was_given(click.get_current_context(), "xy"):
            raise click.BadParameter(f"machine {machine.name} has no stage (stage.present = false): the tip is "
                                     "where the head puts it; leave --xy out", param_hint="'--xy'")
        record = setting_record(machine, strokes, xy)
        click.echo(json.dumps(record, indent=2, allow_nan=False) if as_json else fk_text(record), nl=as_json)
        return 0 if record["ok"] else 1

    run_reported(body)

