"""Subdivide feed moves whose tool axis changes, so the controller's joint-space line stays on path.

The controller interpolates the machine axes (X, Y, T1..T3) linearly. Where the axis is constant
along a move, X, Y and T are affine in the tip (the parasitic shift is constant), so the tip moves
on the straight line exactly. Where the axis changes, the joint-space line is a curve at the tip:
each such move is bisected, inserting the intended pose at the midpoint (tip on the straight
line, axis on the great circle), until forward kinematics of the joint-space interpolation stays
within ``tolerance`` (mm) of the intended tip and within ``angle_tolerance`` (rad) of the intended
axis at the checked fractions. Every round treats all moves that still need it at once.

Each move is bisected on its own end points alone, so a path cut into chunks gets the same rows:
:func:`subdivide_axis_changes` takes the pose the machine is at before a chunk's first row
(``start``), as the streaming pipeline carries it from the chunk before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from prs3_post.core.errors import LimitError
from prs3_post.core.toolpath import MoveKind, Toolpath
from prs3_post.core.types import FloatArray, IntArray
from prs3_post.kinematics import IKModel
from prs3_post.kinematics.registry import Kinematics, as_kinematics
from prs3_post.machine.model import Geometry

#: Bisection rounds before a move that still strays is an error. Halving a move divides its
#: deviation by about 4, so 14 rounds take a deviation of 500 mm (more than this machine can stray)
#: below 0.0001 mm; a move that needs more passes a singularity, and each round doubles its rows.
MAX_ROUNDS = 14

#: Fractions of a move where the joint-space interpolation is compared with the intended move.
CHECK_FRACTIONS = np.array([0.25, 0.5, 0.75])

#: Rows :func:`linearize` may insert into one move before it gives up on it (a move that keeps
#: doubling passes near a singularity; bisecting on would only cost time and memory).
MAX_INSERTED = 1000


def slerp(a: FloatArray, b: FloatArray, t: FloatArray) -> FloatArray:
    """Unit vectors on the great circle from ``a`` to ``b`` at fractions ``t`` (all (N, 3) / (N,))."""
    cos_angle = np.clip(np.sum(a * b, axis=1), -1.0, 1.0)       # clip: rounding past ±1
    angle = np.arccos(cos_angle)
    small = angle < 1e-9
    sin_angle = np.where(small, 1.0, np.sin(angle))
    wa = np.where(small, 1.0 - t, np.sin((1.0 - t) * angle) / sin_angle)
    wb = np.where(small, t, np.sin(t * angle) / sin_angle)
    out = wa[:, None] * a + wb[:, None] * b
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def joint_path_deviation(
    geometry: Geometry | Kinematics, tip: FloatArray, axis: FloatArray, starts: IntArray,
    model: IKModel = IKModel.EXACT) -> FloatArray:
    """(K,) float — mm, the worst tip deviation of each move: the first half of :func:`joint_path_deviations`."""
    return joint_path_deviations(geometry, tip, axis, starts, model)[0]


def joint_path_deviations(
    geometry: Geometry | Kinematics, tip: FloatArray, axis: FloatArray, starts: IntArray,
    model: IKModel = IKModel.EXACT) -> tuple[FloatArray, FloatArray]:
    """Worst tip deviation (mm) and worst axis deviation (rad) of the joint-space line, per move.

    The intended pose at fraction t of move k: the tip on the straight line, the axis on the great
    circle (:func:`slerp`) between the move's end poses.

    Parameters
    ----------
    tip, axis : (M + 1, 3) float — poses, machine frame; move k runs from row k to row k + 1
    starts : (K,) int — which moves k to check

    Returns
    -------
    tip_deviation : (K,) float — mm, max over CHECK_FRACTIONS of |FK tip − intended tip|
    angle_deviation : (K,) float — rad, max over CHECK_FRACTIONS of the angle from the intended axis
        to the FK axis (inf where FK does not converge)
    """
    starts = np.asarray(starts, dtype=np.int64)
    kinematics = as_kinematics(geometry)
    ik = kinematics.inverse(tip, axis, model=model)
    joints = np.column_stack([ik.stage, ik.strokes])                     # (M + 1, 2 + J)
    worst = np.zeros(len(starts))
    worst_angle = np.zeros(len(starts))
    for t in CHECK_FRACTIONS:
        mixed = (1.0 - t) * joints[starts] + t * joints[starts + 1]
        fk = kinematics.forward(mixed[:, 2:], mixed[:, :2])
        intended = (1.0 - t) * tip[starts] + t * tip[starts + 1]
        gap = np.linalg.norm(fk.tip - intended, axis=1)
        worst = np.maximum(worst, np.where(fk.converged, gap, np.inf))
        intended_axis = slerp(axis[starts], axis[starts + 1], np.full(len(starts), t))
        # the angle from the chord's length: exact for small angles, unlike arccos of the dot product
        chord = np.linalg.norm(fk.axis - intended_axis, axis=1)
        angle = 2.0 * np.arcsin(np.clip(0.5 * chord, 0.0, 1.0))          # clip: rounding past 1
        worst_angle = np.maximum(worst_angle, np.where(fk.converged, angle, np.inf))
    return worst, worst_angle


@dataclass(frozen=True, slots=True)
class Linearized:
    """A toolpath with its axis-changing moves subdivided, and how far they strayed before and after.

    Attributes
    ----------
    path : Toolpath — the rows, with the inserted ones
    tip_before, angle_before : float — mm, rad: the worst deviation of the joint-space line of an
        axis-changing feed move as given (0 when there is none)
    tip_after, angle_after : float — mm, rad: the same after the subdivision (within the tolerances)
    """

    path: Toolpath
    tip_before: float
    angle_before: float
    tip_after: float
    angle_after: float


def subdivide_axis_changes(
    geometry: Geometry | Kinematics, path: Toolpath, *, tolerance: float,
    angle_tolerance: float, max_rounds: int = MAX_ROUNDS, max_inserted: int = MAX_INSERTED,
    start: Toolpath | None = None,
) -> Toolpath:
    """Insert intended poses into FEED moves whose axis changes until they stay within the tolerances.

    Parameters and errors as :func:`linearize`; returns its ``path``.
    """
    return linearize(geometry, path, tolerance=tolerance, angle_tolerance=angle_tolerance, max_rounds=max_rounds,
                     max_inserted=max_inserted, start=start).path


def linearize(
    geometry: Geometry | Kinematics, path: Toolpath, *, tolerance: float,
    angle_tolerance: float, max_rounds: int = MAX_ROUNDS, max_inserted: int = MAX_INSERTED,
    start: Toolpath | None = None,
) -> Linearized:
    """Insert intended poses into FEED moves whose axis changes until they stay within the tolerances.

    Parameters
    ----------
    geometry : Geometry or Kinematics — the machine's kinematics (a Geometry: the 3-PRS head's)
    path : Toolpath — machine frame, unit axes
    tolerance : float — mm, allowed tip deviation of the joint-space interpolation
    angle_tolerance : float — rad, allowed angle between its tool axis and the intended one
    max_rounds : int — bisection rounds (each halves the moves that still deviate)
    max_inserted : int — rows that may be inserted into one move
    start : Toolpath, optional — one row, machine frame, unit axis: the pose before ``path``'s first
        row (the last row of the chunk before), so that the move to row 0 is subdivided too

    Returns
    -------
    Linearized — ``path``: the same rows plus inserted ones (same kind, feed and source as the
    move's end row), and the worst deviations before and after

    Raises
    ------
    LimitError
        A move still out of tolerance after ``max_rounds`` bisections, or one that would need more
        than ``max_inserted`` rows (forward kinematics does not converge along it: it passes a
        singularity), naming its source (the move's end row). Either stops the work early: a
        round costs as much as the rows it bisects, which double with every round on such a move.
    """
    head = 0 if start is None else 1
    if start is not None and len(start) != 1:
        raise ValueError(f"subdivide_axis_changes: start must be one row, got {len(start)}")
    if not _turns(path, start):                            # nothing to subdivide: the rows as they are
        return Linearized(path=path, tip_before=0.0, angle_before=0.0, tip_after=0.0, angle_after=0.0)
    if start is not None:
        joined = [start, path]
        kind = np.concatenate([p.kind for p in joined])
        tip, axis = np.concatenate([p.tip for p in joined]), np.concatenate([p.axis for p in joined])
        feed, source = np.concatenate([p.feed for p in joined]), np.concatenate([p.source for p in joined])
    else:
        kind, tip, axis = path.kind.copy(), path.tip.copy(), path.axis.copy()
        feed, source = path.feed.copy(), path.source.copy()
    # event positions move with the rows they precede: track original row ids
    origin = np.arange(len(kind))
    owner = np.arange(len(kind))                           # each row's move, by the original index of its end row
    inserted = np.zeros(len(kind), dtype=np.int64)         # rows inserted so far into each (original) move
    worst: list[tuple[float, float]] = []                  # (tip, angle) of each round's moves
    for round_ in range(max_rounds + 1):
        turning = (kind[1:] == MoveKind.FEED) & (np.abs(axis[1:] - axis[:-1]).max(axis=1) > 1e-12)
        starts = np.flatnonzero(turning)
        if not len(starts):
            break
        deviation, angle = joint_path_deviations(geometry, tip, axis, starts)
        worst.append((float(deviation.max()), float(angle.max())))
        checked = owner[starts + 1]                        # the (original) move of each piece checked
        starts = starts[(deviation > tolerance) | (angle > angle_tolerance)]
        if not len(starts):
            break
        inserted += np.bincount(owner[starts + 1], minlength=len(inserted))
        over = np.flatnonzero(inserted > max_inserted)     # each round costs as much as the rows it bisects
        if round_ == max_rounds or len(over):
            move = int(over[0]) if len(over) else int(owner[starts[0] + 1])
            piece = checked == move
            strays = (f"still strays {float(deviation[piece].max()):.4g} mm / "
                      f"{math.degrees(float(angle[piece].max())):.4g} deg from the intended one after {round_} rounds "
                      f"of bisection (allowed: {tolerance:g} mm, {math.degrees(angle_tolerance):g} deg); the tool "
                      "axis may pass a singularity")
            need = f"to this point would need more than {max_inserted} inserted points: it " if len(over) else ""
            raise LimitError(f"{path.describe(move - head)}: the joint-space move {need}{strays}")
        mid_tip = 0.5 * (tip[starts] + tip[starts + 1])
        mid_axis = slerp(axis[starts], axis[starts + 1], np.full(len(starts), 0.5))
        at = starts + 1                                    # insert before the move's end row
        kind = np.insert(kind, at, kind[at])
        feed = np.insert(feed, at, feed[at])
        source = np.insert(source, at, source[at])
        origin = np.insert(origin, at, -1)
        owner = np.insert(owner, at, owner[at])
        tip = np.insert(tip, at, mid_tip, axis=0)
        axis = np.insert(axis, at, mid_axis, axis=0)
    # an event before original row r happens before the move to r, i.e. right after row r - 1
    # (and before any row inserted into that move); with a start row, path row r is row r + 1 here
    new_index = np.zeros(len(path) + head, dtype=np.int64)
    new_index[origin[origin >= 0]] = np.flatnonzero(origin >= 0)
    events = tuple(
        replace(e, before=0 if e.before + head == 0 else int(new_index[e.before + head - 1]) + 1 - head)
        for e in path.events
    )
    out = Toolpath(kind=kind[head:], tip=tip[head:], axis=axis[head:], feed=feed[head:], source=source[head:],
                   events=events, source_labels=path.source_labels, source_file=path.source_file)
    before, after = (worst[0], worst[-1]) if worst else ((0.0, 0.0), (0.0, 0.0))
    return Linearized(path=out, tip_before=before[0], angle_before=before[1], tip_after=after[0],
                      angle_after=after[1])


def _turns(path: Toolpath, start: Toolpath | None) -> bool:
    """Whether any FEED move of ``path`` (the first one from ``start``) changes the tool axis: the
    first round of :func:`linearize`'s test, without joining the rows."""
    if not len(path):
        return False
    feed = path.kind == MoveKind.FEED
    if start is not None and feed[0] and np.abs(path.axis[0] - start.axis[0]).max() > 1e-12:
        return True
    if len(path) < 2 or not feed[1:].any():
        return False
    axis = path.axis
    if (axis[1:] == axis[:-1]).all():                      # constant axis (3-axis, 3+2): no move turns
        return False
    return bool(((np.abs(axis[1:] - axis[:-1]).max(axis=1) > 1e-12) & feed[1:]).any())
