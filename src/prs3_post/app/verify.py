"""The `verify` job: a program, the machine, dialect and setup it was made for, and what it should
do (the `preview` job draws it: :mod:`prs3_post.app.preview`).

    PROGRAM ──► header (machine, dialect, setup, the operation) ──► read ──► replay ──► report / picture
                                                         └── PART.stl (its SHA-256) ──► rebuilt job ──► intended path

A program made by the main job says in its header what it was made from
(:mod:`prs3_post.emit.header`). Its machine, dialect and setup are then the defaults; a value
given explicitly that contradicts the header is an error (:class:`HeaderConflict`), not a silent
or warned override: verifying a program against something it was not made for answers another
question than the one asked, and a warning above a pass is easily missed. A program without a
header is read with the values given (or the defaults).

No I/O beyond the readers; messages do not name command-line flags (the CLI adds them).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

import numpy as np

from prs3_post.app.read_ahead import read_ahead
from prs3_post.app.requests import resolve_setup
from prs3_post.check.verify import Intended, Problem, Verifier, VerifyReport, verify_program
from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE_DEG, DEFAULT_CLEARANCE_MIN, DEFAULT_TOLERANCE
from prs3_post.core.errors import ConfigError, InputError, PoseError, Prs3Error, quoted
from prs3_post.core.input_files import file_sha256
from prs3_post.core.toolpath import MoveKind
from prs3_post.core.types import BoolArray, FloatArray, IntArray, Progress
from prs3_post.emit.header import ProgramHeader, SourceCounts, SourceHeader
from prs3_post.emit.header_read import read_counts, read_header
from prs3_post.kinematics import unit_axes
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.loading import (
    DEFAULT_DIALECT,
    DEFAULT_MACHINE,
    Dialect,
    Machine,
    load_dialect,
    load_machine,
    load_source,
)
from prs3_post.part.face import Face
from prs3_post.part.setup_transform import Setup
from prs3_post.readers.program import CHUNK_LINES, ProgramFile, ProgramStream, load_program
from prs3_post.toolpaths.common import require_tolerance as require_tolerance  # the front ends check theirs

# The main job (to rebuild one) and the collision measure load only for `verify --against` and
# `preview --part`: a plain verify starts without them.
if TYPE_CHECKING:
    from prs3_post.app.cross_check import CrossCheck
    from prs3_post.app.job import JobResult, JobSpec

_Config = TypeVar("_Config", Machine, Dialect)


class HeaderConflict(InputError):
    """A value given explicitly contradicts the program's header.

    Attributes
    ----------
    what : str — ``machine``, ``dialect``, ``part origin``, ``part rotation``, ``part`` (what the header records)
    """

    def __init__(self, message: str, *, path: str, line: int | None, what: str):
        super().__init__(message, path=path, line=line)
        self.what = what


@dataclass(frozen=True, slots=True)
class ProgramContext:
    """A program read with the machine, dialect and setup it was made for.

    Attributes
    ----------
    program : ProgramFile
    header : ProgramHeader | None — None for a program without a prs3-post header
    machine : Machine
    dialect : Dialect
    setup : Setup
    """

    program: ProgramFile
    header: ProgramHeader | SourceHeader | None
    machine: Machine
    dialect: Dialect
    setup: Setup


def _conflict(header: ProgramHeader | SourceHeader, key: str, what: str, recorded: str, given: str) -> HeaderConflict:
    return HeaderConflict(f"the program's header says {what} {recorded}, but {what} {given} was given (leave it "
                          "out to use the header's)", path=header.path, line=header.line(key), what=what)


def load_recorded(header: ProgramHeader | SourceHeader, kind: str, load: Callable[[str], _Config]) -> _Config:
    """The machine or dialect a header names: its file when given by path, else the shipped name (a
    dialect may have upper-cased the comment: its lower-case spelling is tried too)."""
    name, file = (header.machine, header.machine_file) if kind == "machine" else (header.dialect, header.dialect_file)
    tries = [file] if file is not None else list(dict.fromkeys([name, name.lower()]))
    problems: list[ConfigError] = []
    for ref in tries:
        try:
            return load(ref)
        except ConfigError as error:
            problems.append(error)
    problem = problems[0]                            # the name as written (tries is never empty)
    detail = problem.args[0] if problem.line is None else f"line {problem.line}: {problem.args[0]}"
    # the file is opened as an explicit one is (a regular file within the TOML size limit): a header is input
    raise InputError(f"header: the {kind} it names ({quoted(tries[0])}) cannot be loaded here ({detail}; a header's "
                     f"{kind} is read as a given one is): give the {kind} explicitly", path=header.path,
                     line=header.line(f"{kind} file" if file else kind))


def _same(a: Machine | Dialect, b: Machine | Dialect) -> bool:
    """The same machine (or dialect), wherever its file was loaded from."""
    return dataclasses.replace(a, source="") == dataclasses.replace(b, source="")


@dataclass(frozen=True, slots=True)
class ProgramSetting:
    """What a program was made for, before its moves are read: header, machine, dialect, setup
    (attributes as :class:`ProgramContext`)."""

    path: str
    header: ProgramHeader | SourceHeader | None
    machine: Machine
    dialect: Dialect
    setup: Setup


def open_program(path: str, *, machine: str | None = None, dialect: str | None = None,
                 origin: tuple[float, ...] | None = None, rotation_deg: float | None = None) -> ProgramContext:
    """Read a program with the machine, dialect and setup its header names, or those given
    (:func:`open_setting`, then the whole program).

    Raises
    ------
    HeaderConflict, InputError, ConfigError
        As :func:`open_setting`, and an unreadable program.
    """
    setting = open_setting(path, machine=machine, dialect=dialect, origin=origin, rotation_deg=rotation_deg)
    program = load_program(path, setting.dialect, stage=setting.machine.stage.present,
                           kinematics=kinematics_of(setting.machine))
    return ProgramContext(program=program, header=setting.header, machine=setting.machine, dialect=setting.dialect,
                          setup=setting.setup)


def open_setting(path: str, *, machine: str | None = None, dialect: str | None = None,
                 origin: tuple[float, ...] | None = None, rotation_deg: float | None = None) -> ProgramSetting:
    """The machine, dialect and setup a program's header names, or those given (its moves unread).

    Parameters
    ----------
    path : str — the program file
    machine, dialect : str | None — a shipped name or a TOML path given explicitly (None: the header's,
        or :data:`DEFAULT_MACHINE` / :data:`DEFAULT_DIALECT` for a program without a header)
    origin : (3,) mm | None, rotation_deg : float | None — the setup given explicitly (None: the header's,
        or the machine's default setup)

    Raises
    ------
    HeaderConflict
        A given value that is not the header's.
    FieldError
        A setup given out of range (``setup.part_origin``, ``setup.part_rotation_deg``).
    InputError, ConfigError
        An unreadable header, machine or dialect.
    """

    given_dialect = load_dialect(dialect) if dialect is not None else None
    style = (given_dialect or load_dialect(DEFAULT_DIALECT)).comments
    header = read_header(path, open_=style.open, close=style.close)
    if header is None:
        chosen_machine = load_machine(machine if machine is not None else DEFAULT_MACHINE)
        chosen_dialect = given_dialect or load_dialect(DEFAULT_DIALECT)
        setup = resolve_setup(chosen_machine, origin, rotation_deg)
    else:
        chosen_machine = _recorded_or_given(header, "machine", load_machine,
                                            load_machine(machine) if machine is not None else None)
        chosen_dialect = _recorded_or_given(header, "dialect", load_dialect, given_dialect)
        setup = header.setup
        if origin is not None and tuple(float(v) for v in origin) != setup.origin:
            raise _conflict(header, "setup", "part origin", _vector(setup.origin), _vector(origin))
        if rotation_deg is not None and float(rotation_deg) != setup.rotation_deg:
            raise _conflict(header, "setup", "part rotation", f"{setup.rotation_deg:g} deg", f"{rotation_deg:g} deg")
        if isinstance(header, SourceHeader) and header.tool_length != chosen_machine.geometry.tool_length:
            # a converted program's IK used the tool length its header states: replay it with that one
            chosen_machine = chosen_machine.with_tool_length(header.tool_length)
    return ProgramSetting(path=path, header=header, machine=chosen_machine, dialect=chosen_dialect, setup=setup)


def _recorded_or_given(header: ProgramHeader | SourceHeader, kind: str, load: Callable[[str], _Config],
                       given: _Config | None) -> _Config:
    if given is None:
        return load_recorded(header, kind, load)
    try:
        recorded = load_recorded(header, kind, load)
    except InputError:                                 # cannot compare: the given one is all there is
        return given
    if not _same(recorded, given):
        shown = f"{given.name} ({given.source})" if given.name == recorded.name else given.name
        raise _conflict(header, f"{kind} file" if header.line(f"{kind} file") else kind, kind, recorded.name, shown)
    return given


def _vector(values: tuple[float, ...] | FloatArray) -> str:
    return "[" + ", ".join(f"{float(v):g}" for v in values) + "]"


def check_part(header: ProgramHeader | SourceHeader, part: str) -> None:
    """Refuse a part file that is not the one the program was made from (by SHA-256).

    Raises
    ------
    HeaderConflict
        Naming both files and both hashes.
    """
    if isinstance(header, SourceHeader):
        raise HeaderConflict(f"the program was converted from {header.source_name}, not made from a part: verify it "
                             "against that file", path=header.path, line=header.line("source"), what="part")
    _check_sha256(header, part, "the part the program was made from", header.part_name, header.part_sha256, "part")


def _check_sha256(header: ProgramHeader | SourceHeader, path: str, what: str, name: str, sha256: str,
                  key: str) -> None:
    """Refuse ``path`` unless its SHA-256 is the one the header records for ``name`` (``what`` says what it is)."""
    digest = file_sha256(path)
    if digest != sha256:
        raise HeaderConflict(f"{path} (SHA-256 {digest}) is not {what}: its header names {name} (SHA-256 {sha256})",
                             path=header.path, line=header.line(key), what="part")


def header_job(context: ProgramContext, part: str) -> tuple[JobSpec, ...]:
    """The job a program's header records, on ``part`` (checked by SHA-256), with the context's
    machine and dialect: its operations (one for the main job).

    Raises
    ------
    InputError
        No header (the operation must then be given), or not the recorded part.
    """
    from prs3_post.app.job import specs_from_header

    header = context.header
    if header is None:
        raise InputError("the program has no prs3-post header: the operation it was made with must be given",
                         path=context.program.path)
    check_part(header, part)
    assert isinstance(header, ProgramHeader)  # check_part refuses a converted program's header
    return specs_from_header(header, part, context.machine, context.dialect)


def intended_from_job(specs: JobSpec | tuple[JobSpec, ...]) -> Intended:
    """The path a job makes (machine frame), as what a program should do.

    Each row's tip is where its operation's tool tip should be (``verify`` replays each row with the
    length of the tool in the spindle, from the program's header).
    """
    return rebuild_job(specs).intended


@dataclass(frozen=True, slots=True)
class RebuiltJob:
    """A job made again (without its collision check) to verify a program against: its path, and
    what the clearance of the tool and holder from the part is measured with.

    Attributes
    ----------
    intended : Intended — the path the program should make
    specs : tuple of JobSpec — the operations
    result : JobResult — the job made again (its faces, part triangles, the rows' step labels)
    """

    intended: Intended
    specs: tuple[JobSpec, ...]
    result: JobResult


def rebuild_job(specs: JobSpec | tuple[JobSpec, ...]) -> RebuiltJob:
    """The job ``specs`` describe made again, without its collision check (the program's own check,
    or its absence, is in its header; :func:`part_clearance` measures the program itself)."""
    from prs3_post.app.job import run_operations

    specs = specs if isinstance(specs, tuple) else (specs,)
    result = run_operations(tuple(replace(s, collision_check=False) for s in specs))
    path = result.post.path
    feed = np.where(path.kind == MoveKind.FEED, path.feed, np.nan)
    what = "+".join(dict.fromkeys(s.operation.value for s in specs))
    intended = Intended(tip=path.tip, axis=path.axis, feed=feed, kind=path.kind,
                        label=f"{Path(specs[0].part).name} ({what})")
    return RebuiltJob(intended=intended, specs=specs, result=result)


@dataclass(frozen=True, slots=True)
class PartClearance:
    """The closest approach of the tool, the holder and the spindle nose to the part over a program's
    replay (``verify --against PART.stl``).

    Attributes
    ----------
    distance : (3,) float — mm, per body (:data:`~prs3_post.check.collision.BODY_NAMES`): the smallest signed
        distance (negative: penetration depth); inf where nothing was measured
    line : (3,) int — the program line of each minimum (0: none)
    at : (3,) float — the fraction along that line's move
    step : tuple of str — the step of each minimum as the job names it (``hole 1 approach``; "" for none)
    point : (3, 3) float — mm, part frame: the body's point of each minimum
    exact : (3,) bool — the minimum over every pose (False: a lower bound, stated as ``over``)
    clearance_min : (3,) float — mm, the clearance each minimum's operation asks (a converted
        program's tool in its rapids: −RAPID_TOUCH_MM, the depth it may touch the part to)
    allowance : str — what of the tool may be in the part (it cuts there), for the report
    tool_in_rapids : bool — the tool's entry is a converted program's tool in its rapids
        (:func:`~prs3_post.check.collision.rapid_tool_clearance`)
    rapids_tool : str — the tool it was measured as there (``6.000 mm diameter``)
    """

    distance: FloatArray
    line: IntArray
    at: FloatArray
    step: tuple[str, ...]
    point: FloatArray
    exact: BoolArray
    clearance_min: FloatArray
    allowance: str
    tool_in_rapids: bool = False
    rapids_tool: str = ""

    def worst(self) -> int:
        """The body closest to the part (relative to its clearance min)."""
        return int(np.argmin(self.distance - self.clearance_min))

    def problems(self) -> tuple[Problem, ...]:
        """A ``collision`` problem for each body closer to the part than its clearance min, on its line."""
        from prs3_post.check.collision import BODY_NAMES, RAPID_TOUCH_MM

        out = []
        for b, name in enumerate(BODY_NAMES):
            d, line = float(self.distance[b]), int(self.line[b])
            if not d < self.clearance_min[b]:
                continue
            what = f"hits the part, {-d:.3f} mm deep" if d < 0 else f"comes within {d:.3f} mm of the part"
            step = f" ({self.step[b]})" if self.step[b] else ""
            if b == 0 and self.tool_in_rapids:
                out.append(Problem(line, "collision", f"line {line}: the tool hits the part in a rapid, {-d:.3f} mm "
                                                      f"deep (a rapid may touch the part, not cut it: "
                                                      f"{RAPID_TOUCH_MM:.3f} mm at most)"))
                continue
            out.append(Problem(line, "collision", f"line {line}{step}: the {name} {what} (clearance min "
                                                  f"{self.clearance_min[b]:.3f} mm)"))
        return tuple(sorted(out, key=lambda p: p.line))


#: Poses measured on the bodies' surfaces beyond those the check needs (whose lower bound is under the
#: clearance min), nearest first, to sharpen the reported minimum; beyond them it is stated as a bound.
REFINE_POSES = 32

#: What the main job's check lets the tool do in the part (and so does ``verify --against PART.stl``).
FACE_ALLOWANCE = "the tool below the worked face, within the feature's swept region"


def part_clearance(report: VerifyReport, machine: Machine, rebuilt: RebuiltJob, *,
                   clearance_min: float | None = None) -> PartClearance:
    """The clearance of the tool, the holder and the spindle nose from the part at every replay sample
    of a program (``report``, its samples kept) and along the motion between them, each operation's
    rows as the main job checked them: its face, tool (diameter, length below the gauge line), the
    tips of its G1 moves (the swept region) and clearance min (``clearance_min`` when given). The
    moves between the operations of a job belong to the operation whose tool is in the spindle.

    Raises
    ------
    ValueError
        The machine has no ``[holder]`` (nothing to measure: :func:`with_clearance` says so).
    InputError
        The program has another number of moves than the job.
    """
    result = rebuilt.result
    program = result.post.program
    if len(program) != len(report.program):
        raise InputError(f"the program has {len(report.program)} moves, the job {len(program)}",
                         path=rebuilt.specs[0].part)
    group = _operation_of_rows(result)
    pieces = [_Piece(rows=group == k, face=operation.face, tool_diameter=spec.cutting.tool_diameter,
                     tool_length=operation.tool_length, clearance_min=spec.clearance_min)
              for k, (spec, operation) in enumerate(zip(rebuilt.specs, result.operations, strict=True))]
    return _measure(report, machine, result.triangles, pieces, clearance_min=clearance_min,
                    describe=program.describe if program.source_labels else None, allowance=FACE_ALLOWANCE)


#: What the check lets the tool do in the part of a program converted from CAM input (no face).
CAM_ALLOWANCE = "the tool in feeds (it cuts what the CAM program removes: its gouges are the CAM system's to check)"


def cam_part_clearance(report: VerifyReport, machine: Machine, against: CamPart, *,
                       clearance_min: float) -> PartClearance:
    """The clearance from the part (``against.triangles``, part frame) of a program converted from CAM
    input, as ``convert --part`` checks it: the holder and the spindle nose at every sample (no face),
    the tool in the rapids only (:func:`~prs3_post.check.collision.rapid_tool_clearance`, with the diameter
    the program's header states; its feeds cut what the CAM program removes); ``machine``: with the
    IK's tool length "TL"."""
    from prs3_post.check.collision import RAPID_TOUCH_MM, rapid_tool_clearance, tool_words

    piece = _Piece(rows=np.ones(len(report.program), dtype=bool), face=None, tool_diameter=0.0,
                   tool_length=against.tool_length, clearance_min=clearance_min)
    found = _measure(report, machine, against.triangles, [piece], clearance_min=clearance_min, describe=None,
                     allowance=CAM_ALLOWANCE)
    rapids = rapid_tool_clearance(machine, report.program, against.setup, against.triangles, against.tool_diameter)
    if rapids.row < 0:                                          # no rapid to check
        return replace(found, tool_in_rapids=True, rapids_tool=tool_words(against.tool_diameter))
    distance, line, at = found.distance.copy(), found.line.copy(), found.at.copy()
    point, exact, asked = found.point.copy(), found.exact.copy(), found.clearance_min.copy()
    distance[0], line[0], at[0] = rapids.distance, int(report.program.source[rapids.row]), rapids.fraction
    point[0], exact[0], asked[0] = rapids.point, rapids.exact, -RAPID_TOUCH_MM
    return replace(found, distance=distance, line=line, at=at, point=point, exact=exact, clearance_min=asked,
                   tool_in_rapids=True, rapids_tool=tool_words(against.tool_diameter))


@dataclass(frozen=True, slots=True)
class _Piece:
    """Rows measured alike: (N,) bool rows, the face (None: no tool), the tool, the clearance min (mm)."""

    rows: BoolArray
    face: Face | None
    tool_diameter: float
    tool_length: float
    clearance_min: float


def _measure(report: VerifyReport, machine: Machine, triangles: FloatArray, pieces: list[_Piece], *,
             clearance_min: float | None, describe: Callable[[int], str] | None, allowance: str) -> PartClearance:
    """Each piece's samples through :func:`~prs3_post.check.collision.clearance` as
    :func:`~prs3_post.check.collision.check_program` calls it; the closest per body (relative to its clearance min)."""
    from prs3_post.check.collision import body_cylinders, clearance

    if machine.holder is None:
        raise ValueError(f"machine {machine.name} has no [holder]")
    rep = report.samples_kept
    tip_all, axis_all = report.tip_part, report.axis_part
    finite = np.isfinite(tip_all).all(axis=1) & np.isfinite(axis_all).all(axis=1)
    best = np.full(3, np.inf)
    sample = np.full(3, -1, dtype=np.int64)
    point = np.zeros((3, 3))
    exact = np.ones(3, dtype=bool)
    asked = np.full(3, DEFAULT_CLEARANCE_MIN if clearance_min is None else clearance_min)
    for piece in pieces:
        mine = np.flatnonzero(piece.rows[rep.row] & finite)
        if not len(mine):
            continue
        wanted = piece.clearance_min if clearance_min is None else clearance_min
        bodies = body_cylinders(piece.tool_diameter, piece.tool_length - machine.geometry.gauge_offset, machine.holder)
        if piece.face is None:
            bodies[0, 2] = bodies[0, 1]                                          # the tool: not measured
        feed_rows = np.flatnonzero(piece.rows & (report.program.kind == MoveKind.FEED))
        connected = np.concatenate([[False], np.diff(mine) == 1])               # from the sample before
        found = clearance(triangles, tip_all[mine], axis_all[mine], bodies, piece.face, tip_all[rep.end[feed_rows]],
                          clearance_min=wanted, refine_max=REFINE_POSES, connected=connected)
        closer = found.distance - wanted < best - asked
        closer[0] &= piece.face is not None                                      # a CAM program's tool: not counted
        for b in np.flatnonzero(closer).tolist():
            best[b], sample[b], point[b] = found.distance[b], mine[found.sample[b]], found.point[b]
            exact[b], asked[b] = found.exact[b], wanted
    lines = report.program.source
    where = np.maximum(sample, 0)
    row = rep.row[where]
    return PartClearance(
        distance=best, line=np.where(sample >= 0, lines[row], 0), at=np.where(sample >= 0, rep.fraction[where], 0.0),
        step=tuple(describe(int(r)) if s >= 0 and describe is not None else ""
                   for r, s in zip(row.tolist(), sample.tolist(), strict=True)),
        point=point, exact=exact, clearance_min=asked, allowance=allowance)


@dataclass(frozen=True, slots=True)
class CamPart:
    """The part a program converted from CAM input is verified against: (T, 3, 3) mm triangles (part
    frame), the tool length "TL" its IK used (mm, its header's), its setup, and the tool diameter
    (mm) its header's ``collision`` entry says its rapids were checked with (0: unknown, the axis)."""

    triangles: FloatArray
    tool_length: float
    setup: Setup
    tool_diameter: float


def with_clearance(report: VerifyReport, machine: Machine, against: RebuiltJob | CamPart, *,
                   clearance_min: float | None = None) -> tuple[VerifyReport, PartClearance | str]:
    """The report with a ``collision`` problem for each body closer to the part than its clearance
    min (problems in line order), and the clearance (:func:`part_clearance` for a job made again,
    :func:`cam_part_clearance` for a converted program); a machine without ``[holder]``: the report
    as it is, and why nothing was measured."""
    if machine.holder is None:
        return report, f"not measured: machine {machine.name} has no [holder]"
    if isinstance(against, CamPart):
        found = cam_part_clearance(report, machine, against,
                                   clearance_min=DEFAULT_CLEARANCE_MIN if clearance_min is None else clearance_min)
    else:
        found = part_clearance(report, machine, against, clearance_min=clearance_min)
    problems = tuple(sorted(report.problems + found.problems(), key=lambda p: p.line))
    return replace(report, problems=problems), found


def _operation_of_rows(result: JobResult) -> IntArray:
    """(N,) int: the operation each row of a job's program belongs to (its step label starts with the
    operation's label; a job of one operation: all 0). The lift after an operation is the one before's,
    the turn to the next face the next one's."""
    post = result.post
    group = np.zeros(len(post.path), dtype=np.int64)
    if len(result.operations) < 2:
        return group
    labels = post.path.source_labels
    owner = np.zeros(len(labels), dtype=np.int64)
    for k, operation in enumerate(result.operations):
        owner[[i for i, text in enumerate(labels) if text.startswith(f"{operation.label}, ")]] = k
    return owner[post.path.source]


def intended_from_source(context: ProgramContext, source: str) -> Intended:
    """What a converted program should do: its CAM source converted again with the settings its header
    records (format, units, ignored words, work plane, setup, tool length, tolerances).

    Raises
    ------
    HeaderConflict
        The program has no converted program's header, or ``source`` is not the file it names (by SHA-256).
    InputError, LimitError, ReachError
        As the conversion.
    """
    from prs3_post.app.convert import ConvertSettings, convert_file  # convert imports the main job, as this does
    from prs3_post.emit.gcode import sanitize_comment

    header = context.header
    if not isinstance(header, SourceHeader):
        raise InputError("the program has no header of a converted CAM file (prs3-post convert writes one): "
                         "there is nothing to rebuild the intended path from", path=context.program.path)
    _check_sha256(header, source, "the file the program was converted from", header.source_name,
                  header.source_sha256, "source")
    settings = ConvertSettings(
        machine=context.machine, dialect=context.dialect, setup=header.setup, tolerance=header.tolerance,
        angle_tolerance_deg=header.angle_tolerance_deg, input_format=header.source_format,
        units=None if header.source_units == "auto" else header.source_units,
        ignore=header.ignore, work_plane=header.work_plane, line_numbers=header.line_numbers,
        source=load_source(header.five_axis) if header.five_axis else None, tcp_on=header.tcp_on or None,
        tcp_off=header.tcp_off or None,
        line_start=header.line_start, line_step=header.line_step)
    check_program_moves(header, len(context.program.moves))
    conversion = convert_file(source, settings)
    # the counts as the program's dialect wrote them (a skipped word's comment is sanitized: '%' may read 'PCT')
    written = read_counts(sanitize_comment(conversion.report.counts().text(), context.dialect.comments))
    _check_counts(header, written, Path(source).name)
    path = conversion.path
    feed = np.where(path.kind == MoveKind.FEED, path.feed, np.nan)
    return Intended(tip=path.tip, axis=path.axis, feed=feed, kind=path.kind, label=Path(source).name)


def check_program_moves(header: ProgramHeader | SourceHeader | None, moves: int) -> None:
    """Raise when a converted program's header counts other motion lines than the program has (a body cut
    short or edited after it was written).

    Raises
    ------
    Prs3Error
        ``PROG:8: header: counts: 103 program moves, but the program has 102 motion lines ...`` (exit 1).
    """
    if not isinstance(header, SourceHeader) or header.counts is None:
        return
    if header.counts.program_moves != moves:
        raise Prs3Error(f"{header.path}:{header.line('counts')}: header: counts: {header.counts.program_moves} program "
                        f"moves, but the program has {moves} motion lines (G0/G1): its body was cut short or edited "
                        "after it was written")


def _check_counts(header: SourceHeader, again: SourceCounts, source_name: str) -> None:
    """Every count of the header's ``counts`` entry against the same input converted again."""
    recorded = header.counts
    if recorded is None or recorded == again:
        return
    for field in dataclasses.fields(SourceCounts):
        said, found = getattr(recorded, field.name), getattr(again, field.name)
        if said != found:
            if field.name == "skipped":              # as the entry writes them: "skipped PAINT 36, TOOL PATH 1"
                said, found = (", ".join(f"{w} {n}" for w, n in v) or "none" for v in (said, found))
                entry = f"skipped {said}"
            else:
                entry = f"{said} {field.name.replace('_', ' ')}"
            raise Prs3Error(f"{header.path}:{header.line('counts')}: header: counts: {entry}, but {source_name} "
                            f"converted again gives {found}: the header was edited, or the program was made from "
                            "another input or by another version")


def intended_from_poses(path: str, program: ProgramFile) -> Intended:
    """One pose per motion line of ``program`` from a poses CSV (the ``ik --batch`` format).

    Raises
    ------
    InputError
        An unreadable table, a bad axis, or another number of poses than motion lines.
    """
    from prs3_post.readers.poses import read_poses

    table = read_poses(path)
    try:
        unit = unit_axes(table.tip, table.axis, row_name="line", row_numbers=table.line)
    except PoseError as error:
        raise InputError(str(error), path=path) from error
    if len(unit) != len(program.moves):
        raise InputError(f"{len(unit)} poses for the {len(program.moves)} motion lines of {program.path}: "
                         "give one pose per G0/G1 line, in order", path=path)
    return Intended(tip=table.tip, axis=unit, feed=np.full(len(unit), np.nan),
                    kind=np.full(len(unit), -1, dtype=np.int64), label=Path(path).name)


def tool_lengths_of(header: ProgramHeader | SourceHeader | None) -> dict[int, float] | None:
    """mm, the tool length "TL" the IK used for each tool a program's header states (None: no such
    entry, every row has the machine's; a converted program's one tool length is its machine's, see
    :func:`open_setting`)."""
    if not isinstance(header, ProgramHeader) or not header.tools:
        return None
    return {tool.number: tool.ik_length for tool in header.tools}


def verify_loaded(program: ProgramFile, machine: Machine, setup: Setup, dialect: Dialect, *,
                  tolerance: float, axis_tolerance_deg: float = DEFAULT_ANGLE_TOLERANCE_DEG,
                  intended: Intended | None = None, tool_lengths: dict[int, float] | None = None,
                  odd_feeds: bool = True, progress: Progress | None = None) -> VerifyReport:
    """verify_program on a read program, with the dialect's decimals (``odd_feeds``, ``progress``: see
    :func:`~prs3_post.check.verify.verify_program`; :func:`odd_feeds_warned` of its header).

    Raises
    ------
    InputError
        A program without moves.
    """
    if not len(program.moves):
        raise InputError("no moves (G0/G1 lines) in the program", path=program.path)
    return verify_program(
        machine, program.moves, setup=setup, tolerance=tolerance,
        axis_tolerance=math.radians(axis_tolerance_deg), intended=intended,
        length_decimals=dialect.decimals.length, feed_decimals=dialect.decimals.inverse_time,
        blending_lines=program.blending_lines, tool_lengths=tool_lengths, odd_feeds=odd_feeds, progress=progress,
    )


def odd_feeds_warned(header: ProgramHeader | SourceHeader | None) -> bool:
    """Whether a G1 feed that matches no other is worth a warning (a hand edit?): not in a converted program,
    whose feeds are the CAM program's (a G81 at F100 among F200 moves)."""
    return not isinstance(header, SourceHeader)


@dataclass(frozen=True, slots=True)
class Verified:
    """What `verify` found: the report, what the program was made for, and its clearance from the part
    (None: not measured; a text: why not)."""

    report: VerifyReport
    setting: ProgramSetting
    clearance: PartClearance | str | None


def verify_steps(path: str, *, machine: str | None, dialect: str | None, origin: tuple[float, ...] | None,
                 rotation_deg: float | None, tolerance: float | None, axis_tolerance_deg: float, whole: bool,
                 intended_of: Callable[[ProgramContext], tuple[Intended | None, RebuiltJob | CamPart | None]] | None,
                 collision_check: bool, clearance_min: float | None,
                 on_cross_check: Callable[[CrossCheck], None] | None = None,
                 progress: Progress | None = None) -> Verified:
    """Verify a program, in the order the checks need: what it was made for (its header, or the values
    given), the tolerance (:func:`check_tolerance`), then either the whole program read with its
    intended path (``intended_of``: the front end's reading of what it is compared with) and its
    clearance from the part, or, for a text report without a path (``whole`` False), the program
    streamed through a chunk at a time.

    Parameters
    ----------
    machine, dialect, origin, rotation_deg : as :func:`open_setting` (None: the header's)
    tolerance : float | None — mm, as given (None: the program's)
    whole : bool — read the whole program (a report of every move) even without an intended path
    intended_of : callable, optional — the intended path and the job or part it comes from
    collision_check : bool — measure the clearance from the part when the intended path has one
    clearance_min : float | None — mm, as given (None: each operation's)
    on_cross_check : callable, optional — given the program read again by pygcode
        (:func:`~prs3_post.app.cross_check.cross_check`) before it is verified, so that what pygcode reads
        of a line our reader refuses is told before that refusal

    Raises
    ------
    HeaderConflict, FieldError, InputError, ConfigError
        As :func:`open_setting` and :func:`open_program`, and as ``intended_of``.
    """
    setting = open_setting(path, machine=machine, dialect=dialect, origin=origin, rotation_deg=rotation_deg)
    checked = check_tolerance(setting.header, tolerance)
    if on_cross_check is not None:
        from prs3_post.app.cross_check import cross_check

        on_cross_check(cross_check(path, setting.dialect, stage=setting.machine.stage.present,
                                   kinematics=kinematics_of(setting.machine)))
    if not (whole or intended_of is not None):        # no samples needed: the program streams through
        return Verified(verify_file(setting, tolerance=checked, axis_tolerance_deg=axis_tolerance_deg,
                                    progress=progress), setting, None)
    context = open_program(path, machine=machine, dialect=dialect, origin=origin, rotation_deg=rotation_deg)
    check_program_moves(context.header, len(context.program.moves))
    intended, rebuilt = intended_of(context) if intended_of is not None else (None, None)
    report = verify_loaded(context.program, context.machine, context.setup, context.dialect, tolerance=checked,
                           axis_tolerance_deg=axis_tolerance_deg, intended=intended,
                           tool_lengths=tool_lengths_of(context.header), odd_feeds=odd_feeds_warned(context.header),
                           progress=progress)
    clearance: PartClearance | str | None = None
    if rebuilt is not None and not collision_check:
        clearance = "not measured (asked not to)"
    elif rebuilt is not None:                          # the clearance min: as given, else each operation's
        report, clearance = with_clearance(report, context.machine, rebuilt, clearance_min=clearance_min)
    return Verified(report, setting, clearance)


def check_tolerance(header: ProgramHeader | SourceHeader | None, given: float | None) -> float:
    """The tip deviation a program is checked with, mm: the one given, else the one its header says it
    was made with, else :data:`~prs3_post.core.defaults.DEFAULT_TOLERANCE`."""
    if given is not None:
        return given
    return header.tolerance if header is not None else DEFAULT_TOLERANCE


def verify_program_file(path: str, *, machine: str | None = None, dialect: str | None = None,
                        part_origin: tuple[float, ...] | None = None, part_rotation_deg: float | None = None,
                        tolerance: float | None = None,
                        axis_tolerance_deg: float = DEFAULT_ANGLE_TOLERANCE_DEG) -> VerifyReport:
    """Replay a program file through forward kinematics and check it: limits, straightness, feeds.

    Parameters
    ----------
    path : str — the program (G-code for this machine, as the main job or ``convert`` wrote it)
    machine, dialect : str | None — a shipped name or a TOML path (None: the program header's, or the defaults)
    part_origin : (3,) mm | None, part_rotation_deg : float | None — the setup (None: the header's, or the
        machine's default)
    tolerance : float | None — mm, the allowed tip deviation (None: the one the program was made with,
        :func:`check_tolerance`)
    axis_tolerance_deg : float — degrees, the allowed tool-axis deviation

    Returns
    -------
    VerifyReport — ``ok`` when every sample is within every limit and tolerance

    Raises
    ------
    HeaderConflict
        A value given that contradicts the program's header.
    InputError, ConfigError
        An unreadable program, or a machine or dialect file that is wrong.
    """
    setting = open_setting(path, machine=machine, dialect=dialect, origin=part_origin, rotation_deg=part_rotation_deg)
    return verify_file(setting, tolerance=check_tolerance(setting.header, tolerance),
                       axis_tolerance_deg=axis_tolerance_deg)


def verify_file(setting: ProgramSetting, *, tolerance: float, axis_tolerance_deg: float = DEFAULT_ANGLE_TOLERANCE_DEG,
                chunk_lines: int = CHUNK_LINES, progress: Progress | None = None) -> VerifyReport:
    """Read and verify a program a chunk of lines at a time (:class:`~prs3_post.readers.program.ProgramStream`
    into a :class:`~prs3_post.check.verify.Verifier`): memory does not grow with the samples, only by a few
    numbers per move. The report keeps no samples (the text report needs none); it is the report
    :func:`verify_loaded` gives for any ``chunk_lines``. ``progress``: told the bytes read of the file's size.

    Raises
    ------
    InputError
        An unreadable program, or one without moves.
    """
    stream = ProgramStream(setting.path, setting.dialect, stage=setting.machine.stage.present, chunk_lines=chunk_lines,
                           kinematics=kinematics_of(setting.machine))
    stream.progress = progress
    decimals = setting.dialect.decimals
    verifier = Verifier(setting.machine, setup=setting.setup, tolerance=tolerance,
                        axis_tolerance=math.radians(axis_tolerance_deg), length_decimals=decimals.length,
                        feed_decimals=decimals.inverse_time, capacity=stream.check(),
                        tool_lengths=tool_lengths_of(setting.header), odd_feeds=odd_feeds_warned(setting.header))
    for chunk in read_ahead(stream):
        verifier.add(chunk)
    if not verifier.rows:
        raise InputError("no moves (G0/G1 lines) in the program", path=setting.path)
    check_program_moves(setting.header, verifier.rows)
    return verifier.report(blending_lines=stream.blending_lines)
