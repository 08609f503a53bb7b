"""The one intermediate representation: a toolpath as a struct of arrays, plus non-motion events.

Every stage after a reader or an operation works on a :class:`Toolpath`; after inverse kinematics
the same rows become a :class:`JointProgram` (actuator space), which the emitter writes.

Rows are motion *end points*. The start of row 0 is wherever the machine is (the emitter's safe
start puts it at a known place). ``source[i]`` is the line number (readers) or the operation step
(operations) that row ``i`` came from; ``source_labels`` (when not empty) names each step, so that
an error can say ``hole 2, peck 3`` instead of ``step 17``; ``source_file`` (readers) names the
input file, so that an error says ``part.cl:12`` instead of ``line 12``.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field, replace
from typing import TypeVar

import numpy as np

from prs3_post.core.errors import shown_path
from prs3_post.core.types import BoolArray, FloatArray, IntArray


class MoveKind(enum.IntEnum):
    """How the machine moves to a row's end point."""

    RAPID = 0
    """G0: the fastest joint-space move; the path between end points is not controlled."""
    FEED = 1
    """G1: a controlled move at the row's tip feed, straight at the tool tip."""


class Coolant(enum.Enum):
    """The coolant while the tool cuts: ``--coolant``, a job file's ``coolant``, what a COOLANT_ON
    event turns on (its ``text`` holds the value) and what M7/M8 or ``COOLNT/`` in an input ask for."""

    FLOOD = "flood"
    """M8: flood coolant on while cutting, M9 at the end."""
    MIST = "mist"
    """M7: mist coolant on while cutting, M9 at the end."""
    OFF = "off"
    """No coolant words at all (dry cutting)."""

    @classmethod
    def from_m_code(cls, code: float) -> Coolant:
        """The coolant an M code turns on: 7 → MIST, 8 → FLOOD.

        >>> Coolant.from_m_code(7), Coolant.from_m_code(8)
        (<Coolant.MIST: 'mist'>, <Coolant.FLOOD: 'flood'>)
        """
        return {7.0: cls.MIST, 8.0: cls.FLOOD}[code]

    @property
    def m_word(self) -> str:
        """The block that turns it on: ``M8`` (flood) or ``M7`` (mist); OFF has none (ValueError)."""
        if self is Coolant.OFF:
            raise ValueError("no M word turns coolant 'off' on (COOLANT_OFF is M9)")
        return "M7" if self is Coolant.MIST else "M8"


class EventKind(enum.Enum):
    """A non-motion action between rows."""

    SPINDLE_ON = "spindle_on"
    """M3 at ``value`` rpm: the spindle turns clockwise (seen from the spindle toward the tip)."""
    SPINDLE_ON_CCW = "spindle_on_ccw"
    """M4 at ``value`` rpm: the spindle turns counter-clockwise (left-hand tools, taps)."""
    SPINDLE_OFF = "spindle_off"
    """M5."""
    COOLANT_ON = "coolant_on"
    """M8 or M7: the :class:`Coolant` whose value is ``text`` (empty: flood), see :attr:`Event.coolant`."""
    COOLANT_OFF = "coolant_off"
    """M9."""
    TOOL_CHANGE = "tool_change"
    """M6 T``value``; ``text`` describes the tool."""
    DWELL = "dwell"
    """G4 P``value`` seconds."""
    COMMENT = "comment"
    """An operator-visible comment ``text``."""
    STOP = "stop"
    """M0: program stop, cycle start resumes."""
    OPTIONAL_STOP = "optional_stop"
    """M1: program stop only where the operator's optional-stop switch is on; cycle start resumes."""


@dataclass(frozen=True, slots=True)
class Event:
    """A non-motion event that happens before motion row ``before`` (== N: after the last row)."""

    before: int
    kind: EventKind
    value: float = 0.0
    text: str = ""

    @property
    def coolant(self) -> Coolant:
        """The coolant a COOLANT_ON event turns on: ``Coolant(text)``, FLOOD when ``text`` is empty.

        >>> Event(0, EventKind.COOLANT_ON, text=Coolant.MIST.value).coolant, Event(0, EventKind.COOLANT_ON).coolant
        (<Coolant.MIST: 'mist'>, <Coolant.FLOOD: 'flood'>)
        """
        return Coolant(self.text) if self.text else Coolant.FLOOD


#: A row shape ``(ANY_WIDTH,)``: rows of any one width ≥ 1 (a program's joints: as many as the
#: machine's kinematics has; empty: 3).
ANY_WIDTH = -1


