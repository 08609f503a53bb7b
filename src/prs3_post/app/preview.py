"""The `preview` job: a program replayed through forward kinematics and drawn as one picture.

    ProgramFile + machine, setup (app.verify.open_program) ──► verify_loaded ──► check.preview ──► PNG / SVG bytes
                                     └── the job it was made by (app.verify.rebuild_job) ──► closest approach

Which part a preview draws and what its closest approach is measured against (a main job's program:
the job made again from its checked part; a converted one: its part, as ``verify --part`` measures it)
is :func:`preview_part_of`, for the picture and the HTML view alike.

matplotlib is optional: :func:`require_plotting` refuses a picture before any work is done for it.
No I/O beyond the readers; messages do not name command-line flags (the CLI adds them).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from prs3_post.app.verify import CamPart, PartClearance, ProgramContext, RebuiltJob, verify_loaded, with_clearance
from prs3_post.check.timeline import Mark, MarkKind
from prs3_post.core.defaults import DEFAULT_TOLERANCE
from prs3_post.core.errors import InputError, Prs3Error
from prs3_post.core.input_files import file_sha256
from prs3_post.core.toolpath import EventKind
from prs3_post.core.types import FloatArray, Progress
from prs3_post.emit.header import ProgramHeader, SourceHeader
from prs3_post.machine.loading import Dialect, Machine, postproc_dir
from prs3_post.part.face import Face
from prs3_post.part.setup_transform import Setup
from prs3_post.readers.program import ProgramFile

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from prs3_post.check.collision import Approach

__all__ = ["HeaderContradiction", "PreviewPart", "closest_mark", "header_part", "preview_bytes", "preview_figure",
           "preview_part", "preview_part_of", "program_marks", "program_part", "require_plotting", "tool_diameters_of"]


def require_plotting() -> None:
    """Refuse a picture (``preview``, ``--preview``) before any work is done for it, when matplotlib cannot
    be imported.

    Raises
    ------
    MissingDependency
        Giving the command that installs it.
    """
    from prs3_post.check.preview import require_matplotlib

    require_matplotlib()


def preview_bytes(program: ProgramFile, machine: Machine, setup: Setup, fmt: str, *,
                  dialect: Dialect, tolerance: float = DEFAULT_TOLERANCE, mesh: FloatArray | None = None,
                  faces: Sequence[Face] = (), title: str = "", rapid_rate: float,
                  tool_lengths: dict[int, float] | None = None, rebuilt: RebuiltJob | CamPart | None = None,
                  closest: Approach | None = None, header: ProgramHeader | SourceHeader | None = None,
                  progress: Progress | None = None) -> bytes:
    """Replay a read program and draw it as ``png`` or ``svg`` bytes (:func:`preview_figure`; ``progress``:
    told the rows replayed, before the drawing)."""
    from prs3_post.check.preview import figure_bytes

    return figure_bytes(preview_figure(program, machine, setup, dialect=dialect, tolerance=tolerance, mesh=mesh,
                                       faces=faces, title=title, rapid_rate=rapid_rate, tool_lengths=tool_lengths,
                                       rebuilt=rebuilt, closest=closest, header=header, progress=progress), fmt)


def preview_figure(program: ProgramFile, machine: Machine, setup: Setup, *, dialect: Dialect,
                   tolerance: float = DEFAULT_TOLERANCE, mesh: FloatArray | None = None, faces: Sequence[Face] = (),
                   title: str = "", rapid_rate: float, tool_lengths: dict[int, float] | None = None,
                   rebuilt: RebuiltJob | CamPart | None = None, closest: Approach | None = None,
                   header: ProgramHeader | SourceHeader | None = None, progress: Progress | None = None) -> Figure:
    """Replay a read program and draw it (matplotlib is imported here); ``tool_lengths`` as
    :func:`~prs3_post.check.verify.verify_program`. ``faces``: each operation's face, in program order
    (one face: every operation's); ``header``: the program's, for its operations, tool changes
    (:func:`program_marks`) and tool diameters. With the job it was made by (``rebuilt``) and a machine
    with ``[holder]``, the body that comes closest to the part (:func:`part_clearance`, relative to
    its clearance min) is marked where it does, with its clearance and line; or, from the check that
    made the program (the main job's, :attr:`~prs3_post.app.job.JobProgram.closest`), where ``closest``
    says (its row is the program's move: the mark names that move's line). ``rebuilt`` may be a converted
    program's part (:class:`~prs3_post.app.verify.CamPart`): its closest approach is marked as ``verify
    --part`` measures it, the program is not compared with a path."""
    from prs3_post.check.preview import FaceMark, render_preview
    from prs3_post.check.timeline import timeline_of

    # against the job's path, as `verify --against` replays it: the same samples, the same closest approach
    report = verify_loaded(program, machine, setup, dialect, tolerance=tolerance, tool_lengths=tool_lengths,
                           intended=rebuilt.intended if isinstance(rebuilt, RebuiltJob) else None, progress=progress)
    mark = None
    if rebuilt is not None:
        report, found = with_clearance(report, machine, rebuilt)
        mark = None if isinstance(found, str) else closest_mark(found)
    elif closest is not None:                          # the check made it already: its minimum, not measured again
        mark = (closest.point, closest.label(int(program.moves.source[closest.row])), False)
    timeline = timeline_of(report, rapid_rate=rapid_rate, marks=program_marks(program, header, dialect))
    users: dict[int, list[int]] = {}                 # a face several operations work on: drawn once
    for k, face in enumerate(faces):
        users.setdefault(face.index, []).append(k)
    marks = [FaceMark(triangles=face.triangles, operation=k,
                      label=f"face {face.index} ({math.degrees(face.inclination):.2f}°)"
                            + (f", op {', '.join(str(j + 1) for j in users[face.index])}" if len(faces) > 1 else ""))
             for k, face in enumerate(faces) if users[face.index][0] == k]
    heading = f"{title}: " if title else ""
    moves = f"{len(program.moves)} move" + "s" * (len(program.moves) != 1)
    return render_preview(
        report, machine, mesh=mesh, faces=marks, timeline=timeline, tool_lengths=tool_lengths,
        tool_diameters=tool_diameters_of(header),
        title=f"{heading}{Path(program.path).name}, machine {machine.name}, {moves} "
              f"({'ok' if report.ok else f'{len(report.problems)} problem' + 's' * (len(report.problems) > 1)})",
        rapid_rate=rapid_rate, closest=mark,
    )


def tool_diameters_of(header: ProgramHeader | SourceHeader | None) -> dict[int, float]:
    """mm, the diameter of each tool a program's header states (empty: none stated)."""
    if isinstance(header, ProgramHeader):
        found = {tool.number: tool.diameter for tool in header.tools}
        for cutting in [header.cutting, *(record.cutting for record in header.operations)]:
            found.setdefault(cutting.tool_number, cutting.tool_diameter)
        return found
    return {}


def header_part(program_path: str, header: ProgramHeader | SourceHeader | None) -> tuple[str | None, str]:
    """The part a main job's program was made from, found by the name and SHA-256 its header records:
    beside the program, in the current folder, or among the shipped parts (``postproc/parts``).

    Returns
    -------
    path : str | None — the part's file (None: no header part, or no file there has its bytes)
    name : str — the part's name in the header ("" when it names none)
    """
    if not isinstance(header, ProgramHeader):
        return None, ""
    name = Path(header.part_name).name
    for folder in (Path(program_path).parent, Path.cwd(), postproc_dir() / "parts"):
        candidate = folder / name
        try:
            if candidate.is_file() and file_sha256(str(candidate)) == header.part_sha256:
                return str(candidate), name
        except (OSError, Prs3Error):
            continue
    return None, name


def program_part(program_path: str, part: str | None,
                 header: ProgramHeader | SourceHeader | None) -> tuple[str | None, str]:
    """The part a preview (picture or HTML view) draws a program on: ``part`` when one is given, else the
    part the program's header names when :func:`header_part` finds it.

    Returns
    -------
    path : str | None — the part's file (None: none given, and the header's not found or none named)
    named : str — the part's name in the header when it was looked for ("" otherwise)
    """
    if part is not None:
        return part, ""
    return header_part(program_path, header)


def preview_part(part: str, header: ProgramHeader | SourceHeader | None, face: int | None, *, units: str,
                 up: str) -> tuple[FloatArray, tuple[Face, ...]]:
    """A part's triangles (part frame, mm) and the faces to highlight: each operation's face a main job's
    or job file's header records, else ``face`` (None: none: a converted program, or one without a
    header, names no face; the part need not have one the main job would choose)."""
    from prs3_post.part.faces import find_faces, select_face
    from prs3_post.part.stl import load_part

    loaded = load_part(part, units=units, up=up)
    if not isinstance(header, ProgramHeader) and face is None:
        return loaded.triangles, ()
    table = find_faces(loaded)
    if isinstance(header, ProgramHeader):
        indices = [record.face_index for record in header.operations] or [header.face_index]
        return loaded.triangles, tuple(select_face(table, index)[0] for index in indices)
    return loaded.triangles, (select_face(table, face)[0],)


class HeaderContradiction(InputError):
    """Options given (for the part's face, units, up axis) that say otherwise than a main job's header.

    Attributes
    ----------
    wrong : list of (key, the header's value shown) — each option that contradicts it
    """

    def __init__(self, wrong: list[tuple[str, Any]], *, path: str):
        super().__init__(f"contradicts the program's header: {', '.join(key for key, _ in wrong)}", path=path)
        self.wrong = wrong


@dataclass(frozen=True, slots=True)
class PreviewPart:
    """The part a preview draws a program on, and what its closest approach is measured against.

    Attributes
    ----------
    path : str | None — the part's file (None: no part drawn)
    named : str — the part's name in the header, when it was looked for and not found ("" otherwise)
    from_header : bool — the part is the one the header names, found (not given)
    mesh : (T, 3, 3) float | None — its triangles (part frame, mm)
    faces : tuple of Face — the faces to highlight, in operation order (a converted program, or one
        without a header: none unless a face is asked for)
    against : RebuiltJob | CamPart | None — the job a main job's program was made by, or a converted
        program's part, to measure the closest approach with (None: not measured)
    """

    path: str | None
    named: str
    from_header: bool
    mesh: FloatArray | None
    faces: tuple[Face, ...]
    against: RebuiltJob | CamPart | None


def preview_part_of(context: ProgramContext, part: str | None, *, face: int | None, units: str, up: str,
                    given: Mapping[str, Any], html: bool) -> PreviewPart:
    """The part ``preview`` draws a program on (:func:`program_part`: ``part``, else its header's), loaded.

    A main job's program (:class:`ProgramHeader`): the part must be the one it was made from (by
    SHA-256), its face, units and up axis are the header's (``given``: the ones asked for explicitly,
    by key ``face``/``units``/``up``, must agree), and the job is made again for the closest
    approach of the tool, holder and nose (when the machine has ``[holder]``, or for the HTML view's
    faces). A converted program (:class:`SourceHeader`) or one without a header: the part at the
    program's setup, in ``units`` and ``up``, ``face`` highlighted when given (else none); a converted program's
    closest approach is measured as ``verify --part`` does (the machine has ``[holder]``).

    Raises
    ------
    HeaderConflict
        Not the part a main job's program was made from.
    HeaderContradiction
        An option given says otherwise than a main job's header.
    """
    from prs3_post.app.verify import check_part, header_job, rebuild_job
    from prs3_post.app.verify_inputs import cam_part, header_contradictions, recorded_part

    header = context.header
    path, named = program_part(context.program.path, part, header)
    if path is None:
        return PreviewPart(path=None, named=named, from_header=False, mesh=None, faces=(), against=None)
    from_header = part is None
    against: RebuiltJob | CamPart | None = None
    if isinstance(header, ProgramHeader):             # the part as the program was made from it
        check_part(header, path)
        recorded = recorded_part(header)
        wrong = header_contradictions(recorded, given)
        if wrong:
            raise HeaderContradiction(wrong, path=header.path)
        face, units, up = recorded["face"], recorded["units"], recorded["up"]
        # the job it was made by: where its tool, holder and nose come closest to the part
        # (and, for the HTML view, every operation's face)
        if context.machine.holder is not None or html:
            against = rebuild_job(header_job(context, path))
    elif isinstance(header, SourceHeader) and context.machine.holder is not None:
        against = cam_part(context, path, units=units, up=up)
        if face is None:                               # loaded once: no face to find
            return PreviewPart(path=path, named=named, from_header=from_header, mesh=against.triangles, faces=(),
                               against=against)
    mesh, faces = preview_part(path, header, face, units=units, up=up)
    return PreviewPart(path=path, named=named, from_header=from_header, mesh=mesh, faces=faces, against=against)


def closest_mark(found: PartClearance) -> tuple[FloatArray, str, bool] | None:
    """Where the preview marks the closest approach (part frame, mm), its label, and whether it is a
    collision (closer than the clearance min); None: no body near the part at any pose."""
    from prs3_post.check.collision import approach_label

    b = found.worst()
    if not found.line[b]:
        return None
    d, asked = float(found.distance[b]), float(found.clearance_min[b])
    return (found.point[b].copy(), approach_label(b, d, bool(found.exact[b]), int(found.line[b])), d < asked)


_M6 = re.compile(r"(?<![A-Z0-9.])M0*6(?![0-9.])", re.IGNORECASE)
_TITLE = re.compile(r"\bon face (\d+):", re.IGNORECASE)


def program_marks(program: ProgramFile, header: ProgramHeader | SourceHeader | None,
                  dialect: Dialect) -> tuple[Mark, ...]:
    """Where a program's tool changes and operations begin, as its text shows them (for
    :func:`~prs3_post.check.timeline.timeline_of`).

    A tool change is the M6 line of each tool change the reader found, labelled ``T2`` and the comment
    on the line before it (the emitter writes the tool there: ``T2 D8.000 mm tool``). An operation of a
    main job or job file (the header's operations, or its one) begins at its title comment, the one
    the toolpath starts with (``drill 2 holes D6.000 on face 5: ...``, labelled up to its colon),
    found among the lines before each tool change or spindle start, in order; in any other program
    (converted, or without a header) each tool change begins one. Lines between two moves only are
    read: a long program costs no scan of its text.
    """
    moves, lines = program.moves, program.lines
    n = len(moves)
    style = dialect.comments

    def gap(row: int) -> range:                        # the lines between the move before ``row`` and its own
        low = int(moves.source[row - 1]) + 1 if row > 0 else 1
        high = int(moves.source[row]) if row < n else len(lines) + 1
        return range(low, high)

    def comment(line: int) -> str | None:              # a line holding one comment only: its text
        text = lines[line - 1].strip()
        if text.startswith(style.open) and text.endswith(style.close) and len(text) >= 2:
            return text[len(style.open):len(text) - len(style.close)].strip()
        return None

    tools: list[Mark] = []
    for event in moves.events:
        if event.kind is not EventKind.TOOL_CHANGE:
            continue
        found = [ln for ln in gap(event.before) if _M6.search(lines[ln - 1].split(style.open)[0])]
        line = found[0] if found else int(moves.source[min(event.before, n - 1)])
        before = comment(line - 1) if line > 1 else None
        label = f"T{int(event.value)}" + (f" {before}" if before else "")
        tools.append(Mark(row=event.before, line=line, kind=MarkKind.TOOL_CHANGE, label=label))
    if not isinstance(header, ProgramHeader):
        return tuple(tools) + tuple(Mark(m.row, m.line, MarkKind.OPERATION, m.label) for m in tools)
    faces = [record.face_index for record in header.operations] or [header.face_index]
    starts = sorted({e.before for e in moves.events if e.kind in (EventKind.TOOL_CHANGE, EventKind.SPINDLE_ON,
                                                                  EventKind.SPINDLE_ON_CCW)})
    titles = [(ln, text) for row in starts for ln in gap(row) if (text := comment(ln)) is not None
              and _TITLE.search(text)]
    operations: list[Mark] = []
    for number, face in enumerate(faces, start=1):
        after = operations[-1].line if operations else 0
        title = next(((ln, text) for ln, text in titles
                      if ln > after and int(_TITLE.search(text).group(1)) == face), None)  # type: ignore[union-attr]
        if title is None:                              # not this program's text: the tool changes say it
            return tuple(tools) + tuple(Mark(m.row, m.line, MarkKind.OPERATION, m.label) for m in tools)
        line, text = title
        operations.append(Mark(row=int(np.searchsorted(moves.source, line, side="right")), line=line,
                               kind=MarkKind.OPERATION, label=text.split(":")[0] or f"operation {number}"))
    return tuple(tools) + tuple(operations)
