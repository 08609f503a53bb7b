"""The main job: an STL part, faces, operations → one checked program in actuator space.

    STL ──► faces ──► for each operation: its face ──► plan (hole | square | round)
        ──► post_process with its tool's length ──► transitions between operations ──► emit

The main job's command line is a job of one operation (:func:`run_job`); a job file gives several
(:func:`run_operations`). Between two operations the tool goes up along its axis to the job's
safe height (:func:`safe_height`), the spindle and coolant stop, the tool changes if it changes,
the tool axis turns at that height (a joint-space move, subdivided and limit-checked like any
other), and the tool goes over and down to the next operation. Each operation's IK uses its own
tool length: the machine's gauge offset plus the tool table's Z (without a table, the machine's
``tool_length_mm``).

The only I/O is reading the STL (through :mod:`prs3_post.part.stl`); the program comes back
as text for the CLI to write.
"""

from __future__ import annotations

import gc
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

import numpy as np

from prs3_post.app.accuracy import header_accuracy
from prs3_post.app.job_transitions import MACHINE_FRAME, post_transition, safe_height, transition_paths
from prs3_post.check.collision import Approach, CollisionError, ProgramClearance, feed_tips_of, measure_program
from prs3_post.check.placement import (
    PlacementResult,
    SetupCheck,
    axes_reachable,
    place,
    placement_error,
    suggest,
    suggestion_advice,
)
from prs3_post.core.defaults import (
    DEFAULT_ACTUATOR_RESOLUTION_MM,
    DEFAULT_ANGLE_TOLERANCE,
    DEFAULT_CLEARANCE_MIN,
    DEFAULT_TOLERANCE,
)
from prs3_post.core.errors import FeatureError, InputError, LimitError, ReachError
from prs3_post.core.input_files import file_sha256
from prs3_post.core.numbers import exact_text
from prs3_post.core.toolpath import (
    Event,
    EventKind,
    JointProgram,
    MoveKind,
    Toolpath,
    join_programs,
    program_chunks,
    toolpath_pieces,
)
from prs3_post.core.types import FloatArray
from prs3_post.core.version import __version__
from prs3_post.emit.gcode import ProgramEmitter
from prs3_post.emit.header import OperationRecord, ProgramHeader, ToolRecord
from prs3_post.emit.header_write import header_entries
from prs3_post.kinematics import IKResult
from prs3_post.kinematics.registry import Kinematics, kinematics_of
from prs3_post.machine.loading import Dialect, Machine, file_given
from prs3_post.part.face import Face
from prs3_post.part.faces import MIN_FACE_WIDTH_MM, find_faces, project_onto_face, select_face
from prs3_post.part.setup_transform import Setup
from prs3_post.part.stl import load_part
from prs3_post.post.dynamics import NO_DYNAMICS, DynamicsTally, program_time, timed_entry
from prs3_post.post.limits import LimitTally
from prs3_post.post.pipeline import PostResult, PostStream, machine_path, post_process
from prs3_post.post.visible_moves import length_resolution
from prs3_post.readers.tooltable import Tool, ToolTable
from prs3_post.toolpaths import Cutting, plan_holes, plan_profile
from prs3_post.toolpaths.common import require_tolerance
from prs3_post.toolpaths.work import HoleJob, Operation, ProfileJob


@dataclass(frozen=True, slots=True)
class JobSpec:
    """Everything the main job needs; built by the CLI from its options (or from a program header).

    Attributes
    ----------
    part : str — STL path
    units : str — ``mm`` or ``inch`` (the STL's length unit)
    face : int | None — face index, None = automatic choice
    work : HoleJob | ProfileJob — the operation and its parameters
    at_uv : (K, 2) float — mm, feature positions in face (u, v); empty = see ``at_xyz``
    at_xyz : (K, 3) float — mm, feature positions in part coordinates, projected onto the face
    cutting : Cutting
    machine : Machine
    dialect : Dialect
    setup : Setup — where the part sits on the machine (:meth:`Setup.resolve` gives the machine's default)
    tolerance : float — mm, chordal tolerance of arcs and of axis-changing moves
    line_numbers, line_start, line_step : optional overrides of the dialect's block numbering
    up : str — the STL's up axis, turned to +z when it is read (``z``, ``y``, ``-x``...: ``readers.stl.UP_ROTATION``)
    tool_table : ToolTable | None — the tools' lengths (None: every tool is the machine's ``tool_length_mm``)
    auto_origin, auto_rotation : bool — choose the part origin / the rotation (``check.placement.place``);
        ``setup`` then holds only what was given
    clamp : bool — lower feeds that would drive an axis over its top speed (False: refuse them)
    collision_check : bool — check the tool, holder and spindle nose against the part before writing
    clearance_min : float — mm, the least distance they must keep from the part
    """

    part: str
    units: str
    face: int | None
    work: HoleJob | ProfileJob
    at_uv: FloatArray
    at_xyz: FloatArray
    cutting: Cutting
    machine: Machine
    dialect: Dialect
    setup: Setup
    tolerance: float = DEFAULT_TOLERANCE
    line_numbers: bool | None = None
    line_start: int | None = None
    line_step: int | None = None
    up: str = "z"
    tool_table: ToolTable | None = None
    auto_origin: bool = False
    auto_rotation: bool = False
    clamp: bool = True
    collision_check: bool = True
    clearance_min: float = DEFAULT_CLEARANCE_MIN

    @property
    def operation(self) -> Operation:
        """What is cut (from :attr:`work`)."""
        return self.work.operation