def _tail(array: np.ndarray, shape_tail: tuple[int, ...]) -> tuple[int, ...]:
    """``shape_tail`` with :data:`ANY_WIDTH` as the width ``array`` has (2-D, at least one column)."""
    if shape_tail != (ANY_WIDTH,):
        return shape_tail
    return array.shape[1:] if array.ndim == 2 and array.shape[1] >= 1 else (3,)


def _frozen(array: np.ndarray, dtype: type, shape_tail: tuple[int, ...], name: str) -> np.ndarray:
    out: np.ndarray = np.array(array, dtype=dtype, copy=True)
    shape_tail = _tail(out, shape_tail)
    if out.ndim == 1 and shape_tail and out.size == 0:
        out = out.reshape((0, *shape_tail))
    if out.shape[1:] != shape_tail:
        raise ValueError(f"{name}: expected shape (N, {', '.join(map(str, shape_tail))}), got {out.shape}")
    out.flags.writeable = False
    return out


def _freeze_rows(table: object, fields: tuple[tuple[str, type, tuple[int, ...]], ...]) -> None:
    """Replace each (name, dtype, row shape) field of a frozen row table by a read-only array copy,
    check that all have the first field's row count, and sort the events by position."""
    rows = len(getattr(table, fields[0][0]))
    for name, dtype, tail in fields:
        value = _frozen(getattr(table, name), dtype, tail, name)
        if len(value) != rows:
            raise ValueError(f"{name}: {len(value)} rows, {fields[0][0]} has {rows}")
        object.__setattr__(table, name, value)
    object.__setattr__(table, "events", tuple(sorted(table.events, key=lambda e: e.before)))  # type: ignore[attr-defined]


def describe_source(source: IntArray, labels: tuple[str, ...], row: int, file: str = "") -> str:
    """``part.cl:12`` or ``line 12`` (readers: source is a line number, of ``file`` when it is given)
    or the step label (operations).

    >>> describe_source(np.array([12]), (), 0, "part.cl"), describe_source(np.array([12]), (), 0)
    ('part.cl:12', 'line 12')
    """
    step = int(source[row])
    if labels:
        return labels[step]
    return f"{shown_path(file)}:{step}" if file else f"line {step}"


@dataclass(frozen=True, slots=True)
class Toolpath:
    """Motion end points in one frame (part or machine), one row per point.

    Attributes
    ----------
    kind : (N,) int — :class:`MoveKind` values
    tip : (N, 3) float — mm, tool tip
    axis : (N, 3) float — unit vector from the tool tip toward the spindle
    feed : (N,) float — mm/min tip feed for FEED rows, 0 for RAPID rows
    source : (N,) int — input line number or operation step of each row
    events : tuple of Event — non-motion events, ordered by ``before``
    source_labels : tuple of str — names of the steps ``source`` indexes (empty: source is a line number)
    source_file : str — the input file whose line numbers ``source`` holds (readers; "" for operations)
    """

    kind: IntArray
    tip: FloatArray
    axis: FloatArray
    feed: FloatArray
    source: IntArray
    events: tuple[Event, ...] = ()
    source_labels: tuple[str, ...] = field(default=())
    source_file: str = ""

    def __post_init__(self) -> None:
        _freeze_rows(self, (("kind", np.int64, ()), ("tip", np.float64, (3,)), ("axis", np.float64, (3,)),
                            ("feed", np.float64, ()), ("source", np.int64, ())))

    def __len__(self) -> int:
        return len(self.kind)

    def describe(self, row: int) -> str:
        """Human name of the line/step row ``row`` came from (``line 12`` or the step label)."""
        return describe_source(self.source, self.source_labels, row, self.source_file)

    def take(self, keep: BoolArray) -> Toolpath:
        """The rows where ``keep`` (N,) is True; an event before a dropped row moves to the next kept one.

        >>> path = Toolpath(kind=[0, 1, 1], tip=np.zeros((3, 3)), axis=np.tile([0.0, 0, 1], (3, 1)),
        ...                 feed=[0, 9, 9], source=[0, 1, 2], events=(Event(2, EventKind.DWELL, 1.0),))
        >>> taken = path.take(np.array([True, False, True]))
        >>> len(taken), taken.source.tolist(), taken.events[0].before
        (2, [0, 2], 1)
        """
        keep = np.asarray(keep, dtype=bool)
        kept_before = np.concatenate([[0], np.cumsum(keep)])       # kept rows before each row index
        events = tuple(replace(e, before=int(kept_before[e.before])) for e in self.events)
        return Toolpath(kind=self.kind[keep], tip=self.tip[keep], axis=self.axis[keep], feed=self.feed[keep],
                        source=self.source[keep], events=events, source_labels=self.source_labels,
                        source_file=self.source_file)


