"""Where to put the part: a chosen setup (``auto``), or a part origin suggested after a limit error.

Moving the part by d (machine frame) moves every tool tip by d and leaves every tool axis as it
is. With an XY stage, the stage takes x and y (stage X, Y shift by dx, dy) and the head only
translates along z (every stroke shifts by dz); link angles, tilt and condition number depend on
the axis alone. So each limit bounds one component of d: per point and limit, an interval; the
intersection over all points is the shifts that keep that limit. Without a stage the head's own
x, y offset must be zero: dx, dy are then fixed by the path.

Turning the part about the machine z axis by θ turns every tool axis with it: its tilt stays, its
azimuth changes, and with it the link angles and the condition number (the head has three legs
120° apart); the stage and stroke ranges the path needs change too (the part's footprint turns).

**Automatic placement** (:func:`place`) chooses the part origin, and optionally the rotation, that
keeps every point inside every limit with the largest worst-case margin, each limit's margin
normalized by its range (``span``: stroke, link angle, stage travel; tilt 0 … max; condition
number 1 … max). For a fixed rotation the margin of each limit that moves with the part is
``min(v_min + b·t − low, high − v_max − b·t) / span`` along the one direction t it moves with
(b = ±1 mm/mm, measured): lines in t, so the best t of each direction is the peak of the lower
envelope of its limits' lines (the centre of their intervals in normalized units), found exactly
from the lines' crossings; the limits that do not move (link angles, tilt, condition number) take
no part in it. The rotation is a 1-D search: every 5°, then the best three to 1°, the best to
0.1° (the origin to 0.1 mm); ties go to the smaller turn. The tilt is the same at every setup,
so it takes no part in the choice either; it still counts in the margins reported and in the
verdict. Deterministic: the same path gives the same setup.

:func:`suggest` (after a limit error, for the setup the user gave) measures how each
limit's value moves with a unit shift along x, y and z, intersects the intervals, takes the centre
of each, and re-runs the whole post-processing at that origin, then the run's other checks (the
collision check): a suggestion is only made when it passes all of them. A translation moves the
part and the tool axes together, so a collision found there is found at every origin: the error
then says which check fails and what to change instead.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from prs3_post.core.errors import LimitError, ReachError
from prs3_post.core.numbers import exact_text
from prs3_post.core.numbers import fixed as _fixed
from prs3_post.core.toolpath import MoveKind, Toolpath
from prs3_post.core.types import BoolArray, FloatArray
from prs3_post.kinematics import HEAD_XY_TOL, IKModel, PoseError, unit_axes
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.loading import Machine
from prs3_post.part.setup_transform import MAX_ORIGIN_MM, Setup, SetupError
from prs3_post.post.limits import LimitReport, check_limits, limit_margins
from prs3_post.post.pipeline import PostResult, machine_path, model_for, place_toolpath, post_process

#: A value that moves by less than this (per mm of shift) does not depend on that shift direction.
_INDEPENDENT = 1e-6
#: A value that moves along one shift direction and by less than this fraction of it along another is
#: taken to move along the first alone: on a head as built whose rails are a little off parallel
#: (general kinematics), the stage follows z a little too. The search then places the part with
#: margins off by that fraction of the shift; the program made at that place is checked exactly.
_CROSS_SLOPE = 0.02
#: The rotation search, in tenths of a degree: the coarse step, the candidates refined, the steps.
_COARSE_STEP, _REFINED, _FINE_STEPS = 50, 3, (10, 1)
#: Normalized margins closer than this are equal (the tie goes to the smaller rotation).
_TIE = 1e-12
#: The lower end of the range a limit with no lower bound is normalized by: tilt from 0, condition from 1.
_NATURAL_LOW = {"tilt": 0.0, "condition number": 1.0}


class Placement(Exception):
    """The main job does not fit the machine with its setup: mixed into the limit or reach error.

    The message is the original error's, plus the setup used and, where a translation of the part
    puts every point inside every limit, that part origin (also as data).

    Attributes
    ----------
    setup : Setup — the setup used
    suggested_origin : (3,) str | None — mm, a part origin checked to work, as exact decimal texts
        (None: no translation does)
    blocked : bool — a translation keeps every limit, but the run's other checks (the collision check)
        fail there, and so at every part origin: the message says what to change instead
    """

    def __init__(self, message: str, *, setup: Setup, suggested_origin: tuple[str, str, str] | None,
                 names_keys: bool | tuple[str, ...] = False, blocked: bool = False):
        super().__init__(message, names_keys=names_keys)  # type: ignore[call-arg]  # the Prs3Error mixed in takes it
        self.setup, self.suggested_origin, self.blocked = setup, suggested_origin, blocked


class PlacementLimitError(Placement, LimitError):
    """A :class:`LimitError` of the main job's path, with its :class:`Placement` data."""


