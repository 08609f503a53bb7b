"""Verify a program: replay its moves through forward kinematics and check what the machine would do.

    program rows (X, Y, T1..T3) ──► sample every move in joint space ──► FK (+ exact IK for the
    condition number) ──► tip path, limits, straightness, feeds ──► deviation from the intended path

Pure: arrays in, a :class:`VerifyReport` out (plus its text and JSON forms); the CLI reads files.

The controller interpolates the machine axes linearly, so the machine passes through the joint
values q(t) = q_{k-1} + t (q_k - q_{k-1}), t in [0, 1], on move k, and its tool tip follows the
curve p(t) = FK(q(t)). Strokes and stage are linear in t, so they can only reach their extremes at
the end points; link angles, tilt, the condition number and the tip's distance from a straight
line are not, so every move is sampled.

Memory: :class:`Verifier` replays and checks a program a chunk of rows at a time, carrying the
last row, and keeps a few numbers per move (the samples only when asked: the JSON report, the
preview, ``--against``); the report does not depend on the chunking.

Reports
-------
- The FK tool-tip path in part coordinates (every sample).
- The closest approach to every limit of the machine (``prs3_post.post.limits.check_limits`` on the
  samples; condition numbers from exact IK of the FK poses): value, margin and line.
- Straightness: the largest distance of a G1's tip from the straight line between its end points
  (must be ≤ tolerance: a prs3-post program only makes moves that are straight at the tip).
- Feeds (G93: F = 1 / minutes): the implied tip feed of each G1 = chord length × F. With an
  intended path that has feeds (``--against PART.stl``), each one must equal the intended feed
  within what the output rounding allows (of F and of the end points). Without one, the feeds are
  grouped (equal within rounding); a prs3-post operation uses only its feed and plunge feed, so a
  G1 whose implied feed matches no other G1 is *warned* about (a hand-edited F or point), without
  failing the check.
- Against an intended path (one pose per program row): tip and axis deviation at every end point
  and along every G1 (intended: the straight chord and the great-circle axis), their maximum,
  mean and the line of the maximum. Allowed: tolerance + the output rounding (the tip error that
  half a unit of the last decimal on every axis word can cause, from the FK Jacobian) for the
  tip, ``axis_tolerance`` for the axis.

Any limit broken, a pose that does not assemble, a G1 not straight within the tolerance, a
deviation or a feed outside what is allowed is a *problem*: the program fails (exit status 1).
Where the head does not assemble there is no tip, so a move with a reach problem (or whose start
point has one) gets no straightness problem: its straightness is unknown (NaN), not too large.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from prs3_post.core.defaults import NOMINAL_RAPID_RATE
from prs3_post.core.errors import Prs3Error
from prs3_post.core.toolpath import Event, EventKind, JointProgram, MoveKind, program_from_columns
from prs3_post.core.types import BoolArray, FloatArray, IntArray, Progress
from prs3_post.kinematics import IKResult
from prs3_post.kinematics import replay as kinematic
from prs3_post.kinematics.prs3.kinematics import Prs3Kinematics
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.kinematics.replay import (
    EPSILON_FRACTION,
    ROUNDING_STEP,
    condition_numbers,
    expand,
    forward_parts,
    head_shift,
    joints_of,
    replay_joints,
    rounding_from,
    rounding_strokes,
    shift_keys,
    translation_bound,
    translation_candidates,
)
from prs3_post.machine.loading import Machine
from prs3_post.machine.model import Dynamics
from prs3_post.part.setup_transform import Setup
from prs3_post.post.dynamics import axis_names, joint_columns, joint_deltas, move_times, speed_excess
from prs3_post.post.limits import LimitReport, check_limits
from prs3_post.post.linearize import slerp

#: Rows replayed at a time (memory: a few kB per row at most; the report does not depend on it).
CHUNK_ROWS = 16384


# ============================================================================= replay


@dataclass(frozen=True, slots=True)
class Replay(kinematic.Replay):
    """A program's moves replayed through forward kinematics (:class:`prs3_post.kinematics.replay.Replay`)
    and every limit of the machine on every sample.

    Attributes
    ----------
    limits : LimitReport — every limit of the machine on every sample
    """

    limits: LimitReport


def _with_limits(machine: Machine, rep: kinematic.Replay) -> Replay:
    """``rep`` and the limits of ``machine`` on its samples."""
    like = IKResult(stage=rep.joints[:, :2], strokes=rep.joints[:, 2:], link_angle=rep.link_angle,
                    condition=rep.condition, reachable=rep.converged)
    limits = check_limits(machine, like, rep.axis)
    return Replay(**{f.name: getattr(rep, f.name) for f in dataclasses.fields(rep)}, limits=limits)


def replay(machine: Machine, program: JointProgram, *, tolerance: float,
           translations: bool = True) -> Replay:
    """:func:`prs3_post.kinematics.replay.replay` and the machine's limits on every sample."""
    return _with_limits(machine, kinematic.replay(machine, program, tolerance=tolerance, translations=translations))


def move_durations(program: JointProgram, *, rapid_rate: float,
                   dynamics: Dynamics | None = None) -> FloatArray:
    """(N,) min, the time of every row's move from the row before (G1: 1/F; G0: longest joint travel /
    rapid_rate; row 0: 0, its start being unknown); with the machine's ``dynamics``, each move's
    trapezoidal time (:func:`prs3_post.post.dynamics.move_times`). Row by row: the rows of a chunk that
    starts with the row before them get their values in the whole program."""
    n = len(program)
    duration = np.zeros(n)
    if dynamics is not None:
        duration = move_times(dynamics, program.kind, joint_deltas(joint_columns(program.stage, program.strokes)),
                              program.inverse_time)
    elif n > 1:                                        # in place, column by column: a long program's rows
        travel = duration[1:]                          # G0: the longest joint travel / rapid_rate
        for columns in (program.stage, program.strokes):
            for j in range(columns.shape[1]):
                np.maximum(travel, np.abs(np.diff(columns[:, j])), out=travel)
        travel /= rapid_rate
        feed = np.flatnonzero(program.kind[1:] == MoveKind.FEED) + 1
        with np.errstate(divide="ignore"):
            duration[feed] = 1.0 / program.inverse_time[feed]      # G1: 1/F
    return duration


