"""The CLI's shared parts: option types, the options several commands take, the command class that
refuses an option given twice, and how a command's errors are reported.

Every :class:`~prs3_post.core.errors.Prs3Error` is printed as ``prs3-post: error: where: message`` with
its exit code (2 for bad input or configuration, 1 for limits and reach); never a traceback.
"""

from __future__ import annotations

import contextlib
import re
import sys
import time
import warnings
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import click

from prs3_post.app.requests import AUTO, SETTING_FIELDS, UP_ROTATION
from prs3_post.app.values import ANGLE, LENGTH, DecimalKind, IntegerKind, Kind, NumbersKind, ValueProblem
from prs3_post.core.defaults import DEFAULT_TOLERANCE
from prs3_post.core.errors import (
    FieldError,
    KeyedMessage,
    OutputClosed,
    Prs3Error,
    Prs3Warning,
    UnusedFields,
    quoted,
)
from prs3_post.core.output_files import (
    refuse_overwriting,
    refuse_standard_streams_twice,
    stdout_error,
)


class _Checked(click.ParamType):
    """An option type that checks its value with a kind of :mod:`prs3_post.app.values` (shared with job files)."""

    kind: Kind

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        try:
            return self.kind.check(value)
        except ValueProblem as problem:
            self.fail(str(problem), param, ctx)


class Decimal(_Checked):
    """A plain, finite decimal number within ``[low, high]`` (default ``±magnitude``); ``low_open``
    excludes ``low`` itself. The library checks what the value means (``--depth`` > 0); this type
    keeps out what no machine means (``1e308``, ``nan``, ``1_0``)."""

    name = "number"

    def __init__(self, magnitude: tuple[float, str], *, low: float | None = None, low_open: bool = False):
        self.kind = DecimalKind(magnitude, low=low, low_open=low_open)


#: ``--clearance-min`` (the main job and convert): a distance kept from the part, so never negative.
CLEARANCE_MIN = Decimal(LENGTH, low=0.0)


class Integer(_Checked):
    """A plain whole number (``12``, ``-3``; not ``1_0``, ``1e3``, ``٣`` or ``+ 1``) within ``[low, high]``
    (:class:`~prs3_post.app.values.IntegerKind`)."""

    name = "integer"

    def __init__(self, low: int | None = None, high: int | None = None):
        self.kind = IntegerKind(low, high)


class Numbers(_Checked):
    """``X,Y,Z``-style option values: a fixed count of comma-separated plain decimal numbers, each
    within ``±magnitude``."""

    def __init__(self, names: str, magnitude: tuple[float, str] = LENGTH):
        self.kind = NumbersKind(names, magnitude)
        self.name = names
        self.count = len(names.split(","))


class LazyChoice(click.Choice):
    """A :class:`click.Choice` whose choices ``load()`` gives when first asked for (parsing the option,
    ``--help``), not when the CLI is imported: ``convert --format`` lists the registered readers, which
    no other command loads."""

    def __init__(self, load: Callable[[], Iterable[str]]):
        super().__init__(())
        self._load = load
        self._loaded: tuple[str, ...] | None = None

    @property
    def choices(self) -> tuple[str, ...]:
        if self._loaded is None:
            self._loaded = tuple(self._load())
        return self._loaded

    @choices.setter
    def choices(self, value: Iterable[str]) -> None:
        self._loaded = tuple(value)


def demo_part() -> Path:
    """The bundled demo part (:func:`prs3_post.app.listings.demo_part`)."""
    from prs3_post.app.listings import demo_part as bundled  # the listings: only `demo` and the listing commands

    return bundled()


class OutputPath(click.Path):
    """A file the command writes (``-o``, ``--preview``): checked against the inputs before any work.
    ``dir_okay``: a folder is taken too (convert's ``-o DIR``, the old spelling of ``-d DIR``)."""

    def __init__(self, *, dir_okay: bool = False) -> None:
        super().__init__(dir_okay=dir_okay)


