"""Drilling cycles along any tool axis, expanded into explicit moves.

A canned cycle cannot run in joint space (DESIGN.md), so each hole becomes RAPID and FEED rows
along its tool axis. Heights are measured along the axis a (unit, tool tip → spindle) from the
hole point p (where the CAM system puts the cycle's GOTO: the top of the hole): the tip is at
p + h·a, h > 0 above the hole, h < 0 inside it.

Per hole, with the cycle's ``clearance`` c, ``depth`` d, ``retract`` r and ``peck`` s:

1. RAPID to h = c (straight from wherever the tool is: the previous hole's retract height);
2. FEED to the first peck depth −min(s, d) (or −d without pecking);
3. pecking, between pecks: *full retract* (G83, APT ``DEEP``): RAPID out to h = c, RAPID back to
   ``gap`` above the previous bottom; *chip break* (G73, APT ``BRKCHP``): RAPID up by ``gap`` only;
   then FEED to the next depth, until −d;
4. a dwell of ``dwell`` s at the bottom (an event after the bottom row, when > 0);
5. RAPID out to h = r.

Every hole of one cycle has the same pattern of heights, so the expansion is one broadcast.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from prs3_post.core.toolpath import MoveKind
from prs3_post.core.types import FloatArray, IntArray

__all__ = ["MAX_PECKS", "DrillCycle", "Pecking", "drill_pattern", "drill_rows", "peck_count"]

#: The most pecks one hole may take (as the operations' most depth passes): more is a typo in the peck
#: depth, and would expand into millions of rows; the readers refuse it, naming the line.
MAX_PECKS = 10_000


class Pecking(enum.Enum):
    """How a drilling cycle clears chips between pecks."""

    NONE = "none"
    """One feed to the full depth (G81/G82, APT ``CYCLE/DRILL``)."""
    FULL_RETRACT = "full_retract"
    """Out to the clearance height between pecks (G83, APT ``CYCLE/DEEP``)."""
    CHIP_BREAK = "chip_break"
    """A short lift between pecks, staying in the hole (G73, APT ``CYCLE/BRKCHP``)."""


@dataclass(frozen=True, slots=True)
class DrillCycle:
    """One drilling cycle: what every hole drilled under it does (lengths in mm along the tool axis).

    Attributes
    ----------
    depth : float — mm, ≥ 0, the bottom is this far below the hole point
    clearance : float — mm, ≥ 0, rapids stop (and the feed starts) this far above the hole point
    retract : float — mm, ≥ 0, height above the hole point after the hole (moves between holes)
    feed : float — mm/min, > 0
    pecking : Pecking
    peck : float — mm, depth per peck (> 0 when pecking)
    gap : float — mm, ≥ 0, full retract: how far above the previous bottom the rapid back stops;
        chip break: how far the tool lifts
    dwell : float — s, ≥ 0, at the bottom

    Raises
    ------
    ValueError
        On a value out of range (the readers check and word the user-facing message first).
    """

    depth: float
    clearance: float
    retract: float
    feed: float
    pecking: Pecking = Pecking.NONE
    peck: float = 0.0
    gap: float = 0.5
    dwell: float = 0.0

    def __post_init__(self) -> None:
        for name in ("depth", "clearance", "retract", "gap", "dwell"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"DrillCycle.{name} must be a finite number ≥ 0, got {value!r}")
        if not (math.isfinite(self.feed) and self.feed > 0):
            raise ValueError(f"DrillCycle.feed must be > 0 mm/min, got {self.feed!r}")
        if self.pecking is not Pecking.NONE and not (math.isfinite(self.peck) and self.peck > 0):
            raise ValueError(f"DrillCycle.peck must be > 0 mm when pecking, got {self.peck!r}")


def peck_count(depth: float, peck: float) -> int:
    """How many pecks of ``peck`` mm (> 0) drill ``depth`` mm (≥ 0): at least 1.

    >>> peck_count(5.0, 2.0), peck_count(4.0, 2.0), peck_count(1.0, 2.0)
    (3, 2, 1)
    """
    if peck >= depth:
        return 1
    return math.ceil(depth / peck - 1e-9)                 # a last peck of 1e-9 x peck is rounding


def _peck_depths(cycle: DrillCycle) -> list[float]:
    if cycle.pecking is Pecking.NONE:
        return [cycle.depth]
    count = peck_count(cycle.depth, cycle.peck)
    return [min(cycle.peck * i, cycle.depth) for i in range(1, count + 1)]


def drill_pattern(cycle: DrillCycle, *, depths: FloatArray | None = None) -> tuple[FloatArray, IntArray, int]:
    """The heights and move kinds of one hole.

    Parameters
    ----------
    cycle : DrillCycle
    depths : (K,) float, optional — mm, the depth of each peck (increasing, the last = ``cycle.depth``)
        when the caller has chosen them (the operations merge a last peck the program cannot show);
        None: ``min(k·peck, depth)``, k = 1, 2, …

    Returns
    -------
    height : (M,) float — mm along the tool axis above the hole point (negative: in the hole)
    kind : (M,) int — :class:`~prs3_post.core.toolpath.MoveKind` of the move to each height
    bottom : int — index of the row at the full depth (the dwell comes after it)
    """
    rapid, feed = int(MoveKind.RAPID), int(MoveKind.FEED)
    heights: list[float] = [cycle.clearance]
    kinds: list[int] = [rapid]
    previous = 0.0
    for number, depth in enumerate(_peck_depths(cycle) if depths is None else [float(d) for d in depths]):
        if number:
            if cycle.pecking is Pecking.FULL_RETRACT:
                heights += [cycle.clearance, -previous + cycle.gap]
                kinds += [rapid, rapid]
            else:
                heights.append(-previous + cycle.gap)
                kinds.append(rapid)
        heights.append(-depth)
        kinds.append(feed)
        previous = depth
    bottom = len(heights) - 1
    heights.append(cycle.retract)
    kinds.append(rapid)
    return np.array(heights), np.array(kinds, dtype=np.int64), bottom


def drill_rows(points: FloatArray, axes: FloatArray, cycle: DrillCycle) -> tuple[FloatArray, IntArray, IntArray]:
    """Every hole of a cycle as rows, hole after hole.

    Parameters
    ----------
    points : (K, 3) float — mm, hole points (top of each hole)
    axes : (K, 3) float — unit tool axis (tip → spindle) of each hole
    cycle : DrillCycle

    Returns
    -------
    tip : (K·M, 3) float — mm, rows of hole 0, then hole 1, …
    kind : (K·M,) int — MoveKind values
    bottom : (K,) int — the row index at the full depth of each hole (a dwell follows it)

    >>> tip, kind, bottom = drill_rows(np.zeros((1, 3)), np.array([[0.0, 0, 1]]), DrillCycle(2.0, 3.0, 5.0, 100.0))
    >>> tip[:, 2].tolist(), kind.tolist(), bottom.tolist()
    ([3.0, -2.0, 5.0], [0, 1, 0], [1])
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    axes = np.asarray(axes, dtype=np.float64).reshape(-1, 3)
    height, kind, bottom = drill_pattern(cycle)
    tip = points[:, None, :] + height[None, :, None] * axes[:, None, :]       # (K, M, 3)
    count = len(points)
    return (tip.reshape(-1, 3), np.tile(kind, count),
            np.arange(count, dtype=np.int64) * len(height) + bottom)
