"""A program as one interactive, self-contained HTML page: the machine moving over the part, line by line.

    ViewData (arrays, already decimated) ──► render_view ──► one HTML text (plotly.js embedded)

The page works offline and makes no network request: plotly.js is written into it (plotly's own
bundle, ``plotly.offline.get_plotlyjs``), every array is in it (base64 float32, plotly's typed-array
form), no font, MathJax or map data is fetched (``typesetMath`` off, no geo traces), and the view's
own script is a few lines that pick rows. It has:

- the 3D scene, in the table's frame (the machine's frame with the stage at X = Y = 0: the part sits
  still at its setup, and the whole head, base included, is drawn shifted by the stage's X, Y, which
  is the same relative motion as the table moving under a still head): the part (grey), the faces
  the operations cut (in each operation's colour), the tool path of each operation (G1 solid, G0
  dashed), markers with their line numbers (the closest approach to the part, the worst margin),
  and the machine at the current stop: base, rails, sliders, links, platform, spindle nose,
  holder and tool. Two buttons frame the whole machine or the part;
- a slider and a play button over the stops (the program's lines, decimated for a long program by
  the caller), the current line's number, time, text and joint values;
- plots over time, one panel per quantity with its limits as dashed lines (the y axes include
  them), the operations' and tool changes' boundaries as vertical lines, and a cursor at the
  current stop's time. Clicking a plot moves the slider to the nearest stop.

The machine's points at each stop come from :func:`machine_frames` (our forward kinematics through
:func:`prs3_post.check.machine_pose.machine_pose`): the page's script copies one stop's row into the
machine's traces and computes nothing. The machine has its own plotly scene, stacked on the part's
with the same area and camera (the part's turns and zooms are copied to it): a restyle recomputes
every trace of its scene, and the machine's eight small traces take milliseconds where a long tool
path would take seconds at every step. Builders here do no I/O; plotly is imported lazily, and only
for its JavaScript bundle (``pip install 'prs3-post[plot]'``).
"""

from __future__ import annotations

import base64
import html
import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from prs3_post.check.machine_pose import MachinePose
from prs3_post.core.errors import MissingDependency
from prs3_post.core.types import FloatArray, IntArray

__all__ = ["MACHINE_PIECES", "NO_PLOTLY", "PART_COLOUR", "Boundary", "Limit", "MachineFrames", "Marker", "PathTrace",
           "Series", "Stops", "Surface", "TimePanel", "ViewData", "machine_frames", "render_view", "require_plotly",
           "surface_from_triangles"]

#: What the HTML view says without plotly (exit status 2).
NO_PLOTLY = "the HTML view needs plotly: pip install 'prs3-post[plot]'"

#: The machine's traces: name, points per stop, line width (px; 0: markers, -1: a filled triangle), colour.
MACHINE_PIECES: tuple[tuple[str, int, int, str], ...] = (
    ("base", 4, 4, "#555555"),
    ("base plate", 3, -1, "#9a9a9a"),
    ("rails", 9, 5, "#888888"),
    ("sliders", 3, 0, "#333333"),
    ("links", 9, 6, "#e0a030"),
    ("platform", 4, 7, "#4060a0"),
    ("platform plate", 3, -1, "#7090d0"),
    ("spindle nose", 2, 40, "#6a6a7a"),
    ("holder", 2, 18, "#a0a0b0"),
    ("tool", 2, 6, "#d03030"),
)
_POINTS_PER_STOP = sum(p[1] for p in MACHINE_PIECES)
# each line of a panel drawn wider and solid, the next narrower and dashed...: lines that coincide
# (the three strokes of a path at a constant tool axis) stay told apart
_STYLES = ({"width": 2.4, "dash": "solid"}, {"width": 1.8, "dash": "dash"}, {"width": 1.4, "dash": "dot"},
           {"width": 1.4, "dash": "solid"}, {"width": 1.4, "dash": "dashdot"})
#: The part's colour (a light tan: apart from the machine's greys and the operations' colours).
PART_COLOUR = "#d2b48c"


def require_plotly() -> None:
    """Refuse the HTML view before any work is done for it when plotly cannot be imported.

    Raises
    ------
    MissingDependency
        :data:`NO_PLOTLY`.
    """
    _plotly_js()