def _refuse_overwriting_inputs(ctx: click.Context) -> None:
    """No output may be one of the command's input files (PART.stl, POSES.csv, a machine TOML ...); ``-``
    (a standard stream) names one input and one output at most."""
    outputs: dict[str, str | None] = {}
    inputs: dict[str, str | None] = {}
    streams: dict[str, str | tuple[str, ...] | None] = {}
    for param in ctx.command.params:
        value = ctx.params.get(param.name or "")
        name = max(param.opts, key=len) if isinstance(param, click.Option) else param.human_readable_name
        if isinstance(value, tuple) and all(isinstance(v, str) for v in value):
            streams[name] = value                      # several inputs (convert's)
        if not isinstance(value, str):
            continue
        if isinstance(param.type, OutputPath):
            outputs[name] = value
        elif isinstance(param.type, click.Path) or param.name in ("machine_name", "dialect_name"):
            inputs[name] = value
            if not (isinstance(param.type, click.Path) and not param.type.file_okay):   # a folder is no stream
                streams[name] = value
    if ctx.command.name == "demo":
        inputs["the demo part"] = str(demo_part())
    refuse_standard_streams_twice(outputs, streams)
    refuse_overwriting(outputs, inputs)


def _worded(message: Warning | str) -> str:
    """A warning as the command line says it: the keys it names as the flags that set them."""
    return message.worded(flag_of) if isinstance(message, KeyedMessage) else str(message)


@contextlib.contextmanager
def warnings_to_stderr() -> Iterator[None]:
    """Print every :class:`Prs3Warning` as ``prs3-post: warning: message`` on standard error, when it happens."""
    with warnings.catch_warnings():
        warnings.simplefilter("always", Prs3Warning)
        shown = warnings.showwarning

        def show(message: Warning | str, category: type[Warning], *args: Any, **kwargs: Any) -> None:
            if issubclass(category, Prs3Warning):
                say(f"warning: {_worded(message)}")
            else:
                shown(message, category, *args, **kwargs)

        warnings.showwarning = show
        yield


def run_reported(action: Callable[[], int | None]) -> None:
    """Run a command body; report :class:`Prs3Error` as one line and exit with its code.

    Before anything, outputs that name an input are refused; a standard output that cannot be
    written (full, closed pipe) is reported like any other error. With ``-v``, the time of each
    stage (:func:`timed`) ends it."""
    started = time.perf_counter()
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
    except OutputClosed:                             # the reader of standard output went away (| head): quietly
        sys.exit(OutputClosed.exit_code)
    except FieldError as error:                      # a value an option gave (--machine ''): as click's own
        raise option_error(error) from error
    except Prs3Error as error:
        click.echo(f"prs3-post: error: {error_text(error)}", err=True)
        sys.exit(error.exit_code)
    except MemoryError:                              # no traceback: it would say nothing more (and need memory)
        click.echo(f"prs3-post: error: {OUT_OF_MEMORY}", err=True)
        sys.exit(1)
    detail(_times_line(time.perf_counter() - started))
    sys.exit(code or 0)


#: What a command that ran out of memory says (nothing is written: outputs are atomic).
OUT_OF_MEMORY = ("out of memory: the machine, or a limit on this process (ulimit -v), left too little; nothing "
                 "was written (free some memory, or convert the files one at a time with --jobs 1)")


#: The old spelling of the STL's unit (``--units``) in the commands that read an STL (convert: the CL file's).
PART_UNITS_ALIAS = {"--units": "--part-units"}


def part_units_option(help_text: str = "Length unit of the STL file.", *,
                      default: str | None = SETTING_FIELDS["units"].default) -> Callable[[Any], Any]:
    """``--part-units mm|inch``: the STL's length unit (the request's ``units``)."""
    return click.option("--part-units", "units", type=click.Choice(["mm", "inch"]), default=default,
                        show_default=default is not None, help=help_text)


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


machine_option = click.option(
    "--machine", "machine_name", default=SETTING_FIELDS["machine"].default, show_default=True, metavar="NAME|PATH",
    help="Shipped machine name (see `prs3-post machines`) or path to a machine TOML file.",
)


dialect_option = click.option(
    "--dialect", "dialect_name", default=SETTING_FIELDS["dialect"].default, show_default=True, metavar="NAME|PATH",
    help="G-code dialect: linuxcnc, fanuc, or a dialect TOML file.",
)
line_number_options = (
    click.option("--line-numbers/--no-line-numbers", default=None,
                 help="Number the blocks (N words).  [default: as the dialect says]"),
    click.option("--line-start", type=Integer(0, 99999), default=None, help="First block number."),
    click.option("--line-step", type=Integer(1, 1000), default=None, help="Block number increment."),
)
#: The main job's and convert's: what the machine's [dynamics] do to a feed too fast for an axis.
clamp_option = click.option(
    "--clamp/--no-clamp", default=SETTING_FIELDS["clamp"].default, show_default=True,
    help="Lower G1 feeds that would drive an axis over its top speed (the machine's [dynamics]); "
         "--no-clamp refuses such a feed, naming its line.",
)


