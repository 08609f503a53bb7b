"""Machine limits on every point: values, margins, and the error for the first violation.

A margin is the distance from a value to the nearest bound of its limit, in the limit's unit
(mm, rad or plain number): positive inside, 0 on the boundary (still allowed), negative outside. A value
beyond a bound by no more than :data:`~prs3_post.core.defaults.LIMIT_TOLERANCE` (float noise) is on it:
its margin is 0.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

from prs3_post.core.defaults import LIMIT_TOLERANCE
from prs3_post.core.errors import LimitError
from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.kinematics import IKResult
from prs3_post.kinematics.protocol import LimitColumns
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.model import Machine


@dataclass(frozen=True, slots=True)
class LimitReport:
    """Every limit of a machine evaluated on N points.

    Attributes
    ----------
    names : (L,) str — the kinematics' limits (``T1 stroke`` … ``condition number``), ``stage X``, ``stage Y``
    units : (L,) str — ``mm``, ``deg`` (values kept in rad) or ``""``
    low, high : (L,) float — bounds (``-inf`` / ``inf`` where there is none)
    value : (N, L) float — each point's value (mm, rad, number)
    margin : (N, L) float — distance to the nearest bound, negative outside
    ok : (N,) bool — every margin ≥ 0
    """

    names: tuple[str, ...]
    units: tuple[str, ...]
    low: FloatArray
    high: FloatArray
    value: FloatArray
    margin: FloatArray
    ok: BoolArray

    def describe(self, row: int, column: int) -> str:
        """``T2 stroke 412.3456 mm is above the maximum 400.0000 mm by 12.3456 mm`` (or the margin)."""
        name, unit = self.names[column], self.units[column]
        scale = math.degrees(1.0) if unit == "deg" else 1.0
        value, margin = self.value[row, column] * scale, self.margin[row, column] * scale
        low, high = self.low[column] * scale, self.high[column] * scale
        suffix = f" {unit}" if unit else ""
        value_text, margin_text = _shown(value), _shown(abs(margin))
        if margin >= 0:
            return (f"{name} {value_text}{suffix} is within [{low:.4f}, {high:.4f}]{suffix} "
                    f"with margin {margin_text}{suffix}")
        if value > high:
            return f"{name} {value_text}{suffix} is above the maximum {high:.4f}{suffix} by {margin_text}{suffix}"
        return f"{name} {value_text}{suffix} is below the minimum {low:.4f}{suffix} by {margin_text}{suffix}"


def _shown(value: float) -> str:
    """A value for a message: 4 decimals, or 6 significant digits from 1e9 up (``1e+300``, not 301 digits)."""
    return f"{value:.4f}" if abs(value) < 1e9 else f"{value:.6g}"


def _slack(unit: str) -> float:
    """:data:`LIMIT_TOLERANCE` in a limit's code unit (rad for ``deg``)."""
    return math.radians(LIMIT_TOLERANCE) if unit == "deg" else LIMIT_TOLERANCE


def limit_margins(value: FloatArray, low: FloatArray, high: FloatArray, units: tuple[str, ...]) -> FloatArray:
    """(N, L) float — each value's margin to its limit (``value`` (N, L); ``low``, ``high``, ``units`` (L,)):
    min(value − low, high − value), 0 where a value is beyond a bound by no more than
    :data:`LIMIT_TOLERANCE`; NaN stays NaN."""
    margin = np.minimum(value - low, high - value)
    if not np.fmin.reduce(margin, axis=None, initial=0.0) < 0.0:     # all inside (or NaN): the common case
        return margin
    slack = np.array([_slack(unit) for unit in units])
    with np.errstate(invalid="ignore"):
        return np.where((margin < 0.0) & (margin >= -slack), 0.0, margin)


def _groups(machine: Machine, ik: IKResult, axis: FloatArray) -> LimitColumns:
    """The limits of ``machine`` by the bounds they share: names, unit, bounds and the points' values
    (N, one column per name): its kinematics' columns, then the stage's travel."""
    groups = kinematics_of(machine).limit_columns(machine.limits, ik, axis)
    if machine.stage.present:
        groups.append((("stage X",), "mm", *machine.stage.travel_x, ik.stage[:, 0:1]))
        groups.append((("stage Y",), "mm", *machine.stage.travel_y, ik.stage[:, 1:2]))
    return groups


def check_limits(machine: Machine, ik: IKResult, axis: FloatArray) -> LimitReport:
    """Evaluate every limit of ``machine`` on IK results.

    Parameters
    ----------
    machine : Machine
    ik : IKResult — N points
    axis : (N, 3) float — unit tool axes of the same points (for the tilt)

    Returns
    -------
    LimitReport
    """
    columns = [(name, unit, low, high, values[:, j])
               for names, unit, low, high, values in _groups(machine, ik, axis) for j, name in enumerate(names)]
    low = np.array([c[2] for c in columns])
    high = np.array([c[3] for c in columns])
    # one limit per row of (L, N) arrays: each step runs along a contiguous row (the report holds
    # their (N, L) transposes, views)
    value = np.stack([c[4] for c in columns]).reshape(len(columns), len(ik.strokes))
    margin = limit_margins(value.T, low, high, tuple(c[1] for c in columns)).T
    with np.errstate(invalid="ignore"):
        ok = np.logical_and.reduce(margin >= 0.0, axis=0)   # NaN (unreachable) is never ok
    return LimitReport(
        names=tuple(c[0] for c in columns),
        units=tuple(c[1] for c in columns),
        low=low,
        high=high,
        value=value.T,
        margin=margin.T,
        ok=ok,
    )