def _plotly_js() -> str:
    """plotly.js, the bundle plotly's Python package ships (about 4.8 MB)."""
    try:
        from plotly.offline import get_plotlyjs
    except ImportError as exc:
        raise MissingDependency(NO_PLOTLY) from exc
    return str(get_plotlyjs())


@dataclass(frozen=True, slots=True)
class Surface:
    """A triangle mesh to draw: (V, 3) float mm ``vertices``, (T, 3) int ``triangles``, its legend
    ``name`` and ``colour``, ``opacity`` 0..1; ``focus``: the "part" button frames it (a face worked on)."""

    name: str
    vertices: FloatArray
    triangles: IntArray
    colour: str
    opacity: float = 1.0
    focus: bool = False


def surface_from_triangles(name: str, triangles: FloatArray, colour: str, *, opacity: float = 1.0,
                           focus: bool = False) -> Surface:
    """A :class:`Surface` from (K, 3, 3) float triangles (mm), shared corners merged (to 1 µm)."""
    corners = np.asarray(triangles, dtype=np.float64).reshape(-1, 3)
    unique, inverse = np.unique(np.round(corners, 3), axis=0, return_inverse=True)
    return Surface(name=name, vertices=unique, triangles=inverse.reshape(-1, 3).astype(np.int64), colour=colour,
                   opacity=opacity, focus=focus)


@dataclass(frozen=True, slots=True)
class PathTrace:
    """One line of the tool path: (P, 3) float mm ``points``, NaN rows break it; ``rapid``: dashed."""

    name: str
    points: FloatArray
    colour: str
    rapid: bool = False


@dataclass(frozen=True, slots=True)
class Marker:
    """A labelled point of the scene: (3,) float mm ``point``, ``text`` beside it, ``name`` in the legend."""

    name: str
    point: FloatArray
    text: str
    colour: str
    symbol: str = "diamond"


@dataclass(frozen=True, slots=True)
class MachineFrames:
    """The machine's points at R stops, in the drawing frame: (R, P, 3) float mm, P = the points of
    :data:`MACHINE_PIECES` one after the other (NaN rows between a piece's segments)."""

    points: FloatArray


@dataclass(frozen=True, slots=True)
class Stops:
    """The slider's R stops (program lines), in program order.

    Attributes
    ----------
    line : (R,) int — 1-based line numbers
    time : (R,) float — min, the time at the end of each line's move
    text : tuple of str — each line's text
    value_names : tuple of str — the joint values shown (e.g. X, Y, U, V, W)
    values : (R, K) float — mm, those values at each stop
    """

    line: IntArray
    time: FloatArray
    text: tuple[str, ...]
    value_names: tuple[str, ...]
    values: FloatArray


@dataclass(frozen=True, slots=True)
class Series:
    """One line of a time panel: (M,) float ``values`` at :attr:`ViewData.time` (NaN: a gap); ``name``
    on hover, ``short`` in the panel's title in the line's colour (empty: ``name``)."""

    name: str
    values: FloatArray
    colour: str
    short: str = ""


@dataclass(frozen=True, slots=True)
class Limit:
    """A horizontal dashed line of a time panel at ``value`` (the panel's unit)."""

    name: str
    value: float
    colour: str = "#d62728"


@dataclass(frozen=True, slots=True)
class TimePanel:
    """One plot over time: its ``title``, y-axis ``unit``, lines and limits."""

    title: str
    unit: str
    series: tuple[Series, ...]
    limits: tuple[Limit, ...] = ()


@dataclass(frozen=True, slots=True)
class Boundary:
    """A vertical line on every time panel at ``time`` (min): an operation's start or a tool change,
    ``short`` written above it, ``label`` on hover."""

    time: float
    label: str
    kind: str = "operation"          # "operation" (solid) or "tool" (dotted)
    short: str = ""                  # written on the plot (``label`` shows on hover); empty: ``label``


@dataclass(frozen=True, slots=True)
class ViewData:
    """Everything the page shows (module docstring); arrays in the drawing frame, mm, minutes.

    ``time`` (M,) float is the time axis of every panel's series; ``notes`` are lines shown under the title.
    """

    title: str
    machine: MachineFrames
    stops: Stops
    surfaces: tuple[Surface, ...] = ()
    paths: tuple[PathTrace, ...] = ()
    markers: tuple[Marker, ...] = ()
    time: FloatArray = field(default_factory=lambda: np.zeros(0))
    time_label: str = "time (min)"
    panels: tuple[TimePanel, ...] = ()
    boundaries: tuple[Boundary, ...] = ()
    notes: tuple[str, ...] = ()