@dataclass(frozen=True, slots=True)
class JointProgram:
    """A toolpath in actuator space, ready to emit: the machine's own axes, one row per end point.

    Attributes
    ----------
    kind : (N,) int — :class:`MoveKind` values
    stage : (N, 2) float — mm, stage X, Y (zeros on a machine without a stage)
    strokes : (N, J) float — mm, the kinematics' joints (a 3-PRS head's strokes T1, T2, T3)
    inverse_time : (N,) float — 1/min, G93 F word of FEED rows (move time = 1/F min), 0 for rapids
    source : (N,) int — as in :class:`Toolpath`
    events : tuple of Event — as in :class:`Toolpath`
    source_labels : tuple of str — as in :class:`Toolpath`
    source_file : str — as in :class:`Toolpath`
    """

    kind: IntArray
    stage: FloatArray
    strokes: FloatArray
    inverse_time: FloatArray
    source: IntArray
    events: tuple[Event, ...] = ()
    source_labels: tuple[str, ...] = field(default=())
    source_file: str = ""

    def __post_init__(self) -> None:
        _freeze_rows(self, (("kind", np.int64, ()), ("stage", np.float64, (2,)), ("strokes", np.float64, (ANY_WIDTH,)),
                            ("inverse_time", np.float64, ()), ("source", np.int64, ())))

    def __len__(self) -> int:
        return len(self.kind)

    def describe(self, row: int) -> str:
        """Human name of the line/step row ``row`` came from (``line 12`` or the step label)."""
        return describe_source(self.source, self.source_labels, row, self.source_file)


def join_programs(parts: list[JointProgram], *, source_labels: tuple[str, ...] = (),
                  source_file: str = "") -> JointProgram:
    """One program of consecutive pieces, each piece's events counting rows from its own start
    (``source_labels`` and ``source_file``: the joined program's, as in :class:`JointProgram`).

    Takes the pieces out of ``parts`` (which is left empty) so that each column's pieces are freed
    as soon as it is joined: a long program is held about twice, not three times.
    """
    events: list[Event] = []
    offset = 0
    for part in parts:
        events += [Event(before=e.before + offset, kind=e.kind, value=e.value, text=e.text) for e in part.events]
        offset += len(part)
    shapes = {"kind": (np.int64, ()), "stage": (np.float64, (2,)), "strokes": (np.float64, (ANY_WIDTH,)),
              "inverse_time": (np.float64, ()), "source": (np.int64, ())}
    pieces = {name: [getattr(p, name) for p in parts] for name in shapes}
    parts.clear()
    columns = {}
    for name, (dtype, tail) in shapes.items():
        columns[name] = (np.concatenate(pieces.pop(name)).astype(dtype, copy=False) if offset
                         else np.zeros((0, *_tail(np.zeros(0), tail)), dtype=dtype))
    return program_from_columns(columns, events, source_labels=source_labels, source_file=source_file)


def program_from_columns(columns: dict[str, np.ndarray], events: list[Event] | tuple[Event, ...] = (), *,
                         source_labels: tuple[str, ...] = (), source_file: str = "") -> JointProgram:
    """A JointProgram of columns made for it (``kind``, ``stage``, ``strokes``, ``inverse_time``,
    ``source``, of its dtypes and row shapes), frozen in place instead of copied: the caller gives
    them up (a long program is then held once). Checks as the constructor does.

    Raises
    ------
    ValueError
        A column of another dtype, row shape or row count.
    """
    fields = (("kind", np.int64, ()), ("stage", np.float64, (2,)), ("strokes", np.float64, (ANY_WIDTH,)),
              ("inverse_time", np.float64, ()), ("source", np.int64, ()))
    return _frozen_from_columns(JointProgram, [(name, columns[name], dtype, tail) for name, dtype, tail in fields],
                                events, source_labels, source_file)


def toolpath_from_columns(*, kind: IntArray, tip: FloatArray, axis: FloatArray, feed: FloatArray, source: IntArray,
                          events: tuple[Event, ...] = (), source_labels: tuple[str, ...] = (),
                          source_file: str = "") -> Toolpath:
    """A Toolpath of columns made for it (int64 ``kind`` and ``source``, float64 ``tip``, ``axis``
    (N, 3) and ``feed``), frozen in place instead of copied: the caller gives them up (a long
    toolpath is then held once). Checks as the constructor does.

    Raises
    ------
    ValueError
        A column of another dtype, row shape or row count.
    """
    return _frozen_from_columns(Toolpath, [("kind", kind, np.int64, ()), ("tip", tip, np.float64, (3,)),
                                           ("axis", axis, np.float64, (3,)), ("feed", feed, np.float64, ()),
                                           ("source", source, np.int64, ())],
                                events, source_labels, source_file)