def within_limits(machine: Machine, ik: IKResult, axis: FloatArray) -> bool:
    """Whether every point is within every limit, ``check_limits(machine, ik, axis).ok.all()``, from
    each limit's least and greatest value: no (N, L) report, no temporaries.

    A point is ok exactly where each of its values is finite and low ≤ value ≤ high (a margin
    min(value − low, high − value) of two floats is ≥ 0 exactly then; an infinite value makes one
    term NaN or negative, NaN makes both NaN), and a NaN or infinite value makes its column's least
    or greatest value NaN or infinite, so the extremes of the columns decide. Both allow
    :data:`LIMIT_TOLERANCE` beyond a bound.
    """
    for _, unit, low, high, values in _groups(machine, ik, axis):   # (strokes, link angles: one reduction each)
        if len(values):
            least, most, slack = float(values.min()), float(values.max()), _slack(unit)
            if not (math.isfinite(least) and math.isfinite(most) and low - slack <= least and most <= high + slack):
                return False
    return True


def raise_first_violation(report: LimitReport, describe_row: Callable[[int], str], *, scope: str = "in all") -> None:
    """Raise :class:`LimitError` for the first point outside a limit (its first broken limit), if any.

    Parameters
    ----------
    report : LimitReport
    describe_row : row index → where it came from (``hole 1 feed``, ``part.cl:12``)
    scope : str — what the count of bad points counts (``in all``: the whole path)
    """
    bad = np.flatnonzero(~report.ok)
    if not len(bad):
        return
    row = int(bad[0])
    column = int(np.flatnonzero(~(report.margin[row] >= 0.0))[0])   # first limit broken (or NaN)
    count = f" ({len(bad)} points outside limits {scope})" if len(bad) > 1 else ""
    raise LimitError(f"{describe_row(row)}: {report.describe(row, column)}{count}")


def _no_floats() -> FloatArray:
    return np.zeros(0)


def _no_rows() -> IntArray:
    return np.zeros(0, dtype=np.int64)


@dataclass(slots=True)
class LimitTally:
    """The closest approach to each limit over the rows of a program made in pieces: per limit, the
    smallest margin, its value and its row (the first row on ties). Folded a report at a time
    (:meth:`fold`), so that a streamed program need not be held; NaN margins (none in a checked
    program) are passed over.

    Attributes
    ----------
    names, units : (L,) str — as :class:`LimitReport`'s (empty until the first report)
    low, high : (L,) float — the bounds (code units: mm, rad, number)
    margin, value : (L,) float — the closest approach (``inf`` / NaN while no row is folded)
    row : (L,) int — its row in the program (0-based; -1 while none)
    rows : int — rows folded
    """

    names: tuple[str, ...] = ()
    units: tuple[str, ...] = ()
    low: FloatArray = field(default_factory=_no_floats)
    high: FloatArray = field(default_factory=_no_floats)
    margin: FloatArray = field(default_factory=_no_floats)
    value: FloatArray = field(default_factory=_no_floats)
    row: IntArray = field(default_factory=_no_rows)
    rows: int = 0

    def fold(self, report: LimitReport, first_row: int | None = None) -> None:
        """Add the rows of ``report``, which are the program's rows from ``first_row`` (default: the rows
        folded so far, consecutive)."""
        start = self.rows if first_row is None else first_row
        if not self.names:
            count = len(report.names)
            self.names, self.units, self.low, self.high = report.names, report.units, report.low, report.high
            self.margin, self.value = np.full(count, np.inf), np.full(count, np.nan)
            self.row = np.full(count, -1, dtype=np.int64)
        n = len(report.margin)
        self.rows = max(self.rows, start + n)
        if not n:
            return
        margin = np.where(np.isnan(report.margin), np.inf, report.margin)     # (N, L)
        best = np.argmin(margin, axis=0)                                     # the first of equals
        found = margin[best, np.arange(len(best))]
        better = found < self.margin
        self.margin = np.where(better, found, self.margin)
        self.value = np.where(better, report.value[best, np.arange(len(best))], self.value)
        self.row = np.where(better, best + start, self.row)

    def merged(self, other: LimitTally, offset: int) -> None:
        """Fold ``other``, whose row 0 is this program's row ``offset`` (a piece joined after the others)."""
        if not other.names:
            self.rows = max(self.rows, offset + other.rows)
            return
        if not self.names:
            self.names, self.units, self.low, self.high = other.names, other.units, other.low, other.high
            self.margin, self.value = other.margin.copy(), other.value.copy()
            self.row = np.where(other.row >= 0, other.row + offset, -1)
            self.rows = offset + other.rows
            return
        better = other.margin < self.margin                                  # ties: the earlier row stays
        self.margin = np.where(better, other.margin, self.margin)
        self.value = np.where(better, other.value, self.value)
        self.row = np.where(better, other.row + offset, self.row)
        self.rows = max(self.rows, offset + other.rows)

    def closest(self) -> LimitReport:
        """The closest approaches as a report of one row (each column's value and margin from its own
        :attr:`row`)."""
        with np.errstate(invalid="ignore"):
            ok = np.array([bool((self.margin >= 0.0).all())])
        return LimitReport(names=self.names, units=self.units, low=self.low, high=self.high,
                           value=self.value[None, :], margin=self.margin[None, :], ok=ok)

    @staticmethod
    def joined(pieces: Iterable[tuple[LimitTally | None, int]]) -> LimitTally:
        """The tally of pieces joined in order, given as each one's tally (None: not tallied) and rows."""
        tally, at = LimitTally(), 0
        for own, rows in pieces:
            if own is not None:
                tally.merged(own, at)
            at += rows
        return tally

    @staticmethod
    def of(report: LimitReport) -> LimitTally:
        """The tally of one report (its rows are rows 0…N-1)."""
        tally = LimitTally()
        tally.fold(report, 0)
        return tally
