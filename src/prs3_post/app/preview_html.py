"""The `preview PROGRAM -o view.html` job: a program replayed and drawn as one interactive HTML page.

    ProgramFile ──► verify_loaded (FK replay) ──► stops, path, machine at each stop ──► ViewData ──► HTML text

A long program is decimated to what a browser draws at once, and the lines that matter are always kept:

- the slider's stops: every line up to :data:`MAX_STOPS`; beyond, evenly spaced lines plus the first
  and last, the lines where any joint or stage axis reaches its lowest and highest value, each
  operation's and tool change's first line, the worst-margin line and the closest approach's line;
- the 3D tool path: every replay sample up to :data:`MAX_PATH_POINTS`; beyond, each move's end point
  only, and beyond that every k-th point of each run of moves, a run's first and last points kept
  (the path between is drawn as a chord; the stops and the markers stay exact);
- the plots over time: the timeline's own decimation (each bucket's lowest and highest value kept).

The machine at each stop is :func:`prs3_post.check.machine_pose.machine_pose` (our forward kinematics)
with the length of the tool in the spindle at that line.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from prs3_post.app.preview import closest_mark, header_part, program_marks
from prs3_post.app.verify import CamPart, RebuiltJob, verify_loaded, with_clearance
from prs3_post.check.html_view import (
    MACHINE_PIECES,
    PART_COLOUR,
    Boundary,
    Limit,
    MachineFrames,
    Marker,
    PathTrace,
    Series,
    Stops,
    Surface,
    TimePanel,
    ViewData,
    machine_frames,
    render_view,
    require_plotly,
    surface_from_triangles,
)
from prs3_post.check.machine_pose import machine_pose
from prs3_post.check.timeline import MarkKind, Timeline, timeline_of
from prs3_post.check.timeline import Series as TimelineSeries
from prs3_post.core.defaults import DEFAULT_TOLERANCE
from prs3_post.core.toolpath import EventKind, JointProgram, MoveKind
from prs3_post.core.types import BoolArray, FloatArray, IntArray, Progress
from prs3_post.emit.header import ProgramHeader, SourceHeader
from prs3_post.kinematics.protocol import joint_letters
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.kinematics.replay import joints_of
from prs3_post.machine.loading import Dialect, Machine
from prs3_post.part.setup_transform import Setup
from prs3_post.readers.program import ProgramFile

if TYPE_CHECKING:
    from prs3_post.check.collision import Approach
    from prs3_post.part.face import Face

__all__ = ["MAX_PATH_POINTS", "MAX_PLOT_SAMPLES", "MAX_STOPS", "OPERATION_COLOURS", "PREVIEW_SUFFIXES",
           "SERIES_COLOURS", "ViewPart", "decimate_path", "header_part", "path_points", "require_view", "stop_rows",
           "view_html", "view_part"]

#: What ``preview -o`` writes, by suffix: a picture (PNG, SVG) or the interactive page (HTML).
PREVIEW_SUFFIXES = {".png": "png", ".svg": "svg", ".html": "html"}

#: The slider's most stops (program lines) before the lines are decimated.
MAX_STOPS = 3000
#: The 3D tool path's most points before it is decimated.
MAX_PATH_POINTS = 300_000
#: The plots' most replay samples before they are decimated (:meth:`~prs3_post.check.timeline.Timeline.decimate`).
MAX_PLOT_SAMPLES = 30_000
#: The lines of one plot, in order.
SERIES_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b")
#: Each operation's colour (path, face), in program order, round again after the last.
OPERATION_COLOURS = ("#1f5fbf", "#2ca02c", "#9467bd", "#d62728", "#17becf", "#e377c2", "#8c564b")


@dataclass(frozen=True, slots=True)
class ViewPart:
    """The part drawn in the view: (K, 3, 3) float mm triangles in part coordinates, and the faces
    to highlight, one per operation (``label``, the face)."""

    triangles: FloatArray
    faces: tuple[tuple[str, Face], ...] = ()


def require_view() -> None:
    """Refuse the HTML view before any work is done for it when plotly cannot be imported.

    Raises
    ------
    MissingDependency
        Giving the command that installs it.
    """
    require_plotly()


def view_part(triangles: FloatArray, face: Face | None, rebuilt: RebuiltJob | CamPart | None) -> ViewPart:
    """The part to draw: the job's operations' faces (``rebuilt`` a job), else ``face`` (None: none)."""
    if isinstance(rebuilt, RebuiltJob):
        faces = tuple((f"op {k + 1}: {spec.operation.value} on face {op.face.index}", op.face)
                      for k, (spec, op) in enumerate(zip(rebuilt.specs, rebuilt.result.operations, strict=True)))
        return ViewPart(triangles=rebuilt.result.triangles, faces=faces)
    return ViewPart(triangles=triangles, faces=() if face is None else ((f"face {face.index}", face),))


def stop_rows(joints: FloatArray, keep: IntArray, *, most: int = MAX_STOPS) -> IntArray:
    """The rows the slider stops at (module docstring): all of them up to ``most``; beyond, ``most``
    evenly spaced rows plus the first and last, each column's lowest and highest row of ``joints``
    (N, K) and the rows ``keep``.

    >>> stop_rows(np.array([[0.0], [5.0], [1.0], [2.0], [-3.0], [0.0]]), np.array([3]), most=2).tolist()
    [0, 1, 3, 4, 5]
    """
    n = len(joints)
    if n <= most:
        return np.arange(n)
    chosen = [np.linspace(0, n - 1, most).round().astype(np.int64), np.asarray(keep, dtype=np.int64).ravel()]
    finite = np.where(np.isfinite(joints), joints, np.nan)
    for column in finite.T:
        if np.isfinite(column).any():
            chosen.append(np.array([np.nanargmin(column), np.nanargmax(column)]))
    rows = np.unique(np.concatenate(chosen))
    return rows[(rows >= 0) & (rows < n)]


def path_points(points: FloatArray, row_of: IntArray, first: IntArray, end: IntArray, rows: BoolArray) -> FloatArray:
    """The line through the samples of the selected rows, NaN between runs of consecutive rows.

    ``points`` (S, 3) are the samples, ``row_of`` (S,) each one's row, ``first`` and ``end`` (N,) each
    row's first and last sample; each run starts at the previous row's last sample (where its move
    starts). Row 0 has no move and is never drawn.

    Returns
    -------
    (P, 3) float — mm, NaN rows between runs

    >>> p = np.arange(12.0).reshape(4, 3)
    >>> path_points(p, np.arange(4), np.arange(4), np.arange(4), np.array([False, True, True, False]))[:, 0].tolist()
    [0.0, 3.0, 6.0, nan]
    """
    rows = np.asarray(rows, dtype=bool).copy()
    if len(rows):
        rows[0] = False
    index = np.flatnonzero(rows[row_of])
    if not len(index):
        return np.zeros((0, 3))
    row = row_of[index]
    before = np.concatenate([[False], rows[:-1]])
    after = np.concatenate([rows[1:], [False]])
    opens = (index == first[row]) & ~before[row]
    closes = (index == end[row]) & ~after[row]
    # each sample as (its start point where a run opens, itself, a break where a run closes)
    triple = np.stack([np.where(opens, end[np.maximum(row - 1, 0)], -2), index, np.where(closes, -1, -2)], axis=1)
    flat = triple.ravel()
    flat = flat[flat != -2]
    out = np.full((len(flat), 3), np.nan)
    real = flat >= 0
    out[real] = points[flat[real]]
    return out


def decimate_path(points: FloatArray, most: int) -> FloatArray:
    """Every k-th point of a NaN-separated line (``points`` (P, 3)), so that at most about ``most``
    remain; each piece's first and last points and the breaks are kept.

    >>> line = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [4, 0, 0], [np.nan] * 3, [9, 0, 0], [8, 0, 0]])
    >>> decimate_path(line, 4)[:, 0].tolist()
    [0.0, 2.0, 4.0, nan, 9.0, 8.0]
    """
    if len(points) <= most:
        return points
    step = int(np.ceil(len(points) / max(most, 1)))
    gap = np.asarray(~np.isfinite(points).all(axis=1))
    edge = gap | np.concatenate([[True], gap[:-1]]) | np.concatenate([gap[1:], [True]])
    return points[edge | (np.arange(len(points)) % step == 0)]


def _row_tool_lengths(program: JointProgram, machine: Machine, lengths: dict[int, float] | None) -> FloatArray:
    """(N,) float mm: the length of the tool in the spindle at each row (an M6 before a row: from it on)."""
    tl = np.full(len(program), machine.geometry.tool_length)
    if not lengths:
        return tl
    for event in sorted((e for e in program.events if e.kind is EventKind.TOOL_CHANGE), key=lambda e: e.before):
        tl[event.before:] = lengths.get(int(event.value), machine.geometry.tool_length)
    return tl


def _machine_at(machine: Machine, joints: FloatArray, tool_length: FloatArray) -> MachineFrames:
    """The machine's points at the stops (joints (R, 2 + J): X, Y, the joints), each with the length
    of its tool (one forward kinematics per tool)."""

    points = np.full((len(joints), sum(p[1] for p in MACHINE_PIECES), 3), np.nan)
    for length in np.unique(tool_length).tolist():
        rows = tool_length == length
        geometry = dataclasses.replace(machine.geometry, tool_length=length)
        tooled = dataclasses.replace(machine, geometry=geometry)
        pose = machine_pose(tooled, joints[rows, 2:], joints[rows, :2])
        points[rows] = machine_frames(pose).points
    return MachineFrames(points=points)


def view_html(program: ProgramFile, machine: Machine, setup: Setup, *, dialect: Dialect,
              header: ProgramHeader | SourceHeader | None, tolerance: float = DEFAULT_TOLERANCE,
              part: ViewPart | None = None, rapid_rate: float, tool_lengths: dict[int, float] | None = None,
              rebuilt: RebuiltJob | CamPart | None = None, closest: Approach | None = None, title: str = "",
              notes: tuple[str, ...] = (), progress: Progress | None = None) -> str:
    """Replay a read program and draw it as the HTML page (module docstring,
    :mod:`prs3_post.check.html_view`); the arguments as :func:`prs3_post.app.preview.preview_figure`'s,
    ``header``: the program's (its operations and tool changes mark the time axis), ``part``: the
    part and the faces its operations cut (None: no part drawn).

    Raises
    ------
    MissingDependency
        plotly is not installed (checked before the replay).
    """

    require_plotly()
    # a program edited after it was made (other moves than its header's job): its faces are drawn, the
    # job's path and clearance do not apply
    job = rebuilt if isinstance(rebuilt, RebuiltJob) else None
    matched = job is not None and len(job.result.post.program) == len(program.moves)
    if job is not None and not matched:
        notes += (f"the program has {len(program.moves)} moves, the job its header records "
                  f"{len(job.result.post.program)}: its faces are drawn, the closest approach is not measured",)
    report = verify_loaded(program, machine, setup, dialect, tolerance=tolerance, tool_lengths=tool_lengths,
                           intended=job.intended if job is not None and matched else None, progress=progress)
    mark = None
    closest_line = 0
    if rebuilt is not None and (matched or job is None):  # a converted program's part: measured as verify does
        report, found = with_clearance(report, machine, rebuilt)
        mark = None if isinstance(found, str) else closest_mark(found)
        closest_line = 0 if isinstance(found, str) else int(found.line[found.worst()])
    elif closest is not None:
        closest_line = int(program.moves.source[closest.row])
        mark = (closest.point, closest.label(closest_line), False)
    timeline = timeline_of(report, rapid_rate=rapid_rate, marks=program_marks(program, header, dialect))
    moves = report.program
    n = len(moves)
    rep = report.samples_kept
    tip = setup.points_to_machine(report.tip_part)                        # the table's frame
    markers: list[Marker] = []
    keep = [np.array([b.row for b in timeline.boundaries if b.row < n], dtype=np.int64)]
    if mark is not None:
        point, text, hit = mark
        markers.append(Marker(name=text, point=setup.points_to_machine(np.asarray(point).reshape(1, 3))[0],
                              text=f"closest, line {text.rsplit('line ', 1)[-1]}" if "line " in text else text,
                              colour="#d62728" if hit else "#7b2cbf", symbol="x"))
        keep.append(np.flatnonzero(moves.source == closest_line)[:1])    # its line is a stop
    if timeline.worst >= 0:
        row = int(timeline.row[timeline.worst])
        line = int(moves.source[row])
        keep.append(np.array([row]))
        fraction = next((c.fraction_of_range for c in report.closest if c.name == timeline.worst_series), np.nan)
        share = f" {100 * fraction:.1f} % of its range" if np.isfinite(fraction) else ""
        markers.append(Marker(name=f"worst margin: {timeline.worst_series}{share}, line {line}",
                              point=tip[timeline.worst], text=f"worst margin, line {line}",
                              colour="#d62728" if fraction < 0 else "#ff7f0e"))
    joints = joints_of(moves)
    stops = stop_rows(joints, np.concatenate(keep), most=MAX_STOPS)
    tool_length = _row_tool_lengths(moves, machine, tool_lengths)
    kinematics = kinematics_of(machine)
    letters = joint_letters(kinematics.joint_names, kinematics.default_letters, dialect.axes)
    names = (dialect.axes.x, dialect.axes.y,
             *(f"{letter} ({name})" for letter, name in zip(letters, kinematics.joint_names, strict=True)))
    lines = moves.source[stops]
    data = ViewData(
        title=title or f"{Path(program.path).name}: machine {machine.name}, {n} move{'s' * (n != 1)}",
        machine=_machine_at(machine, joints[stops], tool_length[stops]),
        stops=Stops(line=lines, time=timeline.time[rep.end[stops]],
                    text=tuple(program.lines[int(line) - 1].strip() for line in lines.tolist()),
                    value_names=names, values=joints[stops]),
        surfaces=_surfaces(part, setup),
        paths=_paths(tip, rep.row, rep.first, rep.end, moves.kind, timeline.row_operation),
        markers=tuple(markers),
        notes=notes + _decimation_notes(n, len(stops), len(timeline)),
        **_plots(timeline),
    )
    return render_view(data)


def _decimation_notes(rows: int, stops: int, samples: int) -> tuple[str, ...]:
    """What the page says when it shows fewer lines or samples than the program has."""
    notes = []
    if stops < rows:
        notes.append(f"{rows} moves: the slider stops at {stops} of them (evenly spaced, with every axis's "
                     "extremes, each operation's and tool change's first line, the worst margin and the closest "
                     "approach)")
    if samples > MAX_PLOT_SAMPLES:
        notes.append(f"the plots show {MAX_PLOT_SAMPLES} or so of {samples} replay samples: in each stretch of "
                     "time, every quantity's lowest and highest value")
    return tuple(notes)


def _plots(timeline: Timeline) -> dict[str, Any]:
    """The time panels, one per group of the timeline's series (decimated), with the limits and boundaries."""

    shown = timeline.decimate(MAX_PLOT_SAMPLES)
    panels = []
    for group in shown.groups:
        members = shown.group(group)
        series: list[Series] = []
        limits: list[Limit] = []
        for k, member in enumerate(members):
            values, low, high = member.shown()
            series.append(Series(name=member.name, values=values, colour=SERIES_COLOURS[k % len(SERIES_COLOURS)],
                                 short=_short_name(group, member.name)))
            for bound, word in ((low, "min"), (high, "max")):
                if np.isfinite(bound) and all(abs(bound - lim.value) > 1e-9 for lim in limits):
                    own = f"{member.name} " if len(members) > 1 and not _same_bounds(members) else ""
                    limits.append(Limit(name=f"{own}{word} {bound:g}", value=float(bound)))
        unit = members[0].unit
        panels.append(TimePanel(title=group if len(members) > 1 else members[0].name, unit=unit or "-",
                                series=tuple(series),
                                limits=tuple(limits)))
    boundaries = []
    number = 0
    for b in shown.boundaries:
        operation = b.kind is MarkKind.OPERATION
        number += operation
        boundaries.append(Boundary(time=b.time, label=f"line {b.line}: {b.label}",
                                   kind="operation" if operation else "tool",
                                   short=f"op {number}" if operation else b.label.split(" ")[0]))
    label = ("cycle time (min), the machine's [dynamics]" if shown.dynamics
             else f"program time (min): G1 1/F, G0 at {shown.rapid_rate:g} mm/min (no [dynamics])")
    return {"time": shown.time, "time_label": label, "panels": tuple(panels), "boundaries": tuple(boundaries)}