_Framed = TypeVar("_Framed", "Toolpath", "JointProgram")


def _frozen_from_columns(cls: type[_Framed], fields: list[tuple[str, np.ndarray, type, tuple[int, ...]]],
                         events: Iterable[Event], source_labels: Iterable[str], source_file: str) -> _Framed:
    """An instance of the frozen ``cls`` holding the checked columns ``fields`` (name, column, dtype,
    row shape; the first column's length is the row count), frozen in place, not copied."""
    made = object.__new__(cls)
    rows = len(fields[0][1])
    row_shape: tuple[int, ...]
    for name, column, dtype, given_shape in fields:
        row_shape = _tail(column, given_shape)
        if column.dtype != dtype or column.shape != (rows, *row_shape):
            raise ValueError(f"{name}: expected {np.dtype(dtype).name} of shape {(rows, *row_shape)}, got "
                             f"{column.dtype.name} of shape {column.shape}")
        column.flags.writeable = False
        object.__setattr__(made, name, column)
    object.__setattr__(made, "events", tuple(sorted(events, key=lambda e: e.before)))
    object.__setattr__(made, "source_labels", tuple(source_labels))
    object.__setattr__(made, "source_file", source_file)
    return made


def _events_of_rows(events: tuple[Event, ...], lo: int, hi: int, last: bool) -> tuple[Event, ...]:
    """The events before rows ``lo:hi``, counted from ``lo`` (with ``last``: also those after row ``hi − 1``)."""
    return tuple(replace(e, before=e.before - lo) for e in events if lo <= e.before < hi or (last and e.before == hi))


def toolpath_chunks(path: Toolpath, rows: int) -> Iterator[Toolpath]:
    """``path`` as consecutive pieces of at most ``rows`` rows (at least one piece): an event goes with
    the row it comes before, those after the last row with the last piece (as
    :class:`~prs3_post.post.pipeline.PostStream` takes a toolpath)."""
    n = len(path)
    for lo in range(0, max(n, 1), rows):
        hi = min(n, lo + rows)
        yield Toolpath(kind=path.kind[lo:hi], tip=path.tip[lo:hi], axis=path.axis[lo:hi], feed=path.feed[lo:hi],
                       source=path.source[lo:hi], events=_events_of_rows(path.events, lo, hi, hi == n),
                       source_labels=path.source_labels, source_file=path.source_file)


def toolpath_pieces(columns: dict[str, np.ndarray], rows: int, *, events: tuple[Event, ...] = (),
                    source_labels: tuple[str, ...] = (), source_file: str = "") -> list[Toolpath]:
    """The toolpath of ``columns`` (``kind``, ``tip``, ``axis``, ``feed``, ``source``, as
    :func:`toolpath_from_columns` takes them) cut as :func:`toolpath_chunks` cuts it, each piece
    owning its rows: the columns are taken out of ``columns`` (left empty) one at a time and freed
    once cut, so that a long toolpath is held about once, and a caller that drops each piece once
    it is used frees the toolpath as it goes."""
    n = len(columns["kind"])
    spans = [(lo, min(n, lo + rows)) for lo in range(0, max(n, 1), rows)]
    cut: list[dict[str, np.ndarray]] = [{} for _ in spans]
    for name in ("kind", "tip", "axis", "feed", "source"):
        column = columns.pop(name)
        for piece, (lo, hi) in zip(cut, spans, strict=True):
            piece[name] = column[lo:hi].copy()
        del column
    return [toolpath_from_columns(kind=piece["kind"], tip=piece["tip"], axis=piece["axis"], feed=piece["feed"],
                                  source=piece["source"], events=_events_of_rows(events, lo, hi, hi == n),
                                  source_labels=source_labels, source_file=source_file)
            for piece, (lo, hi) in zip(cut, spans, strict=True)]


def program_chunks(program: JointProgram, rows: int) -> Iterator[JointProgram]:
    """``program`` as consecutive pieces of at most ``rows`` rows (at least one piece), events as in
    :func:`toolpath_chunks`; the pieces' columns are views of the program's (nothing is copied), so
    that the emitter (:class:`~prs3_post.emit.gcode.ProgramEmitter`) writes a long program a piece at a time."""
    n = len(program)
    for lo in range(0, max(n, 1), rows):
        hi = min(n, lo + rows)
        columns = {name: getattr(program, name)[lo:hi] for name in ("kind", "stage", "strokes", "inverse_time",
                                                                     "source")}
        yield program_from_columns(columns, _events_of_rows(program.events, lo, hi, hi == n),
                                   source_labels=program.source_labels, source_file=program.source_file)
