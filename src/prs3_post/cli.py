"""Command line: click options → library calls → atomic writes. No math here.

Every :class:`~prs3_post.errors.Prs3Error` is printed as ``prs3-post: error: where: message`` with
its exit code (2 for bad input or configuration, 1 for limits and reach); never a traceback.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click
import numpy as np

from prs3_post import __version__
from prs3_post.config import load_machine, shipped_names
from prs3_post.errors import InputError, Prs3Error, ReachError
from prs3_post.kinematics import IKModel, PoseError, forward, inverse, unit_axes
from prs3_post.limits import check_limits
from prs3_post.readers.poses import read_poses
from prs3_post.tables import fk_records, fk_text, ik_csv, ik_records, ik_text


# ----------------------------------------------------------------------------- helpers


class Numbers(click.ParamType):
    """``X,Y,Z``-style option values: a fixed count of comma-separated numbers."""

    def __init__(self, names: str):
        self.names = names
        self.count = len(names.split(","))
        self.name = names

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> tuple[float, ...]:
        if isinstance(value, tuple):
            return value
        parts = str(value).split(",")
        try:
            numbers = tuple(float(p) for p in parts)
        except ValueError:
            numbers = ()
        if len(numbers) != self.count or not all(np.isfinite(numbers)):
            self.fail(f"expected {self.count} numbers {self.names}, got {value!r}", param, ctx)
        return numbers


def write_atomic(path: str, text: str) -> None:
    """Write ``text`` to ``path`` via a temp file in the same folder and a rename: never half a file."""
    target = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent or ".")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as stream:
            stream.write(text)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def output(text: str, path: str | None) -> None:
    """``text`` to ``path`` (atomically) or, without a path, to standard output."""
    if path is None or path == "-":
        click.echo(text, nl=False)
    else:
        write_atomic(path, text)


def run_reported(action: Callable[[], int | None]) -> None:
    """Run a command body; report :class:`Prs3Error` as one line and exit with its code."""
    try:
        code = action()
    except Prs3Error as error:
        click.echo(f"prs3-post: error: {error}", err=True)
        sys.exit(error.exit_code)
    sys.exit(code or 0)


machine_option = click.option(
    "--machine", "machine_name", default="patel2020", show_default=True, metavar="NAME|PATH",
    help="Shipped machine name (see `prs3-post machines`) or path to a machine TOML file.",
)


# ----------------------------------------------------------------------------- commands


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="prs3-post")
def main() -> None:
    """prs3-post: the post-processor for 3-PRS parallel-kinematic machines.

    Turns a tool pose (tip and axis) into actuator strokes T1, T2, T3 and stage X, Y, and back.

    \b
    Examples:
      prs3-post ik --tip -81.0264,21.2132,-679.4865 --axis 0.447214,0,0.894427
      prs3-post fk --strokes 36.2244,170.3886,88.9519 --xy -2.7640,12.0703
      prs3-post machines
    """


@main.command()
@click.option("--tip", type=Numbers("X,Y,Z"), help="Tool tip in the machine frame, mm (part-relative, stage included).")
@click.option("--axis", type=Numbers("I,J,K"), help="Tool axis from the tip toward the spindle (normalized; K > 0).")
@click.option(
    "--batch", "batch_path", type=click.Path(dir_okay=False), metavar="POSES.csv",
    help="Many poses: CSV with header tip_x,tip_y,tip_z,axis_x,axis_y,axis_z.",
)
@click.option("-o", "--output", "out_path", type=click.Path(dir_okay=False), help="Batch output CSV (default: standard output).")
@click.option(
    "--model", type=click.Choice([m.value for m in IKModel]), default="exact", show_default=True,
    help="exact: rigid platform + XY stage; head: no stage; paper: the paper's per-leg method (validation).",
)
@machine_option
@click.option("--json", "as_json", is_flag=True, help="Print the single-pose result as JSON (keys = CSV columns).")
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

    def body() -> int:
        machine = load_machine(machine_name)
        if batch_path is not None:
            if tip is not None or axis is not None:
                raise click.UsageError("--batch cannot be combined with --tip/--axis")
            table = read_poses(batch_path)
            try:
                unit = unit_axes(table.tip, table.axis, row_name="line", row_numbers=table.line)
            except PoseError as error:
                raise InputError(str(error), path=batch_path) from error
            result = inverse(machine.geometry, table.tip, unit, model=IKModel(model))
            report = check_limits(machine, result, unit)
            output(ik_csv(table.tip, unit, result, report), out_path)
            bad = np.flatnonzero(~report.ok)
            if len(bad):
                shown = ", ".join(str(table.line[i]) for i in bad[:10]) + (", ..." if len(bad) > 10 else "")
                click.echo(f"prs3-post: {len(bad)} of {len(report.ok)} poses unreachable or outside limits "
                           f"(lines {shown}); see the ok column", err=True)
                return 1
            return 0
        if tip is None or axis is None:
            raise click.UsageError("give --tip and --axis, or --batch POSES.csv")
        tips, axes = np.array([tip]), unit_axes(np.array([tip]), np.array([axis]), row_name="pose")
        result = inverse(machine.geometry, tips, axes, model=IKModel(model))
        if IKModel(model) is IKModel.HEAD and not result.reachable[0] and np.isfinite(result.stage[0]).all():
            dx, dy = result.stage[0]
            raise ReachError(
                f"machine {machine.name} has no stage and its head alone misses this tip by "
                f"{np.hypot(dx, dy):.4f} mm (x {dx:.4f}, y {dy:.4f}): the tilt's parasitic shift must be "
                "matched by the part setup, or use a machine with an XY stage"
            )
        if not result.reachable[0]:
            raise ReachError("this pose cannot be reached: the head does not assemble there (a link cannot reach)")
        report = check_limits(machine, result, axes)
        record = ik_records(tips, axes, result, report)[0]
        click.echo(json.dumps(record, indent=2) if as_json else ik_text(record), nl=as_json)
        return 0 if record["ok"] else 1

    run_reported(body)


@main.command()
@click.option("--strokes", type=Numbers("T1,T2,T3"), required=True, help="Actuator strokes, mm (downward from the base).")
@click.option("--xy", type=Numbers("X,Y"), default="0,0", show_default=True, help="Stage position X, Y, mm.")
@machine_option
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
def fk(strokes: tuple[float, ...], xy: tuple[float, ...], machine_name: str, as_json: bool) -> None:
    """Forward kinematics: strokes T1..T3 (and stage X, Y) → tool tip, tool axis and link angles.

    \b
    Example:
      prs3-post fk --strokes 36.2244,170.3886,88.9519 --xy -2.7640,12.0703
    """

    def body() -> int:
        machine = load_machine(machine_name)
        result = forward(machine.geometry, np.array([strokes]), np.array([xy]))
        if not result.converged[0]:
            raise ReachError(
                f"strokes {', '.join(f'{s:g}' for s in strokes)} mm do not assemble the head of {machine.name} "
                f"(no rigid platform pose after {result.iterations[0]} Newton steps; "
                f"side-length error {result.residual[0]:.3g} mm)"
            )
        record = fk_records(result)[0]
        click.echo(json.dumps(record, indent=2) if as_json else fk_text(record), nl=as_json)
        return 0

    run_reported(body)


@main.command()
def machines() -> None:
    """List the shipped machines (use a name or a TOML path with --machine)."""

    def body() -> int:
        for name in shipped_names("machines"):
            machine = load_machine(name)
            stage = "XY stage" if machine.stage.present else "no stage"
            click.echo(f"{name:<18} {stage:<9} {machine.description}")
        return 0

    run_reported(body)