def machine_frames(pose: MachinePose) -> MachineFrames:
    """The machine's points at every row of ``pose``, in the table's frame (+ the stage's X, Y).

    Per row, in the order of :data:`MACHINE_PIECES`: the base (the rails' top ends, closed), the
    three rails, the three sliders, the three links (slider → spherical joint), the platform (its
    corners, closed), then the spindle nose, the holder and the tool as their axis segments.

    Returns
    -------
    MachineFrames — (N, P, 3) float mm; a row whose joints give no pose is all NaN
    """
    n = len(pose.tip)
    nan = np.full((n, 1, 3), np.nan)
    rails = np.broadcast_to(pose.rails, (n, *pose.rails.shape))                 # (N, J, 2, 3)
    tops = rails[:, :, 1] if np.mean(pose.rails[:, 1, 2]) > np.mean(pose.rails[:, 0, 2]) else rails[:, :, 0]
    base = np.concatenate([tops, tops[:, :1]], axis=1)                               # (N, 4, 3)
    rail_lines = np.concatenate([rails, np.broadcast_to(nan[:, None], (n, 3, 1, 3))], axis=2).reshape(n, -1, 3)
    links = np.stack([pose.sliders, pose.spherical], axis=2)                         # (N, J, 2, 3)
    link_lines = np.concatenate([links, np.broadcast_to(nan[:, None], (n, 3, 1, 3))], axis=2).reshape(n, -1, 3)
    platform = np.concatenate([pose.spherical, pose.spherical[:, :1]], axis=1)
    bodies = pose.body_segments()                                                    # (N, B, 2, 3) tool, holder, nose
    pieces = [base, tops, rail_lines, pose.sliders, link_lines, platform, pose.spherical, bodies[:, 2], bodies[:, 1],
              bodies[:, 0]]
    points = pose.on_table(np.concatenate(pieces, axis=1))
    points[~pose.converged] = np.nan
    return MachineFrames(points=points)


def _typed(values: Any, dtype: str = "f4") -> dict[str, str]:
    """An array in plotly.js's typed-array form, little-endian, base64: float32 (``f4``, NaN kept) or
    int32 (``i4``)."""
    data = np.ascontiguousarray(np.asarray(values, dtype=f"<{dtype}").ravel())
    return {"dtype": dtype, "bdata": base64.b64encode(data.tobytes()).decode("ascii")}


def _listed(values: FloatArray) -> list[float | None]:
    """Numbers for JSON, NaN as null (a gap in a plotly line)."""
    return [None if not np.isfinite(v) else round(float(v), 4) for v in np.asarray(values).ravel()]


def _columns(points: FloatArray) -> dict[str, Any]:
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return {"x": _typed(points[:, 0]), "y": _typed(points[:, 1]), "z": _typed(points[:, 2])}


def _box(points: FloatArray, pad: float) -> tuple[list[float], float]:
    """The centre and half size of a cube around the finite ``points``, ``pad`` of its size added."""
    finite = points[np.isfinite(points).all(axis=1)] if len(points) else points
    if not len(finite):
        return [0.0, 0.0, 0.0], 50.0
    low, high = finite.min(axis=0), finite.max(axis=0)
    half = max(float((high - low).max()) / 2.0, 5.0) * (1.0 + pad)
    return ((low + high) / 2.0).tolist(), half


def _ranges(centre: list[float], half: float) -> dict[str, list[float]]:
    return {f"scene.{a}axis.range": [c - half, c + half] for a, c in zip("xyz", centre, strict=True)}


