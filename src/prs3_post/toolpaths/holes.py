"""Drilling: holes normal to a face, with optional pecking and a dwell at the bottom.

A drilling cycle cannot run in joint space (DESIGN.md), so every hole is expanded here into
explicit moves along the tool axis, which is the face normal w. Per hole, in face coordinates
(u, v, w) with the hole centre c:

1. RAPID to (c, retract), RAPID down to (c, clearance);
2. FEED at ``plunge_feed`` down to the first peck depth (or the full depth without pecking);
3. pecking: RAPID out to (c, clearance) to clear the chips, RAPID back down to ``reapproach_gap``
   above the previous bottom, FEED to the next depth; repeat until the full depth;
4. DWELL ``dwell`` s at the bottom (when > 0);
5. RAPID out to (c, clearance), then to (c, retract).

Holes are drilled in the order given; the move between two holes is at the retract height. The
pecks (steps 2 and 3) are the shared drilling cycle's (:func:`prs3_post.toolpaths.cycles.drill_pattern`, full
retract), with the peck depths chosen here (:func:`~prs3_post.toolpaths.common.pass_depths`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from prs3_post.core.errors import FeatureError
from prs3_post.core.toolpath import EventKind, MoveKind, Toolpath
from prs3_post.core.types import FloatArray
from prs3_post.part.face import Face
from prs3_post.toolpaths.common import (
    MIN_TOLERANCE,
    Cutting,
    ToolpathBuilder,
    approach,
    check_fits,
    check_heights,
    depart,
    end_program,
    format_uv,
    pass_depths,
    require_nonnegative,
    require_positive,
    start_program,
    swept_region,
)
from prs3_post.toolpaths.cycles import DrillCycle, Pecking, drill_pattern
from prs3_post.toolpaths.fitting import hole_advice

if TYPE_CHECKING:
    import shapely

__all__ = ["HoleParams", "plan_holes"]


@dataclass(frozen=True, slots=True)
class HoleParams:
    """How deep and how to drill (all heights in mm along the face normal w).

    Attributes
    ----------
    depth : float — mm, > 0, below the face (``--depth``)
    peck : float — mm, ≥ 0, depth per peck; 0 = drill to depth in one feed (``--peck``)
    dwell : float — s, ≥ 0, pause at the bottom of each hole; 0 = none (``--dwell``)
    clearance : float — mm, > 0, above the face, where rapids stop and the feed starts (``--clearance``)
    retract : float — mm, ≥ clearance, safe height for moves between holes (``--retract``)
    reapproach_gap : float — mm, ≥ 0 and < peck when pecking: how far above the previous bottom
        the rapid back into the hole stops (``--reapproach-gap``)

    Raises
    ------
    FeatureError
        On a value out of range, naming its key: ``{depth} must be > 0 mm (got 0)``.
    """

    depth: float
    peck: float
    dwell: float
    clearance: float
    retract: float
    reapproach_gap: float = 0.5

    def __post_init__(self) -> None:
        require_positive("depth", self.depth, "mm")
        require_nonnegative("peck", self.peck, "mm")
        require_nonnegative("dwell", self.dwell, "s")
        check_heights(self.clearance, self.retract)
        require_nonnegative("reapproach_gap", self.reapproach_gap, "mm")
        if self.peck > 0 and self.reapproach_gap >= self.peck:
            raise FeatureError(
                f"{{reapproach_gap}} must be < {{peck}} when pecking "
                f"(got {{reapproach_gap}} {self.reapproach_gap:.6g} mm ≥ {{peck}} {self.peck:.6g} mm; "
                f"use a smaller gap, a larger peck, or {{peck}} 0 for no pecking)"
            )


def _on_axis(center_uv: FloatArray, w: float) -> FloatArray:
    """(3,) face point (u, v, w) mm on the hole's axis at height ``w`` (negative: depth)."""
    return np.array([center_uv[0], center_uv[1], w], dtype=np.float64)


def _disc(center: FloatArray, diameter: float) -> shapely.Geometry:
    """The region a tool of ``diameter`` mm sweeps drilling at ``center`` (face u, v)."""
    return swept_region(center, 0.5 * diameter)


def _hole_name(index: int, center_uv: FloatArray, cutting: Cutting) -> str:
    return f"hole {index} at {format_uv(center_uv)} with tool Ø{cutting.tool_diameter:.3f}"


def _refuse_repeated(centers: FloatArray, resolution: float) -> None:
    """FeatureError naming the first hole that lies less than ``resolution`` mm from an earlier one.

    Such a hole is the same hole drilled twice: the program cannot even show the two apart. Each centre
    is compared with the earlier ones in its cell of a ``resolution`` grid and the 8 cells around it.
    """
    cells: dict[tuple[float, float], list[int]] = {}
    keys = np.floor(centers / resolution)                       # (K, 2) float: no integer overflow
    for index, (ku, kv) in enumerate(keys.tolist()):
        near = {j for du in (-1.0, 0.0, 1.0) for dv in (-1.0, 0.0, 1.0) for j in cells.get((ku + du, kv + dv), ())}
        for j in sorted(near):
            if float(np.hypot(*(centers[index] - centers[j]))) < resolution:
                raise FeatureError(
                    f"hole {index + 1} at {format_uv(centers[index])} is hole {j + 1} at {format_uv(centers[j])} "
                    f"again (closer than the program's resolution, {resolution:g} mm): it would be drilled twice; "
                    f"give each position once ({{at}}, {{at_xyz}})", key="at")
        cells.setdefault((ku, kv), []).append(index)


