"""Command line: click options → library calls → atomic writes. No math here.

Every :class:`~prs3_post.core.errors.Prs3Error` is printed as ``prs3-post: error: where: message`` with
its exit code (2 for bad input or configuration, 1 for limits and reach); never a traceback.
"""

from __future__ import annotations

import contextlib
import dataclasses
import difflib
import json
import math
import os
import re
import stat
import sys
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click
import numpy as np

from prs3_post import __version__
from prs3_post.core.defaults import (
    DEFAULT_ANGLE_TOLERANCE_DEG,
    DEFAULT_TOLERANCE,
    FEED_RANGE_MM_MIN,
    MAX_SPINDLE_RPM,
)
from prs3_post.core.errors import ConfigError, FeatureError, InputError, Prs3Error, Prs3Warning, ReachError, quoted
from prs3_post.core.lexer import code_name
from prs3_post.emit.output_files import (
    check_writable,
    is_stdout,
    refuse_overwriting,
    stdout_error,
    write_atomic,
    write_outputs,
)
from prs3_post.kinematics import IKModel, forward, inverse, unit_axes
from prs3_post.machine.loading import (
    DEFAULT_DIALECT,
    DEFAULT_MACHINE,
    Machine,
    load_dialect,
    load_machine,
    load_source,
    postproc_dir,
    shipped_names,
)
from prs3_post.part.setup_transform import AUTO, UP_ROTATION, Setup, SetupError
from prs3_post.post.limits import check_limits
from prs3_post.readers.detect import FORMATS
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
from prs3_post.toolpaths.common import TOOL_DIAMETER_RANGE, require_tolerance
from prs3_post.toolpaths.work import HoleJob, Operation, ProfileJob

# What only some commands need is imported where it is used (the main job, convert, verify, preview,
# faces: each about 0.1 s of imports), so that `ik`, `fk` and a small `verify` start fast.
if TYPE_CHECKING:
    from prs3_post.app.convert import FileOutcome
    from prs3_post.app.job import JobProgram, JobSpec
    from prs3_post.app.verify import CamPart, ProgramContext, ProgramSetting, RebuiltJob
    from prs3_post.check.verify import Intended
    from prs3_post.readers.jobfile import JobFile
    from prs3_post.readers.tooltable import ToolTable

#: What _open_program opens: the whole program, or only what it was made for.
_Opened = TypeVar("_Opened", "ProgramContext", "ProgramSetting")

# ----------------------------------------------------------------------------- helpers


#: Plain decimal numbers only: ``-12.5``, ``.5``, ``5.``, ``1e-3``; not ``1_0``, ``nan``, ``inf``, ``0x1p3``,
#: ``٣`` or surrounding spaces, which Python's float() would take.
_PLAIN_DECIMAL = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")

#: The magnitudes an option may have (physically meaningful, with room to spare): (limit, unit).
LENGTH = (1e6, "mm")            # a kilometre
ANGLE = (3600.0, "degrees")     # ten turns
FEED = (FEED_RANGE_MM_MIN[1], "mm/min")  # a kilometre a minute
SPEED = (MAX_SPINDLE_RPM, "rpm")  # spindles reach some 100,000 rpm
TIME = (1e4, "s")               # almost three hours
RATIO = (1e6, "")               # direction components (normalized later)


def compact(value: float) -> str:
    """A number for a message: at most 6 significant digits, ``1e+308`` rather than 309 digits."""
    return f"{value:.6g}"


def _plain_decimal(text: str) -> float | None:
    """``text`` as a float if it is a plain decimal number, else None."""
    return float(text) if _PLAIN_DECIMAL.fullmatch(text) else None


class Decimal(click.ParamType):
    """A plain, finite decimal number within ``[low, high]`` (default ``±magnitude``); ``low_open``
    excludes ``low`` itself. The library checks what the value means (``--depth`` > 0); this type
    keeps out what no machine means (``1e308``, ``nan``, ``1_0``)."""

    name = "number"

    def __init__(self, magnitude: tuple[float, str], *, low: float | None = None, low_open: bool = False):
        self.limit, self.unit = magnitude
        self.low = -self.limit if low is None else low
        self.low_open = low_open

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> float:
        number = float(value) if isinstance(value, (int, float)) else _plain_decimal(str(value))
        if number is None:
            self.fail(f"expected a plain decimal number (like 12.5 or -0.25), got {quoted(str(value))}", param, ctx)
        too_low = number <= self.low if self.low_open else number < self.low
        if too_low or not number <= self.limit:          # `not <=`: also NaN from a default
            unit = f" {self.unit}" if self.unit else ""
            allowed = (f"> {compact(self.low)} and ≤ {compact(self.limit)}" if self.low_open
                       else f"{compact(self.low)} to {compact(self.limit)}")
            self.fail(f"{compact(number)}{unit} is out of range (allowed: {allowed}{unit})", param, ctx)
        return number


#: ``--clearance-min`` (the main job and convert): a distance kept from the part, so never negative.
CLEARANCE_MIN = Decimal(LENGTH, low=0.0)


class Integer(click.ParamType):
    """A plain whole number (``12``, ``-3``; not ``1_0``, ``1e3``, ``٣`` or ``+ 1``) within ``[low, high]``.

    Without bounds only a count of digits no controller takes is refused (more than 30), so that no
    message prints a 300-digit number; what the value means is checked where it is used."""

    name = "integer"

    def __init__(self, low: int | None = None, high: int | None = None):
        self.low, self.high = low, high

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> int:
        if isinstance(value, int):
            number = value
        elif _PLAIN_INTEGER.fullmatch(str(value)):
            number = int(str(value))
        else:
            self.fail(f"expected a whole number (like 12), got {quoted(str(value))}", param, ctx)
        low = -_INTEGER_LIMIT if self.low is None else self.low
        high = _INTEGER_LIMIT if self.high is None else self.high
        if not low <= number <= high:
            shown = str(number) if abs(number) < 10**12 else compact(float(number))
            allowed = f"{low} to {high}" if self.low is not None or self.high is not None else "at most 30 digits"
            self.fail(f"{shown} is out of range (allowed: {allowed})", param, ctx)
        return number


_PLAIN_INTEGER = re.compile(r"[+-]?[0-9]+")
_INTEGER_LIMIT = 10**30 - 1


class Numbers(click.ParamType):
    """``X,Y,Z``-style option values: a fixed count of comma-separated plain decimal numbers, each
    within ``±magnitude``."""

    def __init__(self, names: str, magnitude: tuple[float, str] = LENGTH):
        self.names = names
        self.count = len(names.split(","))
        self.name = names
        self.limit, self.unit = magnitude

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> tuple[float, ...]:
        if isinstance(value, tuple):
            return value
        parts = [_plain_decimal(p) for p in str(value).split(",")]
        if len(parts) != self.count or None in parts:
            self.fail(f"expected {self.count} plain decimal numbers {self.names}, got {quoted(str(value))}",
                      param, ctx)
        numbers = tuple(float(p) for p in parts if p is not None)
        for name, number in zip(self.names.split(","), numbers, strict=True):
            if not abs(number) <= self.limit:
                unit = f" {self.unit}" if self.unit else ""
                self.fail(f"{name} = {compact(number)}{unit} is out of range (allowed: within ±{compact(self.limit)}"
                          f"{unit})", param, ctx)
        return numbers


