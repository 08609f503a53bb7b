"""A program in one picture: the replayed tool path on the part, the axes over time, the limit margins.

    VerifyReport (FK replay) ──► render_preview ──► matplotlib Figure ──► figure_bytes (PNG / SVG)

Panels
------
(a) 3D, part coordinates: the part's edges (clipped to the view, which frames the face and the
    path), the selected face (highlighted), the FK tool-tip path (every replay sample: G1 moves
    solid, G0 moves dashed, each move a separate piece) and the tool axis at a few G1 end points;
    given the closest approach of the tool, holder or spindle nose to the part, a marker there
    with the body, its clearance and line (red when closer than allowed).
(b) The actuator strokes T1..T3 and the stage X, Y over program time: with the machine's
    ``[dynamics]``, each move's cycle time (the slowest axis's trapezoidal profile, rapids at the
    axes' top speeds: :func:`prs3_post.post.dynamics.move_times`); without it, G1 moves take 1/F min
    (G93) and G0 moves the longest joint travel at a nominal rapid rate (``rapid_rate``, 5000
    mm/min unless given). G4 dwells take their time. The time axis's label says which. Each move is
    drawn from its start to its end point (a straight line in joint space; in time, linear without
    dynamics, trapezoidal with them: the line is then the chord of the S-shaped curve). G0 intervals
    are shaded grey; beyond the stroke limits is shaded red, beyond each stage axis' travel in that
    axis' colour (dotted lines at its bounds).
(c) The worst margin of every limit over the replay, as a fraction of the limit's range
    (:func:`prs3_post.check.verify.margin_fraction`): red below 0, orange below 10 %.

matplotlib is optional (``pip install 'prs3-post[plot]'``): it is imported here, lazily, and the
figure is built with the object-oriented API on the Agg canvas (no pyplot, no display, no global
state). Output is deterministic: no time stamps or software versions in the file metadata, and a
fixed SVG hash salt.
"""

from __future__ import annotations

import io
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from prs3_post.check.verify import VerifyReport, row_times
from prs3_post.core.errors import MissingDependency
from prs3_post.core.toolpath import MoveKind
from prs3_post.core.types import FloatArray, IntArray
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.kinematics.replay import joints_of
from prs3_post.machine.loading import Machine

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["FORMATS", "NO_MATPLOTLIB", "clip_segments", "feature_edges", "figure_bytes", "path_segments",
           "render_preview", "require_matplotlib", "time_label"]

#: Image formats by file suffix.
FORMATS = {".png": "png", ".svg": "svg"}
_FEED_COLOUR, _RAPID_COLOUR, _AXIS_COLOUR = "#1f5fbf", "#d62728", "#2ca02c"
_JOINT_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c")
_STAGE_COLOURS = ("#9467bd", "#8c564b")
_LIMIT_COLOUR = "#d62728"


#: What a picture asked for without matplotlib says (exit status 2).
NO_MATPLOTLIB = "preview needs matplotlib: pip install 'prs3-post[plot]'"


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


def path_segments(report: VerifyReport, kind: MoveKind) -> FloatArray:
    """The FK tip path of every move of ``kind``, part coordinates, for drawing as one line.

    Move k (k ≥ 1) is its start point (the previous row's end) and its samples up to its end, then
    a NaN row that breaks the line before the next move. Row 0 has no start point and no piece.

    Returns
    -------
    (P, 3) float — mm, part coordinates, NaN rows between moves
    """
    rep = report.samples_kept
    rows = np.flatnonzero(report.program.kind == kind)
    rows = rows[rows > 0]
    tip = report.tip_part
    pieces = []
    nan_row = np.full((1, 3), np.nan)
    for r in rows.tolist():                            # one slice per move (drawing, not a hot path)
        pieces += [tip[rep.end[r - 1]][None], tip[rep.first[r]:rep.end[r] + 1], nan_row]
    return np.concatenate(pieces) if pieces else np.zeros((0, 3))


