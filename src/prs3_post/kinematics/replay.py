"""Replay a joint program through forward kinematics: sample every move in joint space, FK each sample.

    program rows (X, Y, T1..T3) ──► sample every move in joint space ──► FK (+ exact IK for the
    condition number) ──► tip path, link angles, condition numbers, the sampling bound of every move

Pure: a :class:`~prs3_post.core.toolpath.JointProgram` in, a :class:`Replay` out. What the samples
mean for the machine (limits, straightness, feeds) is :mod:`prs3_post.check.verify`'s; the collision
check takes the samples' tips and axes.

The controller interpolates the machine axes linearly, so the machine passes through the joint
values q(t) = q_{k-1} + t (q_k - q_{k-1}), t in [0, 1], on move k, and its tool tip follows the
curve p(t) = FK(q(t)). Strokes and stage are linear in t, so they can only reach their extremes at
the end points; link angles, tilt, the condition number and the tip's distance from a straight
line are not, so every move is sampled.

Sampling rule and its error bound
---------------------------------
Move k is sampled at t = j/n_k, j = 1 … n_k (t = 0 is the previous move's last sample). Between
two samples h = 1/n_k apart, a smooth f(t) differs from the straight line through its samples
by at most h²/8 · max|f''| (the linear interpolation error). This bounds what sampling can miss
of the tip's deviation from any straight intended chord (whose second derivative is zero:
|d''| = |p''|) and, with f = U·θ_i (U the link length, so that angles count as the length they
move a link end), of the link angles. max|f''| is estimated from second differences of the
samples, |f(t+h) - 2 f(t) + f(t-h)| / h² (= |f''| somewhere in [t-h, t+h]), taken over the
move and doubled for safety (SAFETY): M_k. The rule: probe every move with PROBE_INTERVALS = 8,
then use

    n_k = max(8, ceil(sqrt(SAFETY · M_k / (8 ε))))      (at most MAX_INTERVALS)

with ε = tolerance / 20, recomputing M_k on the denser samples and repeating (never coarsening,
at most REFINE_ROUNDS times) until n_k no longer grows; so the reported bound SAFETY · M_k h² / 8
(per move, from the final samples) is ≤ ε: the worst deviation between samples exceeds the worst sampled one by
less than 5 % of the tolerance. The estimate is exact for a constant f'' and is good when the
probe resolves the curvature (h·max|f'''| ≪ max|f''|), which holds for moves a machine can make:
the curvature of FK varies on the scale of the link length.

Moves that translate the head: the guides are parallel, so adding s to all three strokes moves the
whole head by −s along z and changes nothing else (by s along the kinematics' ``shift_direction``; a
head as built whose rails are not parallel has none: FK runs once per run of equal joint rows, and
such a move's bound is the second difference of the whole move, :func:`_whole_move_bound`). A move
whose three stroke changes are equal up to d (|d_i| ≤ TRANSLATION_SPREAD: the output rounding leaves
a few units) is a translation (linear: the stage and the common stroke change) plus g(t) =
FK(q_{k-1} + t d), so its tip path and link angles curve only as g does.
Such a move is sampled at its end point only (n_k = 1) when the bound
from g's second difference g(1) − 2 g(0) + g(−1) (one more FK, at q_{k-1} − d), ×SAFETY / 8, is ≤ ε
(that bound is its reported bound); else it is probed as above. A limit broken at its start point
is the previous move's end point and is reported there. Against an intended path every move is
probed (the deviation along a move is compared with the intended line). FK, the condition number
and the rounding allowance are computed once per distinct head pose up to a common stroke shift.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prs3_post.core.toolpath import JointProgram
from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.model import Machine

#: Intervals every move is probed with (and its minimum).
PROBE_INTERVALS = 8
#: Most intervals one move gets.
MAX_INTERVALS = 4096
#: The sampling aims at a bound ε = tolerance × EPSILON_FRACTION.
EPSILON_FRACTION = 0.05
#: Rounds of refinement (each recomputes the curvature on the denser samples).
REFINE_ROUNDS = 4
#: Factor on the curvature estimated from second differences.
SAFETY = 2.0
#: mm: a move whose three stroke changes differ from their mean by at most this is a translation of
#: the head along z plus a small rest, sampled at its end point only when its bound allows.
TRANSLATION_SPREAD = 0.01
#: mm: the stroke step of the rounding allowance's central differences.
ROUNDING_STEP = 1e-3


@dataclass(frozen=True, slots=True)
class Replay:
    """A program's moves replayed through forward kinematics, S samples in all.

    Attributes
    ----------
    row : (S,) int — program row (move) of each sample; samples of a row are contiguous
    fraction : (S,) float — t in (0, 1] along the move (row 0, whose start is unknown: its end, 1)
    joints : (S, 2 + J) float — mm, X, Y and the J joints (joint-space interpolation)
    tip : (S, 3) float — mm, tool tip, machine frame (part-relative: stage included)
    axis : (S, 3) float — unit tool axis
    converged : (S,) bool — FK found the head's pose (NaN tip/axis where not)
    link_angle : (S, 3) float — rad
    condition : (S,) float — actuator-Jacobian condition number (exact IK of the FK pose)
    first, end : (N,) int — index of each row's first and last (t = 1) sample
    intervals : (N,) int — n_k (row 0: 1)
    bound : (N,) float — mm, the sampling error bound SAFETY · M_k / (8 n_k²) of each move
    epsilon : float — mm, the bound the rule aims for
    """

    row: IntArray
    fraction: FloatArray
    joints: FloatArray
    tip: FloatArray
    axis: FloatArray
    converged: BoolArray
    link_angle: FloatArray
    condition: FloatArray
    first: IntArray
    end: IntArray
    intervals: IntArray
    bound: FloatArray
    epsilon: float


def joints_of(program: JointProgram) -> FloatArray:
    """(N, 2 + J) float — mm, X, Y and the J joints of every row."""
    return np.column_stack([program.stage, program.strokes]).reshape(-1, 2 + program.strokes.shape[1])


@dataclass(frozen=True, slots=True)
class _Poses:
    """FK (and the condition number) of N joint settings; NaN where the head does not assemble."""

    tip: FloatArray            # (N, 3) mm, machine frame, stage included
    axis: FloatArray           # (N, 3)
    link_angle: FloatArray     # (N, 3) rad
    converged: BoolArray       # (N,)
    condition: FloatArray      # (N,) exact IK of the FK pose


def head_shift(machine: Machine) -> FloatArray | None:
    """(3,) — the direction the head moves by s along when every joint grows by s (the kinematics'
    ``shift_direction``), or None when a common shift does more than move it."""
    direction = kinematics_of(machine).shift_direction
    return None if direction is None else np.asarray(direction, dtype=np.float64)


def shift_keys(strokes: FloatArray, *, shift: bool = True) -> tuple[FloatArray, IntArray]:
    """The distinct head poses of ``strokes`` up to a common shift: (U, 3) strokes with T1 = 0 and,
    for each of the N rows, its index in them. ``shift`` False (a head without a
    :func:`head_shift`): the distinct rows themselves.

    The guides are parallel (z_i = −T_i − U sin θ_i, DESIGN.md): adding s to every stroke moves the
    whole head by −s along z and changes nothing else (link angles, axis, condition number, the FK
    Jacobian). So FK, the exact IK's condition number and the rounding allowance are computed once
    per distinct (T2 − T1, T3 − T1): on a constant-axis stretch of a program, a handful of poses.
    """
    strokes = np.asarray(strokes, dtype=np.float64)
    strokes = strokes.reshape(-1, strokes.shape[-1])
    if not shift:
        return _distinct_rows(strokes)
    if strokes.shape[1] != 3:
        return _shift_keys_of_rows(strokes)
    key = (strokes[:, 1] - strokes[:, 0]) + 1j * (strokes[:, 2] - strokes[:, 0])   # two differences: one number
    # a program repeats a pose row after row: sort only the first row of each run of equal keys
    head = np.ones(len(key), dtype=bool)
    head[1:] = key[1:] != key[:-1]
    distinct, head_index = np.unique(key[head], return_inverse=True)
    inverse_index = head_index.reshape(-1)[np.cumsum(head) - 1]
    canonical = np.column_stack([np.zeros(len(distinct)), distinct.real, distinct.imag])
    return canonical, inverse_index.reshape(-1)


def _shift_keys_of_rows(strokes: FloatArray) -> tuple[FloatArray, IntArray]:
    """:func:`shift_keys` of (N, J) joints, J ≠ 3: the differences to the first joint as rows."""
    key = strokes[:, 1:] - strokes[:, :1]
    head = np.ones(len(key), dtype=bool)
    head[1:] = (key[1:] != key[:-1]).any(axis=1)
    distinct, head_index = np.unique(key[head], axis=0, return_inverse=True)
    inverse_index = head_index.reshape(-1)[np.cumsum(head) - 1]
    return np.column_stack([np.zeros(len(distinct)), distinct]), inverse_index.reshape(-1)


def _distinct_rows(strokes: FloatArray) -> tuple[FloatArray, IntArray]:
    """:func:`shift_keys` without the shift: (U, J) rows, a row for each run of equal rows of (N, J) joints
    (a program repeats a pose row after row; a pose met again later is solved again: sorting rows
    to find it costs more than its FK), and each row's index in them."""
    head = np.ones(len(strokes), dtype=bool)
    head[1:] = (strokes[1:] != strokes[:-1]).any(axis=1)
    return strokes[head].reshape(-1, strokes.shape[1]), np.cumsum(head) - 1