class OutputPath(click.Path):
    """A file the command writes (``-o``, ``--preview``): checked against the inputs before any work."""

    def __init__(self) -> None:
        super().__init__(dir_okay=False)


def _refuse_overwriting_inputs(ctx: click.Context) -> None:
    """No output may be one of the command's input files (PART.stl, POSES.csv, a machine TOML ...)."""
    outputs: dict[str, str | None] = {}
    inputs: dict[str, str | None] = {}
    for param in ctx.command.params:
        value = ctx.params.get(param.name or "")
        if not isinstance(value, str):
            continue
        name = max(param.opts, key=len) if isinstance(param, click.Option) else param.human_readable_name
        if isinstance(param.type, OutputPath):
            outputs[name] = value
        elif isinstance(param.type, click.Path) or param.name in ("machine_name", "dialect_name"):
            inputs[name] = value
    if ctx.command.name == "demo":
        inputs["the demo part"] = str(demo_part())
    refuse_overwriting(outputs, inputs)


@contextlib.contextmanager
def warnings_to_stderr() -> Iterator[None]:
    """Print every :class:`Prs3Warning` as ``prs3-post: warning: message`` on standard error, when it happens."""
    with warnings.catch_warnings():
        warnings.simplefilter("always", Prs3Warning)
        shown = warnings.showwarning

        def show(message: Warning | str, category: type[Warning], *args: Any, **kwargs: Any) -> None:
            if issubclass(category, Prs3Warning):
                click.echo(f"prs3-post: warning: {message}", err=True)
            else:
                shown(message, category, *args, **kwargs)

        warnings.showwarning = show
        yield


def run_reported(action: Callable[[], int | None]) -> None:
    """Run a command body; report :class:`Prs3Error` as one line and exit with its code.

    Before anything, outputs that name an input are refused; a standard output that cannot be
    written (full, closed pipe) is reported like any other error."""
    try:
        ctx = click.get_current_context(silent=True)
        if ctx is not None:
            _refuse_overwriting_inputs(ctx)
        try:
            with warnings_to_stderr():
                code = action()
            sys.stdout.flush()
        except OSError as exc:                       # the library reports its own I/O as Prs3Error
            failed = stdout_error(exc)
            if failed is None:
                raise                                # not standard output: a bug, and its traceback helps
            raise failed from exc
    except Prs3Error as error:
        click.echo(f"prs3-post: error: {error}", err=True)
        sys.exit(error.exit_code)
    except MemoryError:                              # no traceback: it would say nothing more (and need memory)
        click.echo(f"prs3-post: error: {OUT_OF_MEMORY}", err=True)
        sys.exit(1)
    sys.exit(code or 0)


#: What a command that ran out of memory says (nothing is written: outputs are atomic).
OUT_OF_MEMORY = ("out of memory: the machine, or a limit on this process (ulimit -v), left too little; nothing "
                 "was written (free some memory, or convert the files one at a time with --jobs 1)")


def demo_part() -> Path:
    """The bundled demo part: the paper's wedge."""
    return postproc_dir() / "parts" / "patel2020-wedge.stl"


up_option = click.option(
    "--up", type=click.Choice(list(UP_ROTATION)), default="z", show_default=True,
    help="The STL's up axis; the part is turned so that it becomes +z: "
         + ", ".join(f"{axis}: {turn}" for axis, (turn, _) in UP_ROTATION.items() if axis != "z") + ".",
)


part_origin_option = click.option(
    "--part-origin", type=Numbers("X,Y,Z"), default=None,
    help="Machine coordinates of the part origin, mm.  [default: the machine file's setup]",
)
part_rotation_option = click.option(
    "--part-rotation", "part_rotation", type=Decimal(ANGLE), default=None, metavar="DEG",
    help="Rotation of the part about the machine z axis, degrees, counter-clockwise seen from above "
         "(p_machine = Rz(DEG)·p_part + part origin).  [default: 0]",
)


class OrAuto(click.ParamType):
    """``auto`` or a value of ``inner``: the main job's setup options."""

    def __init__(self, inner: click.ParamType):
        self.inner = inner
        self.name = f"auto|{inner.name}"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        return AUTO if value == AUTO else self.inner.convert(value, param, ctx)


_AUTO_HELP = ("auto: chosen so that every point of the job keeps the largest margin to every limit, as a fraction "
              "of the limit's range (printed, and written to the program's header).")
job_part_origin_option = click.option(
    "--part-origin", type=OrAuto(Numbers("X,Y,Z")), default=None, metavar="auto|X,Y,Z",
    help="Machine coordinates of the part origin, mm; " + _AUTO_HELP + "  [default: the machine file's setup]",
)
job_part_rotation_option = click.option(
    "--part-rotation", "part_rotation", type=OrAuto(Decimal(ANGLE)), default=None, metavar="auto|DEG",
    help="Rotation of the part about the machine z axis, degrees, counter-clockwise seen from above "
         "(p_machine = Rz(DEG)·p_part + part origin); auto: chosen with the part origin (or for the one given), "
         "searched in 0.1° steps.  [default: 0]",
)


def resolve_setup(machine: Machine, origin: tuple[float, ...] | str | None, rotation_deg: float | str | None) -> Setup:
    """The job's :class:`Setup` from --part-origin / --part-rotation (None: the machine's default; ``auto``:
    the default until the job chooses it)."""
    try:
        return Setup.resolve(machine, None if origin == AUTO else origin,  # type: ignore[arg-type]
                             None if rotation_deg == AUTO else rotation_deg)  # type: ignore[arg-type]
    except SetupError as error:
        hint = "'--part-rotation'" if error.field == "rotation" else "'--part-origin'"
        raise click.BadParameter(str(error), param_hint=hint) from error


machine_option = click.option(
    "--machine", "machine_name", default=DEFAULT_MACHINE, show_default=True, metavar="NAME|PATH",
    help="Shipped machine name (see `prs3-post machines`) or path to a machine TOML file.",
)


dialect_option = click.option(
    "--dialect", "dialect_name", default=DEFAULT_DIALECT, show_default=True, metavar="NAME|PATH",
    help="G-code dialect: linuxcnc, fanuc, or a dialect TOML file.",
)
line_number_options = (
    click.option("--line-numbers/--no-line-numbers", default=None,
                 help="Number the blocks (N words).  [default: as the dialect says]"),
    click.option("--line-start", type=Integer(0, 99999), default=None, help="First block number."),
    click.option("--line-step", type=Integer(1, 1000), default=None, help="Block number increment."),
)
tolerance_option = click.option(
    "--tolerance", type=Decimal(LENGTH), default=DEFAULT_TOLERANCE, show_default=True,
    help="Chordal tolerance of arcs (and of moves that turn the tool axis), mm (0.0001 to 1).",
)


# ----------------------------------------------------------------------------- commands


def _takes_value(option: click.Option) -> bool:
    return not (option.is_flag or option.count)


