"""A replayed program over time: every limit's value at every sample, with its bounds, and where the
operations and tool changes begin (the plots of the preview and of the HTML view).

    VerifyReport (FK replay, every sample) ──► timeline_of ──► Timeline ──► decimate(n_max) ──► plots

Time: each sample of move k is at ``start_k + t·(end_k − start_k)``, t its fraction along the move,
start and end from :func:`~prs3_post.check.verify.row_times` (the machine's ``[dynamics]``, else G1
1/F and G0 the longest joint travel at a nominal rapid rate; G4 dwells delay the next move). With
dynamics a move's axes run a trapezoid in time: the sample is placed linearly (the chord of the
S-shaped curve), as the preview draws it.

Series: one per column of the replay's :class:`~prs3_post.post.limits.LimitReport` (the
kinematics' strokes, link angles, tilt, condition number, then stage X and Y when the machine has
a stage), with its bounds, then each axis's speed: a G1's axis runs at ``|Δq|·F``, a G0's axes at
the speed of the slowest axis's move (with ``[dynamics]`` its trapezoid's peak: the top speed, or
``√(d·a)`` on a move too short to reach it; without, the longest travel at the rapid rate), the
others in proportion, bounded by ``[dynamics]``'s top speeds (unbounded without). Values are in
code units (mm, rad, mm/min); a series whose ``unit`` is ``deg`` is kept in rad
(:meth:`Series.shown` converts).

Boundaries: the tool changes (M6) and the operations a program's text marks (found by the
``app`` layer, which reads the text and the header: :class:`Mark`); without marks, each tool change
event of the program, at the line of its first move after.

Pure numpy: no I/O, no plotting library.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from prs3_post.check.verify import VerifyReport, margin_fraction, row_times
from prs3_post.core.defaults import NOMINAL_RAPID_RATE
from prs3_post.core.toolpath import EventKind, MoveKind
from prs3_post.core.types import FloatArray, IntArray
from prs3_post.kinematics.replay import joints_of
from prs3_post.post.dynamics import joint_deltas

__all__ = ["Boundary", "Mark", "MarkKind", "Series", "Timeline", "timeline_of"]


class MarkKind(enum.Enum):
    """What begins at a boundary."""

    TOOL_CHANGE = "tool change"
    """An M6: another tool in the spindle from this row on."""
    OPERATION = "operation"
    """An operation of the job (a header's operation, or a converted program's tool path) begins."""


@dataclass(frozen=True, slots=True)
class Mark:
    """Where something begins in a program's text (found by who reads the text).

    Attributes
    ----------
    row : int — the first program row (move) after it (N: after the last move)
    line : int — 1-based program line (the M6's line, an operation's title comment)
    kind : MarkKind
    label : str — ``T2 D8.000 mm tool``, ``drill 2 holes D6.000 on face 5``
    """

    row: int
    line: int
    kind: MarkKind
    label: str


@dataclass(frozen=True, slots=True)
class Boundary:
    """A :class:`Mark` placed in time.

    Attributes
    ----------
    row, line, kind, label : as :class:`Mark`
    time : float — min, when the move of ``row`` starts (the end of the program after the last move)
    """

    row: int
    line: int
    kind: MarkKind
    label: str
    time: float


@dataclass(frozen=True, slots=True)
class Series:
    """One quantity over the samples, with its bounds.

    Attributes
    ----------
    name : str — ``T1 stroke``, ``θ2 link angle``, ``tilt``, ``stage X``, ``T1 speed``, ``stage X speed``
    group : str — what series sharing a plot share (``stroke``, ``link angle``, ``tilt``, ``condition number``,
        ``stage``, ``stroke speed``, ``stage speed``)
    unit : str — ``mm``, ``deg`` (values kept in rad), ``mm/min`` or ``""``
    values : (S,) float — code units (mm, rad, mm/min); NaN where the head does not assemble
    low, high : float — the bounds (``-inf`` / ``inf`` where there is none), code units
    """

    name: str
    group: str
    unit: str
    values: FloatArray
    low: float
    high: float

    @property
    def scale(self) -> float:
        """The factor from code units to the shown unit (degrees for ``deg``, else 1)."""
        return math.degrees(1.0) if self.unit == "deg" else 1.0

    def shown(self) -> tuple[FloatArray, float, float]:
        """The values and bounds in the shown unit (degrees for ``deg``): (S,) float, low, high."""
        return self.values * self.scale, self.low * self.scale, self.high * self.scale


@dataclass(frozen=True, slots=True)
class Timeline:
    """A replayed program's samples over time (module docstring); S samples, N program rows.

    Attributes
    ----------
    time : (S,) float — min, program time of each sample (ascending)
    row : (S,) int — each sample's program row (ascending)
    series : tuple of Series — each with (S,) values
    boundaries : tuple of Boundary — the tool changes and operation starts, in program order
    row_line : (N,) int — each row's program line (``source``)
    row_operation : (N,) int — each row's operation: the index of the last OPERATION boundary at or
        before it (0 before the first; one operation for a program without)
    operations : tuple of str — each operation's label
    worst : int — the sample of the smallest margin of any limit, as a fraction of its range
        (:func:`~prs3_post.check.verify.margin_fraction`; speeds excluded); -1 when no sample has one
    worst_series : str — the series of that margin ("" when none)
    dynamics : bool — timed with the machine's ``[dynamics]`` (else at ``rapid_rate``)
    rapid_rate : float — mm/min, the G0 rate without dynamics
    kept : (S,) int — each sample's index among the replay's samples (``arange(S)`` until decimated)
    """

    time: FloatArray
    row: IntArray
    series: tuple[Series, ...]
    boundaries: tuple[Boundary, ...]
    row_line: IntArray
    row_operation: IntArray
    operations: tuple[str, ...]
    worst: int
    worst_series: str
    dynamics: bool
    rapid_rate: float
    kept: IntArray

    def __len__(self) -> int:
        return len(self.time)

    @property
    def line(self) -> IntArray:
        """(S,) int — the program line of each sample."""
        return self.row_line[self.row]

    @property
    def operation(self) -> IntArray:
        """(S,) int — the operation (index into :attr:`operations`) of each sample."""
        return self.row_operation[self.row]

    def get(self, name: str) -> Series:
        """The series named ``name``; KeyError when there is none."""
        for series in self.series:
            if series.name == name:
                return series
        raise KeyError(f"no series {name!r} (there are {', '.join(s.name for s in self.series)})")

    def group(self, group: str) -> tuple[Series, ...]:
        """The series of one group (empty when there is none)."""
        return tuple(s for s in self.series if s.group == group)

    @property
    def groups(self) -> tuple[str, ...]:
        """The groups, in the order of their first series."""
        return tuple(dict.fromkeys(s.group for s in self.series))

    def decimate(self, n_max: int) -> Timeline:
        """At most ``n_max`` samples (this one when it has no more), keeping every extreme: the first
        and last samples, the worst-margin sample, the samples on both sides of each boundary and, in
        each of B equal buckets of samples, each series' least and greatest value (B as large as
        ``n_max`` allows, at least 1: with many series and a small ``n_max`` the kept extremes may
        come to more than ``n_max``, never fewer than every series' global minimum and maximum).

        Every series' overall minimum and maximum, and every value beyond a bound, lies in some
        bucket's extremes, so what a plot of the kept samples shows reaches as far as the whole.
        """
        n = len(self.time)
        if n <= n_max:
            return self
        fixed = [np.array([0, n - 1]), self._boundary_samples()]
        if self.worst >= 0:
            fixed.append(np.array([self.worst]))
        per_bucket = 2 * max(1, len(self.series))
        buckets = max(1, (int(n_max) - 2 - 2 * len(self.boundaries) - 1) // per_bucket)
        extremes = [_bucket_extremes(s.values, buckets) for s in self.series]
        keep = np.unique(np.concatenate(fixed + extremes).astype(np.int64))
        worst = int(np.searchsorted(keep, self.worst)) if self.worst >= 0 else -1
        return dataclasses.replace(
            self, time=self.time[keep], row=self.row[keep], kept=self.kept[keep], worst=worst,
            series=tuple(dataclasses.replace(s, values=s.values[keep]) for s in self.series))

    def _boundary_samples(self) -> IntArray:
        """The last sample before each boundary and the first at or after it."""
        rows = np.array([b.row for b in self.boundaries], dtype=np.int64)
        first = np.searchsorted(self.row, rows, side="left")
        both = np.concatenate([first - 1, first])
        return both[(both >= 0) & (both < len(self.time))]


def _bucket_extremes(values: FloatArray, buckets: int) -> IntArray:
    """The index of the least and of the greatest finite value of each of ``buckets`` runs of equal
    length (the last one shorter); a bucket of NaN only keeps its first sample."""
    n = len(values)
    size = -(-n // buckets)
    padded = np.full(size * buckets, np.nan)
    padded[:n] = values
    table = padded.reshape(buckets, size)
    finite = np.isfinite(table)
    low = np.argmin(np.where(finite, table, np.inf), axis=1)
    high = np.argmax(np.where(finite, table, -np.inf), axis=1)
    base = np.arange(buckets) * size
    found = np.concatenate([base + low, base + high])
    return found[found < n]


def _group_of(names: Sequence[str]) -> str:
    """The words the names share at their end (``T1 stroke``, ``T2 stroke`` → ``stroke``), else the first name."""
    words = [name.split(" ") for name in names]
    common: list[str] = []
    for k in range(1, min(len(w) for w in words)):
        tail = words[0][-k:]
        if all(w[-k:] == tail for w in words):
            common = tail
    return " ".join(common) if common and len(names) > 1 else names[0]


def _limit_series(report: VerifyReport) -> list[Series]:
    """A series per limit column of the replay, grouped by consecutive columns of the same unit and
    bounds (the stage's axes together)."""
    limits = report.samples_kept.limits
    names, units = limits.names, limits.units
    runs: list[list[int]] = []
    for j, name in enumerate(names):
        same = runs and (units[runs[-1][0]] == units[j] and limits.low[runs[-1][0]] == limits.low[j]
                         and limits.high[runs[-1][0]] == limits.high[j])
        stage = name.startswith("stage ") and runs and names[runs[-1][0]].startswith("stage ")
        if same or stage:
            runs[-1].append(j)
        else:
            runs.append([j])
    series = []
    for run in runs:
        group = "stage" if names[run[0]].startswith("stage ") else _group_of([names[j] for j in run])
        series += [Series(name=names[j], group=group, unit=units[j], values=limits.value[:, j],
                          low=float(limits.low[j]), high=float(limits.high[j])) for j in run]
    return series


def row_speeds(report: VerifyReport, *, rapid_rate: float) -> FloatArray:
    """(N, 2 + J) mm/min — each row's axis speeds (module docstring; row 0: 0), columns X, Y, the joints."""
    program = report.program
    deltas = joint_deltas(joints_of(program))
    feed = program.kind == MoveKind.FEED
    speed = deltas * np.where(feed, program.inverse_time, 0.0)[:, None]
    rapid = np.flatnonzero(~feed)
    if len(rapid):
        d = deltas[rapid]
        dynamics = report.dynamics
        if dynamics is not None:
            width = d.shape[1]
            top, accel = np.array(dynamics.speeds(width - 2)), np.array(dynamics.accels(width - 2))
            with np.errstate(divide="ignore", invalid="ignore"):
                peak = np.minimum(top, np.sqrt(d * accel))     # each axis alone: its trapezoid's (triangle's) peak
                alone = np.where(d > 0, np.where(d >= top * top / accel, d / top + top / accel,
                                                 2.0 * np.sqrt(d / accel)), 0.0)
            slow = np.argmax(alone, axis=1)
            at = np.arange(len(rapid))
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(d[at, slow] > 0, peak[at, slow] / d[at, slow], 0.0)
        else:
            longest = d.max(axis=1) if d.shape[1] else np.zeros(len(d))
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(longest > 0, rapid_rate / longest, 0.0)
        speed[rapid] = d * ratio[:, None]
    if len(speed):
        speed[0] = 0.0
    return speed


def _speed_series(report: VerifyReport, rows: IntArray, *, rapid_rate: float, stage: bool) -> list[Series]:
    """Each axis's speed at every sample (its move's), bounded by ``[dynamics]``'s top speeds."""
    speed = row_speeds(report, rapid_rate=rapid_rate)
    joints = len(report.joint_names)
    dynamics = report.dynamics
    top = dynamics.speeds(joints) if dynamics is not None else (math.inf,) * (2 + joints)
    series = []
    columns = [(0, "stage X speed", "stage speed"), (1, "stage Y speed", "stage speed")] if stage else []
    columns += [(2 + k, f"{name} speed", "stroke speed") for k, name in enumerate(report.joint_names)]
    for column, name, group in columns:
        low = 0.0 if math.isfinite(top[column]) else -math.inf
        series.append(Series(name=name, group=group, unit="mm/min", values=speed[rows, column], low=low,
                             high=float(top[column])))
    return series


def _worst(report: VerifyReport) -> tuple[int, str]:
    """The sample of the smallest margin as a fraction of its limit's range, and the limit's name."""
    limits = report.samples_kept.limits
    spread = margin_fraction(limits)
    best, where, name = math.inf, -1, ""
    for j in range(len(limits.names)):
        if not (np.isfinite(spread[j]) and spread[j] > 0):
            continue
        margin = limits.margin[:, j]
        finite = np.isfinite(margin)
        if not finite.any():
            continue
        at = int(np.argmin(np.where(finite, margin, np.inf)))
        value = float(margin[at]) / float(spread[j])
        if value < best:
            best, where, name = value, at, limits.names[j]
    return where, name


def _tool_marks(report: VerifyReport) -> list[Mark]:
    """Each tool change event, at the line of its first move after (the end of the program after the last)."""
    program = report.program
    n = len(program)
    marks = []
    for event in program.events:
        if event.kind is EventKind.TOOL_CHANGE:
            line = int(program.source[min(event.before, n - 1)]) if n else 0
            marks.append(Mark(row=event.before, line=line, kind=MarkKind.TOOL_CHANGE, label=f"T{int(event.value)}"))
    return marks


def timeline_of(report: VerifyReport, *, rapid_rate: float = NOMINAL_RAPID_RATE,
                marks: Sequence[Mark] | None = None) -> Timeline:
    """The samples of a replay (``report.replay``, kept) over time, their limits and boundaries.

    Parameters
    ----------
    report : VerifyReport — with its samples (``verify_program(..., keep_samples=True)``)
    rapid_rate : float — mm/min, the joint-space rate of G0 moves without ``[dynamics]``
    marks : sequence of Mark, optional — the program's tool changes and operations as its text
        shows them (None: each tool change event, which also begins an operation)

    Returns
    -------
    Timeline

    Raises
    ------
    ValueError
        When the report kept no samples.
    """
    rep = report.samples_kept
    program = report.program
    n = len(program)
    durations = report.duration if (report.duration is not None and
                                    (report.dynamics is not None or rapid_rate == NOMINAL_RAPID_RATE)) else None
    start, end = row_times(program, rapid_rate=rapid_rate, dynamics=report.dynamics, durations=durations)
    rows = rep.row
    time = start[rows] + rep.fraction * (end[rows] - start[rows])
    stage = any(name.startswith("stage ") for name in rep.limits.names)
    series = _limit_series(report) + _speed_series(report, rows, rapid_rate=rapid_rate, stage=stage)
    if marks is None:
        tools = _tool_marks(report)
        marks = tools + [dataclasses.replace(m, kind=MarkKind.OPERATION) for m in tools]
    ordered = sorted(marks, key=lambda m: (m.row, m.line, m.kind is MarkKind.OPERATION))
    total = float(end[-1]) if n else 0.0
    boundaries = tuple(Boundary(row=m.row, line=m.line, kind=m.kind, label=m.label,
                                time=float(start[m.row]) if m.row < n else total) for m in ordered)
    starts = [b for b in boundaries if b.kind is MarkKind.OPERATION]
    operations = tuple(b.label for b in starts) or ("",)
    first_rows = np.array([b.row for b in starts], dtype=np.int64)
    row_operation = np.maximum(np.searchsorted(first_rows, np.arange(n), side="right") - 1, 0)
    worst, worst_series = _worst(report)
    return Timeline(time=time, row=rows, series=tuple(series), boundaries=boundaries, row_line=program.source,
                    row_operation=row_operation, operations=operations, worst=worst, worst_series=worst_series,
                    dynamics=report.dynamics is not None, rapid_rate=rapid_rate, kept=np.arange(len(time)))
