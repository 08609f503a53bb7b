"""Inverse and forward kinematics of the 3-PRS head: pure numpy, batched along the first axis.

:func:`inverse` dispatches on :class:`IKModel`; :func:`forward` is in :mod:`.forward`. Kinematics
reports (``reachable``, ``converged`` masks); the stage that knows the source lines raises.
"""

from __future__ import annotations

import enum

import numpy as np

from prs3_post.core.errors import PoseError
from prs3_post.core.rowwise import row_lengths, same_rows
from prs3_post.core.types import FloatArray, IntArray
from prs3_post.kinematics.prs3.exact import AxisMemo, IKResult, inverse_exact
from prs3_post.kinematics.prs3.forward import FKResult, forward
from prs3_post.machine.model import Geometry

__all__ = ["AxisMemo", "FKResult", "IKModel", "IKResult", "PoseError", "forward", "inverse", "unit_axes"]


class IKModel(enum.Enum):
    """Which inverse kinematics turns a tool pose into machine axes."""

    EXACT = "exact"
    """Rigid platform; the XY stage supplies the tip's x, y that the head's parasitic motion misses."""
    HEAD = "head"
    """Rigid platform, no stage: only poses whose parasitic x, y equal the target are reachable."""
    PAPER = "paper"
    """The paper's per-leg method (not rigid): for validation against its tables only."""


#: mm: how far the head's own tip may miss the target on a machine without a stage.
HEAD_XY_TOL = 1e-6


def unit_axes(
    tip: FloatArray, axis: FloatArray, *, row_name: str = "row", row_numbers: IntArray | None = None
) -> FloatArray:
    """Check poses and return the axes scaled to unit length.

    Parameters
    ----------
    tip : (N, 3) float — mm
    axis : (N, 3) float — any length > 0, pointing from the tip toward the spindle (a_z > 0)
    row_name : how a row is called in the message (``row``, ``line``)
    row_numbers : (N,) int, optional — the number shown for each row (default 0 … N−1)

    Returns
    -------
    (N, 3) float — unit axes

    Raises
    ------
    PoseError
        Naming the offending rows (at most 10 listed, each number once) for each problem.

    >>> unit_axes(np.zeros((1, 3)), np.array([[0.0, 0.0, 2.0]])).tolist()
    [[0.0, 0.0, 1.0]]
    """
    tip = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
    axis = np.asarray(axis, dtype=np.float64).reshape(-1, 3)
    one = len(axis) > 1 and same_rows(axis)         # one axis on every row (3-axis, 3+2): scaled once
    given = axis[:1] if one else axis
    length = row_lengths(given)
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = given / length[:, None]
    if (np.isfinite(tip).all() and np.isfinite(given).all() and (length > 1e-12).all()
            and (unit[:, 2] > 0.0).all()):              # no problem: the rows named below are none
        if not one:
            return unit
        repeated = np.zeros((len(axis), 3))               # a column at a time (np.repeat: 3 values a row)
        for column in range(3):
            repeated[:, column] = unit[0, column]
        return repeated
    return _named_problems(tip, axis, row_name, row_numbers)


def _named_problems(tip: FloatArray, axis: FloatArray, row_name: str, row_numbers: IntArray | None) -> FloatArray:
    """:func:`unit_axes` row by row: raise the PoseError that names every bad row (or return the unit
    axes, when there is none)."""
    length = row_lengths(axis)
    finite = np.isfinite(tip).all(axis=1) & np.isfinite(axis).all(axis=1)
    nonzero = finite & (length > 1e-12)
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = axis / length[:, None]
    upward = nonzero & (unit[:, 2] > 0.0)
    problems = []
    for mask, what in (
        (~finite, "a value is NaN or infinite"),
        (finite & ~nonzero, "the axis has zero length"),
        (nonzero & ~upward, "the axis points away from the spindle (axis z must be > 0)"),
    ):
        rows = np.flatnonzero(mask)
        if len(rows):
            numbers = rows if row_numbers is None else np.asarray(row_numbers)[rows]
            _, first = np.unique(numbers, return_index=True)     # several rows of one line: the line once
            numbers = numbers[np.sort(first)]
            shown = ", ".join(str(r) for r in numbers[:10]) + (", ..." if len(numbers) > 10 else "")
            problems.append(f"{row_name}{'s' if len(numbers) > 1 else ''} {shown}: {what}")
    if problems:
        raise PoseError("; ".join(problems))
    return unit


def inverse(geometry: Geometry, tip: FloatArray, axis: FloatArray, *, model: IKModel = IKModel.EXACT,
            memo: AxisMemo | None = None) -> IKResult:
    """Inverse kinematics of N poses with the chosen model.

    Parameters
    ----------
    geometry : Geometry
    tip : (N, 3) float — mm, target tool tip, machine frame
    axis : (N, 3) float — unit tool axes (see :func:`unit_axes`)
    model : IKModel
    memo : AxisMemo, optional — the exact model's terms of axes seen before, kept by the caller
        (:class:`~prs3_post.kinematics.prs3.exact.AxisMemo`; no effect on the result)

    Returns
    -------
    IKResult — for ``HEAD``, ``stage`` is the x, y offset the head cannot make (reachable only
    where it is below ``HEAD_XY_TOL``)
    """
    if model is IKModel.PAPER:
        from prs3_post.kinematics.prs3.paper import inverse_paper  # validation only: the other models never load it

        return inverse_paper(geometry, tip, axis)
    result = inverse_exact(geometry, tip, axis, memo=memo)
    if model is IKModel.HEAD:
        with np.errstate(invalid="ignore"):
            on_target = np.hypot(result.stage[:, 0], result.stage[:, 1]) <= HEAD_XY_TOL
        return IKResult(
            stage=result.stage,
            strokes=result.strokes,
            link_angle=result.link_angle,
            condition=result.condition,
            reachable=result.reachable & on_target,
        )
    return result