@dataclass(frozen=True, slots=True)
class OperationResult:
    """One operation of a job.

    Attributes
    ----------
    face : Face — the face worked on
    face_note : str — how that face was chosen
    path_part : Toolpath — the operation's toolpath in part coordinates
    tool_length : float — mm, the tool length "TL" its IK used (platform centre to tip)
    label : str — ``operation 2 (round on face 6)`` (empty in a job of one operation)
    """

    face: Face
    face_note: str
    path_part: Toolpath
    tool_length: float
    label: str


@dataclass(frozen=True, slots=True)
class JobResult:
    """What the main job made.

    Attributes
    ----------
    text : str — the program
    face : Face — the (first) operation's face
    face_note : str — how that face was chosen
    path_part : Toolpath — the (first) operation's toolpath in part coordinates
    post : PostResult — the whole program's machine-frame rows, IK, limits and joint program
    setup : Setup — the setup used
    triangles : (F, 3, 3) float — mm, the part's triangles in part coordinates (for pictures)
    operations : tuple of OperationResult — every operation, in program order
    tool_length : (N,) float — mm, the tool length "TL" the IK used for each row of ``post``
    placement : PlacementResult | None — how the setup was chosen (None: as given)
    dynamics : str — the header's ``dynamics`` entry (cycle time, feeds slowed), for the summary
    closest : Approach | None — the body that came closest to the part in the collision check (rows of
        :attr:`program`; relative to each operation's clearance min), for the preview's mark; None: not
        checked, or every body over the horizon
    """

    text: str
    face: Face
    face_note: str
    path_part: Toolpath
    post: PostResult
    setup: Setup
    triangles: FloatArray
    operations: tuple[OperationResult, ...]
    tool_length: FloatArray
    placement: PlacementResult | None = None
    dynamics: str = ""


def positions(face: Face, at_uv: FloatArray, at_xyz: FloatArray) -> FloatArray:
    """Feature positions in face (u, v): the --at points, then the --at-xyz points projected onto the
    face (each must lie on its plane within 0.01 mm: a point off the face is a mistake, not a
    position to move silently); the face origin when neither is given. (K, 2) mm."""
    uv = [np.asarray(at_uv, dtype=np.float64).reshape(-1, 2)]
    xyz = np.asarray(at_xyz, dtype=np.float64).reshape(-1, 3)
    if len(xyz):
        uv.append(project_onto_face(face, xyz))
    out = np.concatenate(uv)
    return out if len(out) else np.zeros((1, 2))


def plan(spec: JobSpec, face: Face) -> Toolpath:
    """The operation's toolpath in part coordinates."""
    centres = positions(face, spec.at_uv, spec.at_xyz)
    work = spec.work
    resolution = length_resolution(spec.dialect.decimals.length)   # what the program can show, mm
    if isinstance(work, HoleJob):
        return plan_holes(face, centres, work.params, spec.cutting, resolution=resolution)
    if len(centres) > 1:
        raise FeatureError(f"{{profile}} {spec.operation.value} cuts one feature: give one {{at}} or {{at_xyz}} "
                           f"(got {len(centres)})", key="at")
    return plan_profile(face, centres[0], work.shape, work.params, spec.cutting, tolerance=spec.tolerance,
                        resolution=resolution)


def run_job(spec: JobSpec) -> JobResult:
    """Load the part, choose the face, plan, post-process and emit: a job of one operation.

    Raises
    ------
    InputError, FeatureError
    PlacementLimitError, PlacementReachError
        The path breaks a limit or cannot be reached with this setup: the message says the setup and,
        where a translation of the part fits, that part origin (``suggested_origin``).
    """
    return run_operations((spec,))


def tool_length_of(spec: JobSpec) -> float:
    """mm, the tool length "TL" the IK uses for ``spec``'s tool: the machine's gauge offset plus the
    tool table's Z, or the machine's ``tool_length_mm`` without a table.

    Raises
    ------
    InputError
        The tool is not in the table, or the table's diameter is not the operation's.
    """
    geometry = spec.machine.geometry
    table = spec.tool_table
    if table is None:
        return geometry.tool_length
    cut = spec.cutting
    tool = table.find(cut.tool_number)
    if tool is None:
        numbers = ", ".join(f"T{t.number}" for t in table.tools)
        raise InputError(f"tool T{cut.tool_number} is not in the tool table (it has {numbers})", path=table.path)
    if tool.diameter != cut.tool_diameter:
        raise InputError(f"T{tool.number} has diameter {exact_text(tool.diameter, 3)} mm in the tool table, but the "
                         f"operation's tool diameter is {exact_text(cut.tool_diameter, 3)} mm", path=table.path,
                         line=tool.line or None)
    return geometry.with_tool(tool.length).tool_length


def _check_tools(specs: tuple[JobSpec, ...]) -> None:
    """One tool number, one tool: every operation that uses it gives it the same diameter.

    Raises
    ------
    FeatureError
        Naming both operations and diameters.
    """
    seen: dict[int, tuple[int, float]] = {}
    for number, spec in enumerate(specs, start=1):
        cut = spec.cutting
        first = seen.setdefault(cut.tool_number, (number, cut.tool_diameter))
        if first[1] != cut.tool_diameter:
            raise FeatureError(f"operation {number} uses T{cut.tool_number} with diameter "
                               f"{exact_text(cut.tool_diameter, 3)} mm, operation {first[0]} with "
                               f"{exact_text(first[1], 3)} mm: one tool number is one tool", key="tool_diameter",
                               operation=number)


def operation_label(number: int, spec: JobSpec, face: Face) -> str:
    """``operation 2 (round on face 6)``: what every step label of an operation in a job starts with."""
    return f"operation {number} ({spec.operation.value} on face {face.index})"


