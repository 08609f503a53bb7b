"""The machine's axis speeds: feed clamping and cycle time of a joint-space program.

A program row moves every axis (stage X, Y and the three strokes, in that column order) on a
straight line in joint space from the row before, so over a G1 of inverse-time feed F (1/min)
axis ``a`` moves at ``|Δq_a| · F`` mm/min. :func:`clamp_feeds` lowers each F where an axis
would exceed its top speed: ``F' = min(F, min_a(v_a / |Δq_a|))`` (the tip feed drops by the same
ratio, as the move's time grows by it).

Cycle time (:func:`move_times`): every move starts and ends at rest (the programs run in exact-stop
mode, G61). Each axis follows a trapezoidal speed profile (accelerate at ``a``, cruise at ``v``,
decelerate at ``a``), or a triangular one when the move is too short to reach ``v``::

    t(d, v, a) = d / v + v / a          if d ≥ v² / a
               = 2 √(d / a)             otherwise

with ``v`` the axis's speed for the move (``|Δq_a| · F`` on a G1, the axis's top speed on a G0)
and the move's time is the slowest axis's ``t``. Pure numpy over whole columns, no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prs3_post.core.errors import LimitError
from prs3_post.core.toolpath import EventKind, JointProgram, MoveKind, describe_source
from prs3_post.core.types import BoolArray, FloatArray
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.model import Dynamics, Machine

__all__ = [
    "NO_DYNAMICS",
    "DynamicsTally",
    "FeedClamp",
    "FeedSpeedError",
    "axis_names",
    "axis_speed_ratio",
    "clamp_feeds",
    "dynamics_entry",
    "joint_columns",
    "joint_deltas",
    "move_times",
    "program_time",
    "speed_excess",
    "streamed_entry",
    "timed_entry",
    "trapezoid_time",
]


def axis_names(machine: Machine) -> tuple[str, ...]:
    """The program's axes in :func:`joint_columns` order, for messages: ``stage X``, ``stage Y`` and
    ``stroke`` and each joint's name (``stroke T1``)."""
    return ("stage X", "stage Y", *(f"stroke {name}" for name in kinematics_of(machine).joint_names))

#: Relative slack of the speed check of an existing program: the F word's rounding (the emitted
#: feed may be up to half a unit of its last digit above the clamped one).
SPEED_SLACK = 1e-6


def joint_columns(stage: FloatArray, strokes: FloatArray) -> FloatArray:
    """(N, 2 + J) mm: stage X, Y and the J joints side by side (the order of :meth:`Dynamics.speeds`).

    ``strokes`` : (N, J), or (J,) for one row. Copied a column at a time: np.column_stack copies each
    row's 2 and J values as inner loops of 2 and J elements, about three times slower."""
    stage = np.asarray(stage, dtype=np.float64).reshape(-1, 2)
    strokes = np.asarray(strokes, dtype=np.float64)
    strokes = strokes.reshape(-1, strokes.shape[-1])
    if len(stage) != len(strokes):
        raise ValueError(f"joint_columns: {len(stage)} stage rows, {len(strokes)} stroke rows")
    out = np.zeros((len(stage), 2 + strokes.shape[1]))
    for column, values in enumerate((stage[:, 0], stage[:, 1], *strokes.T)):
        out[:, column] = values
    return out


def joint_deltas(joints: FloatArray, start: FloatArray | None = None) -> FloatArray:
    """(N, 2 + J) mm: |Δq| of each row's move from the row before (row 0 from ``start``; zeros when None)."""
    joints = np.asarray(joints, dtype=np.float64)
    joints = joints.reshape(-1, joints.shape[-1])
    width = joints.shape[1]
    before = np.concatenate([joints[:1] if start is None else np.asarray(start, dtype=np.float64).reshape(1, width),
                             joints[:-1]])
    return np.abs(joints - before[: len(joints)])


def axis_speed_ratio(dynamics: Dynamics, kind: np.ndarray, deltas: FloatArray,
                     inverse_time: FloatArray) -> tuple[FloatArray, np.ndarray]:
    """Each G1's worst axis speed as a fraction of that axis's top speed, and which axis it is.

    Returns
    -------
    ratio : (N,) float — max_a |Δq_a| · F / v_a (0 on rapids: they run at the axes' own speeds)
    axis : (N,) int — the axis of that maximum (index into :func:`axis_names`)
    """
    feed = np.asarray(kind) == MoveKind.FEED
    top = np.asarray(dynamics.speeds(deltas.shape[1] - 2))
    per_axis = deltas * np.where(feed, inverse_time, 0.0)[:, None] / top
    if not len(per_axis):
        return np.zeros(0), np.zeros(0, dtype=np.int64)
    return per_axis.max(axis=1), per_axis.argmax(axis=1)