def row_times(program: JointProgram, *, rapid_rate: float,
              dynamics: Dynamics | None = None, durations: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
    """Start and end time of every row's move, min: :func:`move_durations` (``durations``, if at hand),
    and G4 dwells before a row delay it (row 0 starts and ends at 0).

    Returns
    -------
    start, end : (N,) float — min
    """
    n = len(program)
    duration = move_durations(program, rapid_rate=rapid_rate, dynamics=dynamics) if durations is None else durations
    end = duration.copy()
    for event in program.events:                       # a dwell before a row delays it (after the last: nothing)
        if event.kind is EventKind.DWELL and event.before < n:
            end[event.before] += event.value / 60.0
    np.cumsum(end, out=end)
    return end - duration, end


def margin_fraction(limits: LimitReport) -> FloatArray:
    """(L,) float — the bounds' spread each margin is measured against: max − min for a two-sided
    limit, |bound| for a one-sided one (tilt, condition number). Divide a margin by it."""
    low, high = limits.low, limits.high
    both = np.isfinite(low) & np.isfinite(high)
    one = np.where(np.isfinite(high), np.abs(high), np.abs(low))
    return np.where(both, high - low, one)


# ============================================================================= checks


@dataclass(frozen=True, slots=True)
class Intended:
    """The path a program should make: one pose per program row, machine frame.

    Attributes
    ----------
    tip : (N, 3) float — mm, part-relative tip in the machine frame (as ``ik`` takes it)
    axis : (N, 3) float — unit tool axes
    feed : (N,) float — mm/min tip feed of G1 rows, NaN where unknown (no check)
    kind : (N,) int — MoveKind of each row, −1 where unknown
    label : str — where it came from, for the report
    """

    tip: FloatArray
    axis: FloatArray
    feed: FloatArray
    kind: IntArray
    label: str


@dataclass(frozen=True, slots=True)
class Problem:
    """One reason a program fails (or, as a warning, a thing to look at).

    Attributes
    ----------
    line : int — program line (0: the whole program)
    kind : str — ``limit``, ``reach``, ``straightness``, ``deviation``, ``axis``, ``feed``, ``move``, ``speed``
    message : str — ``line 12: ...``
    """

    line: int
    kind: str
    message: str


@dataclass(frozen=True, slots=True)
class Closest:
    """The closest approach to one limit over all samples."""

    name: str
    unit: str
    low: float
    high: float
    value: float
    margin: float
    fraction_of_range: float
    line: int
    at: float


@dataclass(frozen=True, slots=True)
class FeedGroup:
    """G1 moves whose implied tip feeds are equal within the output rounding.

    Attributes
    ----------
    feed : float — mm/min, their mean implied tip feed
    lines : (M,) int — their program lines, ascending (an array: a group may hold every G1 of a long program)
    """

    feed: float
    lines: IntArray


@dataclass(frozen=True, slots=True)
class Against:
    """Deviation of the replayed path from the intended one (C compared samples).

    Attributes
    ----------
    label : str
    compared : (S,) bool — end points of every row, and every sample of G1 moves
    tip_deviation : (S, 3) float — mm, FK tip − intended tip (NaN where not compared)
    axis_deviation : (S,) float — rad, angle between FK axis and intended axis (NaN where not compared)
    allowed : (S,) float — mm, tolerance + output rounding at each sample
    """

    label: str
    compared: BoolArray
    tip_deviation: FloatArray
    axis_deviation: FloatArray
    allowed: FloatArray


@dataclass(frozen=True, slots=True)
class VerifyReport:
    """Everything ``prs3-post verify`` found (see the module docstring).

    Attributes
    ----------
    program : JointProgram — the rows as read (``source`` = line numbers)
    replay : Replay | None — every sample (None when verified without keeping them: the text report
        needs only the per-move values below)
    machine : str
    setup : Setup — the part → machine transform the program was made for
    tolerance : float — mm
    axis_tolerance : float — rad
    rounding : (N,) float — mm, tip allowance for the output rounding of each row
    straightness : (N,) float — mm, the largest |tip − straight chord| over each G1's samples, NaN elsewhere
    chord : (N,) float — mm, tip chord length of each move (NaN for row 0)
    implied_feed : (N,) float — mm/min, chord × F of G1 rows, NaN elsewhere
    feed_slack : (N,) float — mm/min, what the rounding of F and of the end points allows
    intervals : (N,) int — n_k, the intervals each move was sampled with (row 0: 1)
    bound : (N,) float — mm, the sampling error bound of each move
    samples : int — FK samples in all
    epsilon : float — mm, the bound the sampling aims for
    feed_groups : tuple of FeedGroup
    closest : tuple of Closest — one per limit
    against : Against | None
    problems, warnings : tuple of Problem
    dynamics : Dynamics | None — the machine's axis speeds (None: the file has none; times at a nominal rapid rate)
    fastest : (ratio, line, axis) — the G1 whose axis runs closest to (or over) its top speed: speed /
        top speed, its line, the axis (0, 0, '' without dynamics or G1)
    duration : (N,) float | None — min, each move's time (:func:`move_durations` with ``dynamics``, at the
        nominal rapid rate without), computed chunk by chunk: the text report needs no pass over the whole
        program for it (None: not computed)
    """

    program: JointProgram
    replay: Replay | None
    machine: str
    setup: Setup
    tolerance: float
    axis_tolerance: float
    rounding: FloatArray
    straightness: FloatArray
    chord: FloatArray
    implied_feed: FloatArray
    feed_slack: FloatArray
    intervals: IntArray
    bound: FloatArray
    samples: int
    epsilon: float
    feed_groups: tuple[FeedGroup, ...]
    closest: tuple[Closest, ...]
    against: Against | None
    problems: tuple[Problem, ...]
    warnings: tuple[Problem, ...]
    dynamics: Dynamics | None = None
    fastest: tuple[float, int, str] = (0.0, 0, "")
    duration: FloatArray | None = None
    joint_names: tuple[str, ...] = Prs3Kinematics.joint_names        # the kinematics' joints (program columns)

    @property
    def ok(self) -> bool:
        """No problem: within every limit and tolerance."""
        return not self.problems

    @property
    def samples_kept(self) -> Replay:
        """The replay's samples; raises ValueError where they were not kept."""
        if self.replay is None:
            raise ValueError("the samples were not kept (verify with keep_samples=True)")
        return self.replay

    @property
    def line(self) -> IntArray:
        """(S,) int — the program line of every sample."""
        return self.program.source[self.samples_kept.row]

    @property
    def tip_part(self) -> FloatArray:
        """(S, 3) float — mm, FK tool tip in part coordinates."""
        return self.setup.points_to_part(self.samples_kept.tip)

    @property
    def axis_part(self) -> FloatArray:
        """(S, 3) float — unit, FK tool axis in part coordinates."""
        return self.setup.axes_to_part(self.samples_kept.axis)


def verify_program(
    machine: Machine,
    program: JointProgram,
    *,
    setup: Setup,
    tolerance: float,
    axis_tolerance: float,
    length_decimals: int,
    feed_decimals: int,
    intended: Intended | None = None,
    blending_lines: tuple[int, ...] = (),
    keep_samples: bool = True,
    chunk_rows: int = CHUNK_ROWS,
    tool_lengths: dict[int, float] | None = None,
    odd_feeds: bool = True, progress: Progress | None = None,
) -> VerifyReport:
    """Replay and check a program (module docstring), ``chunk_rows`` rows at a time (:class:`Verifier`).

    Parameters
    ----------
    machine : Machine
    program : JointProgram — N ≥ 1 rows, ``source`` = line numbers
    setup : Setup — the part → machine transform (for part coordinates in the report)
    tolerance : float — mm, allowed tip deviation (plus the output rounding against a path)
    axis_tolerance : float — rad, allowed axis deviation from an intended path
    length_decimals, feed_decimals : int — decimals of the axis words and of F (the dialect's)
    intended : Intended, optional — one pose per row
    blending_lines : tuple of int — lines that switch on G64 path blending (each gets a warning: the
        replay assumes exact stops at every row, as G61 asks)
    keep_samples : bool — keep every sample in ``report.replay`` (the JSON report and the preview
        need them; the text report does not)
    chunk_rows : int — rows replayed at a time (the report does not depend on it); ``progress``: told (done, N)
    tool_lengths : dict, optional — mm, the tool length "TL" (platform centre to tip) of each tool
        number: after a tool change (M6 T) the tip is that far from the platform centre (a program
        made with a tool table states them in its header); None: the machine's for every row
    odd_feeds : bool — without an intended path with feeds, warn of a G1 whose feed matches no other (a hand
        edit in a main job's program, whose operations each use a feed and a plunge feed); False for a converted
        program, whose feeds are the CAM program's

    Returns
    -------
    VerifyReport

    Raises
    ------
    Prs3Error
        When ``intended`` has another number of rows than the program (not the same program).
    """
    n = len(program)
    if intended is not None and len(intended.tip) != n:
        raise Prs3Error(f"the program has {n} moves, {intended.label} has {len(intended.tip)}: they do not "
                        "describe the same path (check the options it was made with)")
    verifier = Verifier(machine, setup=setup, tolerance=tolerance, axis_tolerance=axis_tolerance,
                        length_decimals=length_decimals, feed_decimals=feed_decimals, intended=intended,
                        keep_samples=keep_samples, keep_rows=False, capacity=n, tool_lengths=tool_lengths,
                        odd_feeds=odd_feeds)
    step = max(1, int(chunk_rows))
    for first in range(0, n, step):
        rows = _rows_of(program, first, min(first + step, n))
        if tool_lengths:                               # the tool changes in these rows, counted from the first
            rows = dataclasses.replace(rows, events=tuple(
                dataclasses.replace(e, before=e.before - first) for e in program.events
                if e.kind is EventKind.TOOL_CHANGE and first <= e.before < first + step))
        verifier.add(rows)
        if progress is not None:
            progress(min(first + step, n), n)
    return verifier.report(blending_lines=blending_lines, program=program)


def _rows_of(program: JointProgram, start: int, stop: int) -> JointProgram:
    """Rows ``start:stop`` of a program (without its events: the report takes them from the whole)."""
    return JointProgram(kind=program.kind[start:stop], stage=program.stage[start:stop],
                        strokes=program.strokes[start:stop], inverse_time=program.inverse_time[start:stop],
                        source=program.source[start:stop])


class Verifier:
    """Verify a program chunk by chunk (consecutive rows, in order), in memory that does not grow with
    the samples: each chunk is replayed from the previous chunk's last row (replayed again as the
    start of the next move), checked, and reduced to a few numbers per move and the running closest
    approach to each limit. The report is the same for any chunking (tests/test_verify.py).

    Use: ``v = Verifier(machine, setup=...); for chunk in chunks: v.add(chunk); v.report()``.
    Parameters as :func:`verify_program`, and ``keep_rows`` (False: :meth:`report` is given the whole
    program), ``capacity`` (rows to reserve room for: an upper bound saves growing the arrays),
    ``tool_lengths`` (as :func:`verify_program`; the chunks' tool-change events say which tool), ``odd_feeds``
    (as :func:`verify_program`).
    """

    def __init__(self, machine: Machine, *, setup: Setup, tolerance: float, axis_tolerance: float,
                 length_decimals: int, feed_decimals: int,
                 intended: Intended | None = None, keep_samples: bool = False, keep_rows: bool = True,
                 capacity: int = 0, tool_lengths: dict[int, float] | None = None, odd_feeds: bool = True):
        self.machine, self.setup, self.tolerance, self.axis_tolerance = machine, setup, tolerance, axis_tolerance
        self.odd_feeds = odd_feeds                           # warn of a G1 feed that matches no other
        self.tool_lengths = tool_lengths or {}
        self.tool_length = machine.geometry.tool_length    # mm, "TL" of the tool in the spindle (before any M6)
        self.last_tool_length = self.tool_length             # mm, "TL" the previous chunk's last row was cut with
        self.length_decimals, self.feed_decimals, self.intended = length_decimals, feed_decimals, intended
        self.keep_samples = keep_samples or intended is not None
        self.rows = 0                                        # rows added so far
        # the program's rows (unless the caller has them) and the per-move values, each in one array
        joints = (len(kinematics_of(machine).joint_names),)                 # each row's joints
        self.program_rows = _Columns({**_ROW_COLUMNS, "strokes": (np.float64, joints)}, capacity) if keep_rows else None
        self.events: list[Event] = []
        self.per_move = _Columns(_PER_MOVE, capacity)
        self.samples = 0
        self.kept: list[tuple[Replay, FloatArray, Against | None]] = []
        self.best: list[tuple[float, float, int, float] | None] = []       # per limit: margin, value, line, at
        self.limit_table: LimitReport | None = None
        self.problems: list[Problem] = []
        self.warnings: list[Problem] = []
        self.last: JointProgram | None = None                # the previous chunk's last row
        self.fastest: tuple[float, int, str] = (0.0, 0, "")   # the worst G1 axis speed / top speed, line, axis

    def add(self, chunk: JointProgram) -> None:
        """Replay and check the next rows (their events count rows from the chunk's start)."""
        if self.program_rows is not None:
            self.events += [Event(before=e.before + self.rows, kind=e.kind, value=e.value, text=e.text)
                            for e in chunk.events]
            self.program_rows.append({"kind": chunk.kind, "stage": chunk.stage, "strokes": chunk.strokes,
                                      "inverse_time": chunk.inverse_time, "source": chunk.source})
        if not len(chunk):                               # events only (an M6 T line read alone): the tool in
            self._row_tool_lengths(chunk, carried=False)  # the spindle changes all the same
            return
        carried = self.last is not None
        rows = _rows_of(chunk, 0, len(chunk)) if self.last is None else _join_rows(self.last, chunk)
        skip = 1 if carried else 0
        offset = self.rows - skip                              # global row of local row 0
        joints = joints_of(rows)
        machine = self.machine
        # every FK the chunk needs before sampling, in one call: the rows' distinct head poses, the
        # mirror points of the translation moves (their sampling bound), the rounding's differences
        direction = head_shift(machine)
        canonical, index = shift_keys(joints[:, 2:], shift=direction is not None)
        translations = self.intended is None
        moves = translation_candidates(joints) if translations and direction is not None else None
        mirror_keys = shift_keys(moves.back[:, 2:]) if moves is not None and len(moves.rows) else None
        parts = [canonical] + ([mirror_keys[0]] if mirror_keys is not None else [])
        fk = forward_parts(machine, parts + rounding_strokes(canonical, ROUNDING_STEP))
        ends = expand(fk[0], condition_numbers(machine, fk[0]), index, joints, direction)
        flat_bound = None
        if moves is not None:
            mirror = expand(fk[1], None, mirror_keys[1], moves.back, direction) if mirror_keys is not None else None
            flat_bound = translation_bound(machine, joints, ends, moves, mirror)
        rep = _with_limits(machine, replay_joints(machine, joints, tolerance=self.tolerance,
                                                  translations=translations, ends=ends, flat_bound=flat_bound))
        if self.tool_lengths:                                  # each row's tip with the tool in the spindle
            lengths = self._row_tool_lengths(chunk, carried)
            shift = (self.machine.geometry.tool_length - lengths)[rep.row]
            rep = dataclasses.replace(rep, tip=rep.tip + shift[:, None] * rep.axis)
        rounding = np.take(rounding_from(machine, fk[len(parts):], self.length_decimals, step=ROUNDING_STEP), index)
        self.last = _rows_of(chunk, len(chunk) - 1, len(chunk))
        self.rows += len(chunk)
        self._check(rows, rep, rounding, skip, offset)

    def _row_tool_lengths(self, chunk: JointProgram, carried: bool) -> FloatArray:
        """mm, the tool length "TL" of each row of the chunk (after the carried row, when there is one):
        a tool change (M6 T) before a row makes it and the rows after it use that tool's length
        (``tool_lengths``; a tool not in it: the machine's)."""
        lengths = np.zeros(len(chunk))
        current, at = self.tool_length, 0
        for event in sorted((e for e in chunk.events if e.kind is EventKind.TOOL_CHANGE), key=lambda e: e.before):
            lengths[at:event.before] = current
            current = self.tool_lengths.get(int(event.value), self.machine.geometry.tool_length)
            at = min(event.before, len(chunk))
        lengths[at:] = current
        before = [self.last_tool_length] if carried else []   # an M6 after that row does not move it
        self.tool_length = current
        if len(lengths):
            self.last_tool_length = float(lengths[-1])
        return np.concatenate([before, lengths])

    def _check(self, rows: JointProgram, rep: Replay, rounding: FloatArray, skip: int, offset: int) -> None:
        """The checks of the module docstring on one replayed chunk; local rows ≥ ``skip`` are its own."""
        tolerance, problems, warnings = self.tolerance, self.problems, self.warnings
        n = len(rows)
        lines = rows.source
        feed_row = rows.kind == MoveKind.FEED
        own = slice(int(rep.first[skip]), len(rep.row))       # the chunk's own samples

        # ---- assembly and limits
        bad_rows = np.zeros(0, dtype=np.int64) if rep.converged.all() else np.unique(rep.row[~rep.converged])
        for r in bad_rows[bad_rows >= skip].tolist():
            i = int(rep.first[r] + np.flatnonzero(~rep.converged[rep.first[r]:rep.end[r] + 1])[0])
            strokes = ", ".join(f"{v:.4f}" for v in rep.joints[i, 2:])
            problems.append(Problem(int(lines[r]), "reach", f"line {lines[r]}: the head does not assemble at "
                                    f"{_at(rep.fraction[i])} (strokes {strokes} mm)"))
        limits = rep.limits
        with np.errstate(invalid="ignore"):
            outside = limits.margin < 0.0
        for col in np.flatnonzero(outside.any(axis=0)).tolist():
            bad = np.unique(rep.row[outside[:, col]])
            for r in bad[bad >= skip].tolist():
                i = int(rep.first[r] + np.nanargmin(limits.margin[rep.first[r]:rep.end[r] + 1, col]))
                problems.append(Problem(int(lines[r]), "limit",
                                        f"line {lines[r]}: {limits.describe(i, col)} at {_at(rep.fraction[i])}"))
        self._closest_in(rep, lines, own)

        # ---- axis speeds (the machine's dynamics)
        if self.machine.dynamics is not None:
            names = axis_names(self.machine)
            ratio, axis, over = speed_excess(self.machine.dynamics, rows, names=names, first=skip,
                                             length_decimals=self.length_decimals, feed_decimals=self.feed_decimals)
            for r, text in over:
                problems.append(Problem(int(lines[r]), "speed", f"line {lines[r]}: {text}"))
            if len(ratio) > skip and float(ratio[skip:].max()) > self.fastest[0]:
                r = skip + int(np.argmax(ratio[skip:]))
                self.fastest = (float(ratio[r]), int(lines[r]), names[int(axis[r])])

        # ---- straightness of G1 moves
        end = rep.end
        ends_only = len(rep.row) == n                   # one sample per row: its end point
        on_feed = feed_row[rep.row] & (rep.row > 0)
        straightness = np.where(on_feed, _off_chord(rep, ends_only), np.nan)
        worst, worst_at = _row_max(straightness, rep.first)
        # No tip where the head does not assemble, so no chord to measure from (NaN): the reach
        # problem of this line, or of the previous one (the move's start point), already says so.
        checked = feed_row.copy()
        checked[:max(skip, 1)] = False
        checked[bad_rows] = False
        checked[1:] &= rep.converged[end[:-1]]
        for r in np.flatnonzero(checked & ~(worst <= tolerance)).tolist():
            i = int(worst_at[r])
            problems.append(Problem(int(lines[r]), "straightness",
                                    f"line {lines[r]}: the tip leaves the straight line between the move's end "
                                    f"points by {straightness[i]:.6f} mm at {_at(rep.fraction[i])} "
                                    f"(tolerance {tolerance:g} mm)"))

        # ---- feeds
        chord = np.full(n, np.nan)
        if n > 1:
            tip_end = rep.tip if ends_only else np.take(rep.tip, end, axis=0)
            chord[1:] = _norm3(tip_end[1:] - tip_end[:-1])
        inverse_time = np.asarray(rows.inverse_time)
        implied = np.where(feed_row, chord * inverse_time, np.nan)
        half_f = 0.5 * 10.0 ** (-self.feed_decimals)
        ends_rounding = np.full(n, np.nan)
        if n > 1:
            ends_rounding[1:] = rounding[1:] + rounding[:-1]
        with np.errstate(invalid="ignore", divide="ignore"):
            slack = np.where(feed_row, implied * half_f / inverse_time + inverse_time * ends_rounding, np.nan) + 1e-9
        if offset == 0 and n and feed_row[0]:
            warnings.append(Problem(int(lines[0]), "feed", f"line {lines[0]}: the program starts with a G1: its "
                                    "start point, and so its tip feed, is unknown"))
        for r in np.flatnonzero(feed_row[1:] & (chord[1:] < 1e-9)).tolist():   # local row 0: not a move here
            warnings.append(Problem(int(lines[r + 1]), "feed", f"line {lines[r + 1]}: G1 of zero length (it only "
                                    "waits 1/F min)"))
        intended = self.intended
        local_intended = None
        if intended is not None:
            local_intended = _intended_rows(intended, offset, offset + n)
            want = np.asarray(local_intended.feed)
            check = feed_row & np.isfinite(want) & np.isfinite(implied)
            check[:skip] = False
            for r in np.flatnonzero(check & ~(np.abs(implied - want) <= slack)).tolist():
                problems.append(Problem(int(lines[r]), "feed",
                                        f"line {lines[r]}: implied tip feed {implied[r]:.3f} mm/min (chord "
                                        f"{chord[r]:.4f} mm × F {inverse_time[r]:g}) is not the intended "
                                        f"{want[r]:.3f} mm/min (allowed ± {slack[r]:.3f} for the rounding)"))

        # ---- against an intended path
        against = None
        if local_intended is not None:
            against = _against(rep, rows, local_intended, rounding, tolerance)
            _against_problems(against, rep, rows, local_intended, self.axis_tolerance, problems, skip)

        durations = move_durations(rows, rapid_rate=NOMINAL_RAPID_RATE, dynamics=self.machine.dynamics)
        self.per_move.append({name: values[skip:] for name, values in zip(
            _PER_MOVE, (rounding, chord, implied, slack, worst, rep.intervals, rep.bound, durations), strict=True)})
        self.samples += len(rep.row) - own.start
        if self.keep_samples:
            self.kept.append((_replay_from(rep, own, skip, offset), straightness[own],
                              None if against is None else _against_from(against, own)))

    def _closest_in(self, rep: Replay, lines: IntArray, own: slice) -> None:
        """Fold the chunk's closest approach to each limit into the running one (the first on ties)."""
        limits = rep.limits
        if self.limit_table is None:
            self.limit_table = limits
            self.best = [None] * len(limits.names)
        margin = limits.margin[own]
        for col in range(len(limits.names)):
            if not np.isfinite(margin[:, col]).any():
                if self.best[col] is None and len(margin):
                    i = own.start
                    self.best[col] = (math.nan, math.nan, int(lines[rep.row[i]]), float(rep.fraction[i]))
                continue
            i = int(np.nanargmin(margin[:, col])) + own.start
            held = self.best[col]
            if held is None or not math.isfinite(held[0]) or limits.margin[i, col] < held[0]:
                self.best[col] = (float(limits.margin[i, col]), float(limits.value[i, col]),
                                  int(lines[rep.row[i]]), float(rep.fraction[i]))

    def report(self, *, blending_lines: tuple[int, ...] = (), program: JointProgram | None = None) -> VerifyReport:
        """The report of every row added (``program``: the whole program, if at hand; else the chunks joined).

        Raises
        ------
        Prs3Error
            When an intended path has another number of rows than the program.
        """
        if program is None:
            if self.program_rows is None:
                raise ValueError("a Verifier made with keep_rows=False needs the program")
            program = program_from_columns(self.program_rows.take(), self.events)
        n = len(program)
        if self.intended is not None and len(self.intended.tip) != n:
            raise Prs3Error(f"the program has {n} moves, {self.intended.label} has {len(self.intended.tip)}: they do "
                            "not describe the same path (check the options it was made with)")
        per_move: dict[str, Any] = self.per_move.take()
        lines = program.source
        problems, warnings = list(self.problems), list(self.warnings)
        feed_row = program.kind == MoveKind.FEED
        implied, slack = per_move["implied"], per_move["slack"]
        groups = _feed_groups(implied, slack, lines)
        intended = self.intended
        known = intended is not None and bool(np.isfinite(intended.feed[feed_row]).any())
        if self.odd_feeds and not known and int(feed_row[1:].sum()) >= 3 and len(groups) > 1:
            shown = ", ".join(f"{g.feed:.1f} ×{len(g.lines)}" for g in groups if len(g.lines) > 1) or "none repeat"
            for g in groups:
                if len(g.lines) == 1:
                    line = int(g.lines[0])
                    warnings.append(Problem(line, "feed", f"line {line}: implied tip feed {g.feed:.3f} mm/min "
                                            f"matches no other G1 (feeds: {shown}): a hand-edited F or point?"))
        for number in blending_lines:
            warnings.append(Problem(number, "blending", f"line {number}: G64 path blending: the control may "
                                    "round corners in joint space (a curve at the tip); the replay assumes exact stops "
                                    "(G61)"))
        problems.sort(key=lambda p: p.line)
        warnings.sort(key=lambda p: p.line)
        replay_all, against = self._joined_samples()
        return VerifyReport(
            program=program, replay=replay_all, machine=self.machine.name, setup=self.setup,
            tolerance=self.tolerance, axis_tolerance=self.axis_tolerance, rounding=per_move["rounding"],
            straightness=per_move["straightness"], chord=per_move["chord"], implied_feed=implied, feed_slack=slack,
            intervals=per_move["intervals"], bound=per_move["bound"], samples=self.samples,
            epsilon=self.tolerance * EPSILON_FRACTION, feed_groups=groups, closest=self._closest_table(),
            against=against, problems=tuple(problems), warnings=tuple(warnings),
            dynamics=self.machine.dynamics, fastest=self.fastest, duration=per_move["duration"],
            joint_names=kinematics_of(self.machine).joint_names)

    def _closest_table(self) -> tuple[Closest, ...]:
        limits = self.limit_table
        if limits is None:
            return ()
        spread = margin_fraction(limits)
        out = []
        for col, held in enumerate(self.best):
            margin, value, line, at = held if held is not None else (math.nan, math.nan, 0, 0.0)
            scale = math.degrees(1.0) if limits.units[col] == "deg" else 1.0
            out.append(Closest(name=limits.names[col], unit=limits.units[col], low=float(limits.low[col]) * scale,
                               high=float(limits.high[col]) * scale, value=value * scale, margin=margin * scale,
                               fraction_of_range=margin / float(spread[col]), line=line, at=at))
        return tuple(out)

    def _joined_samples(self) -> tuple[Replay | None, Against | None]:
        if not self.kept:
            return None, None
        reps, base = [], 0
        for kept, _, _ in self.kept:                         # sample indices counted from the program's start
            reps.append(Replay(row=kept.row, fraction=kept.fraction, joints=kept.joints, tip=kept.tip, axis=kept.axis,
                               converged=kept.converged, link_angle=kept.link_angle, condition=kept.condition,
                               limits=kept.limits, first=kept.first + base, end=kept.end + base,
                               intervals=kept.intervals, bound=kept.bound, epsilon=kept.epsilon))
            base += len(kept.row)
        limits = reps[0].limits
        joined = Replay(
            row=np.concatenate([r.row for r in reps]), fraction=np.concatenate([r.fraction for r in reps]),
            joints=np.concatenate([r.joints for r in reps]), tip=np.concatenate([r.tip for r in reps]),
            axis=np.concatenate([r.axis for r in reps]), converged=np.concatenate([r.converged for r in reps]),
            link_angle=np.concatenate([r.link_angle for r in reps]),
            condition=np.concatenate([r.condition for r in reps]),
            limits=LimitReport(names=limits.names, units=limits.units, low=limits.low, high=limits.high,
                               value=np.concatenate([r.limits.value for r in reps]),
                               margin=np.concatenate([r.limits.margin for r in reps]),
                               ok=np.concatenate([r.limits.ok for r in reps])),
            first=np.concatenate([r.first for r in reps]), end=np.concatenate([r.end for r in reps]),
            intervals=np.concatenate([r.intervals for r in reps]), bound=np.concatenate([r.bound for r in reps]),
            epsilon=reps[0].epsilon,
        )
        parts = [k[2] for k in self.kept]
        against = None
        if all(a is not None for a in parts):
            done = [a for a in parts if a is not None]
            against = Against(label=done[0].label, compared=np.concatenate([a.compared for a in done]),
                              tip_deviation=np.concatenate([a.tip_deviation for a in done]),
                              axis_deviation=np.concatenate([a.axis_deviation for a in done]),
                              allowed=np.concatenate([a.allowed for a in done]))
        return joined, against


#: The per-move values a Verifier keeps (dtype, row shape).
_PER_MOVE: dict[str, tuple[type, tuple[int, ...]]] = {
    "rounding": (np.float64, ()), "chord": (np.float64, ()), "implied": (np.float64, ()), "slack": (np.float64, ()),
    "straightness": (np.float64, ()), "intervals": (np.int64, ()), "bound": (np.float64, ()),
    "duration": (np.float64, ())}
#: A program's rows as a Verifier keeps them.
_ROW_COLUMNS: dict[str, tuple[type, tuple[int, ...]]] = {
    "kind": (np.int64, ()), "stage": (np.float64, (2,)), "strokes": (np.float64, (3,)),
    "inverse_time": (np.float64, ()), "source": (np.int64, ())}


class _Columns:
    """Columns that grow by rows, one array each (room reserved, or grown by half): a long program's
    values without a piece per chunk, which would leave the heap fragmented once joined."""

    def __init__(self, layout: dict[str, tuple[type, tuple[int, ...]]], capacity: int = 0):
        self.size = 0
        self.arrays: dict[str, np.ndarray] = {name: np.zeros((max(capacity, 0), *tail), dtype=dtype)
                                              for name, (dtype, tail) in layout.items()}

    def append(self, values: dict[str, np.ndarray]) -> None:
        need = self.size + len(next(iter(values.values())))
        for name, array in self.arrays.items():
            if need > len(array):
                grown = np.zeros((max(need, len(array) * 3 // 2 + 1024), *array.shape[1:]), dtype=array.dtype)
                grown[:self.size] = array[:self.size]
                self.arrays[name] = array = grown
            array[self.size:need] = values[name]
        self.size = need

    def take(self) -> dict[str, np.ndarray]:
        """The filled rows of each column (views)."""
        return {name: array[:self.size] for name, array in self.arrays.items()}


def _norm3(vectors: FloatArray) -> FloatArray:
    """(N,) the length of each row of (N, 3) ``vectors``: np.linalg.norm(vectors, axis=1), the same
    sum in the same order, column by column (numpy's reductions along a row of three are slow)."""
    x, y, z = vectors[:, 0], vectors[:, 1], vectors[:, 2]
    return np.sqrt(x * x + y * y + z * z)


def _off_chord(rep: Replay, ends_only: bool) -> FloatArray:
    """(S,) mm, each sample's distance from the straight chord of its move: |tip − (start + t (end − start))|."""
    end = rep.end
    if ends_only:                                       # sample s is row s's end point (t = 1)
        start_tip = np.take(rep.tip, np.maximum(np.arange(len(end)) - 1, 0), axis=0)
        end_tip = rep.tip
    else:
        start_tip = np.take(rep.tip, np.take(end, np.maximum(rep.row - 1, 0)), axis=0)
        end_tip = np.take(rep.tip, np.take(end, rep.row), axis=0)
    # (1 − t)·start + t·end, not start + t·(end − start): exact at t = 1 (and t = 0), so that a move's end
    # sample is 0 off its chord whether its chunk has one sample per row or more (chunk sizes agree)
    fraction = rep.fraction[:, None]
    chord_point = (1.0 - fraction) * start_tip + fraction * end_tip
    return _norm3(rep.tip - chord_point)


def _row_max(values: FloatArray, first: IntArray) -> tuple[FloatArray, IntArray]:
    """Per row (samples ``first[r]:first[r + 1]``): the largest value, NaN ignored (NaN: none), and the
    first sample that has it."""
    if not len(first):
        return np.zeros(0), np.zeros(0, dtype=np.int64)
    if len(first) == len(values):                       # one sample per row
        return values.copy(), np.where(np.isnan(values), len(values) - 1, np.arange(len(values)))
    top = np.fmax.reduceat(values, first)
    row = np.repeat(np.arange(len(first)), np.diff(np.append(first, len(values))))
    at = np.minimum.reduceat(np.where(values == top[row], np.arange(len(values)), len(values)), first)
    return top, np.minimum(at, len(values) - 1)


def _join_rows(head: JointProgram, chunk: JointProgram) -> JointProgram:
    return JointProgram(kind=np.concatenate([head.kind, chunk.kind]), stage=np.concatenate([head.stage, chunk.stage]),
                        strokes=np.concatenate([head.strokes, chunk.strokes]),
                        inverse_time=np.concatenate([head.inverse_time, chunk.inverse_time]),
                        source=np.concatenate([head.source, chunk.source]))


def _intended_rows(intended: Intended, start: int, stop: int) -> Intended:
    return Intended(tip=intended.tip[start:stop], axis=intended.axis[start:stop], feed=intended.feed[start:stop],
                    kind=intended.kind[start:stop], label=intended.label)


def _replay_from(rep: Replay, own: slice, skip: int, offset: int) -> Replay:
    """The chunk's own samples, with rows and sample indices counted from the program's start."""
    first_sample = own.start
    return Replay(
        row=rep.row[own] + offset, fraction=rep.fraction[own], joints=rep.joints[own], tip=rep.tip[own],
        axis=rep.axis[own], converged=rep.converged[own], link_angle=rep.link_angle[own],
        condition=rep.condition[own],
        limits=LimitReport(names=rep.limits.names, units=rep.limits.units, low=rep.limits.low, high=rep.limits.high,
                           value=rep.limits.value[own], margin=rep.limits.margin[own], ok=rep.limits.ok[own]),
        first=rep.first[skip:] - first_sample, end=rep.end[skip:] - first_sample, intervals=rep.intervals[skip:],
        bound=rep.bound[skip:], epsilon=rep.epsilon,
    )


def _against_from(against: Against, own: slice) -> Against:
    return Against(label=against.label, compared=against.compared[own], tip_deviation=against.tip_deviation[own],
                   axis_deviation=against.axis_deviation[own], allowed=against.allowed[own])


def _at(fraction: float) -> str:
    """Where on a move a sample is: ``the end point`` or ``37.5 % of the move``."""
    return "the end point" if fraction >= 1.0 else f"{100.0 * fraction:.1f} % of the move"


def _feed_groups(implied: FloatArray, slack: FloatArray, lines: IntArray) -> tuple[FeedGroup, ...]:
    """Implied feeds sorted and chained into groups where neighbours agree within their slacks."""
    rows = np.flatnonzero(np.isfinite(implied) & (implied > 0))
    if not len(rows):
        return ()
    rows = rows[np.argsort(implied[rows], kind="stable")]
    split = np.flatnonzero(np.diff(implied[rows]) > slack[rows[:-1]] + slack[rows[1:]]) + 1
    groups = []
    for part in np.split(rows, split):
        members = np.sort(part)
        groups.append(FeedGroup(feed=float(np.mean(implied[members])),
                                lines=np.asarray(lines[members], dtype=np.int64)))
    return tuple(groups)


def _against(rep: Replay, program: JointProgram, intended: Intended, rounding: FloatArray,
             tolerance: float) -> Against:
    row, t = rep.row, rep.fraction
    kind = np.where(np.asarray(intended.kind) >= 0, intended.kind, program.kind)
    is_end = np.zeros(len(row), dtype=bool)
    is_end[rep.end] = True
    compared = is_end | ((kind[row] == MoveKind.FEED) & (row > 0))
    prev = np.maximum(row - 1, 0)
    target_tip = intended.tip[prev] + t[:, None] * (intended.tip[row] - intended.tip[prev])
    target_tip[is_end] = intended.tip[row[is_end]]
    target_axis = slerp(intended.axis[prev], intended.axis[row], t)
    target_axis[is_end] = intended.axis[row[is_end]]
    tip_dev = np.where(compared[:, None], rep.tip - target_tip, np.nan)
    cross = np.linalg.norm(np.cross(rep.axis, target_axis), axis=1)
    axis_dev = np.where(compared, np.arctan2(cross, np.sum(rep.axis * target_axis, axis=1)), np.nan)
    allowed = tolerance + np.where(is_end, rounding[row], np.maximum(rounding[row], rounding[prev]))
    return Against(label=intended.label, compared=compared, tip_deviation=tip_dev, axis_deviation=axis_dev,
                   allowed=allowed)


def _against_problems(against: Against, rep: Replay, program: JointProgram, intended: Intended,
                      axis_tolerance: float, problems: list[Problem], skip: int = 0) -> None:
    """Problems of the rows from ``skip`` on (the rows before are the previous chunk's)."""
    lines = program.source
    differ = np.flatnonzero((intended.kind >= 0) & (intended.kind != program.kind))
    for r in differ[differ >= skip].tolist():
        want = "G1" if intended.kind[r] == MoveKind.FEED else "G0"
        problems.append(Problem(int(lines[r]), "move", f"line {lines[r]}: {want} intended, the program has "
                                f"{'G1' if program.kind[r] == MoveKind.FEED else 'G0'}"))
    tip = np.linalg.norm(against.tip_deviation, axis=1)
    with np.errstate(invalid="ignore"):
        tip_over = tip > against.allowed
        axis_over = against.axis_deviation > axis_tolerance
    for r in (rows := np.unique(rep.row[tip_over]))[rows >= skip].tolist():
        i = int(rep.first[r] + np.nanargmax(tip[rep.first[r]:rep.end[r] + 1]))
        problems.append(Problem(int(lines[r]), "deviation",
                                f"line {lines[r]}: the tip is {tip[i]:.6f} mm from the intended path at "
                                f"{_at(rep.fraction[i])} (allowed {against.allowed[i]:.6f} mm: tolerance + "
                                "output rounding)"))
    for r in (rows := np.unique(rep.row[axis_over]))[rows >= skip].tolist():
        i = int(rep.first[r] + np.nanargmax(against.axis_deviation[rep.first[r]:rep.end[r] + 1]))
        problems.append(Problem(int(lines[r]), "axis",
                                f"line {lines[r]}: the tool axis is {math.degrees(against.axis_deviation[i]):.4f}° "
                                f"from the intended axis at {_at(rep.fraction[i])} (allowed "
                                f"{math.degrees(axis_tolerance):g}°)"))
