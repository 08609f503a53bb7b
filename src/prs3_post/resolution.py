"""What the output can show: rows a program would print as no move at all.

A program's numbers have fixed decimals (the dialect's ``decimals.length``), so two points closer
than one output unit may print the same words. Such a row is no move on the machine, yet it would
be written: a ``G1 F..`` with no axis word (LinuxCNC runs it as a pause of 1/F min, and its F gives
the next move's tip feed for a start point the machine never went to), or a plunge of 1e-5 mm that
prints as a sideways stage move because only the stage word rounds differently. The pipeline drops
those rows (:func:`visible_moves`); the operations avoid making them in the first place (depth
passes and contour points closer than :func:`length_resolution` are merged).
"""

from __future__ import annotations

import numpy as np

from prs3_post.emit.gcode import format_word
from prs3_post.types import BoolArray, FloatArray

__all__ = ["length_resolution", "visible_moves"]


def length_resolution(decimals: int) -> float:
    """mm, one unit of the last printed digit of a length with ``decimals`` digits after the point.

    >>> length_resolution(4), length_resolution(3)
    (0.0001, 0.001)
    """
    return 10.0 ** -decimals


def visible_moves(joints: FloatArray, decimals: int, *, tip: FloatArray | None = None,
                  axis: FloatArray | None = None) -> BoolArray:
    """Which rows make a move the program can show, measured from the last row that is kept.

    Row 0 is always kept. Row i is dropped when its axis words, formatted as the emitter formats
    them (:func:`~prs3_post.emit.gcode.format_word`: fixed decimals, ``-0`` as ``0``), all equal
    those of the last kept row (it would print as no move), or, given ``tip`` and ``axis``, when
    its tip is less than half an output unit from that row's with the same tool axis (a move
    smaller than the program can show, which would print as a one-unit step of whichever word
    happens to round the other way). Every kept row after row 0 changes at least one word.

    Only rows that move no joint by more than one output unit from the row before, or the tip by
    less than half a unit, or that follow a dropped row, are compared one by one: a row that
    moves a joint by more than one unit from a kept row prints a new word (two values that print
    the same lie within one unit of each other).

    Parameters
    ----------
    joints : (N, K) float — the printed axes of each row (stage X, Y and strokes: mm)
    decimals : int — digits after the point of those words
    tip : (N, 3) float, optional — mm, the tool tip of each row
    axis : (N, 3) float, optional — the unit tool axis of each row (needed with ``tip``)

    Returns
    -------
    keep : (N,) bool

    Examples
    --------
    >>> visible_moves(np.array([[0.0, 1.0], [0.00004, 1.0], [0.00006, 1.0], [0.00011, 1.0]]), 4).tolist()
    [True, False, True, False]
    >>> tip = np.array([[0.0, 0, 0], [0.00003, 0, 0], [0.0003, 0, 0]])
    >>> visible_moves(np.array([[0.0], [0.0001], [0.0003]]), 4, tip=tip, axis=np.tile([0.0, 0, 1], (3, 1))).tolist()
    [True, False, True]
    """
    joints = np.asarray(joints, dtype=np.float64)
    n = len(joints)
    keep = np.ones(n, dtype=bool)
    if n < 2:
        return keep
    unit = length_resolution(decimals)
    candidate = np.all(np.abs(np.diff(joints, axis=0)) <= unit * (1.0 + 1e-6), axis=1)  # a little more:
    if tip is not None and axis is not None:                                          # the exact test decides
        close = (np.linalg.norm(np.diff(tip, axis=0), axis=1) < 0.5 * unit) & np.all(np.diff(axis, axis=0) == 0, axis=1)
        candidate |= close

    def words(row: int) -> list[str]:
        return [format_word("", float(v), decimals) for v in joints[row]]

    def same_place(row: int, other: int) -> bool:
        return (tip is not None and axis is not None and bool(np.all(axis[row] == axis[other]))
                and float(np.linalg.norm(tip[row] - tip[other])) < 0.5 * unit)

    rows = (np.flatnonzero(candidate) + 1).tolist()
    last, last_words = 0, words(0)
    index, after_drop = 0, -1
    while True:
        if after_drop >= 0 and (index == len(rows) or after_drop < rows[index]):
            row, after_drop = after_drop, -1                # the row after a dropped one: always compared
        elif index < len(rows):
            row = rows[index]
            index += 1
            if row == after_drop:
                after_drop = -1
        else:
            break
        if keep[row - 1] and row - 1 != last:              # the row before was kept: it is the reference
            last, last_words = row - 1, words(row - 1)
        here = words(row)
        if here == last_words or same_place(row, last):
            keep[row] = False
            if row + 1 < n:
                after_drop = row + 1
        else:
            last, last_words = row, here
    return keep