def _axis_marks(report: VerifyReport, count: int, length: float) -> tuple[FloatArray, IntArray]:
    """Tool-axis segments (tip → tip + length·axis) at up to ``count`` G1 end points, NaN-separated."""
    feed_rows = np.flatnonzero(report.program.kind == MoveKind.FEED)
    if not len(feed_rows):
        feed_rows = np.arange(len(report.program))
    chosen = feed_rows[np.unique(np.linspace(0, len(feed_rows) - 1, min(count, len(feed_rows))).round().astype(int))]
    ends = report.samples_kept.end[chosen]
    tip, axis = report.tip_part[ends], report.axis_part[ends]
    segments = np.stack([tip, tip + length * axis, np.full_like(tip, np.nan)], axis=1).reshape(-1, 3)
    return segments, chosen


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


def render_preview(
    report: VerifyReport,
    machine: Machine,
    *,
    mesh: FloatArray | None = None,
    face_triangles: IntArray | None = None,
    face_label: str = "face",
    title: str = "",
    rapid_rate: float,
    axis_marks: int = 6,
    closest: tuple[FloatArray, str, bool] | None = None,
) -> Figure:
    """Draw the preview figure (module docstring).

    Parameters
    ----------
    report : VerifyReport — the replayed program (``verify_program``)
    machine : Machine — for the limits of panel (b)
    mesh : (K, 3, 3) float, optional — mm, the part's triangles in part coordinates
    face_triangles : (F,) int, optional — indices into ``mesh`` of the face to highlight
    face_label : str — legend text of the face
    title : str — the figure's title
    rapid_rate : float — mm/min, joint-space rate of G0 moves for the time axis (a machine without
        ``[dynamics]``; with it, the moves' cycle times)
    axis_marks : int — how many G1 end points get a tool-axis mark
    closest : (point, label, collision), optional — the closest approach of the tool, holder or nose
        to the part: (3,) mm part frame, its text (body, clearance, line), whether it is closer than
        allowed (drawn red, else purple): a marker, the text its legend entry (the body's name beside it)

    Returns
    -------
    matplotlib.figure.Figure — on an Agg canvas; the path lines carry the labels ``G1 (feed)`` and
    ``G0 (rapid)`` and their data are :func:`path_segments`

    Raises
    ------
    Prs3Error
        When matplotlib is not installed.
    """
    figure_cls, canvas_cls, poly_cls = _matplotlib()
    fig = figure_cls(figsize=(13.0, 8.0), dpi=100, layout="constrained")
    canvas_cls(fig)
    grid = fig.add_gridspec(3, 2, width_ratios=(1.25, 1.0))
    # computed_zorder off: the path stays visible on top of the face it is cut into
    ax3d = fig.add_subplot(grid[:, 0], projection="3d", computed_zorder=False)
    ax_t, ax_xy, ax_bar = (fig.add_subplot(grid[i, 1]) for i in range(3))
    if title:
        fig.suptitle(title, fontsize=11)

    # ---- (a) part, face, path, tool axis (drawn in this order, on top of each other)
    feed = path_segments(report, MoveKind.FEED)
    rapid = path_segments(report, MoveKind.RAPID)
    frame = [report.tip_part]
    on_face = np.zeros(0, dtype=bool)
    if mesh is not None and len(mesh):
        mesh = np.asarray(mesh, dtype=np.float64).reshape(-1, 3, 3)
        on_face = np.zeros(len(mesh), dtype=bool)
        if face_triangles is not None:
            on_face[np.asarray(face_triangles, dtype=np.int64)] = True
        frame.append((mesh[on_face] if on_face.any() else mesh).reshape(-1, 3))
    if closest is not None:
        frame.append(np.asarray(closest[0], dtype=np.float64).reshape(1, 3))
    frame_points = np.concatenate(frame)
    finite = frame_points[np.isfinite(frame_points).all(axis=1)]
    extent = float((finite.max(axis=0) - finite.min(axis=0)).max()) if len(finite) else 1.0
    marks, _ = _axis_marks(report, axis_marks, 0.2 * max(extent, 10.0))
    low, high = _equal_box(ax3d, np.concatenate([finite, marks]))
    if mesh is not None and len(mesh):
        edges = clip_segments(feature_edges(mesh), low, high)
        ax3d.plot(edges[:, 0], edges[:, 1], edges[:, 2], color="#7f7f7f", linewidth=0.8, label="part edges",
                  zorder=1)
        if on_face.any():
            ax3d.add_collection3d(poly_cls(mesh[on_face], facecolor="#f5b041", edgecolor="none",
                                           alpha=0.45, label=face_label, zorder=2))
    if len(feed):
        ax3d.plot(feed[:, 0], feed[:, 1], feed[:, 2], color=_FEED_COLOUR, linewidth=1.4, label="G1 (feed)", zorder=4)
    if len(rapid):
        ax3d.plot(rapid[:, 0], rapid[:, 1], rapid[:, 2], color=_RAPID_COLOUR, linewidth=1.0, linestyle="--",
                  label="G0 (rapid)", zorder=5)
    start = report.tip_part[report.samples_kept.end[0]] if len(report.program) else np.zeros(3)
    ax3d.scatter([start[0]], [start[1]], [start[2]], color="black", s=18, label="start", depthshade=False, zorder=6)
    if closest is not None:
        point, text, hit = np.asarray(closest[0], dtype=np.float64).reshape(3), closest[1], closest[2]
        colour = _LIMIT_COLOUR if hit else "#9467bd"
        ax3d.scatter([point[0]], [point[1]], [point[2]], color=colour, marker="X", s=60, label=text,
                     depthshade=False, zorder=7)
        ax3d.text(point[0], point[1], point[2], "  " + text.split(" ")[1], color=colour, fontsize=8, zorder=8)
    ax3d.plot(marks[:, 0], marks[:, 1], marks[:, 2], color=_AXIS_COLOUR, linewidth=1.6, alpha=0.8, label="tool axis",
              zorder=3)
    ax3d.set_xlabel("x (mm)")
    ax3d.set_ylabel("y (mm)")
    ax3d.set_zlabel("z (mm)")
    ax3d.set_title("(a) tool path on the part (FK replay, part coordinates)", fontsize=10)
    normal = np.nanmean(report.axis_part, axis=0) if len(report.samples_kept.axis) else np.array([0.0, 0.0, 1.0])
    azimuth = math.degrees(math.atan2(normal[1], normal[0])) if np.hypot(normal[0], normal[1]) > 1e-6 else -60.0
    ax3d.view_init(elev=28.0, azim=azimuth - 55.0)
    ax3d.legend(loc="upper left", fontsize=8)

    # ---- (b) axes over time
    start_t, end_t = row_times(report.program, rapid_rate=rapid_rate, dynamics=report.dynamics)
    joints = joints_of(report.program)
    previous = np.vstack([joints[:1], joints[:-1]])
    times = np.column_stack([start_t, end_t]).ravel()
    values = np.stack([previous, joints], axis=1).reshape(-1, joints.shape[1])
    joint_names = kinematics_of(machine).joint_names
    limits = machine.limits
    rapid_rows = np.flatnonzero(report.program.kind == MoveKind.RAPID)
    for ax in (ax_t, ax_xy):
        for r in rapid_rows.tolist():
            if end_t[r] > start_t[r]:
                ax.axvspan(start_t[r], end_t[r], color="#e0e0e0", linewidth=0)
    for leg, name in enumerate(joint_names):
        ax_t.plot(times, values[:, 2 + leg], color=_JOINT_COLOURS[leg % len(_JOINT_COLOURS)], linewidth=1.2,
                  label=name)
    _draw_limits(ax_t, limits.stroke, _LIMIT_COLOUR)
    ax_t.set_ylim(*_limit_view(values[:, 2:], limits.stroke))
    ax_t.set_ylabel("stroke (mm)")
    ax_t.set_title(f"(b) strokes {joint_names[0]}..{joint_names[-1]} over time (limits {limits.stroke[0]:g}.."
                   f"{limits.stroke[1]:g} mm)", fontsize=10)
    ax_t.legend(loc="best", fontsize=8, ncols=3)
    if machine.stage.present:
        for i, name in enumerate("XY"):
            ax_xy.plot(times, values[:, i], color=_STAGE_COLOURS[i], linewidth=1.2, label=name)
        # each axis' own travel, in its colour: the union would hide a Y travel tighter than X's
        travels = (machine.stage.travel_x, machine.stage.travel_y)
        for i, name in enumerate("XY"):
            _draw_limits(ax_xy, travels[i], _STAGE_COLOURS[i], label=f"{name} travel")
        ax_xy.set_ylim(*_limit_view(values[:, :2], *travels))
        ax_xy.set_title(f"stage X, Y over time (travel X {machine.stage.travel_x[0]:g}..{machine.stage.travel_x[1]:g}, "
                        f"Y {machine.stage.travel_y[0]:g}..{machine.stage.travel_y[1]:g} mm)", fontsize=10)
        ax_xy.legend(loc="best", fontsize=8, ncols=2)
    else:
        ax_xy.set_title("stage X, Y: this machine has no stage", fontsize=10)
    ax_xy.set_ylabel("stage (mm)")
    ax_xy.set_xlabel(time_label(report, rapid_rate))
    for ax in (ax_t, ax_xy):
        ax.grid(True, linewidth=0.3)
        if len(times) and times[-1] > 0:
            ax.set_xlim(0.0, times[-1])

    # ---- (c) worst margins
    names = [c.name for c in report.closest]
    fraction = np.array([c.fraction_of_range for c in report.closest], dtype=np.float64)
    shown = np.nan_to_num(fraction, nan=-1.0)
    colours = ["#d62728" if f < 0 else "#ff9f1c" if f < 0.1 else "#2ca02c" for f in shown.tolist()]
    positions = np.arange(len(names))[::-1]
    ax_bar.barh(positions, shown, color=colours, height=0.7)
    ax_bar.set_yticks(positions, names, fontsize=8)
    for y, f, c in zip(positions.tolist(), shown.tolist(), report.closest, strict=True):
        ax_bar.text(max(f, 0.0) + 0.01, y, f"{100 * f:.1f} % (line {c.line})", va="center", fontsize=7)
    ax_bar.axvline(0.0, color="black", linewidth=0.6)
    ax_bar.set_xlim(min(-0.05, float(shown.min(initial=0.0)) - 0.05), 1.0)
    ax_bar.set_xlabel("worst margin / range of the limit")
    ax_bar.set_title("(c) closest approach to each limit", fontsize=10)
    ax_bar.grid(True, axis="x", linewidth=0.3)
    return fig