def run_operations(specs: tuple[JobSpec, ...]) -> JobResult:
    """Several operations on one part in one program (the first spec's part, machine, dialect, setup,
    tolerance and numbering are the job's; the others must share them), with the program's text and
    every row's machine-frame pose, IK and limits (:func:`check_operations` keeps only what writing
    the program needs).

    Raises
    ------
    InputError, FeatureError
    PlacementLimitError, PlacementReachError
        An operation's path breaks a limit or cannot be reached (the step label names the operation).
    LimitError, ReachError
        A transition between operations breaks a limit.
    """
    job, kept = _check(specs, keep=True)
    assert kept is not None                             # keep=True: everything is kept
    post, done, row_length = kept
    return JobResult(text="".join(job.chunks()), face=done[0].face, face_note=done[0].face_note,
                     path_part=done[0].path_part, post=post, setup=job.setup, triangles=job.triangles,
                     operations=tuple(done), tool_length=row_length, placement=job.placement, dynamics=job.dynamics)


def check_job(spec: JobSpec, *, margins: bool = False) -> JobProgram:
    """:func:`check_operations` of a job of one operation (what the main job's command line writes)."""
    return check_operations((spec,), margins=margins)


def check_operations(specs: tuple[JobSpec, ...], *, margins: bool = False) -> JobProgram:
    """The job of :func:`run_operations`, checked (limits, reach, dynamics, collision: every row) and
    ready to be written a chunk at a time (:meth:`JobProgram.chunks`), holding only the joint
    program: the operations' toolpaths are post-processed POST_ROWS rows at a time and dropped once
    posted, so that memory stays a few ten bytes per line of the program. With ``margins``, the closest
    approach to each limit over every row is kept too (:attr:`JobProgram.limits`).

    Raises
    ------
    As :func:`run_operations`.
    """
    return _check(specs, keep=False, margins=margins)[0]


#: Rows of the program that :meth:`JobProgram.chunks` formats together.
EMIT_ROWS = 65536
#: Rows of an operation's toolpath post-processed together by :func:`check_operations` (the scratch
#: memory of the IK, limits and dynamics is about 1 KB a row).
POST_ROWS = 32768


@dataclass(frozen=True, slots=True)
class JobProgram:
    """A checked job, ready to be written (:meth:`chunks`).

    Attributes
    ----------
    program : JointProgram — every row of the program, checked
    header : tuple of (str, str) — the header entries
    dialect : Dialect
    stage : bool — the machine has a stage
    line_numbers, line_start, line_step : the block numbering overrides (as :class:`JobSpec`)
    face : Face — the (first) operation's face
    face_note : str — how that face was chosen
    setup : Setup — the setup used
    triangles : (F, 3, 3) float — mm, the part's triangles in part coordinates (for pictures)
    tool_lengths : tuple of float — mm, each operation's tool length "TL"
    placement : PlacementResult | None — how the setup was chosen (None: as given)
    dynamics : str — the header's ``dynamics`` entry (cycle time, feeds slowed), for the summary
    faces : tuple of Face — each operation's face, in order
    cycle_minutes : float | None — the cycle time of the machine's [dynamics] (None: it has none)
    slowed_moves : int — moves whose feed was lowered to the axis speed limits
    limits : LimitTally | None — the closest approach to each limit over every row (None: not asked for)
    """

    program: JointProgram
    header: tuple[tuple[str, str], ...]
    dialect: Dialect
    stage: bool
    line_numbers: bool | None
    line_start: int | None
    line_step: int | None
    face: Face
    face_note: str
    setup: Setup
    triangles: FloatArray
    tool_lengths: tuple[float, ...]
    placement: PlacementResult | None = None
    dynamics: str = ""
    closest: Approach | None = None
    kinematics: Kinematics | None = None                  # whose joints the program's are (None: 3-PRS)
    faces: tuple[Face, ...] = ()
    cycle_minutes: float | None = None
    slowed_moves: int = 0
    limits: LimitTally | None = None

    def chunks(self, rows: int | None = None) -> Iterator[str]:
        """The program's text, ``rows`` (None: EMIT_ROWS) rows at a time (the header first, the end blocks last): the
        same text whatever ``rows`` is, as :func:`~prs3_post.emit.gcode.emit_program` writes it.

        Raises
        ------
        LimitError
            As :func:`~prs3_post.emit.gcode.emit_program` (a line too long, a feed that prints as 0),
            when the chunk concerned is asked for.
        """
        emitter = ProgramEmitter(self.dialect, stage=self.stage, line_numbers=self.line_numbers,
                                 line_start=self.line_start, line_step=self.line_step, kinematics=self.kinematics)
        yield emitter.begin(self.header)
        for piece in program_chunks(self.program, EMIT_ROWS if rows is None else rows):
            yield from emitter.row_pieces(piece)
        yield emitter.end()


@dataclass(frozen=True, slots=True)
class _Posted:
    """One operation (or transition) post-processed: its program, the machine-frame poses of its first
    and last rows (``ends``, for the transitions), its dynamics tally and, when kept, everything."""

    program: JointProgram
    ends: Toolpath
    dynamics: DynamicsTally | None
    full: PostResult | None
    limits: LimitTally | None = None                    # a streamed operation's, when tallied

    def tally(self) -> LimitTally | None:
        """The closest approach to each limit over the rows (None: neither tallied nor kept)."""
        return self.limits if self.limits is not None or self.full is None else LimitTally.of(self.full.limits)

    @staticmethod
    def of(post: PostResult) -> _Posted:
        return _Posted(post.program, _ends(post.path, post.path), post.dynamics, post)


def _ends(first: Toolpath, last: Toolpath) -> Toolpath:
    """The first row of ``first`` and the last of ``last`` (no rows when they have none)."""
    if not len(first):
        return first
    return Toolpath(kind=np.array([first.kind[0], last.kind[-1]]), tip=np.array([first.tip[0], last.tip[-1]]),
                    axis=np.array([first.axis[0], last.axis[-1]]), feed=np.array([first.feed[0], last.feed[-1]]),
                    source=np.array([first.source[0], last.source[-1]]))