def _scene(data: ViewData) -> tuple[dict[str, Any], dict[str, Any]]:
    """The 3D figures: the part, faces, paths and markers (still), and the machine (restyled at each
    stop), drawn in two plotly scenes stacked on each other with one camera: a restyle recomputes every
    trace of its scene, and the machine's alone costs milliseconds where a long path would take seconds.
    Returns each as ``{"data": traces, "layout": layout}``."""
    traces: list[dict[str, Any]] = []
    for s in data.surfaces:
        v, t = np.asarray(s.vertices).reshape(-1, 3), np.asarray(s.triangles).reshape(-1, 3)
        traces.append({"type": "mesh3d", "name": s.name, "showlegend": True, **_columns(v),
                       "i": _typed(t[:, 0], "i4"), "j": _typed(t[:, 1], "i4"), "k": _typed(t[:, 2], "i4"),
                       "color": s.colour, "opacity": s.opacity, "flatshading": True, "hoverinfo": "name",
                       "lighting": {"ambient": 0.55, "diffuse": 0.6, "specular": 0.05}})
    for p in data.paths:
        line = {"color": p.colour, "width": 2 if p.rapid else 4, "dash": "dash" if p.rapid else "solid"}
        traces.append({"type": "scatter3d", "mode": "lines", "name": p.name, **_columns(p.points), "line": line,
                       "hoverinfo": "name", "connectgaps": False})
    for m in data.markers:
        traces.append({"type": "scatter3d", "mode": "markers+text", "name": m.name, **_columns(m.point),
                       "text": [m.text], "textposition": "top center", "textfont": {"color": m.colour, "size": 12},
                       "marker": {"color": m.colour, "size": 6, "symbol": m.symbol}, "hovertext": [m.text],
                       "hoverinfo": "text"})
    # the machine's legend entry (its traces are in the other scene): a click shows or hides the machine
    traces.append({"type": "scatter3d", "mode": "lines", "name": "machine", "x": [None], "y": [None], "z": [None],
                   "line": {"color": MACHINE_PIECES[0][3], "width": 4}, "hoverinfo": "skip"})
    machine: list[dict[str, Any]] = []
    first = data.machine.points[0] if len(data.machine.points) else np.full((_POINTS_PER_STOP, 3), np.nan)
    at = 0
    for name, count, width, colour in MACHINE_PIECES:
        chunk = first[at:at + count]
        at += count
        trace: dict[str, Any] = {"type": "scatter3d", "name": name, "showlegend": False, "hoverinfo": "skip",
                                 "x": _listed(chunk[:, 0]), "y": _listed(chunk[:, 1]), "z": _listed(chunk[:, 2]),
                                 "connectgaps": False}
        if width < 0:
            trace = {"type": "mesh3d", "name": name, "showlegend": False, "hoverinfo": "skip", "color": colour,
                     "opacity": 0.45, "i": [0], "j": [1], "k": [2], "flatshading": True,
                     "x": _listed(chunk[:, 0]), "y": _listed(chunk[:, 1]), "z": _listed(chunk[:, 2]),
                     "visible": bool(np.isfinite(chunk).all())}
        elif width:
            trace |= {"mode": "lines", "line": {"color": colour, "width": width}}
        else:
            trace |= {"mode": "markers", "marker": {"color": colour, "size": 5, "symbol": "square"}}
        machine.append(trace)
    path_points = [np.asarray(p.points).reshape(-1, 3) for p in data.paths] + \
        [np.asarray(m.point).reshape(-1, 3) for m in data.markers]
    part_points = [np.asarray(s.vertices).reshape(-1, 3) for s in data.surfaces]
    machine_points = data.machine.points.reshape(-1, 3)
    all_points = np.concatenate(path_points + part_points + [machine_points, np.zeros((0, 3))])
    centre, half = _box(all_points, 0.05)
    near = np.concatenate(path_points + [np.asarray(s.vertices).reshape(-1, 3) for s in data.surfaces if s.focus]
                          + [np.zeros((0, 3))])
    near_centre, near_half = _box(near, 0.3)
    ranges = {f"{a}axis": {"range": [c - half, c + half]} for a, c in zip("xyz", centre, strict=True)}
    # both scenes on the same area: the legend sits inside the page below it (outside, it would push
    # the part's margins and not the machine's)
    scene = {"aspectmode": "cube", "camera": {"eye": {"x": 1.5, "y": -1.5, "z": 0.9}},
             "domain": {"x": [0.0, 1.0], "y": [0.16, 1.0]}}
    margin = {"l": 0, "r": 0, "t": 30, "b": 0}
    axis = {"showbackground": True, "backgroundcolor": "#f4f4f8"}
    layout = {
        "margin": margin, "uirevision": "keep",
        "legend": {"orientation": "h", "x": 0.0, "y": 0.15, "yanchor": "top", "font": {"size": 11}},
        "scene": {**scene, **{f"{a}axis": {**axis, **ranges[f"{a}axis"], "title": {"text": f"{a} (mm)"}}
                              for a in "xyz"}},
        "updatemenus": [{"type": "buttons", "direction": "right", "x": 1.0, "xanchor": "right", "y": 1.0,
                         "yanchor": "top", "showactive": False, "buttons": [
                             {"label": "whole machine", "method": "relayout", "args": [_ranges(centre, half)]},
                             {"label": "part", "method": "relayout", "args": [_ranges(near_centre, near_half)]}]}],
    }
    # two points that are never drawn, at the corners of the box: a stop without a pose (every machine
    # point null) leaves the scene with no data, and plotly's camera goes NaN without them
    corners = [[c - half, c + half] for c in centre]
    machine.append({"type": "scatter3d", "mode": "markers", "name": "box", "showlegend": False,
                    "hoverinfo": "skip", "x": corners[0], "y": corners[1], "z": corners[2],
                    "marker": {"size": 1, "opacity": 0}})
    bare = {"visible": False, "showbackground": False, "showgrid": False, "zeroline": False, "showspikes": False}
    machine_layout = {
        "margin": margin, "uirevision": "keep", "showlegend": False, "paper_bgcolor": "rgba(0,0,0,0)",
        "plot_bgcolor": "rgba(0,0,0,0)",
        "scene": {**scene, "bgcolor": "rgba(0,0,0,0)",
                  **{f"{a}axis": {**bare, **ranges[f"{a}axis"]} for a in "xyz"}},
    }
    return {"data": traces, "layout": layout}, {"data": machine, "layout": machine_layout}


