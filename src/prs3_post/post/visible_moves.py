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

from prs3_post.core.numbers import format_word
from prs3_post.core.rowwise import row_all, row_any, row_lengths, same_rows
from prs3_post.core.types import BoolArray, FloatArray

__all__ = ["VisibleMoves", "length_resolution", "printed_units", "visible_moves"]


def length_resolution(decimals: int) -> float:
    """mm, one unit of the last printed digit of a length with ``decimals`` digits after the point.

    >>> length_resolution(4), length_resolution(3)
    (0.0001, 0.001)
    """
    return 10.0 ** -decimals


def visible_moves(joints: FloatArray, decimals: int, *, tip: FloatArray | None = None,
                  axis: FloatArray | None = None) -> BoolArray:
    """Which rows make a move the program can show.

    Row 0 is always kept. Given ``tip`` and ``axis``, a row first goes when its tip is less than half
    an output unit from the last row kept so far, with the same tool axis (a move smaller than the
    program can show, which would print as a one-unit step of whichever word happens to round the
    other way). Then, of the rows left, a row goes when its axis words, formatted as the emitter
    formats them (:func:`~prs3_post.emit.gcode.format_word`: fixed decimals, ``-0`` as ``0``), all
    equal those of the row left before it: it would print as no move. As such a row prints the same
    as the last kept one, comparing with the row before is comparing with the last kept row. Every
    kept row after row 0 changes at least one word. :class:`VisibleMoves` makes the same choice
    over a program given in chunks.

    Parameters
    ----------
    joints : (N, K) float — the printed axes of each row (stage X, Y and strokes: mm), finite
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
    return VisibleMoves(decimals).keep(joints, tip=tip, axis=axis)


class VisibleMoves:
    """:func:`visible_moves` over a program given in chunks: the same rows kept, whatever the chunking.

    Between chunks it remembers the last row (its tip and axis: the short-step test looks at the
    row before) and the last row the distance test kept (its tip and axis: the reference for the
    distance; its printed words: the reference for "prints as no move"). Only the very first row
    of all is always kept.

    >>> joints = np.array([[0.0, 1.0], [0.00004, 1.0], [0.00006, 1.0], [0.00011, 1.0]])
    >>> guard = VisibleMoves(4)
    >>> [guard.keep(joints[i:i + 1]).tolist() for i in range(4)]
    [[True], [False], [True], [False]]
    """

    def __init__(self, decimals: int):
        self.decimals = decimals
        self._previous: tuple[FloatArray, FloatArray] | None = None          # last row's tip, axis
        self._previous_kept = False                                          # ... kept by the distance test
        self._kept: tuple[FloatArray, FloatArray, FloatArray] | None = None  # last row it kept: tip, axis, joints

    def keep(self, joints: FloatArray, *, tip: FloatArray | None = None,
             axis: FloatArray | None = None, steps: FloatArray | None = None) -> BoolArray:
        """(N,) bool — which rows of this chunk to keep (parameters as :func:`visible_moves`;
        ``steps``: (N − 1,) the lengths of the chunk's tip steps, ``row_lengths(np.diff(tip, axis=0))``,
        when the caller has them)."""
        joints = np.asarray(joints, dtype=np.float64)
        n = len(joints)
        distance = tip is not None and axis is not None
        if distance:
            tip = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
            axis = np.asarray(axis, dtype=np.float64).reshape(-1, 3)
        if n == 0:
            return np.ones(0, dtype=bool)
        # the rows before this chunk that the choice depends on, put in front of it
        head_joints: list[FloatArray] = []
        head_tip: list[FloatArray] = []
        head_axis: list[FloatArray] = []
        if self._kept is not None:
            kept_tip, kept_axis, kept_joints = self._kept
            head_joints.append(kept_joints[None, :])
            head_tip.append(kept_tip[None, :])
            head_axis.append(kept_axis[None, :])
            if distance and not self._previous_kept and self._previous is not None:
                head_joints.append(kept_joints[None, :])            # never compared: it is not kept
                head_tip.append(self._previous[0][None, :])
                head_axis.append(self._previous[1][None, :])
        head = len(head_joints)
        all_joints = np.concatenate([*head_joints, joints]) if head else joints
        keep = np.ones(head + n, dtype=bool)
        if distance:
            assert tip is not None and axis is not None   # distance
            all_tip = np.concatenate([*head_tip, tip]) if head else tip
            all_axis = np.concatenate([*head_axis, axis]) if head else axis
            if head + n >= 2:
                lengths = None if steps is None else np.concatenate(
                    [row_lengths(np.diff(all_tip[:head + 1], axis=0)), steps])   # the head's steps, the chunk's
                keep = _away_from_the_last_kept(all_tip, all_axis, 0.5 * length_resolution(self.decimals),
                                                head=head, lengths=lengths)
        else:
            all_tip = all_axis = np.zeros((head + n, 3))
        every = bool(keep.all())                          # nothing near: no copy of the rows kept
        rows = np.arange(len(keep)) if every else np.flatnonzero(keep)
        last_near, last_kept = int(rows[-1]), bool(keep[-1])   # by the distance test (row 0 always is)
        if len(rows) >= 2:
            printed = printed_units(all_joints if every else all_joints[rows], self.decimals)
            changed = row_any(printed[1:] != printed[:-1])
            if not changed.all():
                keep[rows[1:][~changed]] = False
        # remember for the next chunk
        self._previous = (all_tip[-1].copy(), all_axis[-1].copy())
        self._previous_kept = last_kept
        self._kept = (all_tip[last_near].copy(), all_axis[last_near].copy(), all_joints[last_near].copy())
        return keep[head:]


def _away_from_the_last_kept(tip: FloatArray, axis: FloatArray, near: float, *, head: int = 0,
                             lengths: FloatArray | None = None) -> BoolArray:
    """(N,) bool: False where the tip is within ``near`` mm of the last kept row's, axis unchanged.

    Only rows that step less than ``near`` from the row before (with the same axis) are looked at
    one by one; a longer step keeps its row (leaving the last kept row's neighbourhood by going
    back and forth is not looked for: that is not a sub-resolution move of one row).

    ``head`` rows from the chunk before come first and are not decided again: row 0 is the last
    row kept, row 1 (when ``head`` is 2) the last row, which was not kept. ``lengths`` (N − 1,): the
    steps' lengths, ``row_lengths(np.diff(tip, axis=0))``, when the caller has them.
    """
    keep = np.ones(len(tip), dtype=bool)
    if head == 2:
        keep[1] = False
    short = (row_lengths(np.diff(tip, axis=0)) if lengths is None else lengths) < near
    if not (same_rows(axis) and np.isfinite(axis[0]).all()):   # one finite axis: every step keeps it
        short &= row_all(np.diff(axis, axis=0) == 0)
    rows = (np.flatnonzero(short) + 1).tolist()
    rows = [row for row in rows if row >= head]
    if not rows:
        return keep
    points = tip.tolist()
    last = 0 if head else -1
    for row in rows:
        if row - 1 != last and keep[row - 1]:            # the row before was kept: it is the reference
            last = row - 1
        (x, y, z), (lx, ly, lz) = points[row], points[last]
        if (x - lx) ** 2 + (y - ly) ** 2 + (z - lz) ** 2 < near * near:
            keep[row] = False                            # same axis: a short step keeps it along a run
        else:
            last = row
    return keep


def printed_units(values: FloatArray, decimals: int) -> FloatArray:
    """The values as the emitter prints them, in units of the last digit (whole numbers, as floats).

    Equal where :func:`~prs3_post.emit.gcode.format_word` writes the same text (``-0.00004`` and
    ``0.00004`` are both 0). Scaling rounds, so values within a millionth of a unit of a tie (and
    huge ones) are rounded from their exact decimal text instead.

    >>> printed_units(np.array([0.00015, -0.00004, 1.23456]), 4).tolist()   # 0.00015 is 0.000149999... in binary
    [1.0, 0.0, 12346.0]
    """
    values = np.asarray(values, dtype=np.float64)
    scaled = values * 10.0 ** decimals
    units = np.rint(scaled)
    work = scaled - units                                # one scratch array: the distance to the unit,
    doubtful = np.abs(work, out=work) > 0.5 - 1e-6       # then the size
    if scaled.size and np.abs(scaled, out=work).max() > 2.0 ** 40:   # the scaling's error grows with the value
        doubtful |= work > 2.0 ** 40
    flat_values, flat_units = values.reshape(-1), units.reshape(-1)   # units: a view (a new array)
    for index in np.flatnonzero(doubtful).tolist():
        text = format_word("", float(flat_values[index]), decimals)
        flat_units[index] = float(text.replace(".", ""))
    units += 0.0                                         # -0.0 → 0.0
    return units
