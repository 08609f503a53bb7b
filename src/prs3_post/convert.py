"""Conversion of CAM output: one APT CL or 3+2 G-code file → one checked program for this machine.

    INPUT ──► format (content) ──► reader (part frame, mm) ──► post_process (setup, exact IK,
          subdivision, limits on every emitted point) ──► emitter + dialect ──► OUTDIR/<stem><extension>

The program opens with a self-describing header (:func:`prs3_post.readers.header.source_header_entries`):
the source file's name and SHA-256, the setup, the tolerances, the tool length used by the IK and the
counts, so that ``verify --against INPUT`` can rebuild what the program should do.

A batch (:func:`convert_batch`) runs the files in worker processes; each file either completes (its
program written atomically, :func:`prs3_post.output.write_atomic`) or leaves nothing behind, and a
failing file does not stop the others unless asked. Messages name files, lines and values, never a
command-line flag.
"""

from __future__ import annotations

import dataclasses
import glob
import math
import os
import re
import stat
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from prs3_post import __version__
from prs3_post.config import Dialect, Machine
from prs3_post.emit.gcode import emit_program
from prs3_post.errors import FeatureError, InputError, LimitError, Prs3Error, ReachError
from prs3_post.geometry import find_faces, select_face
from prs3_post.job import file_given
from prs3_post.kinematics import PoseError, inverse, unit_axes
from prs3_post.kinematics.blocks import THREADS_VARIABLE
from prs3_post.limits import check_limits, raise_first_violation
from prs3_post.linearize import joint_path_deviation
from prs3_post.output import refuse_overwriting, write_atomic
from prs3_post.pipeline import PostResult, machine_path, model_for, place_toolpath, post_process
from prs3_post.placement import placement_error
from prs3_post.readers.apt import ClFile, read_cl
from prs3_post.readers.detect import DETECT_BYTES, detect_format
from prs3_post.readers.files import open_input
from prs3_post.readers.gcode import GcodeFile, read_gcode
from prs3_post.readers.header import SourceHeader, file_sha256, source_header_entries
from prs3_post.readers.stl import load_part
from prs3_post.setup import Setup
from prs3_post.toolpath import MoveKind, Toolpath
from prs3_post.workplane import WorkPlane, WorkPlaneError