def _post_operation(machine: Machine, paths: list[Toolpath], k: int, spec: JobSpec, decimals: int, *, keep: bool,
                    several: bool, replan: Callable[[], Toolpath], check: SetupCheck | None,
                    margins: bool = False) -> _Posted:
    """Operation ``k``'s toolpath ``paths[k]`` post-processed whole (``keep``), or POST_ROWS rows at a
    time into its joint program only: the toolpath is taken out of ``paths`` and cut into pieces that
    own their rows (:func:`~prs3_post.core.toolpath.toolpath_pieces`), each dropped once posted, so that
    the toolpath and its program are not held whole at once. The same program, and the same first
    error: a chunk that fails has the whole path planned again (``replan``: the toolpath ``paths[k]``
    was) and post-processed, for the error :func:`post_process` raises (its count of bad points is of
    every row). ``check``: the operation's collision check at another setup, for the part origin an error
    suggests (None: not checked).

    Raises
    ------
    PlacementLimitError, PlacementReachError, LimitError, ReachError
        As :func:`run_operations` (the setup, and a part origin that fits where there is one).
    """
    path_part = paths[k]
    whole = path_part if keep else None                # the toolpath an error is told of (None: planned again)
    try:
        if keep:
            return _Posted.of(post_process(machine, path_part, spec.setup, tolerance=spec.tolerance,
                                           length_decimals=decimals, clamp=spec.clamp,
                                           angle_tolerance=DEFAULT_ANGLE_TOLERANCE))
        paths[k] = _NO_ROWS
        labels, file, events = path_part.source_labels, path_part.source_file, path_part.events
        columns = {name: getattr(path_part, name) for name in ("kind", "tip", "axis", "feed", "source")}
        del path_part                                  # only `columns` holds the rows: each freed once cut
        pieces = toolpath_pieces(columns, POST_ROWS, events=events, source_labels=labels, source_file=file)
        pieces.reverse()                               # popped in order, each freed once posted
        stream = PostStream(machine, spec.setup, tolerance=spec.tolerance, length_decimals=decimals,
                            clamp=spec.clamp, tally_limits=margins)
        programs: list[JointProgram] = []
        first = last = None
        try:
            while pieces:
                result = stream.feed(pieces.pop())
                programs.append(result.program)
                if len(result.path):
                    first = result.path if first is None else first
                    last = result.path
        except (LimitError, ReachError):
            whole = replan()
            post_process(machine, whole, spec.setup, tolerance=spec.tolerance, length_decimals=decimals,
                         clamp=spec.clamp, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
            raise                                      # (not reached: the whole path fails too)
    except (LimitError, ReachError) as error:          # say the setup, and one that fits if there is one
        whole = replan() if whole is None else whole
        if several:                                    # a suggestion would fit this operation alone
            raise _operation_error(error, machine, whole, spec, decimals, check) from error
        raise placement_error(error, machine, whole, spec.setup, tolerance=spec.tolerance,
                              angle_tolerance=DEFAULT_ANGLE_TOLERANCE, length_decimals=decimals, check=check,
                              advise=collision_advice) from error
    ends = _ends(first, last) if first is not None and last is not None else _NO_ROWS
    del first, last, result
    return _Posted(join_programs(programs, source_labels=labels, source_file=file), ends, stream.dynamics, None,
                   stream.limits)


def _planned(spec: JobSpec, face: Face, number: int, several: bool) -> Toolpath:
    """Operation ``number``'s toolpath in part coordinates (:func:`plan`; in a job of ``several``, its
    steps' labels start with the operation's).

    Raises
    ------
    FeatureError
        As :func:`plan`, naming the operation.
    """
    try:
        path_part = plan(spec, face)
    except FeatureError as error:                     # say which operation (a job file names it)
        raise FeatureError(error.args[0], key=error.key, operation=number) from error
    if several:
        label = operation_label(number, spec, face)
        path_part = replace(path_part, source_labels=tuple(f"{label}, {t}" for t in path_part.source_labels))
    return path_part


def _check(specs: tuple[JobSpec, ...], *, keep: bool, margins: bool = False
           ) -> tuple[JobProgram, tuple[PostResult, list[OperationResult], FloatArray] | None]:
    """The checked job and, with ``keep``, the whole PostResult, the operations (with their toolpaths)
    and each row's tool length (mm); without, each operation's toolpath is dropped once posted. With
    ``margins``: each limit's closest approach (:attr:`JobProgram.limits`)."""
    if not specs:
        raise ValueError("a job has at least one operation")
    first = specs[0]
    require_tolerance(first.tolerance)
    _check_tools(specs)
    mesh = load_part(first.part, units=first.units, up=first.up)
    faces = find_faces(mesh)
    triangles = np.asarray(mesh.triangles, dtype=np.float64)
    # The mesh, with its cached edges and adjacency (hundreds of MB on a fine part), is not needed past
    # here; trimesh's helpers refer back to it, so only a collection frees it.
    del mesh
    gc.collect()
    several = len(specs) > 1
    decimals = first.dialect.decimals.length
    done: list[OperationResult] = []
    measured: list[ProgramClearance | str | None] = []     # each operation's check (None: not asked)
    for number, spec in enumerate(specs, start=1):
        try:  # automatic selection skips faces narrower than the tool; a hint names a face the machine reaches
            face, note = select_face(faces, spec.face, min_width=max(MIN_FACE_WIDTH_MM, spec.cutting.tool_diameter),
                                     reachable=partial(axes_reachable, spec.machine))
        except FeatureError as error:                     # about this file's faces: say which file
            raise InputError(error.carried(), path=spec.part, names_keys=error.names_keys) from error
        path_part = _planned(spec, face, number, several)
        label = operation_label(number, spec, face) if several else ""
        done.append(OperationResult(face=face, face_note=note, path_part=path_part, tool_length=tool_length_of(spec),
                                    label=label))
        del path_part
    planned = specs                                        # as planned (a toolpath is planned again for an error)
    specs, placement = choose_setup(specs, done, triangles)
    first = specs[0]
    posts: list[_Posted] = []
    paths = [operation.path_part for operation in done]
    if not keep:                                           # only `paths` holds them, until each is posted
        done = [replace(operation, path_part=_NO_ROWS) for operation in done]
    for k, spec in enumerate(specs):
        operation = done[k]
        machine = spec.machine.with_tool_length(operation.tool_length)
        posted = _post_operation(machine, paths, k, spec, decimals, keep=keep, several=several,
                                 replan=partial(_planned, planned[k], done[k].face, k + 1, several),
                                 check=_collision_check(spec, machine, triangles, operation.face), margins=margins)
        try:
            measured.append(measure_program(machine, posted.program, spec.setup, triangles, operation.face,
                                            spec.cutting.tool_diameter, clearance_min=spec.clearance_min)
                            if spec.collision_check else None)
        except LimitError as error:
            if placement is not None:
                raise LimitError(f"{error}; {PLACEMENT_CANNOT_FIX}") from error
            words, keys = collision_advice(error)
            raise LimitError(f"{error.carried()}; no setup changes that (the part and the tool axes move together): "
                             f"{words}", names_keys=keys) from error
        posts.append(posted)
    if several:
        height = safe_height(triangles, first.setup, _retract(specs))
        pieces, lengths, starts, transitions = _assemble(specs, done, posts, height, triangles)
        program = _join_programs([p.program for p in pieces])
        measured = [m.shifted(start) if isinstance(m, ProgramClearance) else m
                    for m, start in zip(measured, starts, strict=True)]
        for k, found in transitions:                   # each body's minimum over the operation's moves and these
            mine = measured[k]
            if isinstance(mine, ProgramClearance):
                measured[k] = mine.merged(found)
    else:
        pieces, lengths, program = posts, [done[0].tool_length], posts[0].program
    sha = file_sha256(first.part)
    header = header_of(first, sha, operations=specs if several else (), lengths=[o.tool_length for o in done])
    entries = with_placement(header_entries(header, done[0].face, description=first.machine.description,
                                            faces=tuple(o.face for o in done) if several else ()), placement)
    tallies = [p.dynamics for p in posts if p.dynamics is not None]
    minutes = None if first.machine.dynamics is None else program_time(first.machine.dynamics, program)
    dynamics = NO_DYNAMICS if minutes is None else timed_entry(minutes, tallies)
    collisions = [m.entry(spec.clearance_min) if isinstance(m, ProgramClearance) else m or ""
                  for m, spec in zip(measured, specs, strict=True)]
    entries += (("dynamics", dynamics), ("collision", _collision_entry(specs, collisions)))
    accuracy = header_accuracy(first.machine, program, resolution=DEFAULT_ACTUATOR_RESOLUTION_MM)
    entries += (("accuracy", accuracy),) if accuracy else ()     # a calibrated machine's only: others' unchanged
    job = JobProgram(program=program, header=entries, dialect=first.dialect, stage=first.machine.stage.present,
                     line_numbers=first.line_numbers, line_start=first.line_start, line_step=first.line_step,
                     face=done[0].face, face_note=done[0].face_note, setup=first.setup, triangles=triangles,
                     tool_lengths=tuple(o.tool_length for o in done), placement=placement, dynamics=dynamics,
                     closest=_closest(measured, specs), kinematics=kinematics_of(first.machine),
                     faces=tuple(o.face for o in done), cycle_minutes=minutes,
                     slowed_moves=sum(t.clamped for t in tallies),
                     limits=LimitTally.joined((p.tally(), len(p.program)) for p in pieces) if margins else None)
    if not keep:
        return job, None
    fulls = [p.full for p in pieces if p.full is not None]      # keep=True: every piece is kept whole
    post = _join_posts(fulls, program) if several else fulls[0]
    counts = [len(p.program) for p in pieces]
    return job, (post, done, np.repeat(np.array(lengths, dtype=np.float64), counts))


#: A toolpath without rows: what a streamed job keeps of an operation's toolpath once it is posted.
_NO_ROWS = Toolpath(kind=np.zeros(0, dtype=np.int64), tip=np.zeros((0, 3)), axis=np.zeros((0, 3)),
                    feed=np.zeros(0), source=np.zeros(0, dtype=np.int64))


def choose_setup(specs: tuple[JobSpec, ...], operations: list[OperationResult],
                 triangles: FloatArray) -> tuple[tuple[JobSpec, ...], PlacementResult | None]:
    """The specs with the setup :func:`~prs3_post.check.placement.place` chooses for the whole job (every
    operation and the transitions between them) where the first asks for one (``auto_origin``,
    ``auto_rotation``), and that choice; the specs and None otherwise.

    Raises
    ------
    LimitError, ReachError
        No setup puts every point inside the machine's limits (the message says which limit, by how much).
    """
    first = specs[0]
    if not (first.auto_origin or first.auto_rotation):
        return specs, None
    pieces, lengths = job_in_part_frame(specs, operations, triangles)
    chosen = place(first.machine, pieces, origin=None if first.auto_origin else first.setup.origin,
                   rotation_deg=None if first.auto_rotation else first.setup.rotation_deg, tool_lengths=lengths,
                   tolerance=first.tolerance, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    return tuple(replace(s, setup=chosen.setup, auto_origin=False, auto_rotation=False) for s in specs), chosen


def job_in_part_frame(specs: tuple[JobSpec, ...], operations: list[OperationResult],
                       triangles: FloatArray) -> tuple[list[Toolpath], list[float]]:
    """Every operation's path and the transitions between them, in part coordinates, with their tool
    lengths: the transitions made at the identity setup are the part-frame transitions of any setup
    (the safe height moves with the part; turning about z turns the great circles with it). The
    turns are FEED rows here, so that placing them subdivides them as :func:`post_transition` does."""
    pieces, lengths = [operations[0].path_part], [operations[0].tool_length]
    height = safe_height(triangles, MACHINE_FRAME, _retract(specs))
    for k in range(1, len(operations)):
        before, after = operations[k - 1], operations[k]
        pair = (before.tool_length, after.tool_length)
        ends = [machine_path(spec.machine.with_tool_length(op.tool_length), op.path_part, MACHINE_FRAME,
                             tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
                for spec, op in ((specs[k - 1], before), (specs[k], after))]
        lift, turn = transition_paths(ends[0], ends[1], pair, height, labels=(
            f"{before.label}, lift to the safe height", f"{after.label}, turn the tool axis at the safe height"))
        for piece, length in ((lift, pair[0]), (replace(turn, kind=np.full(len(turn), MoveKind.FEED)), pair[1]),
                              (after.path_part, pair[1])):
            if len(piece):
                pieces.append(piece)
                lengths.append(length)
    return pieces, lengths


def with_placement(entries: tuple[tuple[str, str], ...],
                   placement: PlacementResult | None) -> tuple[tuple[str, str], ...]:
    """The header entries with a ``placement`` entry after the ``setup`` one when the setup was chosen
    (the setup entry keeps its form: it is what `verify` reads)."""
    if placement is None:
        return entries
    at = [key for key, _ in entries].index("setup") + 1
    return (*entries[:at], ("placement", placement.describe()), *entries[at:])


def _collision_entry(specs: tuple[JobSpec, ...], found: list[str]) -> str:
    """The header's ``collision`` entry: each operation's clearances, each body's minimum over its own
    moves and the moves between operations it owns (:func:`_check_transition`: the lift after it, the
    turn and the way down to it), as ``verify --against`` groups them."""
    if not any(spec.collision_check for spec in specs):
        return "not checked (asked not to)"
    if len(found) == 1:
        return found[0]
    return "; ".join(f"operation {n}: {text or 'not checked'}" for n, text in enumerate(found, start=1))


def _closest(measured: list[ProgramClearance | str | None], specs: tuple[JobSpec, ...]) -> Approach | None:
    """The body nearest its operation's clearance min over the operations checked (None: none measured)."""
    found = [(a.distance - spec.clearance_min, a) for m, spec in zip(measured, specs, strict=True)
             if isinstance(m, ProgramClearance) and (a := m.approach()) is not None]
    return min(found, key=lambda pair: pair[0])[1] if found else None


def _operation_error(error: LimitError | ReachError, machine: Machine, path_part: Toolpath, spec: JobSpec,
                     decimals: int, check: SetupCheck | None) -> LimitError | ReachError:
    """An operation's limit or reach error in a job of several: the setup, and a part origin that
    fits this operation (only: the job's other operations may not fit there)."""
    found = suggest(machine, path_part, spec.setup, tolerance=spec.tolerance, angle_tolerance=DEFAULT_ANGLE_TOLERANCE,
                    length_decimals=decimals, check=check)
    what = "puts this operation inside the machine's limits" if found.origin is None else \
        "puts this operation (alone) inside the machine's limits"
    advice, keys = suggestion_advice(found, collision_advice, error.names_keys, what=what)
    return type(error)(f"{error.carried()}; setup: {spec.setup.describe()}; {advice}", names_keys=keys)


def _collision_check(spec: JobSpec, machine: Machine, triangles: FloatArray, face: Face) -> SetupCheck | None:
    """The operation's collision check at another setup (as :func:`_check` makes it), for a part origin
    suggested after an error; None where the operation is not checked."""
    if not spec.collision_check:
        return None

    def check(setup: Setup, posted: PostResult) -> None:
        measure_program(machine, posted.program, setup, triangles, face, spec.cutting.tool_diameter,
                        clearance_min=spec.clearance_min)

    return check


def collision_advice(error: LimitError) -> tuple[str, tuple[str, ...]]:
    """What to change for a collision no setup avoids (:data:`~prs3_post.check.placement.Advise`): the tool
    itself needs another place or a smaller tool; the holder or the nose, a longer tool (its length is
    the tool table's) or a shorter holder (the machine file's ``[holder]``), or another place."""
    if isinstance(error, CollisionError) and error.body == "tool":
        return "try another {at} (or {face}), or a smaller {tool_diameter}", ("at", "face", "tool_diameter")
    return ("try a longer tool ({tool_table}), a shorter holder (the machine file's [holder]), or another {at} "
            "(or {face})", ("tool_table", "at", "face"))


def _retract(specs: tuple[JobSpec, ...]) -> float:
    """mm, the largest retract of the operations: how far above the part the transitions go."""
    return max(spec.work.params.retract for spec in specs)


def _assemble(specs: tuple[JobSpec, ...], done: list[OperationResult], posts: list[_Posted],
              height: float, triangles: FloatArray | None = None
              ) -> tuple[list[_Posted], list[float], list[int], list[tuple[int, ProgramClearance]]]:
    """The operations and the transitions between them, in program order, each piece's tool length,
    each operation's first row in the joined program, and (with ``triangles``, the part: each
    transition is checked against it, :func:`_check_transition`) each transition's clearances in the
    joined program's rows, with the operation that owns it (the lift: the one before, the turn and the
    way down: the next one)."""
    pieces: list[_Posted] = [posts[0]]
    lengths: list[float] = [done[0].tool_length]
    starts = [0]
    transitions: list[tuple[int, ProgramClearance]] = []
    decimals = specs[0].dialect.decimals.length
    for k in range(1, len(specs)):
        spec, previous = specs[k], specs[k - 1]
        pair = (done[k - 1].tool_length, done[k].tool_length)
        lifted, turned = post_transition(
            spec.machine, posts[k - 1].ends, posts[k].ends, pair, height, tolerance=spec.tolerance,
            length_decimals=decimals, labels=(f"{done[k - 1].label}, lift to the safe height",
                                              f"{done[k].label}, turn the tool axis at the safe height"))
        if triangles is not None and (previous.collision_check or spec.collision_check):
            at = sum(len(p.program) for p in pieces)   # the lift's first row (its check's row 1)
            found = _check_transition(specs[k - 1:k + 1], done[k - 1:k + 1], posts[k - 1].program, lifted, turned,
                                      posts[k].program, triangles)
            for owner, clearance in found:           # a check's row j is the joined program's at + j - 1
                transitions.append((k - 1 + owner, clearance.shifted(at - 1)))
                at += len(lifted.program) if owner == 0 and lifted is not None else 0
        if lifted is not None:
            pieces.append(_Posted.of(lifted))
            lengths.append(pair[0])
        # the next operation's opening events (title, tool change, spindle, coolant) move before the turn
        body = posts[k].program
        opening = [e for e in body.events if e.before == 0]
        if previous.cutting.tool_number == spec.cutting.tool_number:
            opening = [e for e in opening if e.kind is not EventKind.TOOL_CHANGE]
        pieces += [_with_events(_Posted.of(turned), tuple(opening))]
        starts.append(sum(len(p.program) for p in pieces))
        pieces += [_with_events(posts[k], tuple(e for e in body.events if e.before != 0))]
        lengths += [pair[1], pair[1]]
    return pieces, lengths, starts, transitions


#: Said after a collision in a setup chosen automatically: an operation's moves all keep the face's
#: normal as the tool axis (each one translates the head), and the part moves with the setup, so the
#: tool, holder and nose meet the part the same way in every setup (the tests check it on the corpus
#: slope: the same depth at several origins and rotations).
PLACEMENT_CANNOT_FIX = ("the setup was chosen automatically, but no placement changes this: the tool axis is the "
                        "face's normal and the part moves with the setup, so the tool and holder meet the part the "
                        "same way in every setup (change the tool or the holder, or the feature or its face)")


def _check_transition(specs: tuple[JobSpec, ...], operations: list[OperationResult], before: JointProgram,
                      lifted: PostResult | None, turned: PostResult, after: JointProgram,
                      triangles: FloatArray) -> list[tuple[int, ProgramClearance]]:
    """The moves between two operations against the part (:func:`~prs3_post.check.collision.check_program`,
    the smaller ``clearance_min`` of the two that ask for the check): the lift with the first tool,
    from the first operation's last row; the turn with the next tool, from the lift's end, and the
    next operation's first row (its way down, from the turn's end: the operation's own check starts
    at that row's end). Returns each check's clearances (rows of its program: row 0 the row before)
    with the operation (0 or 1) whose tool it was made with.

    Raises
    ------
    LimitError
        ``operation 2 (hole on face 5), lift to the safe height: the holder hits the part, ...``.
    """
    clearance_min = min(s.clearance_min for s in specs if s.collision_check)
    checks = [] if lifted is None else [(0, [_rows(before, -1), lifted.program])]
    checks.append((1, [_rows(before if lifted is None else lifted.program, -1), turned.program, _rows(after, 0)]))
    out = []
    for k, parts in checks:
        spec, operation = specs[k], operations[k]
        machine = spec.machine.with_tool_length(operation.tool_length)
        # the tool spared where the operation whose tool it is cuts (its swept region), as verify groups them
        found = measure_program(machine, _join_programs(parts), specs[1].setup, triangles, operation.face,
                                spec.cutting.tool_diameter, clearance_min=clearance_min,
                                feed_tips=feed_tips_of(machine, before if k == 0 else after))
        if isinstance(found, ProgramClearance):
            out.append((k, found))
    return out


def _rows(program: JointProgram, row: int) -> JointProgram:
    """Row ``row`` of ``program`` alone (its step label kept, no events)."""
    at = slice(row, row + 1 if row != -1 else None)
    return JointProgram(kind=program.kind[at], stage=program.stage[at], strokes=program.strokes[at],
                        inverse_time=program.inverse_time[at], source=np.zeros(1, dtype=np.int64),
                        source_labels=(program.describe(row % len(program)),))


def _with_events(posted: _Posted, events: tuple[Event, ...]) -> _Posted:
    full = posted.full
    if full is not None:
        full = replace(full, program=replace(full.program, events=events), path=replace(full.path, events=events))
    return _Posted(program=full.program if full is not None else replace(posted.program, events=events),
                   ends=posted.ends, dynamics=posted.dynamics, full=full, limits=posted.limits)


def _join_programs(programs: list[JointProgram]) -> JointProgram:
    """The programs one after another; step numbers and labels renumbered."""
    offset = 0
    labels: list[str] = []
    pieces: list[JointProgram] = []
    for piece in programs:
        pieces.append(replace(piece, source=piece.source + offset))
        labels += piece.source_labels
        offset += len(piece.source_labels)
    return join_programs(pieces, source_labels=tuple(labels))


def _join_posts(pieces: list[PostResult], program: JointProgram) -> PostResult:
    """The pieces one after another (``program``: their programs joined by :func:`_join_programs`):
    rows, IK, limits."""
    paths = [p.path for p in pieces]
    path = Toolpath(kind=np.concatenate([p.kind for p in paths]), tip=np.vstack([p.tip for p in paths]),
                    axis=np.vstack([p.axis for p in paths]), feed=np.concatenate([p.feed for p in paths]),
                    source=program.source, events=program.events, source_labels=program.source_labels)
    iks = [p.ik for p in pieces]
    ik = IKResult(**{name: np.concatenate([getattr(r, name) for r in iks])
                     for name in ("stage", "strokes", "link_angle", "condition", "reachable")})
    reports = [p.limits for p in pieces]
    limits = replace(reports[0], value=np.concatenate([r.value for r in reports]),
                     margin=np.concatenate([r.margin for r in reports]), ok=np.concatenate([r.ok for r in reports]))
    return PostResult(program=program, path=path, ik=ik, limits=limits)


def header_of(spec: JobSpec, part_sha256: str, *, operations: tuple[JobSpec, ...] = (),
              lengths: list[float] | tuple[float, ...] = ()) -> ProgramHeader:
    """What the program header records of ``spec`` (the part by its file name and SHA-256) or, with
    ``operations`` (two or more), of the job of those operations; ``lengths`` (mm) are the tool
    lengths "TL" each operation's IK used (the tools are stated with a tool table or several operations)."""
    records = tuple(_record(op) for op in operations)
    tools: dict[int, ToolRecord] = {}
    if spec.tool_table is not None or operations:
        for op, length in zip(operations or (spec,), lengths, strict=True):
            table = op.tool_table.find(op.cutting.tool_number) if op.tool_table is not None else None
            tools.setdefault(op.cutting.tool_number, ToolRecord(
                number=op.cutting.tool_number, diameter=op.cutting.tool_diameter,
                length=None if table is None else table.length, ik_length=length))
    return ProgramHeader(
        version=f"prs3-post {__version__}", machine=spec.machine.name,
        machine_file=file_given(spec.machine.source, "machines", spec.machine.name),
        dialect=spec.dialect.name, dialect_file=file_given(spec.dialect.source, "dialects", spec.dialect.name),
        part_name=Path(spec.part).name, part_sha256=part_sha256, units=spec.units, up=spec.up, face=spec.face,
        face_index=-1 if spec.face is None else spec.face, setup=spec.setup, work=spec.work,
        at_uv=np.asarray(spec.at_uv, dtype=np.float64).reshape(-1, 2),
        at_xyz=np.asarray(spec.at_xyz, dtype=np.float64).reshape(-1, 3), cutting=spec.cutting,
        tolerance=spec.tolerance, line_numbers=spec.line_numbers, line_start=spec.line_start,
        line_step=spec.line_step, operations=records, tools=tuple(tools.values()),
    )


def _record(spec: JobSpec) -> OperationRecord:
    return OperationRecord(face=spec.face, face_index=-1 if spec.face is None else spec.face, work=spec.work,
                           at_uv=np.asarray(spec.at_uv, dtype=np.float64).reshape(-1, 2),
                           at_xyz=np.asarray(spec.at_xyz, dtype=np.float64).reshape(-1, 3), cutting=spec.cutting)


def spec_from_header(header: ProgramHeader, part: str, machine: Machine, dialect: Dialect) -> JobSpec:
    """The JobSpec a program header records, on the part file ``part`` (the caller checks that it is
    the recorded part) with the machine and dialect the header names (loaded by the caller): the
    first operation of a job of several (:func:`specs_from_header` gives them all)."""
    return specs_from_header(header, part, machine, dialect)[0]


def specs_from_header(header: ProgramHeader, part: str, machine: Machine, dialect: Dialect) -> tuple[JobSpec, ...]:
    """Every operation a program header records, as the JobSpecs :func:`run_operations` takes; the
    tool lengths are the header's (a tool table rebuilt from it)."""
    table = None
    if header.tools and all(t.length is not None for t in header.tools):
        line = header.line("tools") or 0
        for t in header.tools:                         # the lengths must give the IK lengths it states
            rebuilt = machine.geometry.with_tool(float(t.length or 0.0)).tool_length
            if abs(rebuilt - t.ik_length) > 5e-4:      # the header's 3 decimals
                raise InputError(f"header: tools: T{t.number}'s IK length {exact_text(t.ik_length, 3)} mm is not "
                                 f"machine {machine.name}'s gauge offset {exact_text(machine.geometry.gauge_offset, 3)}"
                                 f" mm + its length {exact_text(float(t.length or 0.0), 3)} mm: the machine file has "
                                 "changed since the program was made", path=header.path, line=line or None)
        table = ToolTable(path=header.path, tools=tuple(
            Tool(number=t.number, pocket=None, diameter=t.diameter, length=float(t.length or 0.0), line=line)
            for t in header.tools))
    records = header.operations or (OperationRecord(face=header.face, face_index=header.face_index,
                                                    work=header.work, at_uv=header.at_uv, at_xyz=header.at_xyz,
                                                    cutting=header.cutting, collision_check=header.collision_check,
                                                    clearance_min=header.clearance_min),)
    return tuple(JobSpec(
        part=part, units=header.units, face=r.face, work=r.work, at_uv=r.at_uv, at_xyz=r.at_xyz, cutting=r.cutting,
        machine=machine, dialect=dialect, setup=header.setup, tolerance=header.tolerance,
        line_numbers=header.line_numbers, line_start=header.line_start, line_step=header.line_step, up=header.up,
        tool_table=table, collision_check=r.collision_check, clearance_min=r.clearance_min) for r in records)