def _poses(machine: Machine, joints: FloatArray, *, keys: tuple[FloatArray, IntArray] | None = None,
           condition: bool = True) -> _Poses:
    """FK and condition number of (N, 2 + J) joints (X, Y, the joints), once per distinct head pose.

    ``keys``: :func:`shift_keys` of the strokes, if at hand; ``condition``: False skips the exact IK
    (the condition numbers are NaN).
    """
    direction = head_shift(machine)
    canonical, index = shift_keys(joints[:, 2:], shift=direction is not None) if keys is None else keys
    (fk,) = forward_parts(machine, [canonical])
    return expand(fk, condition_numbers(machine, fk) if condition else None, index, joints, direction)


#: FK of distinct head poses: tip, axis, link angle (each (K, 3)) and converged (K,).
_KeyFK = tuple[FloatArray, FloatArray, FloatArray, BoolArray]


def forward_parts(machine: Machine, parts: list[FloatArray]) -> list[_KeyFK]:
    """FK of several (K_i, 3) stroke arrays in one call: FK solves every row on its own, so each part
    gets the values a call of its own would give, without that call's fixed cost."""
    sizes = [len(part) for part in parts]
    fk = kinematics_of(machine).forward(np.concatenate(parts) if len(parts) > 1 else parts[0])
    out, at = [], 0
    for size in sizes:
        rows = slice(at, at + size)
        out.append((fk.tip[rows], fk.axis[rows], fk.link_angle[rows], fk.converged[rows]))
        at += size
    return out