def _occurrences(params: list[click.Parameter], args: list[str]) -> Iterator[tuple[click.Option, str]]:
    """``(option, value as written)`` for each option in ``args`` (a flag's value: its spelling), as
    click reads them: ``--name VALUE``, ``--name=VALUE``, ``-o VALUE``, ``-oVALUE``, grouped short
    flags, and nothing after ``--``. An unknown option is passed over (click reports it)."""
    named = {name: p for p in params if isinstance(p, click.Option) for name in (*p.opts, *p.secondary_opts)}
    i = 0
    while i < len(args):
        arg = args[i]
        i += 1
        if arg == "--":
            return
        if not arg.startswith("-") or arg == "-":
            continue
        if arg.startswith("--"):
            name, equals, value = arg.partition("=")
            option = named.get(name)
            if option is None:
                continue
            if _takes_value(option) and not equals:
                value = " ".join(args[i:i + option.nargs])
                i += option.nargs
            yield option, value if _takes_value(option) else name
            continue
        for at in range(1, len(arg)):                     # -o VALUE, -oVALUE, -ab (flags)
            option = named.get("-" + arg[at])
            if option is None:
                break
            if _takes_value(option):
                value = arg[at + 1:]
                if not value:
                    value = " ".join(args[i:i + option.nargs])
                    i += option.nargs
                yield option, value
                break
            yield option, "-" + arg[at]


class _Command(click.Command):
    """A command whose single-valued options may be given once: ``--profile hole --profile square``
    (or ``-o a -o b``, ``--collision-check --no-collision-check``) is refused, naming both, instead
    of click's silent last-one-wins. Options made to repeat (``multiple``, ``count``) may repeat."""

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        first: dict[str, str] = {}
        for option, value in _occurrences(self.get_params(ctx), args):
            if option.multiple or option.count or option.is_eager or option.name is None:
                continue
            if option.name in first:
                names = "/".join(sorted((*option.opts, *option.secondary_opts), key=lambda n: (len(n) > 2, n)))
                ctx.fail(f"{names} given twice ({quoted(first[option.name])} and {quoted(value)}): give it once")
            first[option.name] = value
        return super().parse_args(ctx, args)


class _MainGroup(click.Group):
    """A group whose first argument may be a part file: ``prs3-post PART.stl ...`` means ``run``."""

    command_class = _Command

    def main(self, *args: Any, **kwargs: Any) -> Any:
        """click's main; a standard output that cannot take what click itself prints (``--help``,
        ``--version``, usage errors go to standard error) is reported as the commands report it."""
        try:
            return super().main(*args, **kwargs)
        except OSError as exc:
            failed = stdout_error(exc)
            if failed is None:
                raise
            click.echo(f"prs3-post: error: {failed}", err=True)
            sys.exit(failed.exit_code)

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        if args and (not args[0].startswith("-") or args[0] == "-") and args[0] not in self.commands:   # '-': run's
            first = args[0]
            if not (Path(first).suffix or os.sep in first or os.path.lexists(first) or first == "-"):   # a word
                near = difflib.get_close_matches(first, list(self.commands), n=1)
                hint = f"did you mean '{near[0]}'? " if near else ""
                ctx.fail(f"no such command or file {quoted(first)} ({hint}commands: {', '.join(sorted(self.commands))};"
                         " or a part file: prs3-post PART.stl --profile ...)")
            args = ["run", *args]
        return super().parse_args(ctx, args)


@click.group(cls=_MainGroup, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="prs3-post")
def main() -> None:
    """prs3-post: the post-processor for 3-PRS parallel-kinematic machines.

    Drills and grooves inclined faces with the tool normal to the face: reads an STL part, finds
    its inclined face, plans the operation and writes a G-code program in actuator space
    (stage X, Y and strokes T1, T2, T3 as U, V, W), checked against every machine limit.

    \b
    Examples:
      prs3-post demo --profile square -o demo.ngc        (the paper's wedge, bundled)
      prs3-post part.stl --profile hole --depth 8 --peck 2 -o part.ngc
      prs3-post faces part.stl
      prs3-post ik --tip -81.0264,21.2132,-679.4865 --axis 0.447214,0,0.894427
      prs3-post fk --strokes 36.2244,170.3886,88.9519 --xy -2.7640,12.0703
    """


@main.command()
@click.option("--tip", type=Numbers("X,Y,Z"), help="Tool tip in the machine frame, mm (part-relative, stage included).")
@click.option("--axis", type=Numbers("I,J,K", RATIO),
              help="Tool axis from the tip toward the spindle (normalized; K > 0).")
@click.option(
    "--batch", "batch_path", type=click.Path(dir_okay=False), metavar="POSES.csv",
    help="Many poses: CSV with header tip_x,tip_y,tip_z,axis_x,axis_y,axis_z.",
)
@click.option("-o", "--output", "out_path", type=OutputPath(), help="Batch output CSV (default: standard output).")
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
    from prs3_post.app.pose_tables import ik_records, ik_text

    def body() -> int:
        machine = load_machine(machine_name)
        if batch_path is not None:
            if tip is not None or axis is not None:
                raise click.UsageError("--batch cannot be combined with --tip/--axis")
            from prs3_post.app.ik_batch import IKBatch

            batch = IKBatch(machine, batch_path, model=IKModel(model))
            write_outputs([(out_path, batch.chunks())])
            if batch.summary():
                click.echo(f"prs3-post: {batch.summary()}", err=True)
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
        click.echo(json.dumps(record, indent=2, allow_nan=False) if as_json else ik_text(record), nl=as_json)
        return 0 if record["ok"] else 1

    run_reported(body)


@main.command()
@click.option("--strokes", type=Numbers("T1,T2,T3"), required=True,
              help="Actuator strokes, mm (downward from the base).")
@click.option("--xy", type=Numbers("X,Y"), default="0,0", show_default=True, help="Stage position X, Y, mm.")
@machine_option
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
def fk(strokes: tuple[float, ...], xy: tuple[float, ...], machine_name: str, as_json: bool) -> None:
    """Forward kinematics: strokes T1..T3 (and stage X, Y) → tool tip, tool axis and link angles.

    The setting is checked against the machine's limits, as `ik` checks a pose (violations are
    listed with their margins); the exit status is 1 when it is outside a limit.

    \b
    Example:
      prs3-post fk --strokes 36.2244,170.3886,88.9519 --xy -2.7640,12.0703
    """
    from prs3_post.app.pose_tables import fk_records, fk_text

    def body() -> int:
        machine = load_machine(machine_name)
        if not machine.stage.present and _given(click.get_current_context(), "xy"):
            raise click.BadParameter(f"machine {machine.name} has no stage (stage.present = false): the tip is "
                                     "where the head puts it; leave --xy out", param_hint="'--xy'")
        result = forward(machine.geometry, np.array([strokes]), np.array([xy]))
        if not result.converged[0]:
            raise ReachError(
                f"strokes {', '.join(f'{s:g}' for s in strokes)} mm do not assemble the head of {machine.name} "
                f"(no rigid platform pose after {result.iterations[0]} Newton steps; "
                f"side-length error {result.residual[0]:.3g} mm)"
            )
        model = IKModel.EXACT if machine.stage.present else IKModel.HEAD
        pose = inverse(machine.geometry, result.tip, result.axis, model=model)     # the same strokes, checked
        record = fk_records(result, check_limits(machine, pose, result.axis))[0]
        click.echo(json.dumps(record, indent=2, allow_nan=False) if as_json else fk_text(record), nl=as_json)
        return 0 if record["ok"] else 1

    run_reported(body)


