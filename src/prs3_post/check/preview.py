"""A program in one picture: the machine at its worst pose, the tool path on the part, every limit over
time with its bounds, the margins.

    VerifyReport (FK replay) ──► Timeline (check.timeline) ──► render_preview ──► Figure ──► figure_bytes (PNG / SVG)

Panels (left: two 3D views; right: six plots over program time and the margins)
------
(a) The machine at the worst-margin sample (the smallest margin of any limit as a fraction of its
    range, :attr:`~prs3_post.check.timeline.Timeline.worst`), machine frame, base still, the part
    and the path moved by the stage (:mod:`prs3_post.check.preview_machine`): base, rails,
    sliders, links, platform, spindle nose, holder and tool, from the project's own forward
    kinematics of that sample's joints (:func:`~prs3_post.check.machine_pose.machine_pose`).
(b) The tool path on the part, part coordinates: the part's edges (clipped to the view, which
    frames the faces and the path), each operation's face highlighted in the operation's colour,
    the FK tool-tip path (every replay sample) coloured by operation, G1 solid and G0 dashed, the
    tool axis at a few G1 end points, the worst-margin point, and (given) the closest approach of
    the tool, holder or spindle nose to the part (red when closer than allowed).
(c)-(g) Over program time (:func:`time_label` says how moves were timed; G0 shaded grey):
    the strokes T1..T3, the stage X and Y, the tilt, the link angles, the axis speeds (as a
    fraction of each axis' top speed with ``[dynamics]``, in mm/min without). Every limit is a red
    line and the y axis always includes it (so a constant is a flat line, not a zoomed step, and
    the distance to the limit is seen); series that coincide are drawn thick to thin, solid,
    dashed, dotted, and the legend says which are equal. Operation boundaries are solid and tool
    changes dashed vertical lines, with their line numbers; a strip along the top of each plot
    shows the operations' colours; the worst-margin sample is a red dotted line.
(h) The worst margin of every limit over the replay, as a fraction of the limit's range
    (:func:`prs3_post.check.verify.margin_fraction`): red below 0, orange below 10 %.

Long programs: the plots draw :meth:`~prs3_post.check.timeline.Timeline.decimate`'s samples (every
extreme kept), the 3D views at most ``max_path_points`` path points (every move's end point where
fewer), so the picture's cost grows little with the program's length.

matplotlib is optional (``pip install 'prs3-post[plot]'``): it is imported here, lazily, and the
figure is built with the object-oriented API on the Agg canvas (no pyplot, no display, no global
state). Output is deterministic: no time stamps or software versions in the file metadata, and a
fixed SVG hash salt.
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from prs3_post.check.machine_pose import machine_pose
from prs3_post.check.preview_machine import draw_machine
from prs3_post.check.timeline import MarkKind, Series, Timeline, timeline_of
from prs3_post.check.verify import VerifyReport
from prs3_post.core.errors import MissingDependency
from prs3_post.core.toolpath import EventKind, MoveKind
from prs3_post.core.types import FloatArray, IntArray
from prs3_post.machine.loading import Machine

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["FORMATS", "NO_MATPLOTLIB", "OPERATION_COLOURS", "FaceMark", "clip_segments", "feature_edges",
           "figure_bytes", "path_segments", "render_preview", "require_matplotlib", "time_label"]

#: Image formats by file suffix.
FORMATS = {".png": "png", ".svg": "svg"}
#: Each operation's colour (its face, its path, its strip on the time axis), in program order, repeating.
OPERATION_COLOURS = ("#1f5fbf", "#2ca02c", "#9467bd", "#e377c2", "#17becf", "#8c564b", "#bcbd22", "#ff7f0e")
_AXIS_COLOUR, _LIMIT_COLOUR, _WORST_COLOUR = "#2ca02c", "#d62728", "#d62728"
_SERIES_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b")
_STYLES = (("-", 2.6), ((0, (5, 3)), 1.8), ((0, (1, 1.5)), 1.4), ("-.", 1.2), ((0, (3, 1, 1, 1)), 1.0))
#: mm, the tool drawn where the program's header states no diameter.
DEFAULT_TOOL_DIAMETER = 6.0
_LABEL_BOUNDARIES = 12                                 # more boundaries than this: their lines only, no text

#: What a picture asked for without matplotlib says (exit status 2).
NO_MATPLOTLIB = "preview needs matplotlib: pip install 'prs3-post[plot]'"


@dataclass(frozen=True, slots=True)
class FaceMark:
    """A face to highlight: the mesh triangles of an operation's face.

    Attributes
    ----------
    triangles : (F,) int — indices into the mesh
    label : str — its legend text (``face 5 (20.00°): drill 2 holes ...``)
    operation : int — the operation it belongs to (its colour)
    """

    triangles: IntArray
    label: str
    operation: int


def _matplotlib() -> Any:
    """Import matplotlib's Figure and the 3D toolkit, or say how to install them.

    Raises
    ------
    MissingDependency
        :data:`NO_MATPLOTLIB`, when matplotlib (or its 3D toolkit) cannot be imported.
    """
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the 3d projection)
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection
    except ImportError as exc:
        raise MissingDependency(NO_MATPLOTLIB) from exc
    return Figure, FigureCanvasAgg, Poly3DCollection


def require_matplotlib() -> None:
    """Refuse a picture before any work is done for it when matplotlib cannot be imported (:func:`_matplotlib`)."""
    _matplotlib()


def path_segments(report: VerifyReport, kind: MoveKind, rows: IntArray | None = None) -> FloatArray:
    """The FK tip path of every move of ``kind`` (among ``rows``, when given), part coordinates, as one line.

    A run of consecutive such moves is one piece: the start point of its first move (the previous
    row's end), then every sample of each move up to its end; a NaN row ends each piece. Row 0 has
    no start point and no piece.

    Returns
    -------
    (P, 3) float — mm, part coordinates, NaN rows between pieces
    """
    rep = report.samples_kept
    select = report.program.kind == kind
    if rows is not None:
        among = np.zeros(len(select), dtype=bool)
        among[rows] = True
        select &= among
    chosen = np.flatnonzero(select[1:]) + 1
    if not len(chosen):
        return np.zeros((0, 3))
    starts = np.ones(len(chosen), dtype=bool)
    starts[1:] = chosen[1:] != chosen[:-1] + 1
    ends = np.ones(len(chosen), dtype=bool)
    ends[:-1] = starts[1:]
    counts = rep.end[chosen] - rep.first[chosen] + 1
    sizes = counts + starts + ends
    offset = np.cumsum(sizes) - sizes
    total = int(sizes.sum())
    within = np.arange(total) - np.repeat(offset, sizes)            # position inside each row's block
    lead = np.repeat(starts, sizes).astype(np.int64)
    index = np.repeat(rep.first[chosen], sizes) + within - lead      # the row's samples
    index[offset[starts]] = rep.end[chosen[starts] - 1]              # a piece's start point
    gap = within == np.repeat(sizes, sizes) - 1
    gap &= np.repeat(ends, sizes)
    tip = report.samples_kept.tip[np.where(gap, 0, index)]
    part = report.setup.points_to_part(tip)
    part[gap] = np.nan
    return part


def _thinned(points: FloatArray, limit: int) -> FloatArray:
    """At most about ``limit`` rows of a NaN-separated line: every k-th point, each piece's ends and breaks kept."""
    if len(points) <= limit:
        return points
    step = -(-len(points) // limit)
    gap = np.isnan(points[:, 0])
    keep = (np.arange(len(points)) % step == 0) | gap
    keep[1:] |= gap[:-1]                               # a piece's first point
    keep[:-1] |= gap[1:]                               # and its last
    keep[-1] = True
    return points[keep]


def _axis_marks(report: VerifyReport, count: int, length: float) -> tuple[FloatArray, IntArray]:
    """Tool-axis segments (tip → tip + length·axis) at up to ``count`` G1 end points, NaN-separated."""
    feed_rows = np.flatnonzero(report.program.kind == MoveKind.FEED)
    if not len(feed_rows):
        feed_rows = np.arange(len(report.program))
    chosen = feed_rows[np.unique(np.linspace(0, len(feed_rows) - 1, min(count, len(feed_rows))).round().astype(int))]
    ends = report.samples_kept.end[chosen]
    tip = report.setup.points_to_part(report.samples_kept.tip[ends])
    axis = report.setup.axes_to_part(report.samples_kept.axis[ends])
    segments = np.stack([tip, tip + length * axis, np.full_like(tip, np.nan)], axis=1).reshape(-1, 3)
    return segments, chosen


def _short(text: str, width: int = 60) -> str:
    """``text`` cut to ``width`` characters with an ellipsis (a legend entry stays inside the figure)."""
    return text if len(text) <= width else text[:width - 1].rstrip() + "…"


def _operation_colour(k: int) -> str:
    return OPERATION_COLOURS[k % len(OPERATION_COLOURS)]


def _tool_at(report: VerifyReport, row: int) -> int | None:
    """The tool in the spindle at ``row`` (the last tool change at or before it; None: none)."""
    tool = None
    for event in report.program.events:
        if event.kind is EventKind.TOOL_CHANGE and event.before <= row:
            tool = int(event.value)
    return tool


def render_preview(
    report: VerifyReport,
    machine: Machine,
    *,
    mesh: FloatArray | None = None,
    faces: Sequence[FaceMark] = (),
    title: str = "",
    rapid_rate: float,
    axis_marks: int = 6,
    closest: tuple[FloatArray, str, bool] | None = None,
    timeline: Timeline | None = None,
    tool_lengths: dict[int, float] | None = None,
    tool_diameters: dict[int, float] | None = None,
    max_samples: int = 20000,
    max_path_points: int = 60000,
) -> Figure:
    """Draw the preview figure (module docstring).

    Parameters
    ----------
    report : VerifyReport — the replayed program (``verify_program``, samples kept)
    machine : Machine — the machine it was replayed on (its limits, its bodies)
    mesh : (K, 3, 3) float, optional — mm, the part's triangles in part coordinates
    faces : sequence of FaceMark — the faces to highlight, each in its operation's colour
    title : str — the figure's title
    rapid_rate : float — mm/min, joint-space rate of G0 moves for the time axis (a machine without
        ``[dynamics]``; with it, the moves' cycle times)
    axis_marks : int — how many G1 end points get a tool-axis mark
    closest : (point, label, collision), optional — the closest approach of the tool, holder or nose
        to the part: (3,) mm part frame, its text (body, clearance, line), whether it is closer than
        allowed (drawn red, else purple)
    timeline : Timeline, optional — the report over time with the program's marks
        (:func:`~prs3_post.check.timeline.timeline_of`; None: made here, tool changes from the events)
    tool_lengths : dict, optional — mm, each tool's length "TL" (the machine is drawn with the tool in
        the spindle at its pose); None: the machine's
    tool_diameters : dict, optional — mm, each tool's diameter (the drawn tool's; 6 mm when not given)
    max_samples, max_path_points : int — the most samples each plot over time and the 3D paths draw

    Returns
    -------
    matplotlib.figure.Figure — on an Agg canvas, axes in the order of the panels (a)..(h); the 3D path
    lines have the ids ``feed K`` and ``rapid K`` for operation K (their data: :func:`path_segments`)

    Raises
    ------
    MissingDependency
        When matplotlib is not installed.
    """
    figure_cls, canvas_cls, poly_cls = _matplotlib()
    timeline = timeline if timeline is not None else timeline_of(report, rapid_rate=rapid_rate)
    fig = figure_cls(figsize=(17.0, 12.5), dpi=100, layout="constrained")
    canvas_cls(fig)
    left, right = fig.subfigures(1, 2, width_ratios=(1.0, 1.05))   # each side laid out on its own
    ax_machine = left.add_subplot(2, 1, 1, projection="3d", computed_zorder=False)
    ax_path = left.add_subplot(2, 1, 2, projection="3d", computed_zorder=False)
    grid = right.add_gridspec(6, 1, height_ratios=(1.0, 1.0, 1.0, 1.0, 1.0, 1.1))
    plots = [right.add_subplot(grid[0])]
    plots += [right.add_subplot(grid[i], sharex=plots[0]) for i in range(1, 5)]
    ax_bar = right.add_subplot(grid[5])
    if title:
        fig.suptitle(_wrapped(title, 160), fontsize=11)
    worst = timeline.worst if timeline.worst >= 0 else 0
    _machine_panel(ax_machine, poly_cls, report, machine, timeline, worst, mesh=mesh, tool_lengths=tool_lengths,
                   tool_diameters=tool_diameters or {}, max_points=max_path_points)
    _path_panel(ax_path, poly_cls, report, timeline, worst, mesh=mesh, faces=faces, axis_marks=axis_marks,
                closest=closest, max_points=max_path_points)
    _time_panels(plots, report, timeline, rapid_rate=rapid_rate, max_samples=max_samples)
    _margin_panel(ax_bar, report)
    return fig


def _wrapped(text: str, width: int) -> str:
    import textwrap

    return "\n".join(textwrap.wrap(text, width)) or text


def _worst_text(report: VerifyReport, timeline: Timeline, sample: int) -> str:
    """``stage X 18.5 % of its range at line 57`` (or what there is)."""
    if timeline.worst < 0:
        return f"line {int(timeline.line[sample])} (no limit measured)"
    closest = {c.name: c for c in report.closest}.get(timeline.worst_series)
    fraction = f" {100 * closest.fraction_of_range:.1f} % of its range" if closest is not None else ""
    return f"{timeline.worst_series}{fraction} at line {int(timeline.line[sample])}"


def _machine_panel(ax: Any, poly_cls: Any, report: VerifyReport, machine: Machine, timeline: Timeline, sample: int,
                   *, mesh: FloatArray | None, tool_lengths: dict[int, float] | None,
                   tool_diameters: dict[int, float], max_points: int) -> None:
    """(a): the machine at ``sample``'s joints, machine frame (:mod:`prs3_post.check.preview_machine`)."""
    rep = report.samples_kept
    joints = rep.joints[sample]
    ax.set_title(_wrapped(f"(a) the machine at the worst margin: {_worst_text(report, timeline, sample)} "
                          "(machine frame: the base still, the part moved by the stage)", 80), fontsize=10)
    if len(joints) != 5:                              # machine_pose draws a head of three legs
        ax.text2D(0.5, 0.5, "this machine's kinematics is not drawn", transform=ax.transAxes, ha="center")
        return
    tool = _tool_at(report, int(rep.row[sample]))
    drawn_machine = machine
    if tool_lengths and tool is not None and tool in tool_lengths:
        drawn_machine = machine.with_tool_length(tool_lengths[tool])
    diameter = tool_diameters.get(tool, DEFAULT_TOOL_DIAMETER) if tool is not None else DEFAULT_TOOL_DIAMETER
    pose = machine_pose(drawn_machine, joints[2:][None], joints[:2][None], tool_diameter=diameter)
    part = None
    if mesh is not None and len(mesh):
        part = report.setup.points_to_machine(np.asarray(mesh, dtype=np.float64).reshape(-1, 3)).reshape(-1, 3, 3)
    path = _thinned(rep.tip, max_points // 2)
    points = draw_machine(ax, poly_cls, pose, part=part, path=path)
    tip = pose.tip[0]
    ax.scatter([tip[0]], [tip[1]], [tip[2]], color=_WORST_COLOUR, marker="*", s=90, depthshade=False, zorder=9,
               label=f"tool tip, line {int(timeline.line[sample])}", gid="tool tip")
    _equal_box(ax, points, pad=0.05)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    ax.view_init(elev=18.0, azim=-62.0)
    ax.legend(loc="upper left", fontsize=7, ncols=2)


def _path_panel(ax: Any, poly_cls: Any, report: VerifyReport, timeline: Timeline, sample: int, *,
                mesh: FloatArray | None, faces: Sequence[FaceMark], axis_marks: int,
                closest: tuple[FloatArray, str, bool] | None, max_points: int) -> None:
    """(b): part, faces, path by operation, tool axis, worst point and closest approach, part frame."""
    operations = len(timeline.operations)
    pieces = []
    for k in range(operations):
        rows = np.flatnonzero(timeline.row_operation == k)
        feed = _thinned(path_segments(report, MoveKind.FEED, rows), max_points // (2 * operations))
        rapid = _thinned(path_segments(report, MoveKind.RAPID, rows), max_points // (2 * operations))
        pieces.append((feed, rapid))
    tip_part = report.setup.points_to_part(report.samples_kept.tip[[sample]])[0]
    frame = [p for pair in pieces for p in pair] + [tip_part[None]]
    mesh = None if mesh is None or not len(mesh) else np.asarray(mesh, dtype=np.float64).reshape(-1, 3, 3)
    highlighted = np.unique(np.concatenate([f.triangles for f in faces])) if faces else np.zeros(0, dtype=np.int64)
    if mesh is not None:
        frame.append((mesh[highlighted] if len(highlighted) else mesh).reshape(-1, 3))
    if closest is not None:
        frame.append(np.asarray(closest[0], dtype=np.float64).reshape(1, 3))
    frame_points = np.concatenate(frame)
    finite = frame_points[np.isfinite(frame_points).all(axis=1)]
    extent = float((finite.max(axis=0) - finite.min(axis=0)).max()) if len(finite) else 1.0
    marks, _ = _axis_marks(report, axis_marks, 0.2 * max(extent, 10.0))
    low, high = _equal_box(ax, np.concatenate([finite, marks]))
    if mesh is not None:
        edges = clip_segments(feature_edges(mesh), low, high)
        ax.plot(edges[:, 0], edges[:, 1], edges[:, 2], color="#7f7f7f", linewidth=0.8, label="part edges", zorder=1)
        for face in faces:
            ax.add_collection3d(poly_cls(mesh[np.asarray(face.triangles, dtype=np.int64)],
                                         facecolor=_operation_colour(face.operation), edgecolor="none", alpha=0.35,
                                         label=_short(face.label), zorder=2, gid=f"face {face.operation}"))
    for k, (feed, rapid) in enumerate(pieces):
        colour = _operation_colour(k)
        name = timeline.operations[k] or "tool path"
        label = _short(f"{k + 1}: {name}" if operations > 1 else name)
        line = ax.plot(feed[:, 0], feed[:, 1], feed[:, 2], color=colour, linewidth=1.4, label=label, zorder=4)[0]
        line.set_gid(f"feed {k}")
        line = ax.plot(rapid[:, 0], rapid[:, 1], rapid[:, 2], color=colour, linewidth=1.0, linestyle="--",
                       label="_nolegend_", zorder=5)[0]
        line.set_gid(f"rapid {k}")
    ax.plot([], [], [], color="black", linewidth=1.4, label="G1 (feed): solid")
    ax.plot([], [], [], color="black", linewidth=1.0, linestyle="--", label="G0 (rapid): dashed")
    start = report.setup.points_to_part(report.samples_kept.tip[report.samples_kept.end[:1]])
    if len(start):
        ax.scatter(start[:, 0], start[:, 1], start[:, 2], color="black", s=18, label="start", depthshade=False,
                   zorder=6)
    ax.scatter([tip_part[0]], [tip_part[1]], [tip_part[2]], color=_WORST_COLOUR, marker="*", s=90, depthshade=False,
               label=f"worst margin, line {int(timeline.line[sample])}", zorder=7)
    if closest is not None:
        point, text, hit = np.asarray(closest[0], dtype=np.float64).reshape(3), closest[1], closest[2]
        colour = _LIMIT_COLOUR if hit else "#9467bd"
        ax.scatter([point[0]], [point[1]], [point[2]], color=colour, marker="X", s=60, label=_short(text, 70),
                   depthshade=False, zorder=8)
        ax.text(point[0], point[1], point[2], "  " + text.split(" ")[1], color=colour, fontsize=8, zorder=8)
    ax.plot(marks[:, 0], marks[:, 1], marks[:, 2], color=_AXIS_COLOUR, linewidth=1.6, alpha=0.8, label="tool axis",
            zorder=3)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    ax.set_title("(b) tool path on the part by operation (FK replay, part coordinates)", fontsize=10)
    axis_part = report.setup.axes_to_part(report.samples_kept.axis[report.samples_kept.end])
    normal = np.nanmean(axis_part, axis=0) if len(axis_part) else np.array([0.0, 0.0, 1.0])
    azimuth = math.degrees(math.atan2(normal[1], normal[0])) if np.hypot(normal[0], normal[1]) > 1e-6 else -60.0
    ax.view_init(elev=28.0, azim=azimuth - 55.0)
    ax.legend(loc="upper left", fontsize=7)


def _time_panels(plots: list[Any], report: VerifyReport, timeline: Timeline, *, rapid_rate: float,
                 max_samples: int) -> None:
    """(c)..(g): strokes, stage, tilt, link angles, speeds over time, with their limits and the boundaries."""
    from prs3_post.check.verify import row_times

    shown = timeline.decimate(max_samples)
    start, end = row_times(report.program, rapid_rate=rapid_rate, dynamics=report.dynamics)
    total = float(end[-1]) if len(end) else 0.0
    ax_stroke, ax_stage, ax_tilt, ax_link, ax_speed = plots
    names = report.joint_names
    stroke = shown.group("stroke")
    _series_panel(ax_stroke, stroke, shown, "stroke (mm)",
                  f"(c) strokes {names[0]}..{names[-1]}" + _bounds_text(stroke))
    stage = shown.group("stage")
    if stage:
        _series_panel(ax_stage, stage, shown, "stage (mm)", "(d) stage X, Y" + _bounds_text(stage))
    else:
        ax_stage.set_title("(d) stage X, Y: this machine has no stage", fontsize=10)
        ax_stage.set_yticks([])
    tilt = shown.group("tilt")
    _series_panel(ax_tilt, tilt, shown, "tilt (deg)", "(e) tool axis tilt" + _bounds_text(tilt))
    link = shown.group("link angle")
    _series_panel(ax_link, link, shown, "link angle (deg)", "(f) link angles" + _bounds_text(link))
    speeds = shown.group("stage speed") + shown.group("stroke speed")
    if report.dynamics is not None:
        relative = tuple(Series(name=s.name, group="speed", unit="%", values=100.0 * s.values / s.high, low=0.0,
                                high=100.0) for s in speeds)
        _series_panel(ax_speed, relative, shown, "speed (% of top)",
                      "(g) axis speeds, % of each axis' top speed ([dynamics]: stage "
                      f"{report.dynamics.stage_speed:g}, strokes {report.dynamics.stroke_speed:g} mm/min)")
    else:
        _series_panel(ax_speed, speeds, shown, "speed (mm/min)", "(g) axis speeds (no [dynamics]: no top speed)")
    rapid = report.program.kind == MoveKind.RAPID
    spans = _runs(rapid, start, end)
    operation_spans = _operation_spans(timeline, total)
    worst_time = float(timeline.time[timeline.worst]) if timeline.worst >= 0 else None
    for ax in plots:
        if len(spans):
            ax.broken_barh(spans, (0.0, 1.0), transform=ax.get_xaxis_transform(), color="#e6e6e6", linewidth=0,
                           zorder=0)
        for k, span in operation_spans:
            ax.broken_barh([span], (0.965, 0.035), transform=ax.get_xaxis_transform(), color=_operation_colour(k),
                           linewidth=0, zorder=1)
        for boundary in timeline.boundaries:
            tool = boundary.kind is MarkKind.TOOL_CHANGE
            ax.axvline(boundary.time, color="#333333", linewidth=0.9, linestyle="--" if tool else "-", zorder=1)
        if worst_time is not None:
            ax.axvline(worst_time, color=_WORST_COLOUR, linewidth=1.2, linestyle=":", zorder=1)
        ax.grid(True, linewidth=0.3)
        ax.set_xlim(0.0, total if total > 0 else 1.0)
        if ax is not ax_speed:
            ax.tick_params(labelbottom=False)
    _boundary_labels(ax_stroke, timeline, worst_time)
    ax_speed.set_xlabel(time_label(report, rapid_rate))


def _bounds_text(series: tuple[Series, ...]) -> str:
    """`` (limits -100..400 mm)`` from the series' shared bounds (each distinct pair once)."""
    pairs = []
    for s in series:
        _, low, high = s.shown()
        unit = {"deg": "°", "": ""}.get(s.unit, f" {s.unit}")
        if math.isfinite(low) and math.isfinite(high):
            pairs.append(f"{low:g}..{high:g}{unit}")
        elif math.isfinite(high):
            pairs.append(f"max {high:g}{unit}")
        elif math.isfinite(low):
            pairs.append(f"min {low:g}{unit}")
    distinct = list(dict.fromkeys(pairs))
    return f" (limits {', '.join(distinct)})" if distinct else ""


def _series_panel(ax: Any, series: tuple[Series, ...], timeline: Timeline, ylabel: str, title: str) -> None:
    """Series over time (coinciding ones told apart), every finite bound a red line, the y range over both."""
    x = timeline.time
    seen: list[tuple[str, FloatArray]] = []
    ranges = []
    for i, s in enumerate(series):
        values, low, high = s.shown()
        name = s.name.removesuffix(" stroke").removesuffix(" link angle").removesuffix(" speed")
        same = [other_name for other_name, other in seen if np.array_equal(values, other, equal_nan=True)]
        style, width = _STYLES[i % len(_STYLES)]        # thick to thin: a line on top of another shows both
        ax.plot(x, values, color=_SERIES_COLOURS[i % len(_SERIES_COLOURS)], linestyle=style, linewidth=width,
                label=name + (f" (= {same[0]})" if same else ""), zorder=3 + i,
                marker="o" if len(x) == 1 else None, markersize=4,          # one sample: a line would not show
                drawstyle="steps-pre" if s.unit in ("%", "mm/min") else "default")   # a speed holds over its move
        seen.append((name, values))
        finite = values[np.isfinite(values)]
        if len(finite):
            ranges += [float(finite.min()), float(finite.max())]
        for bound in (low, high):
            if math.isfinite(bound):
                ranges.append(bound)
    shared = len({s.shown()[1:] for s in series}) == 1  # one limit for all (strokes), or each its own (stage X, Y)
    lines: list[tuple[float, str, str, bool]] = []    # (bound, colour, label, the upper one)
    for i, s in enumerate(series[:1] if shared else series):
        colour = _LIMIT_COLOUR if shared else _SERIES_COLOURS[i % len(_SERIES_COLOURS)]
        name = "limit" if shared else f"{s.name} limit"
        _, low_bound, high_bound = s.shown()
        bounds = [(b, upper) for b, upper in ((low_bound, False), (high_bound, True)) if math.isfinite(b)]
        lines += [(b, colour, name if j == 0 else "_nolegend_", upper) for j, (b, upper) in enumerate(bounds)]
    for bound, colour, name, _ in lines:
        ax.axhline(bound, color=colour, linewidth=1.1, linestyle="-" if shared else (0, (6, 2)), label=name,
                   zorder=2)
    if any(s.group in ("tilt", "speed", "stage speed", "stroke speed") for s in series):
        ranges.append(0.0)                             # a tilt, a speed: from 0
    if ranges:
        low, high = min(ranges), max(ranges)
        pad = 0.06 * (high - low) if high > low else max(1.0, abs(high) * 0.05)
        ax.set_ylim(low - pad, high + pad)
        for bound, colour, _, upper in lines:          # beyond a bound: shaded in its colour
            if upper:
                ax.axhspan(bound, high + pad, color=colour, alpha=0.08, linewidth=0)
            else:
                ax.axhspan(low - pad, bound, color=colour, alpha=0.08, linewidth=0)
    ax.set_ylabel(ylabel, fontsize=9)
    ax.set_title(title, fontsize=10)
    if series:
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=7, borderaxespad=0.2)


def _runs(mask: np.ndarray, start: FloatArray, end: FloatArray) -> list[tuple[float, float]]:
    """(start, width) in min of each run of consecutive rows where ``mask`` holds (of positive width)."""
    rows = np.flatnonzero(mask)
    if not len(rows):
        return []
    first = np.ones(len(rows), dtype=bool)
    first[1:] = rows[1:] != rows[:-1] + 1
    last = np.ones(len(rows), dtype=bool)
    last[:-1] = first[1:]
    begin, finish = start[rows[first]], end[rows[last]]
    keep = finish > begin
    return list(zip(begin[keep].tolist(), (finish - begin)[keep].tolist(), strict=True))


def _operation_spans(timeline: Timeline, total: float) -> list[tuple[int, tuple[float, float]]]:
    """Each operation's (index, (start, width)) in min: from its boundary to the next one's (the first from 0)."""
    starts = [b.time for b in timeline.boundaries if b.kind is MarkKind.OPERATION] or [0.0]
    starts[0] = 0.0
    ends = [*starts[1:], total]
    return [(k, (a, b - a)) for k, (a, b) in enumerate(zip(starts, ends, strict=True)) if b > a]


def _boundary_labels(ax: Any, timeline: Timeline, worst_time: float | None) -> None:
    """The boundaries' texts along the top of the strokes plot: ``op 2, T2 (line 58, 60)``; none when there are many."""
    boundaries = timeline.boundaries
    operations = [b for b in boundaries if b.kind is MarkKind.OPERATION]
    if len(boundaries) > _LABEL_BOUNDARIES:
        return
    at: dict[float, list[str]] = {}
    for b in boundaries:
        name = f"op {operations.index(b) + 1}" if b.kind is MarkKind.OPERATION else b.label.split(" ")[0]
        at.setdefault(b.time, []).append(f"{name} line {b.line}")
    transform = ax.get_xaxis_transform()
    box = {"boxstyle": "round,pad=0.15", "facecolor": "white", "edgecolor": "none", "alpha": 0.85}
    low, high = ax.get_xlim()

    def side(time: float) -> str:                      # text to the right of its line, or left near the end
        return "right" if time > low + 0.7 * (high - low) else "left"

    for i, (time, texts) in enumerate(sorted(at.items())):   # staggered: neighbours do not overlap
        ax.text(time, 0.86 - 0.14 * (i % 3), f" {', '.join(texts)} ", transform=transform, fontsize=7, ha=side(time),
                va="top", color="#333333", clip_on=True, zorder=6, bbox=box)
    if worst_time is not None:
        ax.text(worst_time, 0.04, " worst margin ", transform=transform, fontsize=7, ha=side(worst_time),
                va="bottom", color=_WORST_COLOUR, clip_on=True, zorder=6, bbox=box)


#: Panel (h)'s lowest bar: a limit missed by more than its whole range is drawn there.
_MARGIN_FLOOR = -1.0


def _margin_panel(ax: Any, report: VerifyReport) -> None:
    """(h): the worst margin of every limit as a fraction of its range."""
    names = [c.name for c in report.closest]
    fraction = np.array([c.fraction_of_range for c in report.closest], dtype=np.float64)
    shown = np.nan_to_num(fraction, nan=-1.0)
    colours = ["#d62728" if f < 0 else "#ff9f1c" if f < 0.1 else "#2ca02c" for f in shown.tolist()]
    positions = np.arange(len(names))[::-1]
    # a bar further out than a whole range is drawn to -1 (its label says how far): the scale stays readable
    ax.barh(positions, np.maximum(shown, _MARGIN_FLOOR), color=colours, height=0.7)
    ax.set_yticks(positions, names, fontsize=8)
    for y, f, c in zip(positions.tolist(), shown.tolist(), report.closest, strict=True):
        ax.text(max(f, 0.0) + 0.01, y, f"{100 * f:.1f} % (line {c.line})", va="center", fontsize=7)
    ax.axvline(0.0, color="black", linewidth=0.6)
    low = min(-0.05, max(float(shown.min(initial=0.0)), _MARGIN_FLOOR) - 0.05)
    ax.set_xlim(low, 1.3)
    ax.set_xticks(([-1.0, -0.5] if low < -0.5 else []) + [0.0, 0.2, 0.4, 0.6, 0.8, 1.0])
    ax.set_xlabel("worst margin / range of the limit")
    ax.set_title("(h) closest approach to each limit", fontsize=10)
    ax.grid(True, axis="x", linewidth=0.3)


def _equal_box(ax: Any, points: FloatArray, pad: float = 0.25) -> tuple[FloatArray, FloatArray]:
    """Equal scales on x, y, z around ``points`` (finite rows), with ``pad`` of the largest extent.

    Returns the box's low and high corners, (3,) mm each.
    """
    finite = points[np.isfinite(points).all(axis=1)]
    if not len(finite):
        finite = np.zeros((1, 3))
    low, high = finite.min(axis=0), finite.max(axis=0)
    centre, half = (low + high) / 2.0, max(float((high - low).max()) / 2.0, 1.0) * (1.0 + pad)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    return centre - half, centre + half


def feature_edges(triangles: FloatArray, *, angle: float = math.radians(1.0)) -> FloatArray:
    """The mesh's sharp and open edges: shared by two triangles whose normals differ by more than
    ``angle``, or not shared by exactly two triangles.

    Parameters
    ----------
    triangles : (K, 3, 3) float — mm

    Returns
    -------
    (E, 2, 3) float — mm, edge end points
    """
    triangles = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    ends = np.stack([triangles, np.roll(triangles, -1, axis=1)], axis=2).reshape(-1, 2, 3)   # (3K, 2, 3)
    owner = np.repeat(np.arange(len(triangles)), 3)
    # an edge's key: its end points rounded to 1 µm, lower one first, so both triangles share it
    keyed = np.round(ends, 3)
    key = np.where(_lexless(keyed[:, 1], keyed[:, 0])[:, None, None], keyed[:, ::-1], keyed).reshape(-1, 6)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    keep = counts[inverse] != 2                        # open or non-manifold edges
    halves = np.flatnonzero(counts[inverse] == 2)
    pairs = halves[np.argsort(inverse[halves], kind="stable")].reshape(-1, 2)   # both halves of each edge
    cos = np.sum(normal[owner[pairs[:, 0]]] * normal[owner[pairs[:, 1]]], axis=1)
    keep[pairs[cos < math.cos(angle), 0]] = True       # one half of each sharp edge
    return ends[keep]


def _lexless(a: FloatArray, b: FloatArray) -> np.ndarray:
    """Row-wise ``a < b`` in the lexicographic order of (x, y, z), for (n, 3) arrays."""
    less = a[:, 2] < b[:, 2]
    for col in (1, 0):
        less = np.where(a[:, col] != b[:, col], a[:, col] < b[:, col], less)
    return less


def clip_segments(segments: FloatArray, low: FloatArray, high: FloatArray) -> FloatArray:
    """The parts of line segments inside the box [low, high] (Liang–Barsky), as one NaN-separated line.

    Parameters
    ----------
    segments : (E, 2, 3) float
    low, high : (3,) float — box corners

    Returns
    -------
    (3 E', 3) float — start, end, NaN row for each of the E' segments that meet the box
    """
    p0, d = segments[:, 0], segments[:, 1] - segments[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        to_low, to_high = (low - p0) / d, (high - p0) / d
    enter = np.where(d > 0, to_low, np.where(d < 0, to_high, -np.inf))
    leave = np.where(d > 0, to_high, np.where(d < 0, to_low, np.inf))
    parallel_inside = (d != 0) | ((p0 >= low) & (p0 <= high))   # a segment parallel to a slab must lie in it
    t0 = np.maximum(0.0, enter.max(axis=1))
    t1 = np.minimum(1.0, leave.min(axis=1))
    keep = parallel_inside.all(axis=1) & (t0 < t1)
    a, b = p0 + t0[:, None] * d, p0 + t1[:, None] * d
    return np.stack([a, b, np.full_like(a, np.nan)], axis=1)[keep].reshape(-1, 3)




def time_label(report: VerifyReport, rapid_rate: float) -> str:
    """The time axis's label: how the moves were timed (the machine's dynamics, or a nominal rapid rate)."""
    if report.dynamics is not None:
        return "cycle time (min), the machine's [dynamics]; G0 shaded grey"
    return f"program time (min), G1 1/F, G0 at {rapid_rate:g} mm/min (no [dynamics]); G0 shaded grey"




def figure_bytes(fig: Figure, fmt: str) -> bytes:
    """The figure as PNG or SVG bytes, without time stamps or software versions (deterministic)."""
    import matplotlib

    buffer = io.BytesIO()
    if fmt == "png":
        fig.savefig(buffer, format="png", metadata={"Software": None})
    elif fmt == "svg":
        with matplotlib.rc_context({"svg.hashsalt": "prs3-post", "svg.fonttype": "path"}):
            fig.savefig(buffer, format="svg", metadata={"Date": None, "Creator": None})
    else:
        raise ValueError(f"unknown image format {fmt!r} (expected one of {sorted(FORMATS.values())})")
    return buffer.getvalue()