def condition_numbers(machine: Machine, fk: _KeyFK) -> FloatArray:
    """(K,) the actuator-Jacobian condition number of FK poses (exact IK; NaN where FK failed)."""
    return kinematics_of(machine).condition(fk[0], fk[1])


def expand(fk: _KeyFK, condition: FloatArray | None, index: IntArray, joints: FloatArray,
           direction: FloatArray | None) -> _Poses:
    """The poses of (N, 2 + J) joints from the FK of their distinct head poses (``index``: each row's):
    :func:`shift_keys` of the joints with ``direction`` (:func:`head_shift`), or without a shift (None)."""
    key_tip, key_axis, key_angle, key_converged = fk
    tip = np.take(key_tip, index, axis=0)
    tip[:, :2] += joints[:, :2]
    if direction is not None:                            # the common shift T1: the head moves by T1 along it
        for j in range(3):
            if direction[j] == -1.0:
                tip[:, j] -= joints[:, 2]                # (on parallel vertical guides: −T1 along z, exactly)
            elif direction[j] != 0.0:
                tip[:, j] += joints[:, 2] * direction[j]
    converged = np.take(key_converged, index)
    converged &= np.isfinite(tip[:, 0])
    converged &= np.isfinite(tip[:, 1])
    converged &= np.isfinite(tip[:, 2])
    if not converged.all():
        tip[~converged] = np.nan
    cond = np.full(len(index), np.nan) if condition is None else np.take(condition, index)
    return _Poses(tip=tip, axis=np.take(key_axis, index, axis=0), link_angle=np.take(key_angle, index, axis=0),
                  converged=converged, condition=cond)