tolerance_option = click.option(
    "--tolerance", type=Decimal(LENGTH), default=DEFAULT_TOLERANCE, show_default=True,
    help="Chordal tolerance of arcs (and of moves that turn the tool axis), mm (0.0001 to 1).",
)


def _takes_value(option: click.Option) -> bool:
    return not (option.is_flag or option.count)


def _occurrences(params: list[click.Parameter], args: list[str],
                 aliases: dict[str, str] | None = None) -> Iterator[tuple[click.Option, str, int, str]]:
    """``(option, value as written, index of its name in args, name as written)`` for each option in
    ``args`` (a flag's value: its spelling), as click reads them: ``--name VALUE``, ``--name=VALUE``,
    ``-o VALUE``, ``-oVALUE``, grouped short flags, and nothing after ``--``. An unknown option is passed
    over (click reports it); an old spelling in ``aliases`` (old → new) is read as the new one."""
    named = {name: p for p in params if isinstance(p, click.Option) for name in (*p.opts, *p.secondary_opts)}
    for old, new in (aliases or {}).items():
        if new in named:
            named[old] = named[new]
    i = 0
    while i < len(args):
        arg = args[i]
        at_name = i
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
            yield option, value if _takes_value(option) else name, at_name, name
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
                yield option, value, at_name, "-" + arg[at]
                break
            yield option, "-" + arg[at], at_name, "-" + arg[at]


class Command(click.Command):
    """A command whose single-valued options may be given once: ``--profile hole --profile square``
    (or ``-o a -o b``, ``--collision-check --no-collision-check``) is refused, naming both, instead
    of click's silent last-one-wins. Options made to repeat (``multiple``, ``count``) may repeat.

    ``aliases`` (old spelling → new, e.g. ``{"--units": "--part-units"}``) are the old spellings of
    renamed options: still taken, not shown by ``--help``, each one used noted on standard error
    (:data:`DEPRECATED`) before the command runs."""

    def __init__(self, *args: Any, aliases: dict[str, str] | None = None, **kwargs: Any):
        super().__init__(*args, **kwargs)
        self.aliases = dict(aliases or {})

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        first: dict[str, str] = {}
        args = list(args)
        for option, value, index, written in _occurrences(self.get_params(ctx), args, self.aliases):
            if written in self.aliases:                  # the old spelling: read as the new one, and noted
                new = self.aliases[written]
                args[index] = new + args[index][len(written):]
                add_note(ctx, DEPRECATED.format(old=written, new=new))
            if option.multiple or option.count or option.is_eager or option.name is None:
                continue
            if option.name in first:
                names = "/".join(sorted((*option.opts, *option.secondary_opts), key=lambda n: (len(n) > 2, n)))
                ctx.fail(f"{names} given twice ({quoted(first[option.name])} and {quoted(value)}): give it once")
            first[option.name] = value
        return super().parse_args(ctx, args)

    def invoke(self, ctx: click.Context) -> Any:
        """The command, after the notes its parsing left (old spellings) are printed."""
        for text in ctx.meta.pop(_NOTES, []):
            note(text)
        return super().invoke(ctx)


#: The note an old spelling of an option gives (one line on standard error; the option still works).
DEPRECATED = "{old} is deprecated: use {new} (it means the same)"

_NOTES = "prs3_post.notes"


def add_note(ctx: click.Context, text: str) -> None:
    """A note to print once the command's options are parsed (:meth:`Command.invoke`)."""
    notes = ctx.meta.setdefault(_NOTES, [])
    if text not in notes:
        notes.append(text)


def note(text: str) -> None:
    """``prs3-post: note: TEXT`` on standard error (not with ``-q``)."""
    say(f"note: {text}")


# ----------------------------------------------------------------------------- -q / -v

#: How much a command says on standard error: ``-q`` errors only, ``-v`` also the details.
QUIET, NORMAL, VERBOSE = -1, 0, 1
_VERBOSITY = "prs3_post.verbosity"
_TIMES = "prs3_post.times"


def verbosity() -> int:
    """:data:`QUIET`, :data:`NORMAL` or :data:`VERBOSE`: as the running command was asked (-q, -v)."""
    ctx = click.get_current_context(silent=True)
    return NORMAL if ctx is None else int(ctx.meta.get(_VERBOSITY, NORMAL))


def say(text: str) -> None:
    """``prs3-post: TEXT`` on standard error: what was written, a note, a warning (not with ``-q``)."""
    if verbosity() > QUIET:
        click.echo(f"prs3-post: {text}", err=True)


