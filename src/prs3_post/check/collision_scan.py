"""What the collision check can say about a joint program's motion before replaying it (pure numpy and FK).

verify's replay (:func:`prs3_post.check.verify.replay`) samples every move and runs FK on the samples; on a
long program most of that motion is far from the part. This pass walks the program
``SCAN_ROWS`` rows at a time and keeps, for each group of ``GROUP_ROWS`` rows, a representative
pose and how far the group's motion may stray from it, so that :mod:`prs3_post.check.collision` can bound
a whole group against the part and replay only the groups that may come near it.

The poses of the rows' end points are the replay's own: the FK of the rows' distinct head poses up
to a common stroke shift (:func:`prs3_post.kinematics.replay.shift_keys`: the guides are parallel, so adding
``s`` to every stroke moves the head by −s along z and changes nothing else), shifted by the stage
and the common stroke. A move's samples lie on its joint-space segment, so their stage and common
stroke lie between the two rows', and their head pose key (T2 − T1, T3 − T1) between the two keys:

* tip: |tip − tip₀| ≤ max over the group's rows of |(X, Y, −T1) − (X₀, Y₀, −T1₀)| plus the head's
  own change, at most ``SAFETY`` · J · |Δkey| (J: Σ |∂tip/∂key_j|, central differences at the
  representative key; the keys of a group differ by at most ``FLAT_KEY_MM``, where FK is linear
  to far better than that factor of 2);
* axis: |a − a₀| ≤ ``SAFETY`` · J_axis · |Δkey| likewise (0 where the keys are equal: a stretch of
  constant tool axis, the common case).

A head whose joints have no common shift (a head as built with rails not quite parallel: the
kinematics' ``shift_direction`` is None) keys its poses by all of its strokes (T1, T2, T3) and its
tip's part besides the head is the stage (X, Y, 0) alone.

A group is "flat" (bounded as a whole) when its rows' keys are within ``FLAT_KEY_MM`` of its
representative's and every row's head assembles; group 0 never is (its first pose is where the
check looks for a body inside the part). The representative is the row before the group (the start
of its first move; row 0 for group 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prs3_post.core.toolpath import JointProgram, MoveKind
from prs3_post.core.types import BoolArray, FloatArray
from prs3_post.kinematics.replay import forward_parts, head_shift, shift_keys
from prs3_post.machine.model import Machine

__all__ = ["FLAT_KEY_MM", "GROUP_ROWS", "SCAN_ROWS", "Scan", "scan_program"]

#: Rows per group (a group is bounded as a whole, or replayed).
GROUP_ROWS = 64
#: Rows scanned at a time (memory); groups never straddle two scans when this is a multiple of GROUP_ROWS.
SCAN_ROWS = 1 << 16
#: mm: the most a group's head pose keys (T2 − T1, T3 − T1) may differ from its representative's.
FLAT_KEY_MM = 0.01
#: The linearised head motion is taken this many times over (as verify's sampling bound is).
SAFETY = 2.0
#: mm: the stroke step of the central differences.
_STEP = 1e-3


@dataclass(frozen=True, slots=True)
class Scan:
    """A program's feed tips and its groups (:data:`GROUP_ROWS` rows each), machine frame.

    Attributes
    ----------
    feed_tips : (M, 3) float — mm, the end tips of the FEED rows, in order (as the replay's)
    tip, axis : (G, 3) float — mm, unit: each group's representative pose (its tip: the centre of the box)
    half : (G, 3) float — mm, every tip of the group's motion is within ``half`` of ``tip`` along each
        axis of the scan's frame
    turn : (G,) float — the largest chord between any axis of the group's motion and ``axis``
    wobble : (G,) float — mm, the most a tip may stray from the straight line between its move's end
        tips (the head's own change, linearised)
    feeding : (G,) bool — the group's rows and the row before are FEED rows
    flat : (G,) bool — ``half`` and ``turn`` hold (else the group is replayed)
    """

    feed_tips: FloatArray
    tip: FloatArray
    axis: FloatArray
    half: FloatArray
    turn: FloatArray
    wobble: FloatArray
    feeding: BoolArray
    flat: BoolArray


def scan_program(machine: Machine, program: JointProgram, frame: FloatArray) -> Scan:
    """The :class:`Scan` of ``program`` (module docstring), :data:`SCAN_ROWS` rows at a time; ``frame``
    (3, 3): a machine-frame vector ``x`` has the box coordinates ``x @ frame`` (orthonormal)."""
    n = len(program)
    rows = max(GROUP_ROWS, SCAN_ROWS - SCAN_ROWS % GROUP_ROWS)
    parts: list[tuple[FloatArray, ...]] = []
    feed_tips = np.zeros((int(np.count_nonzero(program.kind == MoveKind.FEED)), 3))   # filled, not joined (memory)
    filled = 0
    for lo in range(0, n, rows):
        hi = min(n, lo + rows)
        feed, *group = _scan_rows(machine, program, lo, hi, frame)
        feed_tips[filled:filled + len(feed)] = feed
        filled += len(feed)
        parts.append(tuple(group))
    shapes = ((0, 3), (0, 3), (0, 3), (0,), (0,), (0,), (0,))
    columns = [np.concatenate([p[k] for p in parts]) if parts else np.zeros(shape) for k, shape in enumerate(shapes)]
    flat = columns[6].astype(bool)
    if len(flat):
        flat[0] = False
    return Scan(feed_tips=feed_tips, tip=columns[0], axis=columns[1],
                half=columns[2], turn=columns[3], wobble=columns[4], feeding=columns[5].astype(bool), flat=flat)


def _scan_rows(machine: Machine, program: JointProgram, lo: int, hi: int, frame: FloatArray
               ) -> tuple[FloatArray, ...]:
    """Rows ``lo`` .. ``hi`` (``lo`` a multiple of GROUP_ROWS), with the row before: the feed tips and
    the groups' tip, axis, half, turn, wobble, feeding and flat (the last two as 0/1)."""
    start = max(lo - 1, 0)
    stage, strokes = program.stage[start:hi], program.strokes[start:hi]
    direction = head_shift(machine)
    canonical, index = shift_keys(strokes, shift=direction is not None)
    key_tip, key_axis, _, key_ok = forward_parts(machine, [canonical])[0]
    linear = _linear_part(stage, strokes, direction)             # (X, Y, −T1): the tip's part besides the head's
    feed = np.flatnonzero(program.kind[lo:hi] == MoveKind.FEED) + (lo - start)
    feed_tips = np.take(key_tip, index[feed], axis=0) + linear[feed]
    # the groups: rows [g·G, (g+1)·G) with the row before as the representative (row 0 for group 0)
    own = np.arange(lo, hi) - start                               # local index of each row of the groups
    owner = (np.arange(lo, hi) // GROUP_ROWS) - lo // GROUP_ROWS
    firsts = np.flatnonzero(np.diff(owner, prepend=-1))           # each group's first row, in ``own``
    ref = np.maximum(own[firsts] - 1, 0)
    ref_of = ref[owner]
    box = linear @ frame                                          # the box's coordinates of (X, Y, −T1)
    low = np.minimum(np.minimum.reduceat(box[own], firsts), box[ref]) if len(own) else np.zeros((0, 3))
    high = np.maximum(np.maximum.reduceat(box[own], firsts), box[ref]) if len(own) else np.zeros((0, 3))
    first_key = 0 if direction is None else 1                     # T1 is the shift, not a key, on parallel guides
    keys = canonical[index, first_key:]
    key_gap = np.abs(keys[own] - keys[ref_of]).max(axis=1)
    dkey = np.maximum.reduceat(key_gap, firsts) if len(own) else np.zeros(0)
    ok = key_ok[index]
    flat = np.logical_and.reduceat(ok[own], firsts) & ok[ref] & (dkey <= FLAT_KEY_MM) if len(own) else \
        np.zeros(0, dtype=bool)
    fed = program.kind[start:hi] == MoveKind.FEED
    feeding = np.logical_and.reduceat(fed[own], firsts) & fed[ref] if len(own) else np.zeros(0, dtype=bool)
    turn = np.zeros(len(firsts))
    wobble = np.zeros(len(firsts))
    moving = np.flatnonzero(flat & (dkey > 0))
    if len(moving):                                               # the head's own change: linearised, ×SAFETY
        tip_rate, axis_rate = _rates(machine, canonical[index[ref[moving]]], first_key)
        wobble[moving] = SAFETY * tip_rate * dkey[moving]
        turn[moving] = SAFETY * axis_rate * dkey[moving]
        flat[moving] &= np.isfinite(tip_rate) & np.isfinite(axis_rate)
    tip = np.take(key_tip, index[ref], axis=0) + (0.5 * (low + high)) @ frame.T
    axis = np.take(key_axis, index[ref], axis=0)
    half = 0.5 * (high - low) + wobble[:, None]
    return (feed_tips, tip, axis, half, turn, wobble, feeding.astype(np.float64), flat.astype(np.float64))


def _linear_part(stage: FloatArray, strokes: FloatArray, direction: FloatArray | None) -> FloatArray:
    """(N, 3) mm: the tip's motion besides the head pose key's: the stage (X, Y, 0) plus the common
    shift T1 along ``direction`` ((X, Y, −T1) on parallel vertical guides); the stage alone without one."""
    linear = np.column_stack([stage, np.zeros(len(stage))])
    if direction is None:
        return linear
    if direction[0] == 0.0 and direction[1] == 0.0 and direction[2] == -1.0:
        linear[:, 2] = -strokes[:, 0]
        return linear
    return linear + strokes[:, :1] * direction


def _rates(machine: Machine, canonical: FloatArray, first_key: int) -> tuple[FloatArray, FloatArray]:
    """(K,), (K,): Σ_j |∂tip/∂key_j| (mm/mm) and Σ_j |∂axis/∂key_j| (1/mm) at head pose keys (K, 3)
    (strokes with T1 = 0, ``first_key`` 1; or whole strokes, 0), by central differences in the keys."""
    parts = []
    for leg in range(first_key, canonical.shape[1]):
        delta = np.zeros(canonical.shape[1])
        delta[leg] = _STEP
        parts += [canonical + delta, canonical - delta]
    fk = forward_parts(machine, parts)
    tip_rate = np.zeros(len(canonical))
    axis_rate = np.zeros(len(canonical))
    for k in range(len(fk) // 2):
        plus, minus = fk[2 * k], fk[2 * k + 1]
        tip_rate += np.linalg.norm(plus[0] - minus[0], axis=1) / (2 * _STEP)
        axis_rate += np.linalg.norm(plus[1] - minus[1], axis=1) / (2 * _STEP)
    return tip_rate, axis_rate
