"""Conversion of CAM output: one APT CL or 3+2 G-code file → one checked program for this machine.

    INPUT ──► format (content) ──► reader (part frame, mm) ──► post_process (setup, exact IK,
          subdivision, limits on every emitted point) ──► emitter + dialect ──► OUTDIR/<stem><extension>

The program opens with a self-describing header (:func:`prs3_post.emit.header_write.source_header_entries`):
the source file's name and SHA-256, the setup, the tolerances, the tool length used by the IK and the
counts, so that ``verify --against INPUT`` can rebuild what the program should do.

A batch (:func:`prs3_post.app.batch.convert_batch`) runs the files in worker processes; each file either completes (its
program written atomically, :func:`prs3_post.core.output_files.write_atomic`) or leaves nothing behind, and a
failing file does not stop the others unless asked. Messages name files, lines and values, never a
command-line flag.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from prs3_post.app.read_ahead import read_ahead
from prs3_post.app.streaming import program_text
from prs3_post.core.defaults import (
    DEFAULT_ANGLE_TOLERANCE_DEG,
    DEFAULT_CIRCLE_TOLERANCE,
    DEFAULT_CLEARANCE_MIN,
    DEFAULT_TOLERANCE,
)
from prs3_post.core.errors import InputError, LimitError, PoseError, ReachError, shown_path
from prs3_post.core.input_files import open_input
from prs3_post.core.output_files import HeadLast, write_atomic
from prs3_post.core.toolpath import Event, EventKind, JointProgram, MoveKind, Toolpath, join_programs
from prs3_post.core.types import FloatArray, Progress
from prs3_post.core.version import __version__
from prs3_post.emit.gcode import ProgramEmitter
from prs3_post.emit.header import SourceCounts, SourceHeader
from prs3_post.emit.header_write import source_header_entries
from prs3_post.kinematics import unit_axes
from prs3_post.kinematics.prs3.blocks import default_workers
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.loading import Dialect, Machine, file_given
from prs3_post.part.setup_transform import Setup
from prs3_post.part.workplane import WorkPlane
from prs3_post.post.dynamics import FeedSpeedError, streamed_entry
from prs3_post.post.limits import check_limits, raise_first_violation
from prs3_post.post.pipeline import (
    PostCounts,
    PostResult,
    PostStream,
    model_for,
    place_toolpath,
)
from prs3_post.readers.common import join_toolpaths
from prs3_post.readers.detect import DETECT_BYTES, detect_format, formats
from prs3_post.readers.protocol import CamStream, ReadOptions
from prs3_post.readers.registry import reader_named, readers

if TYPE_CHECKING:  # imported where used: a plain 3+2 or CL conversion needs none of them (test_startup)
    from prs3_post.machine.cam_conventions import SourceConvention


@dataclass(frozen=True, slots=True)
class ConvertSettings:
    """Everything a conversion needs besides the input file.

    Attributes
    ----------
    machine : Machine — as loaded (its own tool length)
    dialect : Dialect
    setup : Setup — part → machine
    tolerance : float — mm, chordal tolerance of arcs and of axis-changing moves
    angle_tolerance_deg : float — degrees, allowed tool-axis deviation of subdivided moves
    circle_tolerance : float — mm, how far a CAM arc's ends may be from its circle
    tool_length : float | None — mm, platform centre to tool tip for the IK (None: the machine's)
    input_format : str — ``auto``, ``cl`` or ``gcode``
    units : str | None — a CL file's length unit when it has no UNITS/ record (None: from its feeds)
    ignore : tuple of str — CL major words skipped (and counted) instead of refused
    work_plane : WorkPlane | None — where a G-code program's X, Y, Z are in the part (None: the part frame)
    source : SourceConvention | None — G-code is a 5-axis program of this source machine (None: 3+2 G-code)
    tcp_on, tcp_off : tuple of str | None — the codes that switch its TCP on and off (None: the source's);
        codes the reader would read as something else, or one code in both, are a ConfigError here
    line_numbers, line_start, line_step : block numbering overrides (None: the dialect's)
    auto_origin, auto_rotation : bool — choose the part origin / the rotation about z for each file
        (:func:`prs3_post.check.placement.place`: the largest worst-case margin); ``setup`` holds the values kept
    part : str | None — the part's STL, to check the holder and nose against (None: not checked)
    part_units, part_up : str — its length unit and up axis (as :func:`prs3_post.part.stl.load_part`)
    collision_check : bool — with ``part``, check every program before it is written
    clearance_min : float — mm, the least distance the holder and nose must keep from the part
    tool_diameter : float | None — mm, the tool's diameter for its check in the rapids (None: the CAM
        input's, :meth:`~prs3_post.readers.protocol.CamStream.tool_diameter`)
    clamp : bool — lower a feed that would drive an axis over its top speed (the machine's dynamics;
        the header and the report say how many); False: such a feed is a LimitError naming its line
    """

    machine: Machine
    dialect: Dialect
    setup: Setup
    tolerance: float = DEFAULT_TOLERANCE
    angle_tolerance_deg: float = DEFAULT_ANGLE_TOLERANCE_DEG
    circle_tolerance: float = DEFAULT_CIRCLE_TOLERANCE
    tool_length: float | None = None
    input_format: str = "auto"
    units: str | None = None
    ignore: tuple[str, ...] = ()
    work_plane: WorkPlane | None = None
    source: SourceConvention | None = None
    tcp_on: tuple[str, ...] | None = None
    tcp_off: tuple[str, ...] | None = None
    line_numbers: bool | None = None
    line_start: int | None = None
    line_step: int | None = None
    auto_origin: bool = False
    auto_rotation: bool = False
    part: str | None = None
    part_units: str = "mm"
    part_up: str = "z"
    collision_check: bool = True
    clearance_min: float = DEFAULT_CLEARANCE_MIN
    tool_diameter: float | None = None
    clamp: bool = True

    def __post_init__(self) -> None:
        if self.input_format not in formats():
            raise ValueError(f"input_format must be one of {formats()}, got {self.input_format!r}")
        if self.tool_length is not None and not (math.isfinite(self.tool_length) and self.tool_length > 0):
            raise InputError(f"tool length: must be a number > 0 mm, got {self.tool_length:g}",
                             path=self.machine.source)
        for reader in readers():                        # refused once, before any file is read
            reader.check(self.read_options)

    @property
    def read_options(self) -> ReadOptions:
        """How the inputs are to be read (each format takes what concerns it)."""
        return ReadOptions(tolerance=self.tolerance, circle_tolerance=self.circle_tolerance, units=self.units,
                           tool_number_max=self.dialect.tool_number_max,
                           ignore=self.ignore, work_plane=self.work_plane, source=self.source, tcp_on=self.tcp_on,
                           tcp_off=self.tcp_off)

    @property
    def ik_machine(self) -> Machine:
        """The machine with the tool length the IK uses."""
        return self.machine if self.tool_length is None else self.machine.with_tool_length(self.tool_length)


@dataclass(frozen=True, slots=True)
class ConvertReport:
    """What one conversion read and made (every input record accounted for).

    Attributes
    ----------
    input : str — the input path as given
    format : str — ``cl`` or ``gcode``
    units : str — the input's length unit (``mm`` or ``inch``)
    sha256 : str — of the input's bytes
    records : int — input records (CL records, G-code lines with code)
    by_word : tuple of (str, int) — records by major word (CL) or G/M code (G-code)
    input_moves : int — motion records that became one row each
    arcs, arc_rows : int — arcs expanded and the rows they became
    cycles, cycle_holes, cycle_rows : int — drilling cycles, their holes and the rows those became
    comments : int — comments carried into the program
    skipped : tuple of (str, int) — records skipped on purpose (display records, ignored words), with counts
    toolpath_rows : int — rows read (part frame)
    subdivisions : int — rows inserted to keep axis-changing moves within tolerance
    dropped : int — rows the output cannot show (no axis word changes at its decimals)
    emitted_moves : int — motion lines of the program
    deviation_before : float — mm, worst tip deviation of the joint-space moves before subdivision
    deviation_after : float — mm, the same after subdivision (≤ the tolerance)
    angle_before_deg, angle_after_deg : float — degrees, the same for the tool axis
    tool_length : float — mm, used by the IK
    setup : str — the setup used (chosen automatically or given), as the header states it
    five_axis : str — what the input is read as where its reader says (a 5-axis G-code program: its source
        convention and the path it is read as; :attr:`~prs3_post.readers.protocol.CamStream.read_as`)
    slowed_moves : int — G1 moves whose feed was lowered to the axis speed limits (the header's ``dynamics``)
    """

    input: str
    format: str
    units: str
    sha256: str
    records: int
    by_word: tuple[tuple[str, int], ...]
    input_moves: int
    arcs: int
    arc_rows: int
    cycles: int
    cycle_holes: int
    cycle_rows: int
    comments: int
    skipped: tuple[tuple[str, int], ...]
    toolpath_rows: int
    subdivisions: int
    dropped: int
    emitted_moves: int
    deviation_before: float
    deviation_after: float
    angle_before_deg: float
    angle_after_deg: float
    tool_length: float
    setup: str
    five_axis: str = ""
    slowed_moves: int = 0

    @property
    def motion_records(self) -> int:
        """Moves, arcs and drilled holes as the input states them (what "moves/s" counts)."""
        return self.input_moves + self.arcs + self.cycle_holes

    def counts(self) -> SourceCounts:
        """What the program's header states of this accounting."""
        return SourceCounts(records=self.records, moves=self.input_moves, arcs=self.arcs, arc_rows=self.arc_rows,
                            cycle_holes=self.cycle_holes, cycle_rows=self.cycle_rows, comments=self.comments,
                            program_moves=self.emitted_moves, subdivisions=self.subdivisions, skipped=self.skipped)

    def record(self) -> dict[str, object]:
        """The report as JSON-ready data (word counts as objects)."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["by_word"] = dict(self.by_word)
        out["skipped"] = dict(self.skipped)
        return out


@dataclass(frozen=True, slots=True)
class Conversion:
    """One converted file held in memory: the program text, its report, and the machine-frame path
    it follows (one row per program motion line)."""

    text: str
    report: ConvertReport
    path: Toolpath


# ----------------------------------------------------------------------------- one file


def input_format(path: str, requested: str = "auto") -> str:
    """The input's format (a registered reader's name): ``requested`` unless ``auto``, else by the file's
    first bytes (:func:`~prs3_post.readers.detect.detect_format`).

    Raises
    ------
    InputError
        The file cannot be opened (missing, a folder, a FIFO, unreadable), or it is empty (in any format).
    """
    with open_input(path, "a file") as stream:
        try:
            head = stream.read(DETECT_BYTES)
        except OSError as exc:
            raise InputError(f"cannot read the file: {exc.strerror or exc}", path=path) from exc
    if not head:
        raise InputError("the file is empty (0 bytes): nothing to convert", path=path)
    if len(head) < DETECT_BYTES and not head.strip():
        raise InputError("the file has only blank lines: nothing to convert", path=path)
    return requested if requested != "auto" else detect_format(head)


def source_stream(path: str, settings: ConvertSettings, fmt: str, progress: Progress | None = None) -> CamStream:
    """The input's reader for its format ``fmt``, in chunks of lines (part frame, mm); ``progress`` told
    the bytes it reads."""
    stream = reader_named(fmt).open(path, settings.read_options)
    if progress is not None:
        stream.progress = progress
    return stream


def _share(progress: Progress | None, first: float, last: float) -> Progress | None:
    """``progress`` of one pass over the file that is the share ``first`` to ``last`` (fractions) of
    the whole conversion's."""
    if progress is None:
        return None

    def told(done: float, total: float) -> None:
        progress(total * (first + (last - first) * done / total) if total > 0 else 0.0, total)
    return told


def _refuse_tilt(machine: Machine, chunk: Toolpath, run: _Run) -> None:
    """A program's own orientations (:attr:`~prs3_post.readers.protocol.CamStream.refuses_tilt`) beyond the
    machine's tilt limit, named at the first line with its value and the share of the file's rows beyond
    it (read again for that: only a failure pays)."""
    tilt = np.degrees(np.arccos(np.clip(chunk.axis[:, 2], -1.0, 1.0)))     # clip: rounding past ±1
    limit = math.degrees(machine.limits.max_tilt)
    bad = np.flatnonzero(tilt > limit)
    if not len(bad):
        return
    row = int(bad[0])
    beyond = total = 0
    for part in source_stream(run.path, run.settings, run.fmt):
        part_tilt = np.degrees(np.arccos(np.clip(part.axis[:, 2], -1.0, 1.0)))
        beyond += int((part_tilt > limit).sum())
        total += len(part)
    run.placeable = False
    raise LimitError(f"{chunk.describe(row)}: the program's tool axis tilts {tilt[row]:.4f} deg from the part's z, "
                     f"beyond this machine's maximum tilt {limit:.4f} deg; {beyond} of {total} rows "
                     f"({100.0 * beyond / total:.1f}%) tilt beyond it, and a setup turns the part about z only, so no "
                     "setup brings them within it (the CAM program must tilt the tool less)")


def _refuse_feed_first(chunk: Toolpath, fmt: str) -> None:
    """A first motion that is a feed has no start point: an input property (no setup helps); the
    format's reader says what would be valid instead."""
    if len(chunk) and chunk.kind[0] == MoveKind.FEED:
        raise InputError("the first motion is a feed move, so its start point is unknown: "
                         f"{reader_named(fmt).first_move}", path=chunk.source_file, line=int(chunk.source[0]))


class AxisError(ReachError):
    """A tool axis that points away from the spindle (or is zero) in the part frame: no setup, which
    turns the part about z only, can fix it, so no part origin is suggested."""


def _check_poses(machine: Machine, chunk: Toolpath, setup: Setup, *, limits: bool = True) -> Toolpath:
    """The tool axes of the points as read (by input line), and with ``limits`` their reach and limits,
    before any subdivision: a path outside the workspace is named at its first bad line at once
    (subdividing it first could not converge on moves that cross a singularity, and would only
    multiply the bad rows). Returns the chunk placed on the machine with unit axes (what a
    ``placed`` :class:`~prs3_post.post.pipeline.PostStream` takes: the chunk is transformed once)."""
    path = place_toolpath(chunk, setup)
    try:
        axis = unit_axes(path.tip, path.axis, row_name="line", row_numbers=path.source)
    except PoseError as error:
        raise AxisError(f"{chunk.source_file}: {error}; a setup turns the part about z only, so no setup turns "
                        "these tool axes toward the spindle") from error
    path = dataclasses.replace(path, axis=axis)
    if not limits:
        return path
    ik = kinematics_of(machine).inverse(path.tip, axis, model=model_for(machine))
    if ik.reachable.all():                              # else the pipeline names the unreachable pose
        raise_first_violation(check_limits(machine, ik, axis), path.describe)
    return path


@dataclass(slots=True)
class _Run:
    """One conversion under way: the reader, the post-processing stream, and what they counted."""

    path: str
    settings: ConvertSettings
    fmt: str
    sha256: str                                         # of the bytes converted: "" until the reader is through
    reader: CamStream
    post: PostStream
    rows: int = 0
    results: list[PostResult] = field(default_factory=list)   # each chunk's, when kept (convert_file)
    programs: list[JointProgram] = field(default_factory=list)   # each chunk's, for the collision check
    placeable: bool = True                              # False: no setup can help the error raised

    def chunks(self) -> Iterator[Toolpath]:
        """The reader's chunks, checked as read, placed on the machine (unit axes: for the ``placed`` stream)."""
        # the next chunk is read by a thread while this one is post-processed, where this process may use two
        # cores (processes × threads ≤ cores) and the reader allows it
        if default_workers() > 1 and self.reader.reads_ahead:
            yield from self._placed(read_ahead(self.reader))
        else:
            yield from self._placed()

    def _placed(self, chunks: Iterable[Toolpath] | None = None) -> Iterator[Toolpath]:
        """:meth:`chunks` of the reader's ``chunks`` (default: the reader itself)."""
        machine = self.settings.ik_machine
        last_axis: np.ndarray | None = None
        reader = self.reader
        for chunk in reader if chunks is None else chunks:
            if reader.refuses_tilt:
                _refuse_tilt(machine, chunk, self)
            if reader.read_as and not self.rows:        # what the file is read as: the program's first comment
                chunk = dataclasses.replace(chunk, events=(
                    Event(before=0, kind=EventKind.COMMENT, text=reader.read_as), *chunk.events))
            if not self.rows:
                _refuse_feed_first(chunk, self.fmt)
            placed = chunk
            if len(chunk):
                axes = np.vstack([chunk.axis if last_axis is None else [last_axis], chunk.axis])
                turning = np.ptp(axes, axis=0).max() > 0.0   # an axis change: subdivision needs reachable ends
                placed = _check_poses(machine, chunk, self.settings.setup, limits=bool(turning))
                last_axis = chunk.axis[-1]
            self.rows += len(chunk)
            yield placed
        if not self.rows:
            raise InputError("no moves in the file: nothing to convert", path=self.path)
        self.sha256 = self.reader.sha256 or ""          # of the bytes converted (read once, by the reader)

    def report(self, counts: PostCounts) -> ConvertReport:
        """The accounting, once the reader is through."""
        summary = self.reader.summary
        assert summary is not None  # set when the reader's iteration ends
        c = summary.counts
        return ConvertReport(
            input=self.path, format=self.fmt, units=summary.units, sha256=self.sha256, records=c.records,
            by_word=c.by_word, input_moves=c.moves, arcs=c.arcs, arc_rows=c.arc_segments, cycles=c.cycles,
            cycle_holes=c.cycle_holes, cycle_rows=c.cycle_rows, comments=c.comments, skipped=self.reader.skipped(),
            toolpath_rows=counts.input_rows, subdivisions=counts.inserted, dropped=counts.dropped,
            emitted_moves=counts.program_rows, deviation_before=counts.tip_before, deviation_after=counts.tip_after,
            angle_before_deg=math.degrees(counts.angle_before), angle_after_deg=math.degrees(counts.angle_after),
            tool_length=self.settings.ik_machine.geometry.tool_length, setup=self.settings.setup.describe(),
            five_axis=self.reader.read_as, slowed_moves=self.post.dynamics.clamped)


def _start(path: str, settings: ConvertSettings, progress: Progress | None = None) -> _Run:
    fmt = input_format(path, settings.input_format)
    auto = settings.auto_origin or settings.auto_rotation
    if auto:                                             # the whole path decides the setup: read it once more
        whole = source_stream(path, settings, fmt, _share(progress, 0.0, 0.5)).whole()
        if not len(whole.toolpath):
            raise InputError("no moves in the file: nothing to convert", path=path)
        _refuse_feed_first(whole.toolpath, fmt)
        _check_poses(settings.ik_machine, whole.toolpath, settings.setup, limits=False)   # axes by input line
        from prs3_post.check.placement import place

        chosen = place(settings.ik_machine, whole.toolpath,
                       origin=None if settings.auto_origin else settings.setup.origin,
                       rotation_deg=None if settings.auto_rotation else settings.setup.rotation_deg,
                       tolerance=settings.tolerance, angle_tolerance=math.radians(settings.angle_tolerance_deg))
        settings = dataclasses.replace(settings, setup=chosen.setup, auto_origin=False, auto_rotation=False)
    reader = source_stream(path, settings, fmt, _share(progress, 0.5, 1.0) if auto else progress)
    machine = settings.ik_machine
    post = PostStream(machine, settings.setup, tolerance=settings.tolerance,
                      angle_tolerance=math.radians(settings.angle_tolerance_deg),
                      length_decimals=settings.dialect.decimals.length, placed=True, clamp=settings.clamp,
                      timed=True)
    post.dynamics.file_name = shown_path(Path(path).name)   # the header's worst move: as its source entry names it
    return _Run(path=path, settings=settings, fmt=fmt, sha256="", reader=reader, post=post)


def _header(run: _Run) -> SourceHeader:
    """The program header as known before the file is read (without the counts)."""
    settings = run.settings
    notes = run.reader.notes()
    return SourceHeader(
        version=f"prs3-post {__version__}", machine=settings.machine.name,
        machine_file=file_given(settings.machine.source, "machines", settings.machine.name),
        dialect=settings.dialect.name,
        dialect_file=file_given(settings.dialect.source, "dialects", settings.dialect.name),
        source_name=shown_path(Path(run.path).name), source_sha256=run.sha256, source_format=run.fmt,
        source_units=notes.units, ignore=notes.ignore, work_plane=notes.work_plane, setup=settings.setup,
        tool_length=settings.ik_machine.geometry.tool_length, tool_length_given=settings.tool_length is not None,
        tolerance=settings.tolerance, angle_tolerance_deg=settings.angle_tolerance_deg,
        line_numbers=settings.line_numbers, line_start=settings.line_start, line_step=settings.line_step,
        five_axis=notes.five_axis, tcp_on=notes.tcp_on, tcp_off=notes.tcp_off,
    )


def _placed(error: LimitError | ReachError, run: _Run) -> Exception:
    """``error`` with the setup used and a part origin that fits, if one does (the whole file is read
    again for that: only a failure pays for it)."""
    settings = run.settings
    if not run.placeable or isinstance(error, (AxisError, FeedSpeedError)):   # no setup turns a tool axis (about
        return error                                    # z only); a feed too fast is the feed's (no clamping)
    try:
        stream = source_stream(run.path, settings, run.fmt)
        whole = stream.whole()
    except InputError:
        return error
    from prs3_post.check.placement import placement_error

    triangles = _part_triangles(settings)
    check = None if triangles is None else partial(_collision_at, settings, triangles, stream.tool_diameter())
    return placement_error(error, settings.ik_machine, whole.toolpath, settings.setup, tolerance=settings.tolerance,
                           angle_tolerance=math.radians(settings.angle_tolerance_deg),
                           length_decimals=settings.dialect.decimals.length, check=check, advise=_collision_advice)


def _collision_at(settings: ConvertSettings, triangles: FloatArray, cam_diameter: float, setup: Setup,
                  posted: PostResult) -> None:
    """The check :func:`_collision` makes, of the program ``posted`` at ``setup`` (for a part origin an
    error suggests: :data:`~prs3_post.check.placement.SetupCheck`)."""
    from prs3_post.check.collision import check_rapids, measure_program

    machine = settings.ik_machine
    measure_program(machine, posted.program, setup, triangles, None, 0.0, clearance_min=settings.clearance_min)
    check_rapids(machine, posted.program, setup, triangles,
                 cam_diameter if settings.tool_diameter is None else settings.tool_diameter)


def _collision_advice(error: LimitError) -> tuple[str, tuple[str, ...]]:
    """What to change for a collision of a CAM program that no setup avoids
    (:data:`~prs3_post.check.placement.Advise`): a rapid through the part is the CAM program's; the
    holder or the nose, a longer tool or a shorter holder."""
    from prs3_post.check.collision import CollisionError

    if isinstance(error, CollisionError) and error.body == "tool":
        return "the CAM program's rapid moves cut the part: change them in the CAM system", ()
    return ("try a longer tool ({tool_length}, as the CAM program was made for) or a shorter holder (the machine "
            "file's [holder])", ("tool_length",))


def program_chunks(path: str, settings: ConvertSettings, *, keep: bool = False,
                   progress: Progress | None = None) -> tuple[_Run, HeadLast]:
    """The conversion of one file as program text whose header is made last: the body's chunks are
    lazy (see :func:`prs3_post.app.streaming.program_text`), and the head, with the counts, is made once
    they are through (:class:`prs3_post.core.output_files.HeadLast`: a writer spools the body, then writes the
    head and the body). The run's :meth:`_Run.report` follows the body. ``progress``: told the bytes read
    of the file's size (with an automatic setup, the reading that chooses it is the first half)."""
    run = _start(path, settings, progress)
    stream = run.post
    triangles = _part_triangles(settings)
    if keep or triangles is not None:                   # keep each chunk's result (tests, verify --against)
        feed = stream.feed                              # or program (the collision check)

        def kept(chunk: Toolpath) -> PostResult:
            result = feed(chunk)
            if keep:
                run.results.append(result)
            if triangles is not None:
                run.programs.append(result.program)
            return result

        stream.feed = kept  # type: ignore[method-assign]  # a wrapper with the same signature
    header = _header(run)
    description = settings.machine.description
    entries = source_header_entries(header, description=description)
    text = program_text(settings.ik_machine, run.chunks(), settings.setup, settings.dialect, header=entries,
                        tolerance=settings.tolerance, angle_tolerance=math.radians(settings.angle_tolerance_deg),
                        line_numbers=settings.line_numbers, line_start=settings.line_start,
                        line_step=settings.line_step, stream=stream)

    def body() -> Iterator[str]:
        next(text)                                      # its opening, made again below with the counts
        yield from _with_placement(text, run)

    def head() -> str:
        counts = run.report(run.post.finish()).counts()
        collision = _collision(run, triangles)
        entries = source_header_entries(dataclasses.replace(header, counts=counts, collision=collision,
                                                            dynamics=streamed_entry(run.post.dynamics),
                                                            source_sha256=run.sha256),
                                        description=description)
        # the same opening as program_text's (its comments have no block numbers: the body's agree)
        emitter = ProgramEmitter(settings.dialect, stage=settings.ik_machine.stage.present,
                                 line_numbers=settings.line_numbers, line_start=settings.line_start,
                                 line_step=settings.line_step, kinematics=kinematics_of(settings.ik_machine))
        return emitter.begin(entries)

    return run, HeadLast(body=body(), head=head)


def _part_triangles(settings: ConvertSettings) -> FloatArray | None:
    """The part's triangles when its programs are to be checked against it (None: not checked)."""
    if settings.part is None or not settings.collision_check:
        return None
    from prs3_post.part.stl import load_part

    mesh = load_part(settings.part, units=settings.part_units, up=settings.part_up)
    return np.asarray(mesh.triangles, dtype=np.float64)


def _collision(run: _Run, triangles: FloatArray | None) -> str:
    """The header's ``collision`` entry, the program checked: the holder and the nose everywhere
    (:func:`prs3_post.check.collision.measure_program` with no face: the tool cuts what the CAM program
    removes), and the tool in the rapids (:func:`prs3_post.check.collision.check_rapids`: a rapid must not
    cut), with the diameter given (``--tool-diameter``), else the CAM input's
    (:meth:`~prs3_post.readers.protocol.CamStream.tool_diameter`).

    Raises
    ------
    LimitError
        ``part.cls:41: the holder hits the part, 2.100 mm deep (clearance min 1.000 mm)``, or
        ``part.cls:12: the tool hits the part in a rapid, 4.950 mm deep (...)``.
    """
    settings = run.settings
    if settings.part is None:
        return "not checked (no part given)"
    if triangles is None:
        return "not checked (asked not to)"
    from prs3_post.check.collision import check_rapids, measure_program

    parts, run.programs = run.programs, []
    file = parts[0].source_file if parts else run.path
    program = join_programs(parts, source_file=file)
    machine = settings.ik_machine
    found = measure_program(machine, program, settings.setup, triangles, None, 0.0,
                            clearance_min=settings.clearance_min)
    if isinstance(found, str):
        return found
    diameter = run.reader.tool_diameter() if settings.tool_diameter is None else settings.tool_diameter
    rapids = check_rapids(machine, program, settings.setup, triangles, diameter)
    return found.entry(settings.clearance_min, rapids=rapids)


def _with_placement(text: Iterator[str], run: _Run) -> Iterator[str]:
    try:
        yield from text
    except (LimitError, ReachError) as error:
        raise _placed(error, run) from error


def convert_file(path: str, settings: ConvertSettings) -> Conversion:
    """Convert one CAM file into a program held in memory (nothing is written).

    Raises
    ------
    InputError
        An unreadable input (``path:line: message``).
    LimitError, ReachError
        A point outside a limit or the workspace (``path:line: ...``, the setup, and a part origin
        that fits where there is one).
    """
    run, program = program_chunks(path, settings, keep=True)
    body = "".join(program.body)                        # type: ignore[arg-type]  # str chunks
    text = str(program.head()) + body
    report = run.report(run.post.finish())
    path_rows = [r.path for r in run.results if len(r.path)]
    return Conversion(text=text, report=report, path=join_toolpaths(path_rows) if path_rows else run.results[0].path)


def write_conversion(path: str, output: str, settings: ConvertSettings,
                     progress: Progress | None = None) -> ConvertReport:
    """Convert one CAM file and write its program to ``output`` as it is made, atomically: a file that
    fails leaves nothing (the temp file is removed). ``progress``: as :func:`program_chunks`.

    Raises
    ------
    InputError, LimitError, ReachError
        As :func:`convert_file`, and an output that cannot be written.
    """
    run, program = program_chunks(path, settings, progress=progress)
    write_atomic(output, program)
    return run.report(run.post.finish())