def _plots(data: ViewData) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """The time panels: traces and layout (panels stacked, one shared time axis; shape 0 is the cursor)."""
    traces: list[dict[str, Any]] = []
    count = len(data.panels)
    gap = 0.045
    height = (1.0 - gap * (count - 1)) / max(count, 1)
    time = np.asarray(data.time, dtype=np.float64)
    t_end = [float(time[0]), float(time[-1])] if len(time) else [0.0, 1.0]
    layout: dict[str, Any] = {"margin": {"l": 60, "r": 10, "t": 34, "b": 40}, "showlegend": False,
                              "hovermode": "x", "uirevision": "keep", "annotations": []}
    shapes: list[dict[str, Any]] = [{"type": "line", "xref": "x", "yref": "paper", "x0": t_end[0], "x1": t_end[0],
                                     "y0": 0, "y1": 1, "line": {"color": "#000000", "width": 1.5}}]
    for p, panel in enumerate(data.panels):
        suffix = "" if p == 0 else str(p + 1)
        top = 1.0 - p * (height + gap)
        layout[f"yaxis{suffix}"] = {"domain": [max(top - height, 0.0), top], "title": {"text": panel.unit,
                                                                                      "font": {"size": 11}},
                                    "zeroline": False}
        layout[f"xaxis{suffix}"] = {"anchor": f"y{suffix}", "showticklabels": p == count - 1,
                                    **({"matches": "x"} if p else {})}
        # the title at the right: the boundaries' labels are written above the left of the first panel
        key = "  ".join(f"<span style='color:{s.colour}'>{html.escape(s.short or s.name)}</span>"
                        for s in panel.series) if len(panel.series) > 1 else ""
        layout["annotations"].append({"text": f"<b>{html.escape(panel.title)}</b>  {key}".rstrip(), "xref": "paper",
                                      "yref": "paper", "x": 1.0, "y": top, "xanchor": "right", "yanchor": "bottom",
                                      "showarrow": False, "font": {"size": 11}})
        for k, s in enumerate(panel.series):
            traces.append({"type": "scattergl" if len(time) > 20000 else "scatter", "name": s.name,
                           "mode": "lines" if len(time) > 1 else "markers",
                           "x": _typed(time), "y": _typed(s.values), "xaxis": f"x{suffix}", "yaxis": f"y{suffix}",
                           "line": {"color": s.colour, **(_STYLES[k % len(_STYLES)] if len(panel.series) > 1
                                                                    else {"width": 1.5})}, "connectgaps": False})
        for lim in panel.limits:                           # a trace, so that the y axis's autorange includes it
            traces.append({"type": "scatter", "mode": "lines", "name": lim.name, "x": t_end,
                           "y": [lim.value, lim.value], "xaxis": f"x{suffix}", "yaxis": f"y{suffix}",
                           "line": {"color": lim.colour, "width": 1, "dash": "dash"}, "hoverinfo": "name"})
    if count:
        last = "" if count == 1 else str(count)
        layout[f"xaxis{last}"]["title"] = {"text": data.time_label, "font": {"size": 11}}
    for b in data.boundaries:
        shapes.append({"type": "line", "xref": "x", "yref": "paper", "x0": b.time, "x1": b.time, "y0": 0, "y1": 1,
                       "line": {"color": "#2ca02c" if b.kind == "operation" else "#7f7f7f", "width": 1,
                                "dash": "solid" if b.kind == "operation" else "dot"}})
        layout["annotations"].append({"text": html.escape(b.short or b.label), "hovertext": html.escape(b.label),
                                      "xref": "x", "yref": "paper", "x": b.time, "y": 1.0, "yanchor": "bottom",
                                      "yshift": 14 if b.kind == "operation" else 2, "xanchor": "left",
                                      "showarrow": False,
                                      "font": {"size": 10, "color": "#2ca02c" if b.kind == "operation" else "#555"}})
    layout["shapes"] = shapes
    return traces, layout