@main.command()
def machines() -> None:
    """List the shipped machines (use a name or a TOML path with --machine).

    Each line: name, whether it has an XY stage, and its description. The files live in
    postproc/machines/ (every key commented); copy one to describe your own machine.

    \b
    Example:
      prs3-post machines
      prs3-post ik --tip 0,200,-680 --axis 0,0,1 --machine my-machine.toml
    """

    def body() -> int:
        for name in shipped_names("machines"):
            machine = load_machine(name)
            stage = "XY stage" if machine.stage.present else "no stage"
            click.echo(f"{name:<18} {stage:<9} {machine.description}")
        return 0

    run_reported(body)


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


@main.command()
def sources() -> None:
    """List the shipped 5-axis source conventions (how a program for another machine gives its tool axis).

    Each line: name, the rotary words (or the vector words), the TCP on/off codes and the
    description. The files live in postproc/sources/ (every key commented); copy one to describe
    another machine.

    \b
    Example:
      prs3-post sources
    """

    def body() -> int:
        for name in shipped_names("sources"):
            source = load_source(name)
            words = " ".join(source.words or source.vector_words)
            tcp = f"{'/'.join(source.tcp_on)} {'/'.join(source.tcp_off)}"
            click.echo(f"{name:<14} {words:<6} {tcp:<12} {source.description}")
        return 0

    run_reported(body)


# ----------------------------------------------------------------------------- the main job


def _job_options(func: Callable[..., Any]) -> Callable[..., Any]:
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
        click.option("--clearance-min", type=CLEARANCE_MIN, default=1.0, show_default=True,
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


def _refuse_unused_options(profile: str) -> None:
    """A usage error for options the main job was given that ``--profile`` ignores (``--diameter`` on a square)."""
    ctx = click.get_current_context()
    unused = _unused_by(profile, [name for name in _PROFILE_ONLY if _given(ctx, name)])
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

    _refuse_unused_options(opts["profile"])
    spec = _job_spec(part, opts)
    fmt = _image_format(opts["preview_path"], "'--preview'") if opts["preview_path"] else None
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
                              closest=job.closest)
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


def _face_index(choice: str) -> int | None:
    """``auto`` → None, ``7`` → 7 (ASCII digits only: ``²`` is a digit to Python, not to us)."""
    if choice == "auto":
        return None
    if re.fullmatch(r"[0-9]+", choice):
        return int(choice)
    raise click.BadParameter(f"expected auto or a face index, got {quoted(choice)}", param_hint="'--face'")


def _job_spec(part: str, opts: dict[str, Any]) -> JobSpec:
    """The JobSpec the main job's options describe (also rebuilt by `verify --against PART.stl`)."""
    from prs3_post.app.job import JobSpec
    from prs3_post.readers.tooltable import read_tool_table

    operation = Operation(opts["profile"])
    depth = opts["depth"] if opts["depth"] is not None else (5.0 if operation is Operation.HOLE else 2.0)
    face = _face_index(opts["face_choice"])
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
        clearance_min=opts.get("clearance_min", 1.0),
    )


@main.command()
@click.argument("part", type=click.Path(dir_okay=False), metavar="PART.stl")
@_job_options
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


@main.command()
@_job_options
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

    params = {p.name: p for p in _job_options(lambda **_: None).__click_params__}  # type: ignore[attr-defined]
    table: ToolTable | None = read_tool_table(job.settings["tool_table"]) if "tool_table" in job.settings else None
    ctx = click.Context(main)
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
            spec = _job_spec(job.part, opts)
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


@main.command()
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


@main.command()
@click.argument("part", type=click.Path(dir_okay=False), metavar="PART.stl")
@click.option("--units", type=click.Choice(["mm", "inch"]), default="mm", show_default=True,
              help="Length unit of the STL.")
@up_option
@click.option("--json", "as_json", is_flag=True, help="Print the table as JSON.")
def faces(part: str, units: str, up: str, as_json: bool) -> None:
    """List a part's faces: index, area, width, inclination, normal, origin, kind; and the automatic choice.

    Each face says whether automatic selection may take it and why not: it must face up, be inclined
    between 1° and 89°, be a planar face of the design (not a strip of a tessellated curved surface:
    a fillet, a hole wall) and be at least 3 mm wide (the main job: as wide as its tool). A Y-up export needs
    --up y; a part that loads with a size warning probably needs --units inch.

    \b
    Examples:
      prs3-post faces part.stl --json
      prs3-post faces angle_block.STL --units inch --up y
    """
    from prs3_post.part.faces import face_table, find_faces, format_face_table, select_face
    from prs3_post.part.stl import load_part


    def body() -> int:
        found = find_faces(load_part(part, units=units, up=up))
        if as_json:
            click.echo(json.dumps(face_table(found), indent=2, allow_nan=False))
            return 0
        click.echo(format_face_table(found), nl=False)
        try:
            click.echo(select_face(found, None)[1])
        except FeatureError as error:
            click.echo(f"auto: {error}")
        return 0

    run_reported(body)


# ----------------------------------------------------------------------------- verify and preview


def _against_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """The main job's options, for `verify --against PART.stl` to rebuild the intended path with:
    the same options and defaults, but --profile not required and without the output-only ones (a
    program with a prs3-post header needs none of them: they may only repeat what it says)."""
    probe = _job_options(lambda **_: None)
    skip = {"out_path", "preview_path", "line_numbers", "line_start", "line_step", "tool_table"}
    params = getattr(func, "__click_params__", [])
    borrowed: list[click.Parameter] = probe.__click_params__  # type: ignore[attr-defined]  # click stores them here
    for param in borrowed:                           # in click's stored (reversed) order
        if param.name in skip:
            continue
        if param.name == "profile":
            param.required = False
            param.help = "Operation the program was made with (only with --against PART.stl)."
        if param.name == "tolerance":
            param.help = ("Allowed tip deviation, mm (0.0001 to 1; plus the output rounding against a path); also "
                          "the chordal tolerance the job is rebuilt with for --against PART.stl.")
        params.append(param)
    func.__click_params__ = params                   # type: ignore[attr-defined]
    return func


#: The main job's options that describe the operation: `verify` uses them only with --against PART.stl.
_OPERATION_OPTIONS = (
    "profile", "face_choice", "at_uv", "at_xyz", "units", "up", "depth", "peck", "reapproach_gap", "dwell", "size",
    "corner_radius", "rotation", "diameter", "side", "step_down", "direction", "entry", "ramp_angle", "clearance",
    "retract", "tool_diameter", "tool_number", "feed", "plunge_feed", "spindle", "coolant",
)


def _option_flags(ctx: click.Context, names: list[str]) -> list[str]:
    """The flags as the user spells them (``--face`` for the parameter ``face_choice``)."""
    flags = {f"--{p.name.replace('_', '-')}": p.opts[0] for p in ctx.command.params if p.name}
    return [flags.get(name, name) for name in names]


def _image_format(path: str, flag: str) -> str:
    """``png`` or ``svg`` from an output file's suffix; ``flag`` names the option in the error."""
    suffix = Path(path).suffix.lower()
    if suffix not in (".png", ".svg"):
        raise click.BadParameter(f"the image must end in .png or .svg, got {path!r}", param_hint=flag)
    return suffix[1:]


def _given(ctx: click.Context, name: str) -> bool:
    """Whether the user gave the option (not its default)."""
    return ctx.get_parameter_source(name) is not click.core.ParameterSource.DEFAULT