def detail(text: str) -> None:
    """``prs3-post: TEXT`` on standard error, with ``-v`` only."""
    if verbosity() >= VERBOSE:
        click.echo(f"prs3-post: {text}", err=True)


@contextlib.contextmanager
def timed(stage: str) -> Iterator[None]:
    """Time a stage of the command; ``-v`` prints every stage's time when the command ends."""
    started = time.perf_counter()
    try:
        yield
    finally:
        ctx = click.get_current_context(silent=True)
        if ctx is not None:
            ctx.meta.setdefault(_TIMES, []).append((stage, time.perf_counter() - started))


def _times_line(total: float) -> str:
    ctx = click.get_current_context(silent=True)
    stages = [] if ctx is None else ctx.meta.get(_TIMES, [])
    return "time: " + ", ".join([*(f"{stage} {seconds:.3f} s" for stage, seconds in stages), f"total {total:.3f} s"])


def _set_verbosity(level: int) -> Callable[[click.Context, click.Parameter, bool], None]:
    def callback(ctx: click.Context, param: click.Parameter, value: bool) -> None:
        if not value:
            return
        if ctx.meta.get(_VERBOSITY, level) != level:
            raise click.UsageError("-q/--quiet and -v/--verbose: give one of them", ctx)
        ctx.meta[_VERBOSITY] = level
    return callback


def verbosity_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """``-q/--quiet`` and ``-v/--verbose``, which every command takes (:func:`say`, :func:`detail`)."""
    func = click.option("-v", "--verbose", is_flag=True, expose_value=False, callback=_set_verbosity(VERBOSE),
                        help="Say more on standard error: the setup, face, files and settings used, and the time of "
                             "each stage.")(func)
    return click.option("-q", "--quiet", is_flag=True, expose_value=False, callback=_set_verbosity(QUIET),
                        help="Errors only on standard error: no summaries (wrote ...), notes or warnings. What the "
                             "command prints on standard output is unchanged.")(func)


def image_format(path: str, flag: str, suffixes: tuple[str, ...] = (".png", ".svg"), *, what: str = "image") -> str:
    """``png`` or ``svg`` (or another of ``suffixes``, without its dot) from an output file's suffix;
    ``flag`` names the option in the error, ``what`` the file."""
    suffix = Path(path).suffix.lower()
    if suffix not in suffixes:
        listed = " or ".join([", ".join(suffixes[:-1]), suffixes[-1]] if len(suffixes) > 1 else suffixes)
        raise click.BadParameter(f"the {what} must end in {listed}, got {path!r}", param_hint=flag)
    return suffix[1:]


def was_given(ctx: click.Context, name: str) -> bool:
    """Whether the user gave the option (not its default)."""
    return ctx.get_parameter_source(name) is not click.core.ParameterSource.DEFAULT


def face_index(choice: str) -> int | None:
    """``auto`` → None, ``7`` → 7 (ASCII digits only: ``²`` is a digit to Python, not to us)."""
    if choice == "auto":
        return None
    if re.fullmatch(r"[0-9]+", choice):
        return int(choice)
    raise click.BadParameter(f"expected auto or a face index, got {quoted(choice)}", param_hint="'--face'")


#: The flag of each request key whose flag is not ``--`` + the key with - for _.
_FLAG_OF = {"at": "--at", "tool": "--tool-number", "units": "--part-units", "setup.part_origin": "--part-origin",
            "setup.part_rotation_deg": "--part-rotation"}


def flag_of(key: str) -> str:
    """The command line's flag of a request key (``tool`` → ``--tool-number``)."""
    return _FLAG_OF.get(key, "--" + key.replace("_", "-"))


def option_error(error: FieldError) -> click.ClickException:
    """A request's error, worded for the command line (the option's flag, click's usage error)."""
    if isinstance(error, UnusedFields):
        flags = ", ".join(f"{flag_of(key)} ({' and '.join(profiles)} only)" for key, profiles in error.keys)
        return click.UsageError(f"--profile {error.profile} does not use {flags}: leave "
                                f"{'it' if len(error.keys) == 1 else 'them'} out")
    return click.BadParameter(error.worded(flag_of),
                              param_hint=" / ".join(f"'{flag_of(key)}'" for key in (error.field, *error.also)))


def error_text(error: Prs3Error) -> str:
    """A library error as the command line says it: the keys its message names as the flags that set them."""
    return error.worded(flag_of)