def render_view(data: ViewData) -> str:
    """The page (module docstring) as HTML text, plotly.js embedded.

    Raises
    ------
    MissingDependency
        :data:`NO_PLOTLY`.
    """
    plotly_js = _plotly_js()
    scene, machine = _scene(data)
    plot_traces, plot_layout = _plots(data)
    stops = data.stops
    payload = {
        "scene": scene,
        "machine_scene": machine,
        "plots": {"data": plot_traces, "layout": plot_layout},
        "machine": {"counts": [p[1] for p in MACHINE_PIECES], "meshes": [p[2] < 0 for p in MACHINE_PIECES],
                    "traces": list(range(len(MACHINE_PIECES))),
                    "points": _typed(data.machine.points),
                    "per_stop": _POINTS_PER_STOP},
        "stops": {"line": np.asarray(stops.line).astype(int).tolist(),
                  "time": [round(float(t), 6) for t in np.asarray(stops.time)],
                  "text": list(stops.text), "names": list(stops.value_names),
                  "values": [[round(float(v), 4) for v in row] for row in np.asarray(stops.values)]},
    }
    text = json.dumps(payload, separators=(",", ":"), allow_nan=False)
    # the JSON sits in a <script> element: no "</" may end it early
    text = text.replace("</", "<\\/")
    notes = "".join(f"<div class='note'>{html.escape(n)}</div>" for n in data.notes)
    return (_PAGE.replace("@TITLE@", html.escape(data.title)).replace("@NOTES@", notes)
            .replace("@PLOTLY@", plotly_js.replace("</script", "<\\/script")).replace("@DATA@", text)
            .replace("@SCRIPT@", _SCRIPT))


_PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>@TITLE@</title>
<style>
body { margin: 0; font: 13px sans-serif; color: #222; }
header { padding: 6px 10px; border-bottom: 1px solid #ddd; }
header h1 { font-size: 15px; margin: 0 0 2px 0; }
.note { color: #555; font-size: 12px; }
#controls { display: flex; align-items: center; gap: 8px; padding: 6px 10px; }
#slider { flex: 1; }
#info { font-family: monospace; white-space: pre; padding: 0 10px 6px 10px; min-height: 2.6em; }
#main { display: flex; height: calc(100vh - 150px); min-height: 480px; }
#view-scene { flex: 1.3; min-width: 0; position: relative; }
#view-part, #view-machine { position: absolute; left: 0; top: 0; right: 0; bottom: 0; }
#view-machine { pointer-events: none; }
#view-plots { flex: 1; min-width: 0; }
</style></head>
<body>
<header><h1>@TITLE@</h1>@NOTES@</header>
<div id="controls"><button id="play" type="button">&#9654; play</button>
<select id="speed" title="stops per step"><option value="1">x1</option><option value="5">x5</option>
<option value="25">x25</option></select>
<input id="slider" type="range" min="0" max="0" value="0" step="1" aria-label="program line">
<span id="where"></span></div>
<div id="info"></div>
<div id="main"><div id="view-scene"><div id="view-part"></div><div id="view-machine"></div></div>
<div id="view-plots"></div></div>
<script>@PLOTLY@</script>
<script id="prs3-data" type="application/json">@DATA@</script>
<script>@SCRIPT@</script>
</body></html>
"""

# The page's own script: it decodes the machine's rows and copies one into the machine's traces
# (no kinematics here: every point was computed by the post-processor's forward kinematics).
_SCRIPT = r"""
(function () {
  "use strict";
  var D = JSON.parse(document.getElementById("prs3-data").textContent);
  function decode(t) {
    var bin = atob(t.bdata), bytes = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return new Float32Array(bytes.buffer);
  }
  var M = D.machine, rows = decode(M.points), S = D.stops, n = S.line.length;
  var slider = document.getElementById("slider"), info = document.getElementById("info");
  var where = document.getElementById("where"), play = document.getElementById("play");
  var speed = document.getElementById("speed");
  slider.max = String(Math.max(n - 1, 0));
  var config = {displaylogo: false, responsive: true, typesetMath: false, topojsonURL: ""};
  var scene = document.getElementById("view-part"), machine = document.getElementById("view-machine");
  var plots = document.getElementById("view-plots");
  function num(v) { return (v === null || isNaN(v)) ? "-" : v.toFixed(4); }
  function machineAt(k) {
    var xs = [], ys = [], zs = [], shown = [], at = k * M.per_stop * 3;
    for (var p = 0; p < M.counts.length; p++) {
      var x = [], y = [], z = [];
      for (var q = 0; q < M.counts[p]; q++, at += 3) {
        var a = rows[at], b = rows[at + 1], c = rows[at + 2];
        x.push(isNaN(a) ? null : a); y.push(isNaN(b) ? null : b); z.push(isNaN(c) ? null : c);
      }
      // a plate without a pose (a null corner) is hidden (plotly keeps drawing an emptied mesh)
      shown.push(!M.meshes[p] || x.indexOf(null) < 0);
      xs.push(x); ys.push(y); zs.push(z);
    }
    return {x: xs, y: ys, z: zs, visible: shown};
  }
  var current = 0;
  function show(k) {
    if (!n) return;
    k = Math.max(0, Math.min(n - 1, k | 0));
    current = k;
    slider.value = String(k);
    Plotly.restyle(machine, machineAt(k), M.traces);
    var t = S.time[k];
    Plotly.relayout(plots, {"shapes[0].x0": t, "shapes[0].x1": t});
    where.textContent = "stop " + (k + 1) + " / " + n;
    var values = S.names.map(function (name, i) { return name + " " + num(S.values[k][i]); }).join("   ");
    info.textContent = "line " + S.line[k] + "   t = " + t.toFixed(3) + " min   " + S.text[k] + "\n" + values;
  }
  var timer = null;
  function stop() { if (timer !== null) { clearInterval(timer); timer = null; } play.innerHTML = "&#9654; play"; }
  play.addEventListener("click", function () {
    if (timer !== null) { stop(); return; }
    if (current >= n - 1) show(0);
    play.innerHTML = "&#10074;&#10074; pause";
    timer = setInterval(function () {
      if (current >= n - 1) { stop(); return; }
      show(current + Number(speed.value));
    }, 80);
  });
  slider.addEventListener("input", function () { show(Number(slider.value)); });
  Promise.all([
    Plotly.newPlot(scene, D.scene.data, D.scene.layout, config),
    Plotly.newPlot(machine, D.machine_scene.data, D.machine_scene.layout,
                   {displayModeBar: false, responsive: true, typesetMath: false}),
    Plotly.newPlot(plots, D.plots.data, D.plots.layout, config)
  ]).then(function () {
    // one camera: what the part's scene is turned, zoomed or framed to, the machine's follows
    function follow(ev) {
      var update = {}, any = false;
      for (var key in ev) if (key.indexOf("scene") === 0) { update[key] = ev[key]; any = true; }
      if (any) Plotly.relayout(machine, update);
    }
    scene.on("plotly_relayout", follow);
    scene.on("plotly_relayouting", follow);
    scene.on("plotly_legendclick", function (ev) {
      if (ev.data[ev.curveNumber].name !== "machine") return true;
      machine.style.visibility = machine.style.visibility === "hidden" ? "visible" : "hidden";
      return false;
    });
    plots.on("plotly_click", function (ev) {
      if (!ev.points.length) return;
      var t = ev.points[0].x, best = 0;
      for (var i = 1; i < n; i++) if (Math.abs(S.time[i] - t) < Math.abs(S.time[best] - t)) best = i;
      stop(); show(best);
    });
    show(0);
    document.body.setAttribute("data-ready", "1");
  });
  window.prs3View = {show: show, scene: scene, machine: machine, plots: plots, stops: n};
})();
"""