def _same_bounds(members: tuple[TimelineSeries, ...]) -> bool:
    return len({(m.low, m.high) for m in members}) == 1


def _short_name(group: str, name: str) -> str:
    """A series' name without its group's words: ``T1 stroke`` in ``stroke`` → ``T1``."""
    words = group.split(" ")
    return " ".join(w for w in name.split(" ") if w not in words) or name


def _surfaces(part: ViewPart | None, setup: Setup) -> tuple[Surface, ...]:
    """The part (grey, without the faces) and each operation's face in its colour, table frame."""

    if part is None or not len(part.triangles):
        return ()
    triangles = setup.points_to_machine(np.asarray(part.triangles, dtype=np.float64).reshape(-1, 3)).reshape(-1, 3, 3)
    on_face = np.zeros(len(triangles), dtype=bool)
    faces = []
    for k, (label, face) in enumerate(part.faces):
        on_face[face.triangles] = True
        faces.append(surface_from_triangles(label, triangles[face.triangles],
                                            OPERATION_COLOURS[k % len(OPERATION_COLOURS)], opacity=0.5, focus=True))
    rest = [surface_from_triangles("part", triangles[~on_face], PART_COLOUR, opacity=0.6)] if (~on_face).any() else []
    return tuple(rest + faces)


def _paths(tip: FloatArray, row_of: IntArray, first: IntArray, end: IntArray, kind: IntArray,
           operation: IntArray) -> tuple[PathTrace, ...]:
    """Each operation's G1 and G0 moves as lines (decimated: module docstring)."""

    if len(tip) > MAX_PATH_POINTS:                   # each move's end point only
        tip, row_of, first, end = tip[end], np.arange(len(end)), np.arange(len(end)), np.arange(len(end))
    traces = []
    count = max(int(operation.max(initial=0)) + 1, 1)
    for k in range(count):
        colour = OPERATION_COLOURS[k % len(OPERATION_COLOURS)]
        label = "tool path" if count == 1 else f"op {k + 1}"
        for move, rapid, name in ((MoveKind.FEED, False, "G1"), (MoveKind.RAPID, True, "G0")):
            points = path_points(tip, row_of, first, end, (kind == move) & (operation == k))
            if len(points):
                traces.append(PathTrace(name=f"{label}: {name}", points=decimate_path(points, MAX_PATH_POINTS // 2),
                                        colour=colour, rapid=rapid))
    return tuple(traces)

