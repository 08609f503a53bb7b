"""What every machining operation shares: cutting data, the fit check, depth passes and the row builder.

An operation turns a :class:`~prs3_post.part.face.Face` plus options into a
:class:`~prs3_post.core.toolpath.Toolpath` in PART coordinates. It plans in the face frame (u, v, w),
w = outward normal (toward the spindle, w < 0 is depth into the material), and converts to part
coordinates once at the end (:meth:`ToolpathBuilder.build`). The tool axis is the face normal on
every row: the tool stays normal to the face.

Heights along w:

* ``retract`` — safe height for moves between features (and at the start/end of the program);
* ``clearance`` — just above the face, where rapids stop and feed moves start;
* ``0`` — the face; ``-d`` — depth ``d`` into the material.

Error messages name options the way the CLI spells them (``--feed``, ``--tool-diameter``), since
that is what the user typed; the CLI's option for a field is the field name with ``-`` for ``_``.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from prs3_post.core.defaults import FEED_RANGE_MM_MIN
from prs3_post.core.errors import FeatureError
from prs3_post.core.numbers import fixed
from prs3_post.core.toolpath import Coolant, Event, EventKind, MoveKind, Toolpath, toolpath_from_columns
from prs3_post.core.types import FloatArray
from prs3_post.part.face import Face

if TYPE_CHECKING:                      # imported where used: `ik`, `fk`, `verify` never plan a feature
    import shapely

__all__ = [
    "Coolant",
    "Cutting",
    "ToolpathBuilder",
    "approach",
    "check_fits",
    "check_heights",
    "depart",
    "end_program",
    "format_mm",
    "format_uv",
    "pass_depths",
    "require_nonnegative",
    "require_positive",
    "require_tolerance",
    "start_program",
    "swept_region",
]


# --------------------------------------------------------------------------------------------
# Option checks (shared so that every operation words its messages the same way)
# --------------------------------------------------------------------------------------------
#: mm, the largest length any option may have: a kilometre is a typo, and far larger values
#: overflow the outline geometry.
MAX_LENGTH = 1e6


def _unit_suffix(unit: str) -> str:
    return f" {unit}" if unit else ""


def require_positive(key: str, value: float, unit: str = "") -> None:
    """Raise unless ``value`` is a finite number > 0 (and, for lengths in mm, ≤ MAX_LENGTH).

    Parameters
    ----------
    key : str — the value's key, e.g. ``feed`` (the message names it ``{feed}``: each front end words it)
    value : float — what the user gave
    unit : str — unit for the message (``mm``, ``mm/min``, or empty)

    Raises
    ------
    FeatureError
        ``{feed} must be > 0 mm/min (got 0)``, ``{size} must be ≤ 1e+06 mm (got 1e+300)``.
    """
    if not (math.isfinite(value) and value > 0):
        raise FeatureError(f"{{{key}}} must be > 0{_unit_suffix(unit)} (got {value:g})")
    _require_plausible_length(key, value, unit)


def require_feed(key: str, value: float) -> None:
    """Raise unless ``value`` is a feed within :data:`~prs3_post.core.defaults.FEED_RANGE_MM_MIN` (mm/min).

    Raises
    ------
    FeatureError
        ``{feed} must be > 0 mm/min (got 0)``, ``{feed} must be from 0.1 to 1e+06 mm/min (got 1e-07)``.
    """
    require_positive(key, value, "mm/min")
    low, high = FEED_RANGE_MM_MIN
    if not low <= value <= high:
        raise FeatureError(f"{{{key}}} must be from {low:g} to {high:g} mm/min (got {value:g})", key=key)


def _require_plausible_length(key: str, value: float, unit: str) -> None:
    if unit == "mm" and value > MAX_LENGTH:
        raise FeatureError(f"{{{key}}} must be ≤ {MAX_LENGTH:g} mm (got {value:g})")


def require_nonnegative(key: str, value: float, unit: str = "") -> None:
    """Raise unless ``value`` is a finite number ≥ 0 (same wording as :func:`require_positive`).

    Raises
    ------
    FeatureError
        ``{dwell} must be ≥ 0 s (got -1)``.
    """
    if not (math.isfinite(value) and value >= 0):
        raise FeatureError(f"{{{key}}} must be ≥ 0{_unit_suffix(unit)} (got {value:g})")
    _require_plausible_length(key, value, unit)


def check_heights(clearance: float, retract: float) -> None:
    """Check the two safe heights above the face (mm along w).

    Raises
    ------
    FeatureError
        ``{clearance} must be > 0 mm (got 0)``, or
        ``{retract} must be ≥ {clearance} (got {retract} 1.000 mm < {clearance} 2.000 mm)``.
    """
    require_positive("clearance", clearance, "mm")
    require_positive("retract", retract, "mm")
    if retract < clearance:
        raise FeatureError(
            f"{{retract}} must be ≥ {{clearance}} "
            f"(got {{retract}} {retract:.3f} mm < {{clearance}} {clearance:.3f} mm)"
        )


#: Most passes (step-downs) or pecks one feature may take: more is a typo, not a plan.
MAX_PASSES = 10_000
#: mm, the finest chordal tolerance: the programs are written with 4 decimals (0.0001 mm).
MIN_TOLERANCE = 1e-4
#: mm, the coarsest: an arc or an axis turn a millimetre off is no longer the shape asked for.
MAX_TOLERANCE = 1.0
#: mm, the smallest and largest tool diameters: micro drills to face mills.
TOOL_DIAMETER_RANGE = (0.01, 500.0)


def require_tolerance(tolerance: float) -> None:
    """Raise unless the tolerance is a finite number from MIN_TOLERANCE to MAX_TOLERANCE (mm)."""
    if not (math.isfinite(tolerance) and MIN_TOLERANCE <= tolerance <= MAX_TOLERANCE):
        raise FeatureError(
            f"{{tolerance}} must be from {MIN_TOLERANCE:g} mm (the resolution of the program) to {MAX_TOLERANCE:g} mm "
            f"(got {tolerance:g})", key="tolerance")


def pass_depths(depth: float, step: float, *, resolution: float = MIN_TOLERANCE, rel_tol: float = 1e-9,
                key: str = "step_down") -> FloatArray:
    """Depths of successive passes (pecks, step-downs): ``d_k = min(k·step, depth)``.

    ``k = 1 .. ceil(depth/step)``; a last pass less than ``resolution`` below the one before it
    (what the program cannot show: 2.00001 mm in 1 mm steps) is merged into it, and so is one thinner
    than ``rel_tol·step`` (0.9/0.3 = 3.0000000000000004). The last depth is ``depth`` exactly.

    Parameters
    ----------
    depth : float — mm, > 0, final depth
    step : float — mm, > 0, depth per pass
    resolution : float — mm, > 0, the program's length resolution (one unit of its last digit)
    rel_tol : float — fraction of a step below which a last pass is merged into the previous one
    key : str — the key that sets ``step`` (``step_down``, ``peck``), which the message names

    Returns
    -------
    depths : (K,) float — mm, increasing by at least ``resolution``, ``depths[-1] == depth``, K ≥ 1

    Raises
    ------
    FeatureError
        When it would take more than MAX_PASSES passes, or the step is finer than ``resolution``.

    >>> pass_depths(10.0, 3.0).tolist()
    [3.0, 6.0, 9.0, 10.0]
    >>> pass_depths(0.9, 0.3).tolist()
    [0.3, 0.6, 0.9]
    >>> pass_depths(2.00001, 1.0).tolist()
    [1.0, 2.00001]
    """
    passes = depth / step - rel_tol
    if passes > MAX_PASSES:
        shown = f"{math.ceil(passes):g}" if math.isfinite(passes) else "infinitely many"  # a subnormal step
        raise FeatureError(
            f"{{depth}} {depth:g} mm in {{{key}}} {step:g} mm steps would take {shown} passes "
            f"(at most {MAX_PASSES}): use a larger {{{key}}}"
        )
    if step < resolution and passes > 1:
        raise FeatureError(f"{{{key}}} must be ≥ {resolution:g} mm, the resolution of the program (got {step:g})")
    count = max(1, math.ceil(passes))
    depths = np.minimum(np.arange(1, count + 1, dtype=np.float64) * step, depth)
    depths[-1] = depth
    if count > 1 and depth - depths[-2] < resolution:      # the program would show the same depth twice
        depths = np.delete(depths, -2)
    return depths


def format_mm(value: float) -> str:
    """``12.345``: 3 decimals, never ``-0.000``."""
    return fixed(value, 3)


def format_uv(uv: FloatArray | tuple[float, float]) -> str:
    """``(u 10.000, v 0.000)`` for a face point (2,) mm, as messages and comments write it."""
    return f"(u {format_mm(uv[0])}, v {format_mm(uv[1])})"


# --------------------------------------------------------------------------------------------
# Cutting data
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Cutting:
    """The tool and how it cuts, shared by every operation.

    Attributes
    ----------
    tool_diameter : float — mm, > 0 (``--tool-diameter``)
    feed : float — mm/min, > 0, tip feed along the contour (``--feed``)
    plunge_feed : float — mm/min, > 0, tip feed when moving into the material along the axis or
        down a ramp (``--plunge-feed``)
    spindle_rpm : float — rev/min, > 0, clockwise (M3) (``--spindle``)
    coolant : Coolant — (``--coolant``)
    tool_number : int — ≥ 1, the T word of the tool change (``--tool-number``)

    Raises
    ------
    FeatureError
        On a value out of range, naming its key: ``{feed} must be > 0 mm/min (got 0)``.
    """

    tool_diameter: float
    feed: float
    plunge_feed: float
    spindle_rpm: float
    coolant: Coolant
    tool_number: int

    def __post_init__(self) -> None:
        low, high = TOOL_DIAMETER_RANGE
        if not (math.isfinite(self.tool_diameter) and low <= self.tool_diameter <= high):
            raise FeatureError(f"{{tool_diameter}} must be from {low:g} to {high:g} mm (got {self.tool_diameter:g})",
                               key="tool_diameter")
        require_feed("feed", self.feed)
        require_feed("plunge_feed", self.plunge_feed)
        require_positive("spindle", self.spindle_rpm, "rpm")
        number_ok = isinstance(self.tool_number, numbers.Integral) and not isinstance(self.tool_number, bool)
        if not (number_ok and self.tool_number >= 1):
            raise FeatureError(f"{{tool}} must be an integer ≥ 1 (got {self.tool_number!r})")

    @property
    def tool_radius(self) -> float:
        """mm, half the tool diameter."""
        return 0.5 * self.tool_diameter


# --------------------------------------------------------------------------------------------
# Does a feature fit on the face?
# --------------------------------------------------------------------------------------------
def swept_region(path_uv: FloatArray, tool_radius: float, *, tolerance: float = 1e-4) -> shapely.Polygon:
    """The area the tool covers while its centre follows ``path_uv`` (face u, v).

    Parameters
    ----------
    path_uv : (N, 2) float — mm, tool-centre points in face (u, v); N = 1 is a plunge (a disc)
    tool_radius : float — mm, > 0
    tolerance : float — mm, how far the polygon's round parts may fall inside the true circles

    Returns
    -------
    shapely.Polygon — may have interior rings (a closed contour sweeps a band)
    """
    import shapely

    path_uv = np.asarray(path_uv, dtype=np.float64).reshape(-1, 2)
    if len(path_uv) == 0:
        raise ValueError("swept_region: empty path")
    # Segments per quarter circle so that the sagitta r(1 - cos(Δ/2)) stays ≤ tolerance;
    # clip: a tolerance larger than the diameter allows any step.
    max_step = 2.0 * math.acos(float(np.clip(1.0 - tolerance / tool_radius, -1.0, 1.0)))
    quad_segs = max(4, math.ceil((0.5 * math.pi) / max_step))
    if len(path_uv) == 1 or np.all(path_uv == path_uv[0]):
        return shapely.Point(path_uv[0]).buffer(tool_radius, quad_segs=quad_segs)
    return shapely.LineString(path_uv).buffer(tool_radius, quad_segs=quad_segs)


def _reach(region: shapely.Geometry, material: shapely.Geometry, *, tol: float = 1e-6) -> float:
    """sup over the points p of ``region`` of distance(p, ``material``), mm.

    The maximum is often at a vertex of ``region`` (a straight face edge: distance is linear
    along each segment), which gives a lower bound; it is accepted when ``region`` lies within
    ``material`` grown by it. Otherwise (the region covers the middle of an opening, where the
    maximum is inside the region) it is bisected on "region within material grown by t".
    """
    import shapely

    if region.is_empty:
        return 0.0
    vertices = shapely.points(shapely.get_coordinates(region))
    low = float(np.max(shapely.distance(vertices, material)))
    grow_segs = 256   # the grown material's round corners fall inside by t·1.2e-6 at most

    def covered(t: float) -> bool:
        return bool(region.covered_by(material.buffer(t, quad_segs=grow_segs)))

    if covered(low + tol):
        return low
    minx, miny, maxx, maxy = region.bounds
    high = low + math.hypot(maxx - minx, maxy - miny) + tol
    for _ in range(64):                 # only a region far away from the material needs this
        if covered(high):
            break
        high *= 2.0
    # bisect to tol, or to the float spacing at this size (an absolute 1e-6 never comes for 1e10 mm)
    for _ in range(200):
        if high - low <= max(tol, 4.0 * math.ulp(high)):
            break
        middle = 0.5 * (low + high)
        low, high = (low, middle) if covered(middle) else (middle, high)
    return high


def check_fits(face: Face, region: shapely.Geometry, what: str, advice: Callable[[], str] | None = None) -> None:
    """Refuse a feature whose swept area leaves the face material.

    The region must lie within ``face.boundary`` (touching its outer edge is allowed: the tool
    then just reaches the edge) and must not touch any hole in the face (interior ring).

    Parameters
    ----------
    face : Face
    region : shapely geometry — face (u, v), mm: the area the tool sweeps (outline plus tool
        radius, e.g. from :func:`swept_region`)
    what : str — the feature, for the message, e.g. ``hole 2 at (u 10.000, v 0.000) with tool Ø6.000``
    advice : callable, optional — what would fit instead (:mod:`prs3_post.toolpaths.fitting`), said after
        the reason when it does not fit (called only then)

    Raises
    ------
    FeatureError
        ``<what>: does not fit on face 0: overshoots its edge by 12.345 mm`` (the largest distance
        of the part of the region outside the face from the face, mm), or
        ``<what>: does not fit on face 0: cuts 1.234 mm into the hole in the face at (u 5.000, v 0.000)``
        (how deep the region reaches into the hole; ``touches the hole ...`` when it only touches).
    """
    import shapely

    outline = shapely.Polygon(face.boundary.exterior)
    head = f"{what}: does not fit on face {face.index}"

    def instead() -> str:
        words = advice() if advice is not None else ""
        return f"; {words}" if words else ""

    if not region.covered_by(outline):
        raise FeatureError(f"{head}: overshoots its edge by {_reach(region, outline):.3f} mm{instead()}")
    for ring in face.boundary.interiors:
        opening = shapely.Polygon(ring)
        if region.intersects(opening):
            depth = _reach(region.intersection(opening), face.boundary)
            centroid = opening.centroid   # not inside a non-convex opening: then any inside point
            where = centroid if centroid.within(opening) else opening.representative_point()
            place = f"the hole in the face at {format_uv((where.x, where.y))}"
            if f"{depth:.3f}" == "0.000":
                raise FeatureError(f"{head}: touches {place}{instead()}")
            raise FeatureError(f"{head}: cuts {depth:.3f} mm into {place}{instead()}")


# --------------------------------------------------------------------------------------------
# Building the rows
# --------------------------------------------------------------------------------------------
class ToolpathBuilder:
    """Collects motion rows in face coordinates (u, v, w) and events, then makes a part-frame Toolpath.

    Rows belong to the current *step* (a human label such as ``hole 2 peck 3 feed``); ``source``
    of each row is the index of its step in ``source_labels``. Events are placed before the next
    row to be added.

    Parameters
    ----------
    face : Face — gives the frame; every row's axis is ``face.normal``
    """

    __slots__ = ("_events", "_face", "_labels", "_points", "_rows", "_runs")

    def __init__(self, face: Face) -> None:
        self._face = face
        self._points: list[FloatArray] = []           # (n, 3) face points of each call
        self._runs: list[tuple[int, int, float, int]] = []   # (n, kind, feed, step) of each call
        self._labels: list[str] = []
        self._events: list[Event] = []
        self._rows = 0

    @property
    def position(self) -> FloatArray:
        """(3,) float — mm, face (u, v, w) of the last row added."""
        if not self._points:
            raise ValueError("ToolpathBuilder.position: no rows yet")
        return self._points[-1][-1].copy()

    def step(self, label: str) -> None:
        """Start a new step: rows added from now on have ``source`` = this step's index."""
        self._labels.append(label)

    def _add(self, kind: MoveKind, uvw: FloatArray, feed: float) -> None:
        # Only the points are kept as an array; kind, feed and step are one tuple per call, spread
        # over the rows once in build() (per-call arrays of one row cost more than the planning).
        if not self._labels:
            raise ValueError("ToolpathBuilder: call step() before adding rows")
        uvw = np.asarray(uvw, dtype=np.float64).reshape(-1, 3)
        self._points.append(uvw)
        self._runs.append((len(uvw), int(kind), float(feed), len(self._labels) - 1))
        self._rows += len(uvw)

    def rapid(self, uvw: FloatArray) -> None:
        """Add RAPID rows to face points ``uvw`` : (n, 3) or (3,) float — mm."""
        self._add(MoveKind.RAPID, uvw, 0.0)

    def feed(self, uvw: FloatArray, feed: float) -> None:
        """Add FEED rows to face points ``uvw`` : (n, 3) or (3,) float — mm, at ``feed`` mm/min."""
        self._add(MoveKind.FEED, uvw, feed)

    def event(self, kind: EventKind, value: float = 0.0, text: str = "") -> None:
        """Add an event before the next row (after the last row if none follows)."""
        self._events.append(Event(before=self._rows, kind=kind, value=value, text=text))

    def comment(self, text: str) -> None:
        """Add an operator-visible comment before the next row."""
        self.event(EventKind.COMMENT, text=text)

    def build(self) -> Toolpath:
        """The rows in PART coordinates, axis = face normal on every row.

        Returns
        -------
        Toolpath — tip (N, 3) mm part frame, axis (N, 3) = ``face.normal``, feed (N,) mm/min
        (0 on rapids), source (N,) step indices into ``source_labels``.
        """
        uvw = np.concatenate(self._points) if self._points else np.zeros((0, 3))
        runs = np.array(self._runs, dtype=np.float64).reshape(-1, 4)        # n, kind, feed, step
        counts = runs[:, 0].astype(np.int64)
        n = len(uvw)
        # in blocks: one (N, 3) @ (3, 3) product of a long path spends most of its time in the BLAS
        # threads' waiting on a busy machine; each row's result is the same either way
        tip = np.empty((n, 3))
        for lo in range(0, n, _BLOCK_ROWS):
            tip[lo:lo + _BLOCK_ROWS] = self._face.to_part(uvw[lo:lo + _BLOCK_ROWS]).reshape(-1, 3)
        del uvw
        return toolpath_from_columns(
            kind=np.repeat(runs[:, 1].astype(np.int64), counts),
            tip=tip,
            axis=np.tile(np.asarray(self._face.normal, dtype=np.float64), (n, 1)),
            feed=np.repeat(runs[:, 2], counts),
            source=np.repeat(runs[:, 3].astype(np.int64), counts),
            events=tuple(self._events),
            source_labels=tuple(self._labels),
        )