def _any_over(dynamics: Dynamics, kind: np.ndarray, deltas: FloatArray, inverse_time: FloatArray) -> bool:
    """Whether :func:`axis_speed_ratio` finds a ratio over 1: its products, an axis at a time, and its
    maximum as the element-wise maximum of the axes (NaN as NaN), without the reduction along each row."""
    fed = np.where(np.asarray(kind) == MoveKind.FEED, inverse_time, 0.0)
    ratio = None
    for axis, speed in enumerate(np.asarray(dynamics.speeds(deltas.shape[1] - 2))):
        per_axis = deltas[:, axis] * fed / speed
        ratio = per_axis if ratio is None else np.maximum(ratio, per_axis)
    return ratio is not None and bool((ratio > 1.0).any())


@dataclass(frozen=True, slots=True)
class FeedClamp:
    """Feeds lowered to the axis speed limits.

    Attributes
    ----------
    inverse_time : (N,) float — 1/min, the G93 F words after clamping (rapids: 0, as given)
    ratio : (N,) float — requested F / clamped F (> 1: the move was slowed; 1 elsewhere)
    axis : (N,) int — the axis that limits each move (index into :func:`axis_names`)
    """

    inverse_time: FloatArray
    ratio: FloatArray
    axis: np.ndarray

    @property
    def clamped(self) -> BoolArray:
        """(N,) bool: the move was slowed."""
        return self.ratio > 1.0


def clamp_feeds(dynamics: Dynamics, kind: np.ndarray, deltas: FloatArray, inverse_time: FloatArray) -> FeedClamp:
    """Lower each G1's inverse-time feed so that no axis exceeds its top speed.

    Parameters
    ----------
    dynamics : Dynamics
    kind : (N,) int — MoveKind
    deltas : (N, 5) float — mm, |Δq| of each move (:func:`joint_deltas`)
    inverse_time : (N,) float — 1/min, the requested F words

    Returns
    -------
    FeedClamp — a clamped F is exactly the limit: its fastest axis runs at its top speed
    """
    inverse_time = np.asarray(inverse_time, dtype=np.float64)
    ratio, axis = axis_speed_ratio(dynamics, kind, deltas, inverse_time)
    over = ratio > 1.0
    out = inverse_time.copy()
    if over.any():                          # F' = min_a v_a / |Δq_a|, computed directly (not F / ratio)
        with np.errstate(divide="ignore"):          # an axis that does not move allows any feed (inf)
            allowed = np.asarray(dynamics.speeds(deltas.shape[1] - 2)) / deltas[over]
        out[over] = allowed.min(axis=1)
    return FeedClamp(inverse_time=out, ratio=np.where(over, ratio, 1.0), axis=axis)


def trapezoid_time(distance: FloatArray, speed: FloatArray, accel: FloatArray) -> FloatArray:
    """min: time to move ``distance`` mm from rest to rest at top speed ``speed`` mm/min and
    acceleration ``accel`` mm/min² (trapezoidal, or triangular when ``distance < speed²/accel``)."""
    distance, speed, accel = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (distance, speed,
                                                                                           accel)))
    reach = distance >= speed * speed / accel
    with np.errstate(divide="ignore", invalid="ignore"):
        cruise = distance / speed + speed / accel
    triangle = 2.0 * np.sqrt(distance / accel)
    return np.where(distance > 0, np.where(reach, cruise, triangle), 0.0)


def move_times(dynamics: Dynamics, kind: np.ndarray, deltas: FloatArray, inverse_time: FloatArray) -> FloatArray:
    """(N,) min: each move's time, the slowest axis's trapezoid (G1: every axis at |Δq|·F; G0: each
    axis at its top speed). A row without motion takes no time."""
    feed = np.asarray(kind) == MoveKind.FEED
    top = np.asarray(dynamics.speeds(deltas.shape[1] - 2))
    speed = np.where(feed[:, None], deltas * np.asarray(inverse_time)[:, None], top)
    speed = np.where(speed > 0, speed, top)             # an axis that does not move: any speed, t = 0
    times = trapezoid_time(deltas, speed, np.asarray(dynamics.accels(deltas.shape[1] - 2)))
    return times.max(axis=1) if len(times) else np.zeros(0)


#: Rows whose move times :func:`program_time` computes together (its scratch memory is about 300 bytes a row).
TIME_ROWS = 65536