#: Input formats: ``auto`` decides by content (:func:`prs3_post.readers.detect.detect_format`).
FORMATS = ("auto", "cl", "gcode")
#: File name endings taken from a directory (other files there are left alone). Files named
#: one by one are read whatever their name.
CL_SUFFIXES = (".cls", ".clsf", ".cl", ".apt", ".aptsource", ".cldata")
GCODE_SUFFIXES = (".nc", ".ngc", ".gcode", ".tap", ".cnc", ".iso", ".mpf", ".eia")


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
    tool_length : float | None — mm, platform centre to tool tip for the IK (None: the machine's)
    input_format : str — ``auto``, ``cl`` or ``gcode``
    units : str | None — a CL file's length unit when it has no UNITS/ record (None: from its feeds)
    ignore : tuple of str — CL major words skipped (and counted) instead of refused
    work_plane : WorkPlane | None — where a G-code program's X, Y, Z are in the part (None: the part frame)
    line_numbers, line_start, line_step : block numbering overrides (None: the dialect's)
    """

    machine: Machine
    dialect: Dialect
    setup: Setup
    tolerance: float = 0.002
    angle_tolerance_deg: float = 0.01
    tool_length: float | None = None
    input_format: str = "auto"
    units: str | None = None
    ignore: tuple[str, ...] = ()
    work_plane: WorkPlane | None = None
    line_numbers: bool | None = None
    line_start: int | None = None
    line_step: int | None = None

    def __post_init__(self) -> None:
        if self.input_format not in FORMATS:
            raise ValueError(f"input_format must be one of {FORMATS}, got {self.input_format!r}")
        if self.tool_length is not None and not (math.isfinite(self.tool_length) and self.tool_length > 0):
            raise InputError(f"tool length: must be a number > 0 mm, got {self.tool_length:g}",
                             path=self.machine.source)

    @property
    def ik_machine(self) -> Machine:
        """The machine with the tool length the IK uses."""
        if self.tool_length is None:
            return self.machine
        return dataclasses.replace(self.machine,
                                   geometry=dataclasses.replace(self.machine.geometry, tool_length=self.tool_length))


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
    tool_length : float — mm, used by the IK
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
    tool_length: float

    def record(self) -> dict[str, object]:
        """The report as JSON-ready data (word counts as objects)."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["by_word"] = dict(self.by_word)
        out["skipped"] = dict(self.skipped)
        return out


@dataclass(frozen=True, slots=True)
class Conversion:
    """One converted file: the program text and its report (nothing written yet)."""

    text: str
    report: ConvertReport
    post: PostResult
    source: ClFile | GcodeFile


# ----------------------------------------------------------------------------- settings


_NUMBER_LIST = re.compile(r"\s*[-+0-9.eE]+\s*(?:,\s*[-+0-9.eE]+\s*)*")


def work_plane_from_text(text: str) -> WorkPlane:
    """A work plane from ``OX,OY,OZ,NX,NY,NZ[,XX,XY,XZ]`` (mm, normal, x direction) or ``PART.stl[:FACE]``
    (the face frame of the main job on that face; without FACE its automatic choice).

    Raises
    ------
    InputError, WorkPlaneError
        An unreadable part, no such face, or numbers that do not make a plane.
    """
    if _NUMBER_LIST.fullmatch(text):
        try:
            values = [float(v) for v in text.split(",")]
        except ValueError as exc:
            raise WorkPlaneError(f"work plane: expected plain decimal numbers, got {text!r}") from exc
        if not all(math.isfinite(v) for v in values):
            raise WorkPlaneError(f"work plane: expected finite numbers, got {text!r}")
        return WorkPlane.from_values(values)
    part, _, face_text = text.rpartition(":") if re.search(r":[0-9]+\Z", text) else (text, "", "")
    mesh = load_part(part)
    faces = find_faces(mesh)
    try:
        face, _ = select_face(faces, int(face_text) if face_text else None)
    except FeatureError as error:
        raise InputError(str(error), path=part) from error
    return WorkPlane.from_face(face, name=f"face {face.index} of {Path(part).name}")


# ----------------------------------------------------------------------------- one file


def input_format(path: str, requested: str = "auto") -> str:
    """``cl`` or ``gcode``: ``requested`` unless ``auto``, else by the file's first bytes.

    Raises
    ------
    InputError
        The file cannot be opened (missing, a folder, a FIFO, unreadable).
    """
    if requested != "auto":
        return requested
    with open_input(path, "a file") as stream:
        try:
            head = stream.read(DETECT_BYTES)
        except OSError as exc:
            raise InputError(f"cannot read the file: {exc.strerror or exc}", path=path) from exc
    return detect_format(head)


def read_source(path: str, settings: ConvertSettings, fmt: str) -> ClFile | GcodeFile:
    """The input read into a part-frame toolpath by the reader of its format."""
    if fmt == "cl":
        return read_cl(path, tolerance=settings.tolerance, units=settings.units,
                       ignore=frozenset(settings.ignore))
    return read_gcode(path, tolerance=settings.tolerance, work_plane=settings.work_plane)


def _check_poses(machine: Machine, path_part: Toolpath, setup: Setup) -> None:
    """Reach and limits of the points as read, before any subdivision: a path outside the workspace
    is named at its first bad line at once (subdividing it first would only multiply the bad rows)."""
    path = place_toolpath(path_part, setup)
    try:
        axis = unit_axes(path.tip, path.axis, row_name="line", row_numbers=path.source)
    except PoseError as error:
        raise ReachError(str(error)) from error
    ik = inverse(machine.geometry, path.tip, axis, model=model_for(machine))
    if not ik.reachable.all():
        return                                          # post_process names the unreachable pose
    raise_first_violation(check_limits(machine, ik, axis), path.describe)


def _worst_turning_deviation(machine: Machine, path: Toolpath) -> float:
    """mm, the worst joint-space deviation over the feed moves of ``path`` (machine frame) whose axis changes."""
    if len(path) < 2:
        return 0.0
    turning = (path.kind[1:] == MoveKind.FEED) & (np.abs(path.axis[1:] - path.axis[:-1]).max(axis=1) > 1e-12)
    starts = np.flatnonzero(turning)
    if not len(starts):
        return 0.0
    deviation = joint_path_deviation(machine.geometry, path.tip, path.axis, starts,  # type: ignore[arg-type]  # row indices
                                     model=model_for(machine))
    return float(np.nanmax(deviation))


def convert_file(path: str, settings: ConvertSettings) -> Conversion:
    """Convert one CAM file into a program (text only: nothing is written).

    Raises
    ------
    InputError
        An unreadable input (``path:line: message``).
    LimitError, ReachError
        A point outside a limit or the workspace; the message starts with ``path:``, then the input
        line (``path: line 42: stage X ...``).
    """
    fmt = input_format(path, settings.input_format)
    source = read_source(path, settings, fmt)
    machine = settings.ik_machine
    path_part = source.toolpath
    if not len(path_part):
        raise InputError("no moves in the file: nothing to convert", path=path)
    try:
        _check_poses(machine, path_part, settings.setup)
        post = post_process(machine, path_part, settings.setup, tolerance=settings.tolerance,
                            length_decimals=settings.dialect.decimals.length)
    except (LimitError, ReachError) as error:           # say which file, the setup, and one that fits if any
        failure = placement_error(error, machine, path_part, settings.setup, tolerance=settings.tolerance,
                                  length_decimals=settings.dialect.decimals.length)
        raise type(failure)(f"{path}: {failure}", setup=failure.setup,
                            suggested_origin=failure.suggested_origin) from error
    placed = place_toolpath(path_part, settings.setup)
    placed = dataclasses.replace(placed, axis=unit_axes(placed.tip, placed.axis))
    subdivided = machine_path(machine, path_part, settings.setup, tolerance=settings.tolerance)
    counts = source.counts
    report = ConvertReport(
        input=path, format=fmt, units=source.units, sha256=file_sha256(path), records=counts.records,
        by_word=counts.by_word, input_moves=counts.moves, arcs=counts.arcs, arc_rows=counts.arc_segments,
        cycles=counts.cycles, cycle_holes=counts.cycle_holes, cycle_rows=counts.cycle_rows,
        comments=counts.comments, skipped=counts.skipped, toolpath_rows=len(path_part),
        subdivisions=len(subdivided) - len(path_part), dropped=len(subdivided) - len(post.path),
        emitted_moves=len(post.program),
        deviation_before=_worst_turning_deviation(machine, placed),
        deviation_after=_worst_turning_deviation(machine, post.path),
        tool_length=machine.geometry.tool_length,
    )
    header = SourceHeader(
        version=f"prs3-post {__version__}", machine=settings.machine.name,
        machine_file=file_given(settings.machine.source, "machines", settings.machine.name),
        dialect=settings.dialect.name,
        dialect_file=file_given(settings.dialect.source, "dialects", settings.dialect.name),
        source_name=Path(path).name, source_sha256=report.sha256, source_format=fmt, source_units=source.units,
        ignore=tuple(settings.ignore), work_plane=settings.work_plane if fmt == "gcode" else None,
        setup=settings.setup, tool_length=report.tool_length,
        tool_length_given=settings.tool_length is not None, tolerance=settings.tolerance,
        angle_tolerance_deg=settings.angle_tolerance_deg, line_numbers=settings.line_numbers,
        line_start=settings.line_start, line_step=settings.line_step,
    )
    entries = source_header_entries(header, description=settings.machine.description,
                                    counts=_counts_text(report))
    text = emit_program(post.program, settings.dialect, header=entries, stage=machine.stage.present,
                        line_numbers=settings.line_numbers, line_start=settings.line_start,
                        line_step=settings.line_step)
    return Conversion(text=text, report=report, post=post, source=source)


def _counts_text(report: ConvertReport) -> str:
    skipped = ", ".join(f"{word} {count}" for word, count in report.skipped) or "none"
    return (f"{report.records} records, {report.input_moves} moves, {report.arcs} arcs to {report.arc_rows} rows, "
            f"{report.cycle_holes} cycle holes to {report.cycle_rows} rows, {report.comments} comments, "
            f"{report.emitted_moves} program moves, {report.subdivisions} subdivisions, skipped {skipped}")


# ----------------------------------------------------------------------------- a batch


@dataclass(frozen=True, slots=True)
class FileOutcome:
    """How one file of a batch went.

    Attributes
    ----------
    input : str — as found
    output : str — the program's path (written only when ``ok``)
    ok : bool
    error : str — ``path:line: reason`` (empty when ok)
    exit_code : int — the error's (0 when ok): 2 unreadable input or output, 1 limit or reach
    report : ConvertReport | None — None when it failed
    seconds : float — wall time of this file
    """

    input: str
    output: str
    ok: bool
    error: str = ""
    exit_code: int = 0
    report: ConvertReport | None = None
    seconds: float = 0.0

    def record(self) -> dict[str, object]:
        """JSON-ready data."""
        return {"input": self.input, "output": self.output if self.ok else None, "ok": self.ok,
                "error": self.error or None, "seconds": round(self.seconds, 3),
                "report": None if self.report is None else self.report.record()}


@dataclass(frozen=True, slots=True)
class BatchResult:
    """Every file's outcome, in input order, and what was not converted because the batch stopped."""

    outcomes: tuple[FileOutcome, ...]
    not_started: tuple[str, ...] = ()
    seconds: float = 0.0

    @property
    def failures(self) -> tuple[FileOutcome, ...]:
        """The files that failed, in input order."""
        return tuple(o for o in self.outcomes if not o.ok)

    @property
    def moves(self) -> int:
        """Input moves of the converted files."""
        return sum(o.report.input_moves for o in self.outcomes if o.report is not None)

    def record(self) -> dict[str, object]:
        """JSON-ready data: the files and a summary."""
        return {"files": [o.record() for o in self.outcomes], "not_started": list(self.not_started),
                "summary": {"files": len(self.outcomes) + len(self.not_started),
                            "converted": len(self.outcomes) - len(self.failures), "failed": len(self.failures),
                            "not_started": len(self.not_started), "input_moves": self.moves,
                            "seconds": round(self.seconds, 3)}}


def collect_inputs(items: Sequence[str], *, exclude: str | None = None) -> list[str]:
    """The input files named by ``items``: files as given, directories searched recursively for
    CAM files (:data:`CL_SUFFIXES`, :data:`GCODE_SUFFIXES`; regular files only, in name order),
    glob patterns expanded. Each file once, in the order found.

    Parameters
    ----------
    exclude : str | None — a folder whose files are never taken from a directory search (the output folder)

    Raises
    ------
    InputError
        An item that names nothing (no such file, or a pattern or directory without CAM files).
    """
    found: list[str] = []
    seen: set[str] = set()
    skip = os.path.realpath(exclude) if exclude is not None else None

    def add(path: str) -> None:
        key = os.path.realpath(path)
        if key not in seen:
            seen.add(key)
            found.append(path)

    for item in items:
        if os.path.isdir(item):
            hits = list(_search(item, skip))
            if not hits:
                raise InputError("no CAM files in this directory (searched for "
                                 f"{', '.join(CL_SUFFIXES + GCODE_SUFFIXES)})", path=item)
            for hit in hits:
                add(hit)
        elif os.path.lexists(item) or not glob.has_magic(item):
            add(item)                                  # the reader says what is wrong with it
        else:
            matches = sorted(glob.glob(item, recursive=True))
            if not matches:
                raise InputError("no file matches this pattern", path=item)
            for match in matches:
                if os.path.isdir(match):
                    for hit in _search(match, skip):
                        add(hit)
                else:
                    add(match)
    return found


def _search(folder: str, skip: str | None) -> Iterator[str]:
    suffixes = CL_SUFFIXES + GCODE_SUFFIXES
    for root, dirs, files in os.walk(folder):
        dirs.sort()
        if skip is not None:
            dirs[:] = [d for d in dirs if os.path.realpath(os.path.join(root, d)) != skip]
            if os.path.realpath(root) == skip:
                continue
        for name in sorted(files):
            path = os.path.join(root, name)
            if not name.lower().endswith(suffixes):
                continue
            try:
                regular = stat.S_ISREG(os.stat(path).st_mode)
            except OSError:
                regular = True                             # unreadable: let the reader say so
            if regular:
                yield path


def output_path(input_path: str, outdir: str, dialect: Dialect) -> str:
    """``OUTDIR/<input stem><dialect extension>``."""
    return os.path.join(outdir, Path(input_path).stem + dialect.extension)


def prepare_outdir(outdir: str) -> None:
    """Create the output folder if it does not exist, and check that files can be made in it.

    Raises
    ------
    InputError
        ``cannot create the output folder: <reason>`` or ``is not a folder``.
    """
    try:
        os.makedirs(outdir, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder: {exc.strerror or exc}", path=outdir) from exc
    if not os.path.isdir(outdir):
        raise InputError("is not a folder: give the folder the programs go to", path=outdir)
    if not os.access(outdir, os.W_OK | os.X_OK):
        raise InputError("cannot write in the output folder: permission denied", path=outdir)


def convert_one(input_path: str, output: str, settings: ConvertSettings, *, force: bool = False) -> FileOutcome:
    """Convert one file and write its program atomically; every :class:`Prs3Error` becomes a failed outcome."""
    start = time.perf_counter()
    try:
        if not force and os.path.lexists(output):
            raise InputError("exists already: kept (convert with force to replace it)", path=output)
        conversion = convert_file(input_path, settings)
        refuse_overwriting({"the program": output}, {"the input": input_path})
        write_atomic(output, conversion.text)
    except Prs3Error as error:
        return FileOutcome(input=input_path, output=output, ok=False, error=str(error), exit_code=error.exit_code,
                           seconds=time.perf_counter() - start)
    return FileOutcome(input=input_path, output=output, ok=True, report=conversion.report,
                       seconds=time.perf_counter() - start)


def _worker_init(threads: int) -> None:
    os.environ[THREADS_VARIABLE] = str(threads)


def convert_batch(inputs: Sequence[str], outdir: str, settings: ConvertSettings, *, jobs: int = 1,
                  fail_fast: bool = False, force: bool = False,
                  on_done: Callable[[FileOutcome], None] | None = None) -> BatchResult:
    """Convert every input into ``outdir``, ``jobs`` files at a time in worker processes.

    Outputs are :func:`output_path`; two inputs with the same stem would write the same program, so
    both fail (neither is written: which one wins would depend on timing). An input that would be
    overwritten by its own output fails. With ``fail_fast`` the first failure stops the batch: files
    not started are listed in ``not_started``; files under way finish (each is whole or absent).

    Parameters
    ----------
    jobs : int — worker processes (1: in this process); each runs the kinematics on
        ``max(1, cores // jobs)`` threads, so that processes × threads ≤ cores
    on_done : called in this process with each outcome as it comes (progress)

    Returns
    -------
    BatchResult — outcomes in input order
    """
    started = time.perf_counter()
    prepare_outdir(outdir)
    outputs = [output_path(p, outdir, settings.dialect) for p in inputs]
    owners: dict[str, list[int]] = {}
    for index, out in enumerate(outputs):
        owners.setdefault(os.path.realpath(out), []).append(index)
    results: dict[int, FileOutcome] = {}
    todo: list[int] = []
    for index, out in enumerate(outputs):
        same = owners[os.path.realpath(out)]
        if len(same) > 1:
            others = ", ".join(inputs[i] for i in same if i != index)
            results[index] = FileOutcome(
                input=inputs[index], output=out, ok=False, exit_code=2,
                error=f"{inputs[index]}: has the same name as {others}: both would be written to {out} "
                      "(convert them into different folders)")
        else:
            todo.append(index)
    for index in sorted(results):
        if on_done is not None:
            on_done(results[index])
    stopped = fail_fast and bool(results)
    not_started: list[int] = []
    if stopped:
        not_started = todo
    elif jobs <= 1 or len(todo) <= 1:
        for position, index in enumerate(todo):
            outcome = convert_one(inputs[index], outputs[index], settings, force=force)
            results[index] = outcome
            if on_done is not None:
                on_done(outcome)
            if fail_fast and not outcome.ok:
                not_started = todo[position + 1:]
                break
    else:
        not_started = _run_parallel(inputs, outputs, todo, settings, jobs, fail_fast, force, results, on_done)
    return BatchResult(outcomes=tuple(results[i] for i in sorted(results)),
                       not_started=tuple(inputs[i] for i in not_started), seconds=time.perf_counter() - started)


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def default_jobs() -> int:
    """Worker processes by default: the cores this process may run on."""
    return _cores()


def _run_parallel(inputs: Sequence[str], outputs: list[str], todo: list[int], settings: ConvertSettings, jobs: int,
                  fail_fast: bool, force: bool, results: dict[int, FileOutcome],
                  on_done: Callable[[FileOutcome], None] | None) -> list[int]:
    """Run ``todo`` in a process pool, at most ``jobs`` files at a time; the indices not started."""
    threads = max(1, _cores() // jobs)
    pending = list(todo)
    running: dict[Future[FileOutcome], int] = {}
    import multiprocessing

    context = multiprocessing.get_context("forkserver")
    jobs = min(jobs, len(todo))
    with ProcessPoolExecutor(max_workers=jobs, mp_context=context, initializer=_worker_init,
                             initargs=(threads,)) as pool:
        try:
            stop = False
            while pending or running:
                while pending and len(running) < jobs and not stop:
                    index = pending.pop(0)
                    running[pool.submit(convert_one, inputs[index], outputs[index], settings, force=force)] = index
                if not running:
                    break
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for future in done:
                    index = running.pop(future)
                    outcome = future.result()
                    results[index] = outcome
                    if on_done is not None:
                        on_done(outcome)
                    if fail_fast and not outcome.ok:
                        stop = True
                if stop and not running:
                    break
        except BaseException:
            for future in running:
                future.cancel()
            pool.shutdown(wait=True, cancel_futures=True)
            raise
    return pending


def outcome_line(outcome: FileOutcome) -> str:
    """One tab-separated line per file: ``ok<TAB>INPUT<TAB>OUTPUT<TAB>N moves`` or
    ``failed<TAB>INPUT<TAB>-<TAB>path:line: reason``."""
    if outcome.ok and outcome.report is not None:
        r = outcome.report
        return (f"ok\t{outcome.input}\t{outcome.output}\t{r.input_moves} input moves, {r.emitted_moves} program "
                f"moves, {r.subdivisions} subdivisions, {outcome.seconds:.3f} s")
    return f"failed\t{outcome.input}\t-\t{_one_line(outcome.error)}"


def _one_line(text: str) -> str:
    return " ".join(text.split())


def batch_summary(result: BatchResult) -> str:
    """The summary for people: counts, throughput, then every failure (``path:line: reason``)."""
    converted = len(result.outcomes) - len(result.failures)
    rate = result.moves / result.seconds if result.seconds > 0 else 0.0
    lines = [f"prs3-post: converted {converted} of {len(result.outcomes) + len(result.not_started)} files, "
             f"{result.moves} input moves in {result.seconds:.2f} s ({rate:,.0f} moves/s)"]
    if result.failures:
        lines.append(f"prs3-post: {len(result.failures)} failed:")
        lines += [f"  {_one_line(o.error)}" for o in result.failures]
    if result.not_started:
        lines.append(f"prs3-post: not started (stopped at the first failure): {', '.join(result.not_started)}")
    return "\n".join(lines) + "\n"