class PlacementReachError(Placement, ReachError):
    """A :class:`ReachError` of the main job's path, with its :class:`Placement` data."""


# ============================================================================ limit columns


def _span(report: LimitReport) -> FloatArray:
    """(L,) float — the range each limit's margin is normalized by (tilt from 0, condition number from 1)."""
    natural = np.array([_NATURAL_LOW.get(name, -math.inf) for name in report.names])
    return report.high - np.where(np.isfinite(report.low), report.low, natural)


def _with_values(report: LimitReport, value: FloatArray) -> LimitReport:
    """``report``'s limits with other values (N, L): margins and verdicts recomputed."""
    margin = limit_margins(value, report.low, report.high, report.units)
    with np.errstate(invalid="ignore"):
        ok = np.all(margin >= 0.0, axis=1)             # NaN (unreachable) is never ok
    return replace(report, value=value, margin=margin, ok=ok)


def _columns(machine: Machine, path: Toolpath, shift: FloatArray | None = None) -> LimitReport:
    """Every limit's value on ``path`` (machine frame, unit axes) moved by ``shift`` (mm, (3,)).

    Without a stage, the head's x, y offset (which must be 0) is added as two more limits
    (``head x offset``, ``head y offset``).
    """
    tip = path.tip if shift is None else path.tip + shift
    ik = kinematics_of(machine).inverse(tip, path.axis, model=IKModel.EXACT)
    report = check_limits(machine, ik, path.axis)
    if model_for(machine) is IKModel.HEAD:
        bound = HEAD_XY_TOL / 2.0                      # a box inside the round tolerance
        report = _with_values(replace(report, names=(*report.names, "head x offset", "head y offset"),
                                      units=(*report.units, "mm", "mm"), low=np.append(report.low, [-bound, -bound]),
                                      high=np.append(report.high, [bound, bound])),
                              np.column_stack([report.value, ik.stage]))
    return report


