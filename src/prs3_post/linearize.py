"""Subdivide feed moves whose tool axis changes, so the controller's joint-space line stays on path.

The controller interpolates the machine axes (X, Y, T1..T3) linearly. Where the axis is constant
along a move, X, Y and T are affine in the tip (the parasitic shift is constant), so the tip moves
on the straight line exactly. Where the axis changes, the joint-space line is a curve at the tip:
each such move is bisected, inserting the intended pose at the midpoint (tip on the straight
line, axis on the great circle), until forward kinematics of the joint-space interpolation stays
within ``tolerance`` of the intended move at the checked fractions. Every round treats all moves
that still need it at once.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from prs3_post.config import Geometry
from prs3_post.kinematics import IKModel, forward, inverse
from prs3_post.toolpath import MoveKind, Toolpath
from prs3_post.types import FloatArray

#: Fractions of a move where the joint-space interpolation is compared with the intended move.
CHECK_FRACTIONS = np.array([0.25, 0.5, 0.75])


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
    geometry: Geometry, tip: FloatArray, axis: FloatArray, starts: FloatArray, model: IKModel = IKModel.EXACT
) -> FloatArray:
    """Worst tip deviation (mm) of the joint-space line between consecutive poses, per move.

    Parameters
    ----------
    tip, axis : (M + 1, 3) float — poses, machine frame; move k runs from row k to row k + 1
    starts : (K,) int — which moves k to check

    Returns
    -------
    (K,) float — mm, max over CHECK_FRACTIONS of |FK(joint interpolation) − intended tip|
    """
    ik = inverse(geometry, tip, axis, model=model)
    joints = np.column_stack([ik.stage, ik.strokes])                     # (M + 1, 5)
    worst = np.zeros(len(starts))
    for t in CHECK_FRACTIONS:
        mixed = (1.0 - t) * joints[starts] + t * joints[starts + 1]
        fk = forward(geometry, mixed[:, 2:], mixed[:, :2])
        intended = (1.0 - t) * tip[starts] + t * tip[starts + 1]
        gap = np.linalg.norm(fk.tip - intended, axis=1)
        worst = np.maximum(worst, np.where(fk.converged, gap, np.inf))
    return worst


def subdivide_axis_changes(
    geometry: Geometry, path: Toolpath, *, tolerance: float = 0.002, max_rounds: int = 20
) -> Toolpath:
    """Insert intended poses into FEED moves whose axis changes until they stay within ``tolerance``.

    Parameters
    ----------
    geometry : Geometry
    path : Toolpath — machine frame, unit axes
    tolerance : float — mm, allowed tip deviation of the joint-space interpolation
    max_rounds : int — bisection rounds (each halves the moves that still deviate)

    Returns
    -------
    Toolpath — the same rows plus inserted ones (same kind, feed and source as the move's end row)
    """
    kind, tip, axis = path.kind.copy(), path.tip.copy(), path.axis.copy()
    feed, source = path.feed.copy(), path.source.copy()
    # event positions move with the rows they precede: track original row ids
    origin = np.arange(len(kind))
    for _ in range(max_rounds):
        if len(kind) < 2:
            break
        turning = (kind[1:] == MoveKind.FEED) & (np.abs(axis[1:] - axis[:-1]).max(axis=1) > 1e-12)
        starts = np.flatnonzero(turning)
        if not len(starts):
            break
        deviation = joint_path_deviation(geometry, tip, axis, starts)
        starts = starts[deviation > tolerance]
        if not len(starts):
            break
        mid_tip = 0.5 * (tip[starts] + tip[starts + 1])
        mid_axis = slerp(axis[starts], axis[starts + 1], np.full(len(starts), 0.5))
        at = starts + 1                                    # insert before the move's end row
        kind = np.insert(kind, at, kind[at])
        feed = np.insert(feed, at, feed[at])
        source = np.insert(source, at, source[at])
        origin = np.insert(origin, at, -1)
        tip = np.insert(tip, at, mid_tip, axis=0)
        axis = np.insert(axis, at, mid_axis, axis=0)
    # an event before original row r happens before the move to r, i.e. right after row r - 1
    # (and before any row inserted into that move)
    new_index = np.zeros(len(path), dtype=np.int64)
    new_index[origin[origin >= 0]] = np.flatnonzero(origin >= 0)
    events = tuple(
        replace(e, before=0 if e.before == 0 else int(new_index[e.before - 1]) + 1) for e in path.events
    )
    return Toolpath(kind=kind, tip=tip, axis=axis, feed=feed, source=source, events=events,
                    source_labels=path.source_labels)