#: The flag of each value a program header records, for messages about a contradiction.
_HEADER_FLAGS = {"machine": "--machine", "dialect": "--dialect", "part origin": "--part-origin",
                 "part rotation": "--part-rotation", "part": "--against"}


def _open_program(ctx: click.Context, path: str, machine_name: str, dialect_name: str,
                  part_origin: tuple[float, ...] | None, part_rotation: float | None,
                  opener: Callable[..., _Opened]) -> _Opened:
    """The program (``open_program``), or its setting only (``open_setting``), with the machine, dialect and setup
    of its header, or those given."""
    from prs3_post.app.verify import HeaderConflict

    for value, flag in ((part_origin, "--part-origin"), (part_rotation, "--part-rotation")):
        if value == AUTO:
            raise click.BadParameter("auto chooses the setup when a program is made; a program is read with the "
                                     "setup its header states (or the one given as numbers)", param_hint=f"'{flag}'")
    try:
        return opener(path, machine=machine_name if _given(ctx, "machine_name") else None,
                      dialect=dialect_name if _given(ctx, "dialect_name") else None,
                      origin=part_origin, rotation_deg=part_rotation)
    except SetupError as error:
        raise click.BadParameter(str(error), param_hint=_SETUP_HINTS[error.field]) from error
    except HeaderConflict as error:
        raise InputError(f"{_HEADER_FLAGS[error.what]}: {error.args[0]}", path=error.path, line=error.line) from error


def _refuse_cl_file(path: str) -> None:
    """CAM output given where a program for this machine goes (verify, preview): say so, not 'not G-code'.
    Only a file that starts as an APT CL file does (:func:`~prs3_post.readers.detect.detect_format`); any
    other problem is the program reader's to name."""
    from prs3_post.core.input_files import open_input
    from prs3_post.readers.detect import DETECT_BYTES, detect_format

    try:
        with open_input(path, "a file") as stream:
            cl = detect_format(stream.read(DETECT_BYTES)) == "cl"
    except (InputError, OSError):
        return
    if cl:
        raise InputError(f"an APT CL file (CAM output), not a program for this machine: convert it first "
                         f"(prs3-post convert {path} -o OUTDIR), then give the program, with --against {path} to "
                         "compare them", path=path)


_SETUP_HINTS = {"origin": "'--part-origin'", "rotation": "'--part-rotation'"}
#: Options given in degrees whose JobSpec value is in radians.
_DEGREE_OPTIONS = ("rotation", "ramp_angle")


def _operation_values(spec: JobSpec) -> dict[str, Any]:
    """The operation options of the main job that ``spec`` answers, in JobSpec units (angles in
    radians, positions as arrays, the face as an index or None)."""
    cut = spec.cutting
    values: dict[str, Any] = {
        "profile": spec.operation.value, "face_choice": spec.face, "at_uv": spec.at_uv, "at_xyz": spec.at_xyz,
        "units": spec.units, "up": spec.up, "tool_diameter": cut.tool_diameter, "tool_number": cut.tool_number,
        "feed": cut.feed, "plunge_feed": cut.plunge_feed, "spindle": cut.spindle_rpm, "coolant": cut.coolant.value,
    }
    work = spec.work
    if isinstance(work, HoleJob):
        h = work.params
        values |= {"depth": h.depth, "peck": h.peck, "reapproach_gap": h.reapproach_gap, "dwell": h.dwell,
                   "clearance": h.clearance, "retract": h.retract}
        return values
    p, shape = work.params, work.shape
    if isinstance(shape, SquareShape):
        values |= {"size": shape.size, "corner_radius": shape.corner_radius, "rotation": shape.rotation}
    else:
        values |= {"diameter": shape.diameter}
    values |= {"side": p.side.value, "depth": p.depth, "step_down": p.step_down, "direction": p.direction.value,
               "entry": p.entry.value, "ramp_angle": p.ramp_angle, "clearance": p.clearance, "retract": p.retract}
    return values


def _as_spec_value(name: str, value: Any) -> Any:
    """An option's value in JobSpec units (see _operation_values)."""
    if name in _DEGREE_OPTIONS:
        return math.radians(value)
    if name == "face_choice":
        return _face_index(value)
    if name in ("at_uv", "at_xyz"):
        return np.array(value, dtype=np.float64).reshape(-1, 2 if name == "at_uv" else 3)
    return value


def _check_operation_options(ctx: click.Context, spec: JobSpec, opts: dict[str, Any]) -> None:
    """Operation options given with a program that has a header must say what the header says."""
    recorded = _operation_values(spec)
    wrong = []
    for name in _OPERATION_OPTIONS:
        if not _given(ctx, name) or name not in recorded:
            continue
        given, header = _as_spec_value(name, opts[name]), recorded[name]
        same = np.array_equal(given, header) if isinstance(header, np.ndarray) else given == header
        if not same:
            shown = header
            if name in _DEGREE_OPTIONS:
                shown = math.degrees(header)
            elif isinstance(header, np.ndarray):
                shown = " ".join(",".join(f"{v:g}" for v in row) for row in header) or "none"
            elif header is None:
                shown = "auto"
            wrong.append(f"{_option_flags(ctx, [f'--{name.replace(chr(95), chr(45))}'])[0]} (header: {shown})")
    _refuse_contradictions(wrong)


def _refuse_contradictions(wrong: list[str]) -> None:
    """A usage error for options that say otherwise than the program's header (``--depth (header: 5)``)."""
    if len(wrong) == 1:
        raise click.UsageError(f"{wrong[0]}: contradicts the program's header; leave it out to use the header's value")
    if wrong:
        raise click.UsageError(f"{', '.join(wrong)}: contradict the program's header; leave them out to use the "
                               "header's values")


def _intended(ctx: click.Context, against: str, context: ProgramContext,
              opts: dict[str, Any]) -> tuple[Intended | None, RebuiltJob | CamPart | None]:
    """The intended path of `verify --against`: the job rebuilt from PART.stl and the program's header
    (or, without a header, the options), with that job (for the clearance from the part), or POSES.csv;
    a converted program's CAM input, or its part (PART.stl: the clearance only, no path)."""
    from prs3_post.app.verify import (
        CamPart,
        HeaderConflict,
        header_job,
        intended_from_poses,
        intended_from_source,
        rebuild_job,
    )
    from prs3_post.check.collision import rapid_diameter_from_entry
    from prs3_post.emit.header import SourceHeader
    from prs3_post.part.stl import load_part

    suffix = Path(against).suffix.lower()
    if isinstance(context.header, SourceHeader) and suffix == ".stl":   # the part a CAM program cuts
        mesh = load_part(against, units=opts["units"], up=opts["up"])
        return None, CamPart(triangles=np.asarray(mesh.triangles, dtype=np.float64),
                             tool_length=context.header.tool_length, setup=context.header.setup,
                             tool_diameter=rapid_diameter_from_entry(context.header.collision))
    if isinstance(context.header, SourceHeader):            # a converted program: its CAM source
        try:
            return intended_from_source(context, against), None
        except HeaderConflict as error:
            raise InputError(f"--against: {error.args[0]}", path=error.path, line=error.line) from error
    if suffix == ".stl":
        if context.header is not None:
            try:
                specs = header_job(context, against)
            except HeaderConflict as error:
                raise InputError(f"--against: {error.args[0]}", path=error.path, line=error.line) from error
            for spec in specs:                         # an option given must be what every operation says
                _check_operation_options(ctx, spec, opts)
            rebuilt = rebuild_job(specs)
        elif not opts["profile"]:
            raise click.UsageError("--against PART.stl needs --profile and the other operation options the "
                                   "program was made with (it has no prs3-post header that records them)")
        else:
            _refuse_unused_options(opts["profile"])
            rebuilt = rebuild_job(_job_spec(against, opts))
        return rebuilt.intended, rebuilt
    if suffix == ".csv":
        return intended_from_poses(against, context.program), None
    raise InputError("--against takes PART.stl (with the operation options the program was made with), "
                     "POSES.csv (one pose per motion line), or the CAM file a program was converted from (its "
                     "header names it)", path=against)