def _values(machine: Machine, path: Toolpath, shift: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Every limit's value on the path moved by ``shift``, with its bounds: (N, L), (L,), (L,)."""
    columns = _columns(machine, path, shift)
    return columns.value, columns.low, columns.high


# ============================================================================ axes the head takes


#: The rotations about z :func:`axes_reachable` tries, in degrees.
_REACH_ROTATIONS_DEG = np.arange(0.0, 360.0, 5.0)


def axes_reachable(machine: Machine, axes: FloatArray) -> BoolArray:
    """(K,) bool — which tool axes (K, 3), unit, part frame, the head can take at some setup: turned about z
    by one of the rotations every 5°, the limits that depend on the axis alone (tilt, link angles,
    condition number; compared as every limit is, within LIMIT_TOLERANCE) hold and the legs assemble; the
    limits a part origin moves (strokes, stage) are left to the setup (one point fits any of them).
    For a hint that must lead somewhere (a face another up axis would make a candidate)."""
    axes = np.asarray(axes, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(len(axes), dtype=bool)
    angle = np.radians(_REACH_ROTATIONS_DEG)
    cos, sin = np.cos(angle), np.sin(angle)
    count = len(angle)
    for k, (ax, ay, az) in enumerate(axes):
        if az <= 0.0:                                  # away from the spindle at every rotation
            continue
        turned = np.column_stack([cos * ax - sin * ay, sin * ax + cos * ay, np.full(count, az)])
        tip = np.tile(np.asarray(machine.part_origin, dtype=np.float64), (count, 1))
        path = Toolpath(kind=np.full(count, int(MoveKind.RAPID)), tip=tip, axis=turned, feed=np.zeros(count),
                        source=np.arange(count))
        columns = _columns(machine, path)
        value = columns.value
        moves = np.zeros(value.shape, dtype=bool)
        for unit in np.eye(3):
            with np.errstate(invalid="ignore"):
                moves |= np.abs(_values(machine, path, unit)[0] - value) > _INDEPENDENT
        with np.errstate(invalid="ignore"):
            inside = limit_margins(value, columns.low, columns.high, columns.units) >= 0.0
        out[k] = bool((np.isfinite(value).all(axis=1) & (inside | moves).all(axis=1)).any())
    return out


# ============================================================================ suggestion after an error


def _dominant(slopes: FloatArray) -> FloatArray:
    """``slopes`` (3, ...) per mm of shift along x, y, z with those below :data:`_CROSS_SLOPE` of the
    largest of their entry set to 0 (nothing changes on an ideal head: its cross slopes are 0)."""
    largest = np.max(np.abs(slopes), axis=0)
    return np.where(np.abs(slopes) < _CROSS_SLOPE * largest, 0.0, slopes)


def _shift_range(value: FloatArray, slope: FloatArray, low: FloatArray, high: FloatArray) -> tuple[float, float]:
    """The interval of shifts t with low ≤ value + slope·t ≤ high for every entry (may be empty: lo > hi)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        a, b = (low - value) / slope, (high - value) / slope
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    return float(np.max(lo, initial=-np.inf)), float(np.min(hi, initial=np.inf))


def shift_ranges(machine: Machine, path: Toolpath) -> FloatArray | None:
    """(3, 2) mm — for x, y, z, the interval of part shifts that keeps every point inside every limit
    (machine-frame path); None when no translation can (a limit that does not move with the part is
    already broken, a value moves with more than one direction, or an interval is empty)."""
    columns = _columns(machine, path, np.zeros(3))
    value, low, high = columns.value, columns.low, columns.high
    if not np.isfinite(value).all():                   # a pose that does not assemble: the axis, not the place
        return None
    slopes = list(_dominant(np.stack([_values(machine, path, unit)[0] - value for unit in np.eye(3)])))  # per mm
    moves = np.stack([np.abs(s) > _INDEPENDENT for s in slopes])                # (3, N, L)
    if (moves.sum(axis=0) > 1).any():
        return None
    ranges = np.zeros((3, 2))
    for k in range(3):
        ranges[k] = _shift_range(value[moves[k]], slopes[k][moves[k]],
                                 np.broadcast_to(low, value.shape)[moves[k]],
                                 np.broadcast_to(high, value.shape)[moves[k]])
    fixed = ~moves.any(axis=0)
    with np.errstate(invalid="ignore"):
        inside = limit_margins(value, low, high, columns.units) >= 0.0       # at a bound within LIMIT_TOLERANCE too
    if not inside[fixed].all() or (ranges[:, 0] > ranges[:, 1]).any():
        return None
    return ranges


@dataclass(frozen=True, slots=True)
class Suggestion:
    """What :func:`suggest` found for a path that does not fit its setup.

    Attributes
    ----------
    origin : (3,) str | None — mm, a part origin at which the path passes post-processing and ``check``,
        as the exact decimal texts checked (None: none found)
    within_limits : (3,) str | None — mm, the part origin that keeps every point inside every limit
        (the same as ``origin`` unless ``check`` failed there; None: no translation does)
    blocked : LimitError | None — what ``check`` raised at ``within_limits`` (None: it passed, or was not run)
    """

    origin: tuple[str, str, str] | None
    within_limits: tuple[str, str, str] | None = None
    blocked: LimitError | None = None


#: The checks a run makes beyond the limits (the collision check), at a setup, on the path posted
#: there: each raises a :class:`LimitError` where it fails.
SetupCheck = Callable[[Setup, PostResult], None]
#: What to change where a :data:`SetupCheck` fails (no setup changes it), for that check's error: the
#: words (naming request keys as ``{key}``) and the keys they name.
Advise = Callable[[LimitError], tuple[str, tuple[str, ...]]]


def suggest(machine: Machine, path_part: Toolpath, setup: Setup, *, tolerance: float, angle_tolerance: float,
            length_decimals: int | None = None, check: SetupCheck | None = None) -> Suggestion:
    """A part origin (mm, machine frame; same rotation) at which the whole path passes post-processing
    and ``check`` (the run's other checks: the collision check).

    The centre of every allowed shift interval (:func:`shift_ranges`), rounded to 0.1 mm where that
    still passes; checked by running :func:`~prs3_post.post.pipeline.post_process` with it, then
    ``check``. A translation moves the tool and the part together (the tool axes, the part's frame
    and the path in it stay), so where ``check`` fails at that origin it fails at every origin: the
    result says so (``blocked``) instead of searching on.
    """
    none = Suggestion(origin=None)
    try:
        placed = place_toolpath(path_part, setup)
        path = replace(placed, axis=unit_axes(placed.tip, placed.axis))
    except PoseError:
        return none
    # The points as given first: a limit no shift can cure (a tilt past the machine's) ends it here,
    # before subdivision, which cannot converge on moves that cross a singularity.
    if shift_ranges(machine, path) is None:
        return none
    try:
        path = machine_path(machine, path_part, setup, tolerance=tolerance, angle_tolerance=angle_tolerance)
    except (ReachError, LimitError):                   # a bad axis, or a move bisection gives up on
        return none
    ranges = shift_ranges(machine, path)
    if ranges is None:
        return none
    # An unbounded side (no limit in that direction) keeps the current origin in that direction.
    centre = np.where(np.isfinite(ranges).all(axis=1), ranges.mean(axis=1),
                      np.clip(np.zeros(3), ranges[:, 0], ranges[:, 1]))
    for decimals in (1, 3, 6):
        texts = tuple(exact_text(v, decimals) for v in np.round(np.asarray(setup.origin) + centre, decimals))
        try:
            moved = setup.with_origin(tuple(float(t) for t in texts))
            posted = post_process(machine, path_part, moved, tolerance=tolerance, length_decimals=length_decimals,
                                  angle_tolerance=angle_tolerance)
        except (LimitError, ReachError, SetupError):
            continue
        origin: tuple[str, str, str] = texts  # type: ignore[assignment]
        if check is not None:
            try:
                check(moved, posted)
            except LimitError as failed:
                return Suggestion(origin=None, within_limits=origin, blocked=failed)
        return Suggestion(origin=origin, within_limits=origin)
    return none


def suggest_origin(machine: Machine, path_part: Toolpath, setup: Setup, *, tolerance: float, angle_tolerance: float,
                   length_decimals: int | None = None, check: SetupCheck | None = None) -> tuple[str, str, str] | None:
    """:func:`suggest`'s part origin: one at which the whole path passes post-processing and ``check``, as
    the decimal texts (x, y, z) whose values were checked; None when no translation passes."""
    return suggest(machine, path_part, setup, tolerance=tolerance, angle_tolerance=angle_tolerance,
                   length_decimals=length_decimals, check=check).origin


def placement_error(error: LimitError | ReachError, machine: Machine, path_part: Toolpath, setup: Setup, *,
                    tolerance: float, angle_tolerance: float, length_decimals: int | None = None,
                    check: SetupCheck | None = None, advise: Advise | None = None) -> Placement:
    """``error`` (the same kind) with the setup used and, where one exists, a part origin that works:
    one that passes ``check`` too. Where the origin that keeps every limit fails ``check``, the message
    says so, with what ``check`` found there and what ``advise`` says to change instead (no setup
    changes it), and no origin is suggested."""
    found = suggest(machine, path_part, setup, tolerance=tolerance, angle_tolerance=angle_tolerance,
                    length_decimals=length_decimals, check=check)
    advice, keys = suggestion_advice(found, advise, error.names_keys)
    kind = PlacementReachError if isinstance(error, ReachError) else PlacementLimitError
    return kind(f"{error.carried()}; setup: {setup.describe()}; {advice}", setup=setup, suggested_origin=found.origin,
                names_keys=keys, blocked=found.blocked is not None)


def suggestion_advice(found: Suggestion, advise: Advise | None, keys: bool | tuple[str, ...], *,
                      what: str = "puts every point inside the machine's limits") -> tuple[str, bool | tuple[str, ...]]:
    """The words that end a placement error about ``found`` (``what`` the origin does; ``advise``: what to
    change where a check other than the limits fails), and the keys the message names then (``keys``: the
    error's own)."""
    if found.blocked is not None:
        advice = (f"a part origin at machine [{', '.join(found.within_limits or ())}] mm {what}, but the "
                  f"collision check fails there: {found.blocked.carried()}; no setup changes that (the part and "
                  "the tool axes move together)")
        keys = _merged_keys(keys, found.blocked.names_keys)
        if advise is not None:
            words, named = advise(found.blocked)
            advice += f": {words}"
            keys = _merged_keys(keys, named)
        return advice, keys
    if found.origin is None:
        return f"no translation of the part {what}", keys
    return f"a part origin at machine [{', '.join(found.origin)}] mm {what}", keys


def _merged_keys(a: bool | tuple[str, ...], b: bool | tuple[str, ...]) -> bool | tuple[str, ...]:
    """The keys a message that joins two messages names (True: any)."""
    if a is True or b is True:
        return True
    return tuple(dict.fromkeys((*(a or ()), *(b or ())))) or False


# ============================================================================ automatic placement


@dataclass(frozen=True, slots=True)
class LimitMargin:
    """One limit's smallest margin over the whole job, at a setup.

    Attributes
    ----------
    name : str — the limit (``stroke``, ``link angle``, ``tilt``, ``condition number``, ``stage X`` ...;
        the three legs' strokes and link angles are one limit each)
    column : str — the column that has the smallest margin (``T2 stroke``; ``tilt``)
    unit : str — ``mm``, ``deg`` or ``""``
    margin : float — in ``unit`` (degrees for angles): distance to the nearest bound, negative outside
    span : float — in ``unit``: the limit's range (tilt from 0, condition number from 1)
    where : str — the step (or input line) of the row with that margin
    describe : str — that row's value against its bounds (``tilt 50.0000 deg is above the maximum ...``)
    """

    name: str
    column: str
    unit: str
    margin: float
    span: float
    where: str
    describe: str

    @property
    def normalized(self) -> float:
        """The margin as a fraction of the limit's range (0.5 at most: the middle of the range)."""
        return self.margin / self.span

    @property
    def leg(self) -> int | None:
        """The leg (1, 2, 3) of a stroke or link angle; None for the other limits."""
        first = self.column.split(" ", 1)[0]
        return int(first[1:]) if first[1:].isdigit() else None

    @property
    def label(self) -> str:
        """``stroke of leg 2``, ``tilt``: the limit in words (ASCII)."""
        return self.name if self.leg is None else f"{self.name} of leg {self.leg}"

    def text(self) -> str:
        """``stroke 176.0234 mm [0.352, leg 2]``: the margin, the fraction of the range, the leg (ASCII)."""
        unit = f" {self.unit}" if self.unit else ""
        leg = "" if self.leg is None else f", leg {self.leg}"
        return f"{self.name} {_fixed(self.margin, 4)}{unit} [{_fixed(self.normalized, 3)}{leg}]"


@dataclass(frozen=True, slots=True)
class PlacementResult:
    """The setup :func:`place` chose, and every limit's margin there.

    Attributes
    ----------
    setup : Setup — the part origin (0.1 mm steps where that keeps every limit) and rotation (0.1° steps)
    margins : tuple of LimitMargin — one per limit, in the machine's order
    origin_chosen, rotation_chosen : bool — which of the two were chosen (the others were given)
    evaluations : int — rotations at which the whole path was evaluated
    """

    setup: Setup
    margins: tuple[LimitMargin, ...]
    origin_chosen: bool
    rotation_chosen: bool
    evaluations: int

    @property
    def worst(self) -> LimitMargin:
        """The limit with the smallest normalized margin (the first of equals)."""
        return min(self.margins, key=lambda m: m.normalized)

    def describe(self) -> str:
        """One line for the program header and the summary: what was chosen, and every margin."""
        worst = self.worst
        return (f"{_chosen(self.origin_chosen, self.rotation_chosen)} chosen automatically for the largest "
                f"worst-case margin, {_fixed(worst.normalized, 3)} of the range of the {worst.label}. Margins "
                f"[fraction of the range]: {', '.join(m.text() for m in self.margins)}")


def _chosen(origin: bool, rotation: bool) -> str:
    """What was searched: ``part origin``, ``rotation about z`` or ``part origin and rotation about z``."""
    return " and ".join(what for what, on in (("part origin", origin), ("rotation about z", rotation)) if on)


@dataclass(frozen=True, slots=True)
class _Rows:
    """The whole job's rows placed at one rotation (origin 0): limit columns and where each row came from."""

    columns: LimitReport
    pieces: tuple[Toolpath, ...]      # machine frame, after subdivision
    first_row: tuple[int, ...]        # each piece's first row in ``columns.value``

    def describe(self, row: int) -> str:
        piece = int(np.searchsorted(self.first_row, row, side="right")) - 1
        return self.pieces[piece].describe(row - self.first_row[piece])


@dataclass(frozen=True, slots=True)
class _Candidate:
    """The best origin at one rotation and its worst normalized margin (without the tilt)."""

    rotation_deg: float               # degrees about z
    origin: FloatArray                # (3,) mm
    score: float                      # -inf where a row does not assemble


#: A path of no rows (the columns of a job without any).
_EMPTY = Toolpath(kind=np.zeros(0, dtype=np.int64), tip=np.zeros((0, 3)), axis=np.zeros((0, 3)), feed=np.zeros(0),
                  source=np.zeros(0, dtype=np.int64))


class _Search:
    """Evaluates the job's rows at a rotation and finds the best origin there (see the module docstring)."""

    def __init__(self, machine: Machine, paths: tuple[Toolpath, ...], machines: tuple[Machine, ...],
                 origin: FloatArray | None, fallback: FloatArray, tolerance: float, angle_tolerance: float):
        self.machine, self.paths, self.machines = machine, paths, machines
        self.origin, self.fallback = origin, fallback
        self.tolerance, self.angle_tolerance = tolerance, angle_tolerance
        self.evaluations = 0
        self._slope: FloatArray | None = None          # (3, L): d value / d shift, per direction
        self._cache: dict[tuple[float, bool], _Candidate] = {}
        self._sampled: tuple[Toolpath, ...] | None = None   # part frame, unit axes, subdivided once

    def rows(self, setup: Setup, *, sampled: bool = False) -> _Rows:
        """The job's rows at ``setup`` with every limit's value: subdivided as the program's are or, with
        ``sampled``, the search's rows: those subdivided once in the part frame that can hold a limit's
        extreme (:func:`_support`), turned and moved (no subdivision, and no IK of every row, per rotation).

        Raises
        ------
        ReachError
            A zero or downward tool axis.
        """
        if sampled:
            if self._sampled is None:
                whole = (machine_path(machine, path, Setup((0.0, 0.0, 0.0)), tolerance=self.tolerance,
                                      angle_tolerance=self.angle_tolerance)
                         for path, machine in zip(self.paths, self.machines, strict=True))
                self._sampled = tuple(piece.take(_support(piece)) for piece in whole)
            placed = tuple(place_toolpath(piece, setup) for piece in self._sampled)
        else:
            placed = tuple(machine_path(machine, path, setup, tolerance=self.tolerance,
                                        angle_tolerance=self.angle_tolerance)
                           for path, machine in zip(self.paths, self.machines, strict=True))
        blocks = [_columns(machine, piece) for piece, machine in zip(placed, self.machines, strict=True)]
        columns = blocks[0] if blocks else _columns(self.machine, _EMPTY)
        first = tuple(int(n) for n in np.cumsum([0] + [len(piece) for piece in placed])[:-1])
        value = np.concatenate([b.value for b in blocks]) if blocks else columns.value
        return _Rows(columns=_with_values(columns, value), pieces=placed, first_row=first)

    def slope(self, rows: _Rows) -> FloatArray:
        """(3, L) — how each limit's value moves per mm of part shift along x, y, z (measured once:
        it does not depend on the rotation). A limit moves with one direction at most."""
        if self._slope is None:
            value = rows.columns.value
            slopes = np.zeros((3, value.shape[1]))
            for k, unit in enumerate(np.eye(3)):
                moved = np.concatenate([_columns(m, p, unit).value for p, m in zip(rows.pieces, self.machines,
                                                                                  strict=True)])
                with np.errstate(invalid="ignore"):
                    change = np.nanmedian(moved - value, axis=0) if len(value) else np.zeros(value.shape[1])
                slopes[k] = np.where(np.abs(change) > _INDEPENDENT, np.nan_to_num(change), 0.0)
            slopes = _dominant(slopes)
            if ((slopes != 0.0).sum(axis=0) > 1).any():        # the module docstring's argument fails
                raise ValueError("placement: a limit moves with more than one direction of the part's shift")
            self._slope = slopes
        return self._slope

    def candidate(self, rotation_deg: float, *, whole: bool = False) -> _Candidate:
        """The best origin at ``rotation_deg`` (or the given one) and its score: on the search's rows,
        or on ``whole`` the rows of the program."""
        key = (rotation_deg, whole)
        if key in self._cache:
            return self._cache[key]
        self.evaluations += 1
        rows = self.rows(Setup((0.0, 0.0, 0.0), rotation_deg), sampled=not whole)
        columns = rows.columns
        value = columns.value
        if not len(value) or not np.isfinite(value).all():
            found = _Candidate(rotation_deg, self.fallback if self.origin is None else self.origin, -math.inf)
            self._cache[key] = found
            return found
        slope = self.slope(rows)
        low_side, high_side = value.min(axis=0) - columns.low, columns.high - value.max(axis=0)   # (L,) at 0
        span = _span(columns)
        origin = self.fallback.copy() if self.origin is None else self.origin.copy()
        if self.origin is None:
            for k in range(3):
                moving = slope[k] != 0.0
                best = _peak(np.concatenate([low_side[moving], high_side[moving]]) / np.tile(span[moving], 2),
                             np.concatenate([slope[k][moving], -slope[k][moving]]) / np.tile(span[moving], 2))
                if best is not None:
                    origin[k] = best
        shift = slope.T @ origin                         # (L,) how far each limit's values moved
        normalized = np.minimum(low_side + shift, high_side - shift) / span
        counted = np.array([name != "tilt" for name in columns.names])
        found = _Candidate(rotation_deg, origin, float(normalized[counted].min(initial=math.inf)))
        self._cache[key] = found
        return found


def _support(path: Toolpath) -> BoolArray:
    """(N,) bool — rows that hold every limit's extreme, at any rotation and shift: per tool axis (the
    link angles, tilt and condition number depend on it alone), the lowest and highest tip (the
    strokes move with the tip's z alone) and the tips farthest along 36 horizontal directions (the
    stage moves with the tip's x, y: exact at those rotations, within 0.4 % of the spread between).
    """
    count = len(path)
    keep = np.zeros(count, dtype=bool)
    if not count:
        return keep
    _, group = np.unique(np.round(path.axis, 9), axis=0, return_inverse=True)
    order = np.argsort(group.ravel(), kind="stable")
    sorted_group = group.ravel()[order]
    starts = np.flatnonzero(np.concatenate([[True], sorted_group[1:] != sorted_group[:-1]]))
    member = np.repeat(np.arange(len(starts)), np.diff(np.append(starts, count)))   # group of each sorted row
    angle = np.radians(np.arange(0.0, 180.0, 10.0))
    along = np.column_stack([path.tip[:, 2], path.tip[:, :2] @ np.array([np.cos(angle), np.sin(angle)])])
    for column in np.concatenate([along, -along], axis=1).T:
        ordered = column[order]
        keep[order[ordered >= np.maximum.reduceat(ordered, starts)[member]]] = True
    return keep


def _peak(offset: FloatArray, rate: FloatArray) -> float | None:
    """The t that maximizes min_j(offset_j + rate_j·t), or None when it is unbounded (no line falls or
    none rises, or there are none): the crossing of a rising and a falling line where the lower
    envelope is highest (the first such crossing of equals)."""
    finite = np.isfinite(offset)
    offset, rate = offset[finite], rate[finite]
    rising, falling = rate > 0.0, rate < 0.0
    if not rising.any() or not falling.any():
        return None
    crossing = ((offset[falling][None, :] - offset[rising][:, None])
                / (rate[rising][:, None] - rate[falling][None, :])).ravel()
    envelope = np.min(offset[None, :] + rate[None, :] * crossing[:, None], axis=1)
    return float(crossing[int(np.argmax(envelope))])


def _better(a: _Candidate, b: _Candidate) -> bool:
    """``a`` is a better choice than ``b``: a larger score, or as large and a smaller turn (then +)."""
    if a.score > b.score + _TIE:
        return True
    if b.score > a.score + _TIE:
        return False
    return (abs(a.rotation_deg), -a.rotation_deg) < (abs(b.rotation_deg), -b.rotation_deg)


def _best(candidates: list[_Candidate]) -> _Candidate:
    best = candidates[0]
    for candidate in candidates[1:]:
        if _better(candidate, best):
            best = candidate
    return best


def _search_rotation(search: _Search) -> _Candidate:
    """The coarse-to-fine search over the rotation (module docstring)."""
    half_turn = 1800
    coarse = [search.candidate(t / 10.0) for t in range(-half_turn + _COARSE_STEP, half_turn + 1, _COARSE_STEP)]
    ranked: list[_Candidate] = []
    pool = list(coarse)
    while pool and len(ranked) < _REFINED:
        pick = _best(pool)
        ranked.append(pick)
        pool.remove(pick)
    width = _COARSE_STEP
    for step in _FINE_STEPS:
        refined = []
        for centre in ranked:
            tenths = round(centre.rotation_deg * 10.0)
            grid = [_wrap(tenths + k * step) / 10.0 for k in range(-(width // step), width // step + 1)]
            refined.append(_best([search.candidate(t) for t in grid]))
        ranked = [_best(refined)]
        width = step
    return ranked[0]


def _wrap(tenths: int) -> int:
    """A rotation in tenths of a degree, in (-1800, 1800]."""
    return (tenths + 1799) % 3600 - 1799


def _margins(rows: _Rows) -> tuple[LimitMargin, ...]:
    """Each limit's smallest margin over the rows (legs' strokes and link angles as one limit each; a
    row that does not assemble has the margin -inf)."""
    columns = rows.columns
    normalized = np.nan_to_num(columns.margin / _span(columns), nan=-np.inf)   # (N, L)
    groups: dict[str, list[int]] = {}
    for index, name in enumerate(columns.names):
        leg = name[1:2].isdigit() and " " in name        # a joint's or a leg's (T1 stroke, θ1 link angle)
        groups.setdefault(name.split(" ", 1)[1] if leg else name, []).append(index)
    out = []
    for name, indices in groups.items():
        unit = columns.units[indices[0]]
        scale = math.degrees(1.0) if unit == "deg" else 1.0
        span = float(_span(columns)[indices[0]]) * scale
        if not len(normalized):                        # a job without rows keeps every limit
            out.append(LimitMargin(name=name, column=columns.names[indices[0]], unit=unit, margin=math.inf,
                                   span=span, where="", describe=""))
            continue
        row, local = np.unravel_index(int(np.argmin(normalized[:, indices])), (len(normalized), len(indices)))
        column = indices[int(local)]
        margin = float(columns.margin[row, column]) * scale
        out.append(LimitMargin(name=name, column=columns.names[column], unit=unit,
                               margin=margin if math.isfinite(margin) else -math.inf, span=span,
                               where=rows.describe(int(row)), describe=columns.describe(int(row), column)))
    return tuple(out)


def place(machine: Machine, paths: Toolpath | Sequence[Toolpath], *, origin: Sequence[float] | None = None,
          rotation_deg: float | None = None, tool_lengths: Sequence[float] | None = None,
          tolerance: float, angle_tolerance: float) -> PlacementResult:
    """Choose the setup with the largest worst-case normalized margin (module docstring).

    Parameters
    ----------
    machine : Machine
    paths : Toolpath or sequence of Toolpath — the whole job in part coordinates, one piece per
        tool length (each piece is subdivided as the pipeline does)
    origin : (3,) float, optional — mm, the part origin to keep; None: choose it
    rotation_deg : float, optional — degrees about the machine z axis to keep; None: choose it
        (with ``origin`` given, the rotation that suits that origin best)
    tool_lengths : sequence of float, optional — mm, the tool length "TL" of each piece (None: the machine's)
    tolerance, angle_tolerance : as :func:`~prs3_post.post.pipeline.post_process`

    Returns
    -------
    PlacementResult — every limit's margin on every row (after subdivision) at the chosen setup

    Raises
    ------
    LimitError
        No setup puts every row inside every limit: the message names each limit that cannot be met
        and by how much at the best setup found.
    ReachError
        A row whose tool axis the head cannot reach at any rotation tried (or at the given one), or
        a zero or downward tool axis.
    """
    pieces = (paths,) if isinstance(paths, Toolpath) else tuple(paths)
    lengths = [None] * len(pieces) if tool_lengths is None else list(tool_lengths)
    if len(lengths) != len(pieces):
        raise ValueError(f"place: {len(pieces)} paths but {len(lengths)} tool lengths")
    machines = tuple(machine if length is None else machine.with_tool_length(float(length)) for length in lengths)
    given = None if origin is None else np.asarray(origin, dtype=np.float64).reshape(3)
    search = _Search(machine, pieces, machines, given, np.asarray(machine.part_origin, dtype=np.float64),
                     tolerance, angle_tolerance)
    if rotation_deg is None:
        return _finish(search, _search_rotation(search), origin is None, True)
    try:
        return _finish(search, search.candidate(float(rotation_deg)), origin is None, False)
    except LimitError as error:                        # would turning the part help? say so
        try:
            turned = _finish(search, _search_rotation(search), origin is None, True)
        except (LimitError, ReachError):
            raise error from None
        raise LimitError(f"{error}; turning the part about z would fit: {turned.setup.describe()} (worst margin "
                         f"{_fixed(turned.worst.normalized, 3)} of the range of the {turned.worst.label})") from None


def _finish(search: _Search, best: _Candidate, origin_chosen: bool, rotation_chosen: bool) -> PlacementResult:
    """The chosen setup, rounded (0.1 mm where every limit still holds), its margins, or the error."""
    best = search.candidate(best.rotation_deg, whole=True)    # the origin for every row of the program
    if origin_chosen and not np.abs(best.origin).max() <= MAX_ORIGIN_MM:   # a kilometre-long tool, say
        shown = ", ".join(f"{v:.6g}" for v in best.origin)
        raise LimitError(f"no {_chosen(origin_chosen, rotation_chosen)} puts every point inside the machine's limits: "
                         f"the best one is at machine [{shown}] mm, beyond the ±{MAX_ORIGIN_MM:g} mm a part origin may "
                         "be from the machine's origin (is the tool length right?)")
    attempts = [np.round(best.origin, d) for d in (1, 3, 6)] if origin_chosen else [best.origin]
    first: tuple[PlacementResult, _Rows] | None = None
    for origin in attempts:
        setup = Setup(tuple(float(v) for v in origin), best.rotation_deg)  # type: ignore[arg-type]
        rows = search.rows(setup)
        result = PlacementResult(setup=setup, margins=_margins(rows), origin_chosen=origin_chosen,
                                 rotation_chosen=rotation_chosen, evaluations=search.evaluations)
        if result.worst.margin >= 0.0:
            return result
        first = first or (result, rows)
    assert first is not None
    result, rows = first
    if origin_chosen:                                  # "at best": the margins at the unrounded optimum
        exact = Setup(tuple(float(v) for v in best.origin), best.rotation_deg)  # type: ignore[arg-type]
        rows = search.rows(exact)
        result = replace(result, setup=exact, margins=_margins(rows))
    what = _chosen(origin_chosen, rotation_chosen)
    unreachable = np.flatnonzero(~np.isfinite(rows.columns.value).all(axis=1))
    if len(unreachable):
        scope = "any rotation about z tried" if rotation_chosen else "this rotation about z, at any part origin"
        count = f"; {len(unreachable)} points unreachable" if len(unreachable) > 1 else ""
        raise ReachError(f"{rows.describe(int(unreachable[0]))}: the head cannot reach this tool axis at {scope} "
                         f"(a link cannot reach its joint{count})")
    raise LimitError(f"no {what} puts every point inside the machine's limits: {_failures(result)}; the best setup "
                     f"found: {result.setup.describe()}")


def _failures(result: PlacementResult) -> str:
    """``the tilt cannot be met, by 6.5651 deg at best (hole 1 approach: tilt ...)`` and the other limits
    outside at that setup."""
    worst = result.worst
    parts = []
    for m in sorted((m for m in result.margins if m.margin < 0.0), key=lambda m: m.normalized):
        unit = f" {m.unit}" if m.unit else ""
        how = "cannot be met, by" if m is worst else "is outside too, by"
        suffix = " at best" if m is worst else " there"
        parts.append(f"the {m.label} {how} {_fixed(-m.margin, 4)}{unit}{suffix} ({m.where}: {m.describe})")
    return "; ".join(parts)