#: Rows of a toolpath carried into the part frame together (:meth:`ToolpathBuilder.build`).
_BLOCK_ROWS = 32768


def _at(uv: FloatArray, w: float) -> FloatArray:
    return np.array([uv[0], uv[1], w], dtype=np.float64)


def approach(builder: ToolpathBuilder, uv: FloatArray, clearance: float, retract: float, label: str) -> None:
    """Step ``label``: RAPID to ``retract`` above face point ``uv`` (2,) mm, then RAPID down to ``clearance``."""
    builder.step(label)
    builder.rapid(np.stack([_at(uv, retract), _at(uv, clearance)]))


def depart(builder: ToolpathBuilder, uv: FloatArray, clearance: float, retract: float, label: str) -> None:
    """Step ``label``: RAPID up along +w to ``clearance`` above face point ``uv`` (2,) mm, then to ``retract``."""
    builder.step(label)
    builder.rapid(np.stack([_at(uv, clearance), _at(uv, retract)]))


def start_program(builder: ToolpathBuilder, cutting: Cutting, title: str) -> None:
    """Events before the first row: comment ``title``, tool change, spindle on (M3), coolant on."""
    builder.comment(title)
    builder.event(EventKind.TOOL_CHANGE, value=float(cutting.tool_number), text=f"Ø{cutting.tool_diameter:.3f} mm tool")
    builder.event(EventKind.SPINDLE_ON, value=float(cutting.spindle_rpm))
    if cutting.coolant is not Coolant.OFF:
        builder.event(EventKind.COOLANT_ON, text=cutting.coolant.value)


def end_program(builder: ToolpathBuilder, cutting: Cutting) -> None:
    """Events after the last row: coolant off (if it was on), spindle off."""
    if cutting.coolant is not Coolant.OFF:
        builder.event(EventKind.COOLANT_OFF)
    builder.event(EventKind.SPINDLE_OFF)
