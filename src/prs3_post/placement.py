"""Where to put the part when the setup does not fit: a computed part origin, checked before it is offered.

Moving the part by d (machine frame) moves every tool tip by d and leaves every tool axis as it
is. With an XY stage, the stage takes x and y (stage X, Y shift by dx, dy) and the head only
translates along z (every stroke shifts by dz); link angles, tilt and condition number depend on
the axis alone. So each limit bounds one component of d: per point and limit, an interval; the
intersection over all points is the shifts that keep that limit. Without a stage the head's own
x, y offset must be zero: dx, dy are then fixed by the path.

:func:`suggest_origin` measures how each limit's value moves with a unit shift along x, y and z
(rather than assuming the signs), intersects the intervals, takes the centre of each, and re-runs
the whole post-processing at that origin: a suggestion is only made when it passes.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from prs3_post.config import Machine
from prs3_post.errors import LimitError, ReachError
from prs3_post.kinematics import HEAD_XY_TOL, IKModel, PoseError, inverse, unit_axes
from prs3_post.limits import check_limits
from prs3_post.pipeline import machine_path, model_for, place_toolpath, post_process
from prs3_post.readers.header import exact_text
from prs3_post.setup import Setup, SetupError
from prs3_post.toolpath import Toolpath
from prs3_post.types import FloatArray

#: A value that moves by less than this (per mm of shift) does not depend on that shift direction.
_INDEPENDENT = 1e-6


class Placement(Exception):
    """The main job does not fit the machine with its setup: mixed into the limit or reach error.

    The message is the original error's, plus the setup used and, where a translation of the part
    puts every point inside every limit, that part origin (also as data).

    Attributes
    ----------
    setup : Setup — the setup used
    suggested_origin : (3,) str | None — mm, a part origin checked to work, as exact decimal texts
        (None: no translation does)
    """

    def __init__(self, message: str, *, setup: Setup, suggested_origin: tuple[str, str, str] | None):
        super().__init__(message)
        self.setup, self.suggested_origin = setup, suggested_origin


class PlacementLimitError(Placement, LimitError):
    """A :class:`LimitError` of the main job's path, with its :class:`Placement` data."""


class PlacementReachError(Placement, ReachError):
    """A :class:`ReachError` of the main job's path, with its :class:`Placement` data."""


def _values(machine: Machine, path: Toolpath, shift: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Every limit's value on the path moved by ``shift``, with its bounds: (N, L), (L,), (L,).

    Without a stage, the head's x, y offset (which must be 0) is added as two more limits.
    """
    model = model_for(machine)
    ik = inverse(machine.geometry, path.tip + shift, path.axis, model=model)
    report = check_limits(machine, ik, path.axis)
    value, low, high = report.value, report.low, report.high
    if model is IKModel.HEAD:
        bound = HEAD_XY_TOL / 2.0                      # a box inside the round tolerance
        value = np.column_stack([value, ik.stage])
        low, high = np.append(low, [-bound, -bound]), np.append(high, [bound, bound])
    return value, low, high


def _shift_range(value: FloatArray, slope: FloatArray, low: FloatArray, high: FloatArray) -> tuple[float, float]:
    """The interval of shifts t with low ≤ value + slope·t ≤ high for every entry (may be empty: lo > hi)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        a, b = (low - value) / slope, (high - value) / slope
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    return float(np.max(lo, initial=-np.inf)), float(np.min(hi, initial=np.inf))


def shift_ranges(machine: Machine, path: Toolpath) -> FloatArray | None:
    """(3, 2) mm — for x, y, z, the interval of part shifts that keeps every point inside every limit
    (machine-frame path); None when no translation can (a limit that does not move with the part is
    already broken, a value moves with more than one direction, or an interval is empty)."""
    value, low, high = _values(machine, path, np.zeros(3))
    if not np.isfinite(value).all():                   # a pose that does not assemble: the axis, not the place
        return None
    slopes = [_values(machine, path, unit)[0] - value for unit in np.eye(3)]   # per mm along x, y, z
    moves = np.stack([np.abs(s) > _INDEPENDENT for s in slopes])                # (3, N, L)
    if (moves.sum(axis=0) > 1).any():
        return None
    ranges = np.zeros((3, 2))
    for k in range(3):
        ranges[k] = _shift_range(value[moves[k]], slopes[k][moves[k]],
                                 np.broadcast_to(low, value.shape)[moves[k]],
                                 np.broadcast_to(high, value.shape)[moves[k]])
    fixed = ~moves.any(axis=0)
    with np.errstate(invalid="ignore"):
        inside = (value >= low) & (value <= high)
    if not inside[fixed].all() or (ranges[:, 0] > ranges[:, 1]).any():
        return None
    return ranges


def suggest_origin(machine: Machine, path_part: Toolpath, setup: Setup, *, tolerance: float,
                   length_decimals: int | None = None) -> tuple[str, str, str] | None:
    """A part origin (mm, machine frame; same rotation) at which the whole path passes post-processing.

    The centre of every allowed shift interval (:func:`shift_ranges`), rounded to 0.1 mm where that
    still passes; checked by running :func:`~prs3_post.pipeline.post_process` with it. Returned as
    the decimal texts (x, y, z) whose values were checked; None when no translation passes.
    """
    try:
        placed = place_toolpath(path_part, setup)
        path = replace(placed, axis=unit_axes(placed.tip, placed.axis))
    except PoseError:
        return None
    # The points as given first: a limit no shift can cure (a tilt past the machine's) ends it here,
    # before subdivision, which cannot converge on moves that cross a singularity.
    if shift_ranges(machine, path) is None:
        return None
    try:
        path = machine_path(machine, path_part, setup, tolerance=tolerance)
    except ReachError:
        return None
    ranges = shift_ranges(machine, path)
    if ranges is None:
        return None
    # An unbounded side (no limit in that direction) keeps the current origin in that direction.
    centre = np.where(np.isfinite(ranges).all(axis=1), ranges.mean(axis=1),
                      np.clip(np.zeros(3), ranges[:, 0], ranges[:, 1]))
    for decimals in (1, 3, 6):
        texts = tuple(exact_text(v, decimals) for v in np.round(np.asarray(setup.origin) + centre, decimals))
        try:
            post_process(machine, path_part, setup.with_origin(tuple(float(t) for t in texts)), tolerance=tolerance,
                         length_decimals=length_decimals)
        except (LimitError, ReachError, SetupError):
            continue
        return texts  # type: ignore[return-value]
    return None


def placement_error(error: LimitError | ReachError, machine: Machine, path_part: Toolpath, setup: Setup, *,
                    tolerance: float, length_decimals: int | None = None) -> Placement:
    """``error`` (the same kind) with the setup used and, where one exists, a part origin that works."""
    origin = suggest_origin(machine, path_part, setup, tolerance=tolerance, length_decimals=length_decimals)
    if origin is None:
        advice = "no translation of the part puts every point inside the machine's limits"
    else:
        advice = f"a part origin at machine [{', '.join(origin)}] mm puts every point inside the machine's limits"
    kind = PlacementReachError if isinstance(error, ReachError) else PlacementLimitError
    return kind(f"{error}; setup: {setup.describe()}; {advice}", setup=setup, suggested_origin=origin)