@main.command()
@click.argument("program_path", type=click.Path(dir_okay=False), metavar="PROGRAM.ngc")
@click.option("--against", "against_path", type=click.Path(dir_okay=False), metavar="PART.stl|POSES.csv|INPUT",
              help="The intended path: PART.stl (the operation is rebuilt from the program's header; a program "
                   "without one needs the options it was made with: --profile, --at, --depth, ...), "
                   "or POSES.csv (the `ik --batch` format, "
                   "machine frame, one pose per G0/G1 line), or for a program made by `prs3-post convert` its CAM "
                   "input (APT CL or G-code; checked by the SHA-256 its header records).")
@click.option("--axis-tolerance", "axis_tolerance_deg", type=Decimal(ANGLE), default=DEFAULT_ANGLE_TOLERANCE_DEG,
              show_default=True,
              help="Allowed tool-axis deviation from the --against path, degrees.")
@click.option("--json", "as_json", is_flag=True,
              help="Print the complete report as JSON: every move, the FK tool-tip path in part coordinates, "
                   "every limit's closest approach, feeds, deviations, problems.")
@_against_options
def verify(program_path: str, against_path: str | None, axis_tolerance_deg: float, as_json: bool,
           **opts: Any) -> None:
    """Replay a program through forward kinematics and check it: limits, straightness, feeds, deviation.

    Reads PROGRAM.ngc in --dialect (letters, decimals, comments), samples every move in joint
    space as the controller interpolates it (X, Y, T1..T3 linear; at least 8 samples per move,
    more where the tip path or a link angle curves, so that what falls between samples is below
    --tolerance / 20) and checks every sample:

    \b
    - limits: the closest approach to each limit of --machine (value, margin, line);
    - straightness: a G1's tip stays within --tolerance of the line between its end points;
    - feeds: implied tip feed = chord × F (G93, F = 1/min); against PART.stl it must equal the
      intended feed within the rounding of F and the points; otherwise a G1 whose feed matches
      no other G1 is warned about (a hand edit?), except in a converted program (the CAM's feeds);
    - with --against: tip and axis deviation from the intended path (max, mean, line); allowed:
      --tolerance plus what the output rounding moves the tip, and --axis-tolerance.

    A program made by prs3-post states in its header the machine, dialect, setup and operation it
    was made with: they are used, and an option that says otherwise is an error (leave it out).
    A program without that header is read with the options given (or their defaults).

    --tolerance (mm; default: the program's, else 0.002) is the allowed tip deviation. The
    operation options (--profile ... --retract) are used only with --against PART.stl, and only
    for a program without a header. Exit status: 0 within every limit and tolerance, 1 if not,
    2 for a program or option it cannot read.

    \b
    Examples:
      prs3-post demo --profile square -o sq.ngc
      prs3-post verify sq.ngc
      prs3-post verify sq.ngc --against postproc/parts/patel2020-wedge.stl --json
      prs3-post verify paper_2a_2b.ngc --against paper_2a_2b.csv
    """
    from prs3_post.app.verify import (
        PartClearance,
        check_program_moves,
        odd_feeds_warned,
        open_program,
        open_setting,
        tool_lengths_of,
        verify_file,
        verify_loaded,
        with_clearance,
    )
    from prs3_post.app.verify_report import report_record, report_text


    def body() -> int:
        ctx = click.get_current_context()
        _refuse_cl_file(program_path)
        require_tolerance(opts["tolerance"])
        if not (math.isfinite(axis_tolerance_deg) and axis_tolerance_deg >= 0):
            raise click.BadParameter(f"must be a number ≥ 0 degrees, got {axis_tolerance_deg:g}",
                                     param_hint="'--axis-tolerance'")
        if not (against_path and Path(against_path).suffix.lower() == ".stl"):
            given = [f"--{name.replace('_', '-')}" for name in (*_OPERATION_OPTIONS, "collision_check", "clearance_min")
                     if _given(ctx, name)]
            if given:
                raise click.UsageError(f"{', '.join(_option_flags(ctx, given))}: the operation options are only "
                                       "used with --against PART.stl")
        where = (ctx, program_path, opts["machine_name"], opts["dialect_name"], opts["part_origin"],
                 opts["part_rotation"])
        # the text report without an intended path needs no samples: the program streams through
        setting = _open_program(*where, open_setting)
        # the check's tolerance: as given, else the one the program was made with
        tolerance = (setting.header.tolerance if setting.header is not None and not _given(ctx, "tolerance")
                     else opts["tolerance"])
        clearance: PartClearance | str | None = None
        if as_json or against_path:
            context = _open_program(*where, open_program)
            check_program_moves(context.header, len(context.program.moves))
            intended, rebuilt = _intended(ctx, against_path, context, opts) if against_path else (None, None)
            report = verify_loaded(context.program, context.machine, context.setup, context.dialect,
                                   tolerance=tolerance, axis_tolerance_deg=axis_tolerance_deg, intended=intended,
                                   tool_lengths=tool_lengths_of(context.header),
                                   odd_feeds=odd_feeds_warned(context.header))
            if rebuilt is not None and not opts["collision_check"]:
                clearance = "not measured (asked not to)"
            elif rebuilt is not None:                  # the clearance min: as given, else each operation's
                report, clearance = with_clearance(
                    report, context.machine, rebuilt,
                    clearance_min=opts["clearance_min"] if _given(ctx, "clearance_min") else None)
        else:
            report = verify_file(setting, tolerance=tolerance, axis_tolerance_deg=axis_tolerance_deg)
        dialect = setting.dialect.name
        if as_json:
            click.echo(json.dumps(report_record(report, path=program_path, dialect=dialect, clearance=clearance),
                                  allow_nan=False))
        else:
            click.echo(report_text(report, path=program_path, dialect=dialect, clearance=clearance), nl=False)
        return 0 if report.ok else 1

    run_reported(body)


@main.command()
@click.argument("program_path", type=click.Path(dir_okay=False), metavar="PROGRAM.ngc")
@click.option("-o", "--output", "out_path", type=OutputPath(), required=True,
              metavar="OUT.png|OUT.svg",
              help="Image file (PNG or SVG by suffix; written to a temp file, then renamed).")
@click.option("--part", "part_path", type=click.Path(dir_okay=False), metavar="PART.stl",
              help="Draw the part (part coordinates) and highlight its face (--face).")
@click.option("--face", "face_choice", default="auto", show_default=True, metavar="auto|N",
              help="Face to highlight: auto = the main job's automatic choice; N = index from `prs3-post faces`.")
@click.option("--units", type=click.Choice(["mm", "inch"]), default="mm", show_default=True,
              help="Length unit of the STL.")