def plan_holes(face: Face, centers_uv: FloatArray, params: HoleParams, cutting: Cutting, *,
               resolution: float = MIN_TOLERANCE) -> Toolpath:
    """Drill holes normal to ``face`` at the given face points, in the order given.

    Parameters
    ----------
    face : Face — the face to drill into (frame u, v, w; w = outward normal)
    centers_uv : (K, 2) float — mm, hole centres in face (u, v), K ≥ 1
    params : HoleParams
    cutting : Cutting
    resolution : float — mm, > 0, the program's length resolution: pecks closer than it are merged
        (see :func:`~prs3_post.toolpaths.common.pass_depths`)

    Returns
    -------
    Toolpath — PART coordinates; axis = ``face.normal`` on every row; feed = ``plunge_feed`` on
    FEED rows, 0 on RAPID rows; ``source_labels`` like ``hole 2 approach``, ``hole 2 peck 3 feed``;
    events: program comment, tool change, spindle on, coolant, a comment per hole, a dwell at each
    bottom (when ``params.dwell > 0``), coolant off and spindle off at the end.

    Raises
    ------
    FeatureError
        When no centre is given, a centre is not finite, a hole (a disc of the tool radius)
        does not fit on the face (see :func:`~prs3_post.toolpaths.common.check_fits`), or two centres are
        closer than ``resolution`` (the same hole drilled twice).
    """
    centers = np.asarray(centers_uv, dtype=np.float64)
    if centers.ndim != 2 or centers.shape[1] != 2:
        raise FeatureError(f"hole positions: expected (K, 2) face (u, v) in mm, got shape {centers.shape}")
    if len(centers) == 0:
        raise FeatureError("no hole positions given: nothing to drill (give at least one hole)")
    not_finite = ~np.isfinite(centers).all(axis=1)
    if not_finite.any():
        first = int(np.argmax(not_finite))
        raise FeatureError(f"hole {first + 1}: position {format_uv(centers[first])} is not a finite number")
    for index, center in enumerate(centers, start=1):   # refuse before planning anything
        check_fits(face, swept_region(center, cutting.tool_radius), _hole_name(index, center, cutting),
                   advice=partial(hole_advice, face, center, cutting.tool_diameter, _disc))
    _refuse_repeated(centers, resolution)

    depths = (pass_depths(params.depth, params.peck, resolution=resolution, key="peck") if params.peck > 0
              else np.array([params.depth]))
    count = len(centers)
    builder = ToolpathBuilder(face)
    pecking = f", pecks of {params.peck:.3f} mm" if len(depths) > 1 else ""
    dwelling = f", dwell {params.dwell:g} s" if params.dwell > 0 else ""
    start_program(
        builder,
        cutting,
        f"drill {count} hole{'s' if count > 1 else ''} Ø{cutting.tool_diameter:.3f} on face {face.index}: "
        f"depth {params.depth:.3f} mm{pecking}{dwelling}",
    )
    # the pecks between the approach and the retract: the shared drilling cycle's heights and moves
    cycle = DrillCycle(depth=params.depth, clearance=params.clearance, retract=params.retract,
                       feed=cutting.plunge_feed, pecking=Pecking.FULL_RETRACT if len(depths) > 1 else Pecking.NONE,
                       peck=params.peck, gap=params.reapproach_gap, dwell=params.dwell)
    heights, kinds, bottom = drill_pattern(cycle, depths=depths)
    for index, center in enumerate(centers, start=1):
        builder.comment(f"hole {index}/{count} at {format_uv(center)}")
        approach(builder, center, params.clearance, params.retract, f"hole {index} approach")
        peck, previous = 0, MoveKind.RAPID
        for height, kind in zip(heights[1:bottom + 1].tolist(), kinds[1:bottom + 1].tolist(), strict=True):
            if kind == MoveKind.FEED:
                peck += 1
                builder.step(f"hole {index} peck {peck} feed" if len(depths) > 1 else f"hole {index} feed")
                builder.feed(_on_axis(center, height), cutting.plunge_feed)
            elif previous == MoveKind.FEED:            # out to clear the chips
                builder.step(f"hole {index} peck {peck} clear")
                builder.rapid(_on_axis(center, height))
            else:                                      # back to just above the bottom
                builder.step(f"hole {index} peck {peck + 1} reapproach")
                builder.rapid(_on_axis(center, height))
            previous = kind
        if params.dwell > 0:
            builder.event(EventKind.DWELL, value=float(params.dwell))
        depart(builder, center, params.clearance, params.retract, f"hole {index} retract")
    end_program(builder, cutting)
    return builder.build()
