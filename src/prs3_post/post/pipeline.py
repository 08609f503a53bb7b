"""From a part-frame toolpath to a checked actuator-space program, whole or in chunks.

    part toolpath ──► setup (part → machine) ──► subdivide axis changes ──► IK ──► reach
                  ──► drop moves the output cannot show ──► limits ──► G93 feeds ──► JointProgram

Pure: no files. The first failure is raised with the operation step (or input file and line) it
came from; nothing is emitted for a program that has one.

:class:`PostStream` takes the toolpath in consecutive chunks and carries what a row depends on
from the rows before it (the last pose, for the subdivision of the move to the next row and for
its inverse-time feed; the last row kept, for the resolution guard), so that the rows it makes are
those of :func:`post_process` on the whole toolpath, cut in the same places. ``app.streaming.program_text``
adds the emitter: an iterator of toolpath chunks becomes an iterator of G-code text chunks, ready
for :func:`prs3_post.core.output_files.write_atomic`, whose bytes do not depend on the chunking.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_TOLERANCE
from prs3_post.core.errors import LimitError, PoseError, ReachError
from prs3_post.core.rowwise import row_lengths
from prs3_post.core.toolpath import JointProgram, MoveKind, Toolpath
from prs3_post.core.types import FloatArray
from prs3_post.kinematics import AxisMemo, IKModel, IKResult, unit_axes
from prs3_post.kinematics.protocol import tilt_of
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.model import GENERAL_KINEMATICS, Machine
from prs3_post.part.setup_transform import Setup
from prs3_post.post.dynamics import DynamicsTally, joint_columns
from prs3_post.post.limits import LimitReport, LimitTally, check_limits, raise_first_violation, within_limits
from prs3_post.post.linearize import linearize, subdivide_axis_changes
from prs3_post.post.visible_moves import VisibleMoves

__all__ = ["PostCounts", "PostResult", "PostStream", "inverse_time", "machine_path", "model_for",
           "place_toolpath", "post_process"]


def place_toolpath(path: Toolpath, setup: Setup) -> Toolpath:
    """The part-frame toolpath in the machine frame: tips and axes carried through the setup."""
    return replace(path, tip=setup.points_to_machine(path.tip), axis=setup.axes_to_machine(path.axis))


@dataclass(frozen=True, slots=True, init=False)
class PostResult:
    """A checked program (or one chunk of it) and what it was made from.

    ``PostResult(program, path, ik, limits, dynamics=None)``, where ``limits`` is the report or a
    function that makes it: a stream knows every row is within every limit without one
    (:func:`~prs3_post.post.limits.within_limits`), and a program's (L, N) values and margins are made
    only if :attr:`limits` is read.

    Attributes
    ----------
    program : JointProgram — ready to emit
    path : Toolpath — the machine-frame toolpath after subdivision (one row per program row)
    ik : IKResult — per row
    limits : LimitReport — per row (all ok)
    dynamics : DynamicsTally | None — the feeds slowed, of the rows so far (None: not counted)
    """

    program: JointProgram
    path: Toolpath
    ik: IKResult
    _limits: LimitReport | Callable[[], LimitReport]
    dynamics: DynamicsTally | None

    def __init__(self, program: JointProgram, path: Toolpath, ik: IKResult,
                 limits: LimitReport | Callable[[], LimitReport] | None = None,
                 dynamics: DynamicsTally | None = None, *,
                 _limits: LimitReport | Callable[[], LimitReport] | None = None):
        # (``_limits``: the field's own name, as dataclasses.replace passes it)
        report = limits if limits is not None else _limits
        if report is None:
            raise TypeError("PostResult: limits (a LimitReport, or a function that makes it) is required")
        for name, value in (("program", program), ("path", path), ("ik", ik), ("_limits", report),
                            ("dynamics", dynamics)):
            object.__setattr__(self, name, value)

    @property
    def limits(self) -> LimitReport:
        """LimitReport — per row (all ok), made when it is first read."""
        report = self._limits
        if not isinstance(report, LimitReport):
            report = report()
            object.__setattr__(self, "_limits", report)
        return report


@dataclass(frozen=True, slots=True)
class PostCounts:
    """What a :class:`PostStream` did, in rows.

    Attributes
    ----------
    input_rows : int — toolpath rows fed in
    inserted : int — rows the subdivision of axis-changing moves added
    dropped : int — rows dropped because the program could not show their move
    program_rows : int — rows of the program (input_rows + inserted − dropped)
    tip_before, angle_before : float — mm, rad: the worst deviation of an axis-changing feed move's
        joint-space line from its intended path, as given (0: no such move)
    tip_after, angle_after : float — mm, rad: the same after the subdivision (within the tolerances)
    """

    input_rows: int
    inserted: int
    dropped: int
    program_rows: int
    tip_before: float = 0.0
    angle_before: float = 0.0
    tip_after: float = 0.0
    angle_after: float = 0.0


def model_for(machine: Machine) -> IKModel:
    """The IK model a machine runs: exact with a stage, head alone without one."""
    return IKModel.EXACT if machine.stage.present else IKModel.HEAD


def _unit_path(path: Toolpath, first_row: int) -> Toolpath:
    """``path`` with its axes scaled to unit length; a zero or downward axis is a ReachError."""
    try:
        unit = unit_axes(path.tip, path.axis, row_numbers=first_row + np.arange(len(path)))
    except PoseError as error:
        raise ReachError(f"toolpath: {error}") from error
    return replace(path, axis=unit)


def machine_path(machine: Machine, path_part: Toolpath, setup: Setup, *, tolerance: float,
                 angle_tolerance: float) -> Toolpath:
    """The part-frame toolpath placed on the machine, with unit axes, its axis-changing moves subdivided.

    Not subdivided when a row tilts past the machine's limit: no setup runs such a path (the tilt
    does not depend on where the part is), and near the singularity beyond that limit bisection
    does not converge; the rows as given are what the limit check then reports.

    Raises
    ------
    ReachError
        A zero or downward tool axis.
    LimitError
        A move the subdivision gives up on (:func:`~prs3_post.post.linearize.linearize`).
    """
    path = _unit_path(place_toolpath(path_part, setup), 0)
    if (tilt_of(path.axis) > machine.limits.max_tilt).any():
        return path
    return subdivide_axis_changes(kinematics_of(machine), path, tolerance=tolerance, angle_tolerance=angle_tolerance)


class PostStream:
    """:func:`post_process` over a toolpath given in consecutive chunks.

    ``feed(chunk)`` returns the chunk's :class:`PostResult` (its program's events count rows from
    the chunk's start; ``before == len``: after its last row); the programs of all chunks, emitted
    one after the other (:class:`~prs3_post.emit.gcode.ProgramEmitter`), are the program of the
    whole toolpath. A chunk may have any number of rows, including none. The first error stops
    the stream: a chunk that raises leaves it unusable. ``finish()`` returns the counts.

    Parameters
    ----------
    machine, setup, tolerance, angle_tolerance, length_decimals, clamp : as :func:`post_process`
    placed : bool — the chunks come placed already: in the machine frame with unit axes, as
        :func:`place_toolpath` through ``setup`` and :func:`~prs3_post.kinematics.unit_axes` make
        them (a caller that checked the axes by input line on the way; False: part frame)
    timed : bool — add up the cycle time of the rows fed (``dynamics.minutes``, for a program not kept whole)
    tally_limits : bool — keep the closest approach to each limit of the rows fed (:attr:`limits`; each
        chunk's margins are then computed: about 0.9 µs a row, where the check alone takes 0.1 µs)
    """

    def __init__(self, machine: Machine, setup: Setup, *, tolerance: float = DEFAULT_TOLERANCE,
                 angle_tolerance: float = DEFAULT_ANGLE_TOLERANCE, length_decimals: int | None = None,
                 clamp: bool = True, placed: bool = False, timed: bool = False, tally_limits: bool = False):
        self.machine, self.setup, self.placed = machine, setup, placed
        self.limits = LimitTally() if tally_limits else None
        self.tolerance, self.angle_tolerance = tolerance, angle_tolerance
        self.model = model_for(machine)
        self._visible = None if length_decimals is None else VisibleMoves(length_decimals)
        self._last_pose: Toolpath | None = None       # the last row fed (machine frame, unit axis)
        self._last_tip: FloatArray | None = None      # (3,) the tip of the last program row
        self._input_rows = self._inserted = self._dropped = self._program_rows = 0
        self._worst = np.zeros(4)                     # tip, angle before; tip, angle after
        self._failed = False
        self.dynamics = DynamicsTally(machine, clamp=clamp, timed=timed)   # feeds clamped to the axis speeds
        self._axes = AxisMemo(machine.geometry)       # the IK's terms of each work plane's axis, made once

    def feed(self, chunk: Toolpath) -> PostResult:
        """The next chunk of the part-frame toolpath, post-processed (see :func:`post_process`).

        Raises
        ------
        ReachError, LimitError
            As :func:`post_process`; a count of the bad points is of the rows fed so far.
        """
        if self._failed:
            raise RuntimeError("PostStream: an earlier chunk failed; start a new stream")
        self._failed = True                           # until this chunk is through
        result = self._post(chunk, scope="so far")
        self._failed = False
        return result

    def finish(self) -> PostCounts:
        """The counts of the rows fed, added and dropped (the stream needs nothing else to end)."""
        tip_before, angle_before, tip_after, angle_after = self._worst.tolist()
        return PostCounts(input_rows=self._input_rows, inserted=self._inserted, dropped=self._dropped,
                          program_rows=self._program_rows, tip_before=tip_before, angle_before=angle_before,
                          tip_after=tip_after, angle_after=angle_after)

    def _post(self, chunk: Toolpath, *, scope: str) -> PostResult:
        machine, model = self.machine, self.model
        given = chunk if self.placed else _unit_path(place_toolpath(chunk, self.setup), self._input_rows)
        ik = _check_end_points(machine, given, model, self._counted(scope, len(given)), self._axes)
        linear = linearize(kinematics_of(machine), given, tolerance=self.tolerance,
                           angle_tolerance=self.angle_tolerance, start=self._last_pose)
        path = linear.path
        subdivided = len(path)
        checked = path is given                       # nothing inserted: the rows checked above, as they are
        if not checked:
            ik = kinematics_of(machine).inverse(path.tip, path.axis, model=model, memo=self._axes)
            _raise_unreachable(machine, path, ik, model, self._counted(scope, len(path)))
        stage = ik.stage if model is IKModel.EXACT else np.zeros_like(ik.stage)
        last_pose = self._last_pose
        if len(path):                                  # the last row, for the move to the next chunk's first
            last_pose = Toolpath(kind=path.kind[-1:], tip=path.tip[-1:], axis=path.axis[-1:], feed=path.feed[-1:],
                                 source=path.source[-1:], source_labels=path.source_labels,
                                 source_file=path.source_file)
        joints = joint_columns(stage, ik.strokes)        # (N, 2 + J): the printed axes, for the guard and the speeds
        steps: FloatArray | None = row_lengths(np.diff(path.tip, axis=0))   # for the guard and the feeds
        if self._visible is not None:                  # no move the program cannot show (a G1 without a word)
            keep = self._visible.keep(joints, tip=path.tip, axis=path.axis, steps=steps)
            if not keep.all():
                path, stage, joints, steps = path.take(keep), stage[keep], joints[keep], None
                ik = IKResult(stage=ik.stage[keep], strokes=ik.strokes[keep], link_angle=ik.link_angle[keep],
                              condition=ik.condition[keep], reachable=ik.reachable[keep])
        if not checked:                                # (checked: every row is within, so are those kept)
            _raise_outside_limits(machine, path, ik, self._counted(scope, len(path)))
        # the limits' report: made if the result's limits are read, or now when they are tallied
        report: LimitReport | Callable[[], LimitReport] = partial(check_limits, machine, ik, path.axis)
        if self.limits is not None:
            report = check_limits(machine, ik, path.axis)
            self.limits.fold(report, self._program_rows)
        feeds = inverse_time(path, start=self._last_tip, steps=steps)
        self._input_rows += len(chunk)
        self._inserted += subdivided - len(chunk)
        self._dropped += subdivided - len(path)
        self._program_rows += len(path)
        self._worst = np.maximum(self._worst, [linear.tip_before, linear.angle_before, linear.tip_after,
                                               linear.angle_after])
        self._last_pose = last_pose
        if len(path):
            self._last_tip = path.tip[-1].copy()
        program = JointProgram(
            kind=path.kind, stage=stage, strokes=ik.strokes, inverse_time=feeds, source=path.source,
            events=path.events, source_labels=path.source_labels, source_file=path.source_file,
        )
        clamped = self.dynamics.feed(program, joints)
        if clamped is not program.inverse_time:        # slowed: the path's tip feeds drop by the same ratio
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(feeds > 0, clamped / feeds, 1.0)
            program = replace(program, inverse_time=clamped)
            path = replace(path, feed=path.feed * ratio)
        return PostResult(program=program, path=path, ik=ik, limits=report, dynamics=self.dynamics)

    def _counted(self, scope: str, rows: int) -> str:
        """How a count of bad points is qualified: ``in all`` (the whole path) or of the rows so far."""
        if scope == "in all":
            return scope
        return f"among the {self._program_rows + rows} checked so far"


def post_process(machine: Machine, path_part: Toolpath, setup: Setup, *, tolerance: float,
                 angle_tolerance: float, length_decimals: int | None = None,
                 clamp: bool = True) -> PostResult:
    """Turn a part-frame toolpath into a checked joint-space program.

    Parameters
    ----------
    machine : Machine
    path_part : Toolpath — part coordinates
    setup : Setup — part → machine transform
    tolerance : float — mm, tip deviation allowed on moves whose axis changes
    angle_tolerance : float — rad, tool-axis deviation allowed on moves whose axis changes
    length_decimals : int, optional — digits after the point of the program's axis words: rows
        that would print no changed axis word are dropped (None: keep every row)
    clamp : bool — lower a G1 feed that would drive an axis over its top speed (machine dynamics);
        False: such a feed is a LimitError

    Returns
    -------
    PostResult

    Raises
    ------
    ReachError
        A pose that does not assemble, or that a machine without a stage cannot reach.
    LimitError
        A point outside a machine limit, a feed move with zero length, or (``clamp=False``) a feed
        over an axis's top speed.
    """
    stream = PostStream(machine, setup, tolerance=tolerance, angle_tolerance=angle_tolerance,
                        length_decimals=length_decimals, clamp=clamp)
    return stream._post(path_part, scope="in all")



def _check_end_points(machine: Machine, path: Toolpath, model: IKModel, scope: str,
                      memo: AxisMemo | None = None) -> IKResult:
    """Reach and limits of the rows as given, before their moves are subdivided.

    A move whose end point is out of reach or past the tilt limit (the singularity lies not far
    beyond it) cannot be subdivided: its joint-space line does not converge, and bisection would
    double its rows round after round. Such a row is the error, with the same message as after subdivision
    (the count is of the rows as given). The inserted rows cannot break the tilt limit where the end
    points keep it (the axes within a tilt of the vertical are a convex cap: the great circle between
    two of them stays in it); they are checked with the rest after subdivision.

    Returns
    -------
    IKResult — of the rows as given (all reachable, all within the limits): the pipeline's when the
    subdivision inserts nothing

    Raises
    ------
    ReachError, LimitError
        As :func:`post_process`.
    """
    ik = kinematics_of(machine).inverse(path.tip, path.axis, model=model, memo=memo)
    _raise_unreachable(machine, path, ik, model, scope)
    _raise_outside_limits(machine, path, ik, scope)
    return ik


def _raise_outside_limits(machine: Machine, path: Toolpath, ik: IKResult, scope: str) -> None:
    """The LimitError of the first point outside a limit (:func:`~prs3_post.post.limits.raise_first_violation`
    of the rows' report), if any: the report is made only when some value is outside."""
    if not within_limits(machine, ik, path.axis):
        raise_first_violation(check_limits(machine, ik, path.axis), path.describe, scope=scope)


def _raise_unreachable(machine: Machine, path: Toolpath, ik: IKResult, model: IKModel, scope: str) -> None:
    bad = np.flatnonzero(~ik.reachable)
    if not len(bad):
        return
    row = int(bad[0])
    where = path.describe(row)
    tip = ", ".join(f"{v:.4f}" for v in path.tip[row])
    count = f" ({len(bad)} points unreachable {scope})" if len(bad) > 1 else ""
    if model is IKModel.HEAD and np.isfinite(ik.stage[row]).all():
        dx, dy = ik.stage[row]
        raise ReachError(
            f"{where}: machine {machine.name} has no stage and its head alone misses the tip ({tip}) by "
            f"{np.hypot(dx, dy):.4f} mm (x {dx:.4f}, y {dy:.4f}){count}"
        )
    newton = (", or the Newton iterations of its kinematics from the ideal head's pose did not converge"
              if machine.kinematics == GENERAL_KINEMATICS else "")
    raise ReachError(f"{where}: the head cannot reach the tip ({tip}) mm with this axis: a link cannot reach "
                     f"its joint{newton} (check {{setup.part_origin}}){count}", names_keys=("setup.part_origin",))


def inverse_time(path: Toolpath, *, start: FloatArray | None = None, steps: FloatArray | None = None) -> FloatArray:
    """G93 F words: tip feed / tip path length of each FEED row (1/min); 0 for RAPID rows.

    Every move's tip path is the straight line between its end points (moves whose axis changes
    were subdivided until the joint-space line stays within tolerance of it).

    Parameters
    ----------
    path : Toolpath
    start : (3,) float, optional — mm, the tip before row 0 (the last row of the chunk before);
        None: row 0 is the first row of the program
    steps : (N − 1,) float, optional — mm, the lengths of the steps between the rows,
        ``row_lengths(np.diff(path.tip, axis=0))``, when the caller has them

    Raises
    ------
    LimitError
        A FEED row as the first row of the program (no start point) or with zero length (no time to give it).
    """
    if steps is not None and len(steps) != max(len(path) - 1, 0):
        raise ValueError(f"inverse_time: {len(steps)} step lengths for {len(path)} rows")
    fed = path.kind == MoveKind.FEED
    if not len(path) or not fed.any():
        return np.zeros(len(path))
    if fed[0] and start is None:
        raise LimitError(f"{path.describe(0)}: the program starts with a feed move; its start point is unknown")
    first = None if start is None else np.asarray(start, dtype=np.float64).reshape(1, 3)
    if first is not None and fed.all():                  # every row a feed move: the steps as slices, no indexing
        if steps is not None:
            length = np.concatenate([row_lengths(path.tip[:1] - first), steps])
        else:
            length = row_lengths(path.tip - np.concatenate([first, path.tip[:-1]]))
        if (length < 1e-9).any():
            raise LimitError(f"{path.describe(int(np.flatnonzero(length < 1e-9)[0]))}: feed move of zero length")
        return path.feed / length
    feed_rows = np.flatnonzero(fed)
    before = path.tip if first is None else np.concatenate([first, path.tip])
    offset = 0 if start is None else 1
    length = row_lengths(path.tip[feed_rows] - before[feed_rows - 1 + offset])
    zero = np.flatnonzero(length < 1e-9)
    if len(zero):
        raise LimitError(f"{path.describe(int(feed_rows[zero[0]]))}: feed move of zero length")
    out = np.zeros(len(path))
    out[feed_rows] = path.feed[feed_rows] / length
    return out