@up_option
@machine_option
@click.option("--dialect", "dialect_name", default=DEFAULT_DIALECT, show_default=True, metavar="NAME|PATH",
              help="G-code dialect of the program: linuxcnc, fanuc, or a dialect TOML file.")
@part_origin_option
@part_rotation_option
@click.option("--rapid-rate", type=Decimal(FEED, low=0.0, low_open=True), default=5000.0, show_default=True,
              help="Joint-space rate of G0 moves for the time axis, mm/min (the longest joint travel at this rate), "
                   "for a machine without [dynamics]; with them the axis shows the cycle time.")
def preview(program_path: str, out_path: str, part_path: str | None, face_choice: str, units: str, up: str,
            machine_name: str, dialect_name: str, part_origin: tuple[float, ...] | None, part_rotation: float | None,
            rapid_rate: float) -> None:
    """Draw a program: the FK tool path on the part, the axes over time, the limit margins.

    One figure: (a) 3D view in part coordinates of the part mesh (--part), its face (highlighted)
    and the tool-tip path replayed through forward kinematics (G1 solid, G0 dashed) with the tool
    axis at a few points; (b) the strokes T1..T3 and stage X, Y over program time (the cycle time
    of the machine's [dynamics]; without them G1: 1/F min, G0: the longest joint travel at
    --rapid-rate), the machine's limits shaded; (c) the worst margin
    of every limit as a fraction of its range. Needs matplotlib: pip install 'prs3-post[plot]'.
    The machine, dialect and setup (and the part's units, up axis and face) come from the program's
    header when it has one; an option that says otherwise is an error.
    `prs3-post PART.stl ... --preview OUT.png` makes a program and its picture in one step.

    \b
    Examples:
      prs3-post demo --profile square -o sq.ngc
      prs3-post preview sq.ngc --part postproc/parts/patel2020-wedge.stl -o sq.png
      prs3-post demo --profile round -o round.ngc --preview round.svg
    """
    from prs3_post.app.verify import (
        HeaderConflict,
        check_part,
        header_job,
        open_program,
        preview_bytes,
        rebuild_job,
        tool_lengths_of,
    )
    from prs3_post.emit.header import ProgramHeader
    from prs3_post.part.faces import find_faces, select_face
    from prs3_post.part.stl import load_part


    def body() -> int:
        ctx = click.get_current_context()
        fmt = _image_format(out_path, "'-o' / '--output'")
        _refuse_cl_file(program_path)
        context = _open_program(ctx, program_path, machine_name, dialect_name, part_origin, part_rotation,
                                open_program)
        if context.machine.dynamics is not None and _given(ctx, "rapid_rate"):
            raise click.BadParameter(f"machine {context.machine.name} has [dynamics]: the time axis shows its cycle "
                                     "time (each axis's top speed); leave it out", param_hint="'--rapid-rate'")
        mesh = face = None
        rebuilt: RebuiltJob | None = None
        if part_path is not None:
            choice, part_units, part_up = _face_index(face_choice), units, up
            header = context.header
            if header is not None:                     # the part as the program was made from it
                try:
                    check_part(header, part_path)
                except HeaderConflict as error:
                    raise InputError(f"--part: {error.args[0]}", path=error.path, line=error.line) from error
                assert isinstance(header, ProgramHeader)   # check_part refuses a converted program's header
                recorded = {"face_choice": header.face, "units": header.units, "up": header.up}
                wrong = [f"{flag} (header: {'auto' if recorded[name] is None else recorded[name]})"
                         for name, flag in (("face_choice", "--face"), ("units", "--units"), ("up", "--up"))
                         if _given(ctx, name) and _as_spec_value(name, {"face_choice": face_choice, "units": units,
                                                                         "up": up}[name]) != recorded[name]]
                _refuse_contradictions(wrong)
                choice, part_units, part_up = header.face, header.units, header.up
                # the job it was made by: where its tool, holder and nose come closest to the part
                rebuilt = rebuild_job(header_job(context, part_path)) if context.machine.holder is not None else None
            loaded = load_part(part_path, units=part_units, up=part_up)
            face, _ = select_face(find_faces(loaded), choice)
            mesh = loaded.triangles
        image = preview_bytes(context.program, context.machine, context.setup, fmt, dialect=context.dialect,
                              mesh=mesh, face=face, rapid_rate=rapid_rate, tool_lengths=tool_lengths_of(context.header),
                              title=Path(part_path).name if part_path else "", rebuilt=rebuilt)
        write_atomic(out_path, image)
        click.echo(f"prs3-post: wrote {out_path}", err=True)
        return 0

    run_reported(body)


# ----------------------------------------------------------------------------- convert


@main.command()
@click.argument("inputs", nargs=-1, required=True, metavar="INPUT...")
@click.option("-o", "--output-dir", "outdir", type=click.Path(file_okay=False), required=True, metavar="OUTDIR",
              help="Folder for the programs, OUTDIR/<input stem><dialect extension> (created if missing).")
@click.option("--jobs", type=Integer(1, 1024), default=None, help="Files converted at a time, in worker processes.  "
              "[default: the number of cores]")
@click.option("--fail-fast", is_flag=True, help="Stop at the first file that fails (files under way finish).")
@click.option("--force", is_flag=True,
              help="Replace programs that exist already (default: keep them; that file fails).")
@click.option("--format", "input_format", type=click.Choice(list(FORMATS)), default="auto", show_default=True,
              help="Input format: by content (CL records or G-code words), or forced.")
@click.option("--report", "report_path", type=OutputPath(), metavar="FILE.json",
              help="Write every file's accounting (records by word, moves, subdivisions, deviations) as JSON.")
@click.option("--tool-length", type=Decimal(LENGTH, low=0.0, low_open=True), default=None, metavar="MM",
              help="Platform centre to tool tip for the IK, mm.  [default: the machine's tool_length_mm]")
@click.option("--angle-tolerance", "angle_tolerance_deg", type=Decimal(ANGLE, low=0.0, low_open=True), default=0.01,
              show_default=True, metavar="DEG", help="Allowed tool-axis deviation of axis-changing moves, degrees.")
@click.option("--units", type=click.Choice(["mm", "inch"]), default=None,
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
              help="Length unit of the --part and --work-plane STL (--units is the CL files').")
@up_option
@click.option("--collision-check/--no-collision-check", default=True, show_default=True,
              help="With --part: check the holder, spindle nose and the tool in the rapids against it; the header "
                   "says when it was skipped.")