def program_time(dynamics: Dynamics, program: JointProgram) -> float:
    """min: the cycle time of a whole program: its moves (:func:`move_times`, row 0 from where it
    stands: no time) and its dwells."""
    n = len(program)
    moves = np.zeros(n)                     # each move's time, computed TIME_ROWS rows at a time (memory)
    for lo in range(0, n, TIME_ROWS):
        hi = min(n, lo + TIME_ROWS)
        joints = joint_columns(program.stage[lo:hi], program.strokes[lo:hi])
        start = None if lo == 0 else joint_columns(program.stage[lo - 1], program.strokes[lo - 1])
        moves[lo:hi] = move_times(dynamics, program.kind[lo:hi], joint_deltas(joints, start),
                                  program.inverse_time[lo:hi])
    dwell = sum(e.value for e in program.events if e.kind is EventKind.DWELL) / 60.0
    return float(moves.sum()) + dwell


def speed_excess(dynamics: Dynamics, program: JointProgram, *, names: tuple[str, ...], first: int = 0,
                 length_decimals: int, feed_decimals: int) -> tuple[FloatArray, np.ndarray, list[tuple[int, str]]]:
    """The G1 moves of an existing program that drive an axis over its top speed.

    Row 0 is where the program (or the chunk, carried from the one before) starts: not a move here.
    A move is over only beyond what the rounding of its F word and of its end points allows.

    Parameters
    ----------
    program : JointProgram — consecutive rows
    first : int — rows before it are not reported (a carried row)
    length_decimals, feed_decimals : int — the digits of the axis words and of F

    Returns
    -------
    ratio : (N,) float — each row's worst axis speed / top speed (0 on rapids and row 0)
    axis : (N,) int — the axis of that maximum
    over : list of (row, message) — ``the feed drives stroke T2 at 6012.3 mm/min, 1.20 x its top speed 5000.0 mm/min``
        (``names``: :func:`axis_names`)
    """
    joints = joint_columns(program.stage, program.strokes)
    deltas = joint_deltas(joints)
    f = np.asarray(program.inverse_time, dtype=np.float64)
    ratio, axis = axis_speed_ratio(dynamics, program.kind, deltas, f)
    top = np.asarray(dynamics.speeds(deltas.shape[1] - 2))
    # F may be half a unit of its last digit above the value meant, each end point half a unit off
    with np.errstate(divide="ignore", invalid="ignore"):
        slack = 0.5 * 10.0 ** -feed_decimals / f + f * 10.0 ** -length_decimals / top[axis]
    over = np.flatnonzero(ratio > 1.0 + np.where(np.isfinite(slack), slack, 0.0) + SPEED_SLACK)
    messages = [(r, f"the feed drives {names[axis[r]]} at {ratio[r] * top[axis[r]]:.1f} mm/min, "
                    f"{ratio[r]:.2f} x its top speed {top[axis[r]]:.1f} mm/min") for r in over.tolist() if r >= first]
    return ratio, axis, messages


class FeedSpeedError(LimitError):
    """A feed too fast for an axis, refused (``clamp=False``): the feed is the problem, not the setup."""