def _interleave(at_end: BoolArray, ends: _Poses, inner: _Poses) -> _Poses:
    """The poses of all samples: the end points' where ``at_end`` (in order), the others' elsewhere."""
    def merged(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        out = np.zeros((len(at_end), *a.shape[1:]), dtype=a.dtype)
        out[at_end], out[~at_end] = a, b
        return out

    return _Poses(tip=merged(ends.tip, inner.tip), axis=merged(ends.axis, inner.axis),
                  link_angle=merged(ends.link_angle, inner.link_angle),
                  converged=merged(ends.converged, inner.converged), condition=merged(ends.condition, inner.condition))


def _sample_moves(joints: FloatArray, intervals: IntArray) -> tuple[IntArray, FloatArray, FloatArray, IntArray]:
    """Samples of every move: row (S,), fraction (S,), joints (S, 2 + J), first sample of each row (N,)."""
    n = len(joints)
    row = np.repeat(np.arange(n), intervals)
    first = np.cumsum(intervals) - intervals
    step = np.arange(len(row)) - first[row] + 1
    fraction = step / intervals[row]
    start = np.take(joints, np.maximum(row - 1, 0), axis=0)
    sampled = start + fraction[:, None] * (np.take(joints, row, axis=0) - start)
    sampled[first + intervals - 1] = joints            # end points exactly as programmed
    return row, fraction, sampled, first


def _curvature(row: IntArray, intervals: IntArray, tip: FloatArray, link_angle: FloatArray, link_length: float,
               n: int) -> FloatArray:
    """(N,) max |f''| per move from second differences (f = tip, mm; U·θ_i, mm), times SAFETY."""
    i = np.arange(1, len(row) - 1)
    i = i[row[i + 1] == row[i]]                        # not a move's last sample: both neighbours on the move
    h2 = (1.0 / intervals[row[i]]) ** 2
    tip2 = np.linalg.norm(tip[i + 1] - 2.0 * tip[i] + tip[i - 1], axis=1)
    angle2 = link_length * np.max(np.abs(link_angle[i + 1] - 2.0 * link_angle[i] + link_angle[i - 1]), axis=1)
    out = np.zeros(n)
    np.fmax.at(out, row[i], np.fmax(tip2, angle2) / h2)     # fmax: a NaN (no assembly) is reported elsewhere
    return SAFETY * out


@dataclass(frozen=True, slots=True)
class _Translations:
    """The moves whose strokes change alike (within TRANSLATION_SPREAD): their rows (≥ 1), each one's
    mean stroke change ``common`` and the joints ``back`` = q_{k-1} − d (the mirror point of its rest)."""

    rows: IntArray
    common: FloatArray
    back: FloatArray


def translation_candidates(joints: FloatArray) -> _Translations:
    """The translation candidates of (N, 2 + J) joints (:func:`translation_bound`)."""
    n, width = joints.shape
    if n < 2:
        return _Translations(rows=np.zeros(0, dtype=np.int64), common=np.zeros(0), back=np.zeros((0, width)))
    # column by column (numpy's reductions along a row of three are slow; the same sums, in the same order)
    d = [np.subtract(joints[1:, j], joints[:-1, j]) for j in range(2, width)]
    total = d[0]
    for column in d[1:]:
        total = total + column
    common = total / float(len(d))
    s = [column - common for column in d]
    widest = np.abs(s[0])
    for column in s[1:]:
        widest = np.maximum(widest, np.abs(column))
    moves = np.flatnonzero(widest <= TRANSLATION_SPREAD)
    back = np.take(joints, moves, axis=0)                # q_{k-1} of each such move k = moves + 1
    for j, column in enumerate(s):
        back[:, 2 + j] -= column[moves]
    return _Translations(rows=moves + 1, common=common[moves], back=back)


def translation_bound(machine: Machine, joints: FloatArray, ends: _Poses, moves: _Translations | None = None,
                      mirror: _Poses | None = None) -> FloatArray:
    """(N,) mm — the sampling bound of each move whose strokes change alike (within TRANSLATION_SPREAD)
    when it is sampled at its end point only; NaN for the other moves, row 0, and where the head
    does not assemble. ``moves`` (:func:`translation_candidates`) and ``mirror`` (the poses of its ``back``
    joints, no condition numbers needed), if at hand.

    Move k: q(t) = q_{k-1} + t (c·(1, 1, 1) + d), c the mean stroke change, |d_i| ≤ TRANSLATION_SPREAD.
    The common part only shifts the head along z (linear in t), so the tip's deviation from its
    chord and the link angles' from theirs are those of g(t) = FK(q_{k-1} + t d), whose curvature
    is estimated from the second difference g(1) − 2 g(0) + g(−1) (h = 1; g(1) is the end pose
    shifted back by c, g(−1) one more FK) and taken ×SAFETY as for sampled moves: bound M/8.
    """
    n = len(joints)
    bound = np.full(n, np.nan)
    direction = head_shift(machine)
    if direction is None:                                # a common shift is no translation: the whole move
        return _whole_move_bound(machine, joints, ends, bound)
    moves = translation_candidates(joints) if moves is None else moves
    rows = moves.rows
    if not len(rows):
        return bound
    back = moves.back
    if mirror is None:
        mirror = _poses(machine, back, condition=False)      # the shape of the move only: no limits here
    before = rows - 1
    tip, angle = ends.tip, ends.link_angle
    # g(1) = FK(q_{k-1} + d) = FK(q_k) − c·direction (+ c e_z on vertical guides), g(0), g(−1): the head's
    # tip without the stage, column by column
    second_sq = np.zeros(len(rows))
    for j in range(3):
        head_end = np.take(tip[:, j], rows)
        head_start = np.take(tip[:, j], before)
        head_back = mirror.tip[:, j]
        if j < 2:
            head_end -= np.take(joints[:, j], rows)
            head_start -= np.take(joints[:, j], before)
            head_back = head_back - back[:, j]
        if direction[j] == -1.0:
            head_end += moves.common
        elif direction[j] != 0.0:
            head_end -= moves.common * direction[j]
        second = head_end - 2.0 * head_start + head_back
        second_sq = second * second if j == 0 else second_sq + second * second
    tip2 = np.sqrt(second_sq)
    turn = np.zeros(len(rows))
    for j in range(angle.shape[1]):
        bend = np.abs(np.take(angle[:, j], rows) - 2.0 * np.take(angle[:, j], before) + mirror.link_angle[:, j])
        turn = bend if j == 0 else np.maximum(turn, bend)
    angle2 = kinematics_of(machine).link_length * turn
    bound[rows] = SAFETY * np.maximum(tip2, angle2) / 8.0     # NaN stays NaN: no assembly, sample it
    return bound


def _whole_move_bound(machine: Machine, joints: FloatArray, ends: _Poses, bound: FloatArray) -> FloatArray:
    """:func:`translation_bound` on a head without a common shift (rails not parallel): the same
    moves, whose strokes change alike, but the curvature of the whole move's tip path and link angles
    from the second difference FK(q_k) − 2 FK(q_{k-1}) + FK(q_{k-1} − Δ) (Δ = q_k − q_{k-1}, stage
    included: it is linear, its share cancels), ×SAFETY / 8. A common stroke change moves such a head
    along its rails, nearly straight; what curves is its pose, slowly, on the scale of the links."""
    rows = translation_candidates(joints).rows
    if not len(rows):
        return bound
    before = rows - 1
    start = np.take(joints, before, axis=0)
    back = 2.0 * start - np.take(joints, rows, axis=0)
    mirror = _poses(machine, back, condition=False)
    second = np.take(ends.tip, rows, axis=0) - 2.0 * np.take(ends.tip, before, axis=0) + mirror.tip
    bend = np.abs(np.take(ends.link_angle, rows, axis=0) - 2.0 * np.take(ends.link_angle, before, axis=0)
                  + mirror.link_angle)
    angle2 = kinematics_of(machine).link_length * np.max(bend, axis=1)
    bound[rows] = SAFETY * np.maximum(np.sqrt(np.sum(second * second, axis=1)), angle2) / 8.0   # NaN: sample it
    return bound


def replay(machine: Machine, program: JointProgram, *, tolerance: float,
           translations: bool = True) -> Replay:
    """Sample every move of ``program`` in joint space and run FK (and exact IK) on the samples.

    Parameters
    ----------
    machine : Machine
    program : JointProgram — N ≥ 1 rows; ``stage`` zeros on a machine without a stage
    tolerance : float — mm; the sampling aims at a bound of ε = tolerance × EPSILON_FRACTION (1/20)
    translations : bool — sample the moves that translate the head (module docstring) at their end
        points only; False: probe every move (to compare it along its length with an intended path)

    Returns
    -------
    Replay
    """
    return replay_joints(machine, joints_of(program), tolerance=tolerance, translations=translations)


def replay_joints(machine: Machine, joints: FloatArray, *, tolerance: float, translations: bool,
                  ends: _Poses | None = None, flat_bound: FloatArray | None = None) -> Replay:
    """:func:`replay` of (N, 2 + J) joints; row 0 is sampled at its end only (its start is unknown, or it is
    the previous chunk's last row, replayed again to start the next move from). ``ends``: the poses
    of the rows, and ``flat_bound``: :func:`translation_bound` (with ``translations``), if at hand."""
    link_length = kinematics_of(machine).link_length
    n = len(joints)
    epsilon = tolerance * EPSILON_FRACTION
    ends = _poses(machine, joints) if ends is None else ends
    if flat_bound is None:
        flat_bound = translation_bound(machine, joints, ends) if translations else np.full(n, np.nan)
    flat = flat_bound <= epsilon                        # NaN: False
    intervals = np.where(flat, 1, PROBE_INTERVALS).astype(np.int64)
    if n:
        intervals[0] = 1

    def run() -> tuple[IntArray, FloatArray, FloatArray, IntArray, _Poses, FloatArray]:
        if bool((intervals == 1).all()):             # every move at its end point only: the samples are the rows
            rows = np.arange(n)
            return rows, np.ones(n), joints, rows, ends, np.zeros(n)
        row, fraction, sampled, first = _sample_moves(joints, intervals)
        at_end = np.zeros(len(row), dtype=bool)
        at_end[first + intervals - 1] = True
        poses = _interleave(at_end, ends, _poses(machine, sampled[~at_end]))
        return row, fraction, sampled, first, poses, _curvature(row, intervals, poses.tip, poses.link_angle,
                                                               link_length, n)

    row, fraction, sampled, first, poses, curvature = run()
    for _ in range(REFINE_ROUNDS):                     # refine until the bound holds (never coarsen)
        needed = np.ceil(np.sqrt(curvature / (8.0 * epsilon)))
        wanted = np.maximum(np.clip(needed, PROBE_INTERVALS, MAX_INTERVALS).astype(np.int64), intervals)
        wanted[flat] = 1
        wanted[:1] = 1
        if np.array_equal(wanted, intervals):
            break
        intervals = wanted
        row, fraction, sampled, first, poses, curvature = run()
    bound = np.where(flat, flat_bound, curvature / (8.0 * intervals.astype(np.float64) ** 2))
    if n:
        bound[0] = 0.0
    return Replay(
        row=row, fraction=fraction, joints=sampled, tip=poses.tip, axis=poses.axis, converged=poses.converged,
        link_angle=poses.link_angle, condition=poses.condition, first=first,
        end=first + intervals - 1, intervals=intervals, bound=bound, epsilon=epsilon,
    )


def rounding_allowance(machine: Machine, program: JointProgram, decimals: int, *,
                       step: float = ROUNDING_STEP) -> FloatArray:
    """(N,) float — mm, the most the tip of each row can move when every axis word is off by half a
    unit of its last decimal: ½·10^-decimals · Σ_j |∂tip/∂q_j| (FK Jacobian by central differences,
    once per distinct head pose: it does not change with a common stroke shift)."""
    canonical, index = shift_keys(np.asarray(program.strokes), shift=head_shift(machine) is not None)
    return _rounding_of_keys(machine, canonical, decimals, step=step)[index]


def _rounding_of_keys(machine: Machine, canonical: FloatArray, decimals: int, *,
                      step: float = ROUNDING_STEP) -> FloatArray:
    """:func:`rounding_allowance` of the distinct head poses of :func:`shift_keys` (or distinct rows)."""
    return rounding_from(machine, forward_parts(machine, rounding_strokes(canonical, step)), decimals, step=step)


def rounding_strokes(canonical: FloatArray, step: float) -> list[FloatArray]:
    """The strokes whose FK :func:`rounding_from` needs: each pose with one stroke ± ``step``."""
    out = []
    for leg in range(canonical.shape[1]):
        delta = np.zeros(canonical.shape[1])
        delta[leg] = step
        out += [canonical + delta, canonical - delta]
    return out


def rounding_from(machine: Machine, fk: list[_KeyFK], decimals: int, *, step: float = ROUNDING_STEP) -> FloatArray:
    """:func:`_rounding_of_keys` from the FK of :func:`rounding_strokes` (in its order)."""
    half = 0.5 * 10.0 ** (-decimals)
    total = np.full(len(fk[0][0]), 2.0 if machine.stage.present else 0.0)   # ∂tip/∂X, ∂tip/∂Y: unit vectors
    for leg in range(len(fk) // 2):
        plus, minus = fk[2 * leg][0], fk[2 * leg + 1][0]
        total += np.linalg.norm(plus - minus, axis=1) / (2.0 * step)
    return half * total