@click.option("--clearance-min", type=CLEARANCE_MIN, default=1.0, show_default=True,
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
def convert(inputs: tuple[str, ...], outdir: str, jobs: int | None, fail_fast: bool, force: bool, input_format: str,
            report_path: str | None, tool_length: float | None, angle_tolerance_deg: float, units: str | None,
            work_plane_text: str | None, ignore_words: tuple[str, ...], source_name: str | None,
            tcp_on: str | None, tcp_off: str | None, part_path: str | None, part_units: str, up: str,
            collision_check: bool, clearance_min: float, tool_diameter: float | None, machine_name: str,
            part_origin: tuple[float, ...] | str | None, part_rotation: float | str | None, dialect_name: str,
            line_numbers: bool | None, line_start: int | None, line_step: int | None, tolerance: float) -> None:
    """Convert CAM output (APT CL files, 3+2 G-code) into programs for this machine.

    INPUT is a file, a directory (searched recursively for .cls .clsf .cl .apt .nc .ngc .gcode
    .tap ... files) or a glob pattern. Each file goes through the main job's pipeline: setup, exact
    IK, subdivision of axis-changing moves, every point checked against every limit; its program
    is written whole or not at all. A failing file does not stop the others (unless --fail-fast);
    the summary lists every failure with file:line and reason. Exit status: 0 all converted; else
    the worst failure's: 2 for bad input (a file unreadable or not understood, an output kept
    because it exists) or bad options, 1 for a point outside a limit or out of reach, or files
    not started (--fail-fast).

    \b
    Examples:
      prs3-post convert ../shared/corpus/cl/mech491_APT_SimpleMillPlane.cls -o out --part-origin 0,-17.2,-856
      prs3-post convert cam/ -o out --part-origin auto --jobs 2 --report out/report.json
    """
    from prs3_post.app.convert import (
        ConvertSettings,
        batch_summary,
        collect_inputs,
        convert_batch,
        default_jobs,
        outcome_line,
        output_path,
        prepare_outdir,
    )
    from prs3_post.part.workplane import WorkPlaneError, work_plane_from_text

    def body() -> int:
        require_tolerance(tolerance)
        if outdir == "-":                                # it made a folder named '-'
            raise click.BadParameter("'-' is no folder: convert writes one program per input into OUTDIR, standard "
                                     "output cannot take them (a folder named '-' is ./-)",
                                     param_hint="'-o' / '--output-dir'")
        if report_path == "-":                           # the JSON went among the per-file lines
            raise click.BadParameter("'-': standard output has one line per file already, the report would be "
                                     "mixed into them (a file named '-' is ./-)", param_hint="'--report'")
        for word in ignore_words:
            if not word.strip():                         # a word no record has: taken, and nothing ignored
                raise click.BadParameter(f"{word!r}: give a CL major word, like PAINT", param_hint="'--ignore'")
        if part_path is None:                            # else taken and ignored: the user believed it checked
            ctx = click.get_current_context()
            for name, flag in (("tool_diameter", "--tool-diameter"), ("clearance_min", "--clearance-min")):
                if _given(ctx, name):
                    raise click.UsageError(f"{flag} is used only with --part PART.stl (the check against the part): "
                                           "give the part, or leave it out")
        low, high = TOOL_DIAMETER_RANGE
        if tool_diameter is not None and not low <= tool_diameter <= high:
            raise click.BadParameter(f"must be from {low:g} to {high:g} mm (got {tool_diameter:g})",
                                     param_hint="'--tool-diameter'")
        machine = load_machine(machine_name)
        dialect = load_dialect(dialect_name)
        try:
            plane = (work_plane_from_text(work_plane_text, units=part_units, up=up)[0]
                     if work_plane_text is not None else None)
        except (WorkPlaneError, InputError, FeatureError) as error:
            raise click.BadParameter(str(error), param_hint="'--work-plane'") from error
        source = None if source_name is None else load_source(source_name)
        if source is None:                               # else taken and ignored: a 3+2 or CL input has no TCP
            for flag, text in (("--tcp-on", tcp_on), ("--tcp-off", tcp_off)):
                if text is not None:
                    raise click.UsageError(f"{flag} is used only with --source (a 5-axis program's TCP codes): "
                                           "give the source machine, or leave it out")
        codes_on, codes_off = _codes_option(tcp_on, "--tcp-on"), _codes_option(tcp_off, "--tcp-off")
        try:
            settings = ConvertSettings(
                machine=machine, dialect=dialect, setup=resolve_setup(machine, part_origin, part_rotation),
                tolerance=tolerance, angle_tolerance_deg=angle_tolerance_deg, tool_length=tool_length,
                input_format=input_format, units=units, ignore=tuple(w.upper() for w in ignore_words),
                work_plane=plane, source=source, tcp_on=codes_on, tcp_off=codes_off,
                line_numbers=line_numbers, line_start=line_start, line_step=line_step,
                auto_origin=part_origin == AUTO, auto_rotation=part_rotation == AUTO, part=part_path,
                part_units=part_units, part_up=up, collision_check=collision_check, clearance_min=clearance_min,
                tool_diameter=tool_diameter)
        except ConfigError as error:                     # the TCP codes given do not work with the source
            given = [f"'{flag}'" for flag, codes in (("--tcp-on", codes_on), ("--tcp-off", codes_off)) if codes]
            if source is None or not given:
                raise
            raise click.BadParameter(f"{error.args[0]} (source {source.name})", param_hint=" / ".join(given)) from error
        repeats: list[tuple[str, str]] = []
        files = collect_inputs(inputs, exclude=outdir, exclude_suffix=dialect.extension, repeats=repeats)
        if report_path is not None:
            refuse_overwriting({"--report": report_path}, {f"{i + 1} ({f})": f for i, f in enumerate(files)})
            for file in files:                           # the report must not replace a program either
                refuse_overwriting({f"the program of {file}": output_path(file, outdir, dialect),
                                    "--report": report_path}, {})
            # before any work: a report that cannot be written (its folder may be OUTDIR, made by the batch)
            # realpath, not Path.resolve(): a loop of symbolic links is check_writable's clear error, not a RuntimeError
            folder, made = Path(os.path.realpath(report_path)).parent, Path(os.path.realpath(outdir))
            if folder == made:                           # (a report beside OUTDIR: no folder made if it fails)
                prepare_outdir(outdir)
            check_writable(report_path)
        count = jobs or default_jobs()
        terminal = sys.stderr.isatty()
        if terminal:
            with click.progressbar(length=len(files), label="converting", file=sys.stderr) as bar:
                result = convert_batch(files, outdir, settings, jobs=count, fail_fast=fail_fast, force=force,
                                       on_done=lambda outcome: bar.update(1))
        else:
            result = convert_batch(files, outdir, settings, jobs=count, fail_fast=fail_fast, force=force,
                                   on_done=lambda outcome: click.echo(outcome_line(_flag_named(outcome))))
        result = dataclasses.replace(result, outcomes=tuple(_flag_named(o) for o in result.outcomes))
        if report_path is not None:
            write_atomic(report_path, json.dumps(result.record(), indent=1, allow_nan=False) + "\n")
        click.echo(batch_summary(result), err=True, nl=False)
        if repeats:                                  # nothing named is left unsaid
            click.echo(f"prs3-post: {len(repeats)} more name{'s' if len(repeats) > 1 else ''} of files above, "
                       "each converted once: " + ", ".join(f"{name} (= {same})" for name, same in repeats), err=True)
        # the project's exit codes hold for a batch too: 2 when any file was bad input (unreadable, not
        # understood), else 1 when any failed a limit or reach or was not started, else 0
        codes = [outcome.exit_code for outcome in result.failures] + [1] * bool(result.not_started)
        return max(codes, default=0)

    run_reported(body)


def _flag_named(outcome: FileOutcome) -> FileOutcome:
    """A kept program's failure says which option replaces it (the library names no option)."""
    from prs3_post.app.convert import EXISTS

    if not outcome.exists:
        return outcome
    return dataclasses.replace(outcome, error=f"{outcome.output}: {EXISTS} (convert with --force to replace it)")


if __name__ == "__main__":
    main()