def time_label(report: VerifyReport, rapid_rate: float) -> str:
    """The time axis's label: how the moves were timed (the machine's dynamics, or a nominal rapid rate)."""
    if report.dynamics is not None:
        return "cycle time (min), the machine's [dynamics]; G0 shaded grey"
    return f"program time (min), G1 1/F, G0 at {rapid_rate:g} mm/min (no [dynamics]); G0 shaded grey"


def _limit_view(values: FloatArray, *bounds: tuple[float, float]) -> tuple[float, float]:
    """The y range of a panel: the data, padded, and each bound that is near the data (mm)."""
    finite = values[np.isfinite(values)]
    low, high = (float(finite.min()), float(finite.max())) if len(finite) else bounds[0]
    pad = max(0.08 * (high - low), 2.0)
    view = [low - pad, high + pad]
    for bound in (b for pair in bounds for b in pair):
        if abs(bound - low) < 4 * pad or abs(bound - high) < 4 * pad:
            view = [min(view[0], bound - pad), max(view[1], bound + pad)]
    return view[0], view[1]


def _draw_limits(ax: Any, bounds: tuple[float, float], colour: str, *, label: str = "_nolegend_") -> None:
    """Shade beyond ``bounds`` and draw them as dotted lines, in ``colour`` (the lines carry ``label``)."""
    far = 1e6
    ax.axhspan(bounds[1], bounds[1] + far, color=colour, alpha=0.15, linewidth=0)
    ax.axhspan(bounds[0] - far, bounds[0], color=colour, alpha=0.15, linewidth=0)
    for i, bound in enumerate(bounds):
        ax.axhline(bound, color=colour, linewidth=0.8, linestyle=":", label=label if i == 0 else "_nolegend_")


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