class DynamicsTally:
    """Feed clamping of a program made in chunks (held by the pipeline's stream).

    ``feed(...)`` clamps one chunk's F words; the tally carries the last joint position from chunk
    to chunk. (The cycle time is :func:`program_time` of the finished program: the header needs it
    once, not per chunk; a program streamed without being kept, ``timed=True``, has its chunks' times
    added up here instead, with the same :func:`move_times`.) With ``clamp=False`` a needed clamp is a
    LimitError naming the row. A machine without dynamics: F words pass unchanged and nothing is counted.

    Attributes
    ----------
    clamped : int — moves slowed
    worst_ratio : float — the largest requested / clamped feed (1: none slowed)
    worst_where : str — the line or step of that move ('' when none)
    worst_axis : str — the axis that limits it
    minutes : float — with ``timed``: the cycle time of the chunks so far (their moves and dwells)
    file_name : str | None — how :attr:`worst_where` names a CAM file's line (``part.cls:12``; a header names
        the file, not its folder); None: as the program names it
    """

    def __init__(self, machine: Machine, *, clamp: bool = True, timed: bool = False):
        self.dynamics = machine.dynamics
        self.names = axis_names(machine)
        self.clamp = clamp
        self.clamped = 0
        self.worst_ratio = 1.0
        self.worst_where = ""
        self.worst_axis = ""
        self.timed = timed
        self.minutes = 0.0
        self.file_name: str | None = None
        self._last: FloatArray | None = None

    def feed(self, program: JointProgram, joints: FloatArray | None = None) -> FloatArray:
        """The chunk's F words, clamped (``program.inverse_time`` as requested).

        ``joints`` : (N, 5) float, optional — the program's :func:`joint_columns`, when the caller has them.

        Raises
        ------
        LimitError
            With ``clamp=False``: ``hole 1, peck 2: the feed needs stroke T2 at 15000.0 mm/min, 3.00 x its
            top speed 5000.0 mm/min (slow the feed or allow clamping)``.
        """
        if self.dynamics is None or not len(program):
            if self.dynamics is not None:                   # a chunk of events alone: its dwells
                self._time(program, np.zeros((0, 2)), program.inverse_time)
            return program.inverse_time
        joints = joint_columns(program.stage, program.strokes) if joints is None else joints
        deltas = joint_deltas(joints, self._last)
        if not _any_over(self.dynamics, program.kind, deltas, program.inverse_time):
            self._last = joints[-1].copy()              # no move too fast (the common case): nothing to clamp
            self._time(program, deltas, program.inverse_time)
            return program.inverse_time
        result = clamp_feeds(self.dynamics, program.kind, deltas, program.inverse_time)
        over = np.flatnonzero(result.clamped)
        if len(over):
            row = int(over[np.argmax(result.ratio[over])])
            if not self.clamp:
                first = int(over[0])
                axis = int(result.axis[first])
                top = self.dynamics.speeds(deltas.shape[1] - 2)[axis]
                raise FeedSpeedError(f"{program.describe(first)}: the feed needs {self.names[axis]} at "
                                 f"{result.ratio[first] * top:.1f} mm/min, {result.ratio[first]:.2f} x its top "
                                 f"speed {top:.1f} mm/min (slow the feed, or let it be clamped)")
            self.clamped += len(over)
            if result.ratio[row] > self.worst_ratio:
                self.worst_ratio = float(result.ratio[row])
                self.worst_where = describe_source(program.source, program.source_labels, row,
                                                   program.source_file if self.file_name is None else self.file_name)
                self.worst_axis = self.names[int(result.axis[row])]
        self._last = joints[-1].copy()
        feeds = result.inverse_time if len(over) else program.inverse_time
        self._time(program, deltas, feeds)
        return feeds

    def _time(self, program: JointProgram, deltas: FloatArray, inverse_time: FloatArray) -> None:
        """With ``timed``: add the chunk's moves (at the feeds emitted) and dwells to :attr:`minutes`,
        as :func:`program_time` counts them."""
        if not self.timed:
            return
        assert self.dynamics is not None
        for lo in range(0, len(program), TIME_ROWS):        # scratch memory: as program_time
            hi = min(len(program), lo + TIME_ROWS)
            self.minutes += float(move_times(self.dynamics, program.kind[lo:hi], deltas[lo:hi],
                                             inverse_time[lo:hi]).sum())
        self.minutes += sum(e.value for e in program.events if e.kind is EventKind.DWELL) / 60.0

#: The header's ``dynamics`` entry for a machine file without ``[dynamics]``.
NO_DYNAMICS = "none in the machine file: feeds not checked against axis speeds, no cycle time"


def _clamp_text(tallies: list[DynamicsTally]) -> str:
    """``no feed slowed ...`` or ``3 moves slowed to the axis speed limits, worst 2.40 x at line 12 (stroke T2)``."""
    clamped = sum(t.clamped for t in tallies)
    if not clamped:
        return "no feed slowed by the axis speed limits"
    worst = max(tallies, key=lambda t: t.worst_ratio)
    moves = "move" if clamped == 1 else "moves"
    return (f"{clamped} {moves} slowed to the axis speed limits, worst {worst.worst_ratio:.2f} x at "
            f"{worst.worst_where} ({worst.worst_axis})")


def dynamics_entry(machine: Machine, program: JointProgram, tallies: list[DynamicsTally | None]) -> str:
    """The header's ``dynamics`` entry of a program made of pieces: the cycle time of the whole
    ``program`` (:func:`program_time`) and the feeds the pieces' ``tallies`` slowed."""
    if machine.dynamics is None:
        return NO_DYNAMICS
    return timed_entry(program_time(machine.dynamics, program), [t for t in tallies if t is not None])


def streamed_entry(tally: DynamicsTally) -> str:
    """The header's ``dynamics`` entry of a program streamed through one ``timed`` tally (its
    :attr:`~DynamicsTally.minutes`): as :func:`dynamics_entry` words it."""
    if tally.dynamics is None:
        return NO_DYNAMICS
    if not tally.timed:
        raise ValueError("streamed_entry: the tally did not add up the cycle time (timed=False)")
    return timed_entry(tally.minutes, [tally])


def timed_entry(minutes: float, tallies: list[DynamicsTally]) -> str:
    """``cycle time 1.234 min = 74.0 s, no feed slowed ...``: the entry of a machine with dynamics."""
    return f"cycle time {format_minutes(minutes)}, {_clamp_text(tallies)}"


def format_minutes(minutes: float) -> str:
    """``1.234 min = 74.0 s``: a time in minutes, and in seconds for people."""
    return f"{minutes:.3f} min = {minutes * 60.0:.1f} s"
