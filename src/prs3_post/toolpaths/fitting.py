"""What fits where a feature does not: the largest size at its place, and a place where one fits.

A feature that leaves its face (:func:`~prs3_post.toolpaths.common.check_fits`) is refused with what
would fit instead, so that the message names a next step that works: for a hole, the largest tool at
its centre and the nearest centre where its tool fits; for a square or a round, the largest size at
its centre and the largest at the face's widest point (the centre of the largest circle inside the
face: exact for a round, a good place for a square). Sizes are found by bisection on "the swept area
fits" (it grows with the size), written with 3 decimals rounded down and checked again as written;
places likewise, so that the values the message gives are values that pass.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from prs3_post.core.errors import FeatureError
from prs3_post.core.numbers import fixed
from prs3_post.part.face import Face
from prs3_post.toolpaths.common import TOOL_DIAMETER_RANGE

if TYPE_CHECKING:
    import shapely

__all__ = ["fits", "hole_advice", "largest_size", "profile_advice", "widest_point"]

#: Decimals of the sizes and places a message gives (what a user types).
DECIMALS = 3
_STEP = 10.0 ** -DECIMALS

#: A region for a size (mm), or None where that size makes no feature (an inside profile smaller than its tool).
RegionOf = Callable[[float], "shapely.Geometry | None"]


def fits(face: Face, region: shapely.Geometry) -> bool:
    """The rule of :func:`~prs3_post.toolpaths.common.check_fits`: ``region`` (face u, v) within the face's
    outline and clear of every hole in it."""
    import shapely

    if not region.covered_by(shapely.Polygon(face.boundary.exterior)):
        return False
    return not any(region.intersects(shapely.Polygon(ring)) for ring in face.boundary.interiors)


def largest_size(face: Face, region_of: RegionOf, high: float) -> float | None:
    """The largest size up to ``high`` (mm) whose region fits, to :data:`DECIMALS` decimals rounded down and
    checked as written (``high`` itself when it fits); None when none does down to 1/1024 of ``high``."""

    def ok(size: float) -> bool:
        try:
            region = region_of(size)
        except FeatureError:
            return False
        return region is not None and fits(face, region)

    if ok(high):
        return high
    low = high
    for _ in range(10):                               # a size that fits: halve until one does
        low *= 0.5
        if low < _STEP:
            return None
        if ok(low):
            break
    else:
        return None
    top = high
    while top - low > 0.25 * _STEP:
        middle = 0.5 * (low + top)
        low, top = (middle, top) if ok(middle) else (low, middle)
    size = math.floor(top / _STEP) * _STEP              # the largest written value at or below the bound
    while size >= _STEP and not ok(float(_number(size))):
        size -= _STEP
    return float(_number(size)) if size >= _STEP else None


def widest_point(face: Face) -> np.ndarray:
    """(2,) mm — face (u, v) of the centre of the largest circle inside the face, to :data:`DECIMALS` decimals."""
    import shapely

    line = shapely.maximum_inscribed_circle(face.boundary, tolerance=_STEP)
    return np.round(np.asarray(shapely.get_coordinates(line)[0], dtype=np.float64), DECIMALS)


def _number(value: float) -> str:
    """``11.886``, ``0.4``, ``-1.788``: a value as a user types it (:data:`DECIMALS` at most, no trailing zeros)."""
    text = fixed(value, DECIMALS).rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def _text(uv: np.ndarray) -> str:
    return f"{_number(float(uv[0]))},{_number(float(uv[1]))}"


def _where(uv: np.ndarray) -> str:
    return f"(u {fixed(float(uv[0]), DECIMALS)}, v {fixed(float(uv[1]), DECIMALS)})"


def hole_advice(face: Face, center: np.ndarray, tool_diameter: float,
                disc: Callable[[np.ndarray, float], shapely.Geometry]) -> str:
    """For a hole that does not fit at ``center`` (face u, v): the largest tool there, and the nearest place
    where its tool (``tool_diameter`` mm) fits, naming the keys ``{tool_diameter}`` and ``{at}`` ('' when
    neither exists). ``disc(centre, diameter)``: the region the tool sweeps."""
    import shapely

    words = []
    largest = largest_size(face, lambda d: disc(center, d), tool_diameter)
    if largest is not None and largest >= TOOL_DIAMETER_RANGE[0]:
        shown = _number(largest)
        words.append(f"the largest tool that fits at {_where(center)} is Ø{fixed(largest, DECIMALS)} "
                     f"({{tool_diameter}} {shown})")
    for inset in (1.0, 3.0, 10.0):                     # steps inside the room the tool needs (rounding)
        room = face.boundary.buffer(-(0.5 * tool_diameter + inset * _STEP))
        if room.is_empty:
            break
        line = shapely.shortest_line(room, shapely.Point(center))
        place = np.round(np.asarray(shapely.get_coordinates(line)[0], dtype=np.float64), DECIMALS)
        if fits(face, disc(place, tool_diameter)):
            words.append(f"Ø{fixed(tool_diameter, DECIMALS)} fits at {_where(place)}, the nearest place where it "
                         f"does ({{at}} {_text(place)})")
            break
    return "; ".join(words)


def profile_advice(face: Face, center: np.ndarray, size: float, key: str,
                   region_at: Callable[[np.ndarray, float], shapely.Geometry | None]) -> str:
    """For a square or round of ``size`` mm (the key ``key``: ``size``, ``diameter``) that does not fit at
    ``center``: the largest there, and the largest at the face's widest point, naming ``{key}`` and ``{at}``
    ('' when none fits anywhere). ``region_at(centre, size)``: the region it sweeps (None: no such feature)."""
    words = []
    here = largest_size(face, lambda s: region_at(center, s), size)
    if here is not None:
        words.append(f"the largest that fits at {_where(center)} is {fixed(here, DECIMALS)} mm "
                     f"({{{key}}} {_number(here)})")
    widest = widest_point(face)
    if not np.array_equal(np.round(center, DECIMALS), widest):
        there = largest_size(face, lambda s: region_at(widest, s), size)
        if there == size:
            words.append(f"it fits at {_where(widest)}, where the face is widest ({{at}} {_text(widest)})")
        elif there is not None and (here is None or there > here):
            words.append(f"at {_where(widest)}, where the face is widest, {fixed(there, DECIMALS)} mm fits "
                         f"({{at}} {_text(widest)} {{{key}}} {_number(there)})")
    return "; ".join(words)
