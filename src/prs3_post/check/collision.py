"""Clearance of the tool, the holder and the spindle nose from the part, along a program's motion.

The bodies are cylinders on the tool axis (:class:`~prs3_post.machine.model.Holder`): from the tip up
the tool (the operation's diameter, up to the holder), the holder (to the spindle's gauge line:
the tool's length is the machine's, or the tool table's), the spindle nose. The clearance of a pose
is the smallest signed distance of a body to the part's triangles (negative inside the part: ray
parity along a fixed direction), so a penetration is reported by its depth.

Only the tool may be in the part, and only where it cuts: while the tip is within the feature's
swept region (the tool radius around the feed moves' tips, in the face's plane), its part below
``clearance_min`` above the worked face is not checked and the rest is measured from the part
without that face (the tool touches the face where it enters, and the face's edges where a feature
runs over them: a point that high is that far from both; a wall beside the face rises higher, and
is measured). Everything else must stay ``clearance_min`` clear.

How, in three stages (numpy only):

1. **Bounds, coarse to fine.** Each body is cut into pieces (at most ``max(radius, PIECE_MM)``
   long). Poses are grouped ``LEVELS`` at a time (4096, 256, 16, then one): a group's piece is
   bounded by a sphere round its first pose's piece, widened by how far the group moves it, and a
   (group, piece, triangle) pair is dropped as soon as that sphere is ``REACH_MM`` beyond
   ``clearance_min`` from the triangle; the pairs left are split into the next level's groups. For
   one pose and a triangle the bound is the larger of the gap between the cylinder and the
   triangle's plane (tight for the holder's end over the face) and the exact distance between the
   cylinder's axis segment and the triangle less its radius (tight beside a wall). The first level
   meets only the triangles whose boxes the part's :class:`~prs3_post.part.meshindex.TriangleIndex`
   finds within that reach of each group's sphere (a superset of those it keeps, measured the same
   way), so no array is as long as groups × pieces × triangles; most pairs go there, and the cost
   follows the poses that are near the part and the triangles near them.
2. **Exact where it matters.** A pose whose bound is under ``clearance_min`` is measured on its
   bodies' surfaces: rings every ``RING_SPACING_MM`` along each, ``AZIMUTHS`` points per ring, and
   rings on its end discs, against the triangles whose pair bound was under ``clearance_min`` + 2 mm
   (exact point–triangle distances; farther, the body is "over" that); the
   sampling makes a cylinder facing a plane at most ``r (1 − cos(π / AZIMUTHS))`` (0.19 mm for the
   holder) closer than the points say. Poses are measured closest bound first; once a body is
   found too close, ``AFTER_HIT`` more blocks at most (its depth is the deepest of those), and the
   motion between poses is not checked further (the program is refused already).
3. **Between poses.** When the poses are the samples of one motion (``connected``), a body moves at
   most δ = |Δtip| + ρ·θ between two of them (ρ: its farthest point from the tip, θ: the axis's
   turn), so its clearance there is at least (c₀ + c₁ − δ) / 2 from the two poses' clearances c₀,
   c₁. Where that is under ``clearance_min`` − ``SWEEP_SLACK_MM`` the interval is halved (the tip
   straight between them, the axis on its great circle: exact for a move that translates the head,
   which verify samples at its end only) and the halves checked the same way. A rapid through the
   part between two features is caught there.

Why not a library: trimesh's proximity queries need rtree (not installed), and scipy (for a k-d tree)
is not installed either; python-fcl or manifold3d would be a compiled dependency for what the
staged bounds above do in numpy at 10⁵ poses a second or more on the demo parts
(``bench/bench_dynamics.py``). The nearest-triangle queries of the measurements walk the same
index (:func:`~prs3_post.part.meshdist.nearest_distance`); on fine meshes see ``bench/bench_collision.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from prs3_post.check import collision_scan
from prs3_post.check.collision_bodies import BODY_NAMES, CollisionError, Region, body_cylinders, swept_region
from prs3_post.check.collision_distance import (
    MEASURE_BLOCK,
    REACH_MM,
    Clearance,
    ClearancePoses,
    Part,
    Spread,
    body_pieces,
    check_between,
    clearance,
    pose_bounds,
)
from prs3_post.check.collision_rapids import (
    RAPID_TOUCH_MM,
    RapidClearance,
    check_rapids,
    rapid_tool_clearance,
    tool_words,
)
from prs3_post.core.defaults import DEFAULT_TOLERANCE
from prs3_post.core.numbers import exact_text
from prs3_post.core.toolpath import JointProgram, MoveKind, program_from_columns
from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.kinematics.replay import replay
from prs3_post.machine.model import Machine
from prs3_post.part.face import Face
from prs3_post.part.meshdist import inside, point_triangle_distance
from prs3_post.part.setup_transform import Setup

__all__ = ["BODY_NAMES", "RAPID_TOUCH_MM", "Approach", "Clearance", "CollisionError", "ProgramClearance",
           "RapidClearance", "approach_label", "body_cylinders", "check_program", "check_rapids", "clearance",
           "feed_tips_of", "inside", "measure_program", "point_triangle_distance", "rapid_tool_clearance", "tool_words"]


def check_program(machine: Machine, program: JointProgram, setup: Setup, triangles: FloatArray, face: Face | None,
                  tool_diameter: float, *, clearance_min: float) -> str:
    """Replay ``program`` (verify's FK samples) and check the bodies' clearance from the part.

    ``face`` None: a CAM program's (``convert --part``), whose tool cuts what the CAM program
    removes, where it removes it: the tool is not checked (its gouges are the CAM system's to
    check), the holder and the nose are.

    Returns
    -------
    str — the header's ``collision`` entry: each body's smallest clearance (:func:`measure_program`)

    Raises
    ------
    LimitError
        ``hole 1, peck 1: the holder hits the part, 2.498 mm deep (clearance min 1.000 mm)`` or
        ``...: the tool comes within 0.400 mm of the part (clearance min 1.000 mm)``.
    """
    found = measure_program(machine, program, setup, triangles, face, tool_diameter, clearance_min=clearance_min)
    return found if isinstance(found, str) else found.entry(clearance_min, cam=face is None)


@dataclass(frozen=True, slots=True)
class ProgramClearance:
    """Each body's smallest clearance over a program's motion (:func:`measure_program`).

    Attributes
    ----------
    distance : (3,) float — mm, per body (tool, holder, nose): the smallest clearance measured on the
        body's surface points, to the header's 0.001 mm, where it is under the horizon (``exact``);
        else the horizon, ``clearance_min`` + ``REACH_MM`` (the body is farther than that everywhere)
    exact : (3,) bool — the distance is the minimum (else: over the horizon)
    row : (3,) int — the program row of each exact minimum (its earliest sample; -1: over the horizon)
    point : (3, 3) float — mm, part frame: the body's point there (zeros where ``row`` is -1)
    """

    distance: FloatArray
    exact: BoolArray
    row: IntArray = field(default_factory=lambda: np.full(3, -1, dtype=np.int64))
    point: FloatArray = field(default_factory=lambda: np.zeros((3, 3)))

    def merged(self, other: ProgramClearance) -> ProgramClearance:
        """Each body's smaller clearance of this and ``other`` (rows of the same program; a measured
        one before a bound it ties)."""
        take = (other.distance < self.distance) | ((other.distance == self.distance) & other.exact & ~self.exact)
        return ProgramClearance(distance=np.where(take, other.distance, self.distance),
                                exact=np.where(take, other.exact, self.exact), row=np.where(take, other.row, self.row),
                                point=np.where(take[:, None], other.point, self.point))

    def shifted(self, rows: int) -> ProgramClearance:
        """The same minima in a program where this one's rows start at row ``rows``."""
        return replace(self, row=np.where(self.row >= 0, self.row + rows, -1))

    def approach(self) -> Approach | None:
        """The closest of the bodies measured (None: every body over the horizon, or not checked)."""
        measured = np.flatnonzero(self.exact & (self.row >= 0))
        if not len(measured):
            return None
        b = int(measured[np.argmin(self.distance[measured])])
        return Approach(body=b, distance=float(self.distance[b]), exact=True, row=int(self.row[b]),
                        point=self.point[b].copy())

    def entry(self, clearance_min: float, *, cam: bool = False, rapids: RapidClearance | None = None) -> str:
        """The header's ``collision`` entry: ``clear of the part by at least 1.000 mm: tool 3.250 mm,
        holder over 11.000 mm, spindle nose over 11.000 mm`` (``cam``: the tool is not checked;
        ``rapids``: a CAM program's tool, checked in its rapids only)."""
        shown = [f"{name} {'' if exact else 'over '}{d:.3f} mm" for name, d, exact in zip(
            BODY_NAMES, self.distance.tolist(), self.exact.tolist(), strict=True)]
        if cam:
            shown[0] = "tool not checked (it cuts what the CAM program removes)"
        if rapids is not None:
            shown[0] = f"{rapids.entry()}, not in feeds (it cuts what the CAM program removes)"
        return f"clear of the part by at least {exact_text(clearance_min, 3)} mm: {', '.join(shown)}"


@dataclass(frozen=True, slots=True)
class Approach:
    """A body's closest approach to the part, where a preview marks it.

    Attributes
    ----------
    body : int — index in :data:`BODY_NAMES`
    distance : float — mm (negative: depth in the part)
    exact : bool — measured (False: a lower bound, stated as ``over``)
    row : int — the program row (move) of that pose
    point : (3,) float — mm, part frame: the body's point there
    """

    body: int
    distance: float
    exact: bool
    row: int
    point: FloatArray

    def label(self, line: int) -> str:
        """``closest: holder 8.635 mm clear, line 24`` (``line``: the program line of :attr:`row`)."""
        return approach_label(self.body, self.distance, self.exact, line)


def approach_label(body: int, distance: float, exact: bool, line: int) -> str:
    """The preview's words on a closest approach: ``closest: holder 8.635 mm clear, line 24``,
    ``closest: tool 2.000 mm deep in the part, line 9``."""
    what = f"{-distance:.3f} mm deep in the part" if distance < 0 else \
        f"{'over ' if not exact else ''}{distance:.3f} mm clear"
    return f"closest: {BODY_NAMES[body]} {what}, line {line}"


def measure_program(machine: Machine, program: JointProgram, setup: Setup, triangles: FloatArray,
                    face: Face | None, tool_diameter: float, *, clearance_min: float,
                    feed_tips: FloatArray | None = None) -> ProgramClearance | str:
    """Each body's smallest clearance along ``program`` (verify's FK samples and the motion between
    them), streamed: the groups of rows the scan bounds beyond the horizon as a whole
    (:mod:`prs3_post.check.collision_scan`) are not replayed, the others are replayed and checked
    ``REPLAY_ROWS`` rows at a time, keeping only each body's smallest clearance (:class:`_Stream`),
    so the memory does not grow with the program. Once a body is found too close, the whole program
    is checked as :func:`clearance` checks it, for the message (its line and depth). ``feed_tips``
    (M, 3) mm, machine frame: the feed tips whose swept region spares the cutting tool (default:
    this program's; a job's moves between operations: the operation's, :func:`feed_tips_of`).

    Returns
    -------
    ProgramClearance, or str — ``not checked: no [holder] in the machine file``

    Raises
    ------
    LimitError
        A body closer than ``clearance_min`` (:func:`check_program`).
    """
    if machine.holder is None:
        return "not checked: no [holder] in the machine file"
    length = machine.geometry.tool_length - machine.geometry.gauge_offset     # gauge line to tip
    if length <= machine.holder.holder_length:
        raise CollisionError(f"the tool sticks out {length:.3f} mm below the gauge line, not more than the holder's "
                             f"length {machine.holder.holder_length:.3f} mm: the holder would cut (a longer tool, or "
                             "a shorter holder in the machine file)", body=BODY_NAMES[1])
    bodies = body_cylinders(tool_diameter, length, machine.holder)
    if face is None:
        bodies[0, 2] = bodies[0, 1]                             # the tool: not checked
    triangles = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    streamed = _streamed(machine, program, setup, triangles, face, bodies, clearance_min, feed_tips)
    if streamed is not None:
        return streamed
    sample_row, tip, axis, own_tips = _replayed(machine, program)
    feed_tips = own_tips if feed_tips is None else feed_tips
    tip, axis = setup.points_to_part(tip), setup.axes_to_part(axis)
    ok = np.asarray(np.isfinite(tip).all(axis=1) & np.isfinite(axis).all(axis=1), dtype=bool)
    linked = ok & np.concatenate([[False], ok[:-1]])          # the motion from the sample before, both known
    result = clearance(triangles, tip[ok], axis[ok], bodies, face, setup.points_to_part(feed_tips),
                       clearance_min=clearance_min, connected=linked[ok])
    b = result.worst()
    if result.distance[b] < clearance_min:
        row = int(sample_row[np.flatnonzero(ok)[result.sample[b]]])
        d = float(result.distance[b])
        what = (f"hits the part, {-d:.3f} mm deep" if d < 0 else f"comes within {d:.3f} mm of the part")
        raise CollisionError(f"{program.describe(row)}: the {BODY_NAMES[b]} {what} (clearance min "
                             f"{exact_text(clearance_min, 3)} mm)", body=BODY_NAMES[b])
    return ProgramClearance(distance=np.where(result.exact, result.distance, clearance_min + REACH_MM),
                            exact=result.exact.copy())   # not reached: the stream found a body too close


def feed_tips_of(machine: Machine, program: JointProgram) -> FloatArray:
    """(M, 3) mm, machine frame: the end tips of ``program``'s FEED rows, as :func:`measure_program`
    draws its swept region from them."""
    return collision_scan.scan_program(machine, program, np.eye(3)).feed_tips


#: mm: the header's resolution; the streamed minima are found to it (:meth:`_Stream.minima`).
RESOLUTION_MM = 1e-3


def _streamed(machine: Machine, program: JointProgram, setup: Setup, triangles: FloatArray, face: Face | None,
              bodies: FloatArray, clearance_min: float, feed_tips: FloatArray | None = None
              ) -> ProgramClearance | None:
    """:func:`measure_program`'s streamed check; None once a body is found closer than ``clearance_min``."""
    frame = np.eye(3) if face is None else np.stack([face.u, face.v, face.normal])   # part frame, rows
    scan = collision_scan.scan_program(machine, program, setup.axes_to_part(np.eye(3)) @ frame.T)
    part = Part.of(triangles, face, clearance_min)
    region = swept_region(face, scan.feed_tips if feed_tips is None else feed_tips, float(bodies[0, 0]) + 1e-6,
                          setup=setup)
    stream = _Stream(part, face, region, bodies, clearance_min)
    bound = np.full((len(scan.flat), 3), -np.inf)        # each group's bound per body (−inf: none)
    groups = np.flatnonzero(scan.flat)
    tip, axis = setup.points_to_part(scan.tip[groups]), setup.axes_to_part(scan.axis[groups])
    # a group of feed moves (and the row before) follows the feed tips' polyline, which the region
    # is drawn round with the tool's radius and a cell more: every pose of it is over the region
    cutting = scan.feeding[groups] & (region.cells.size > 0) & (scan.wobble[groups] < 0.2 * region.cell)
    spread = Spread(frame=frame, half=scan.half[groups], turn=scan.turn[groups])
    del scan                                             # its feed tips (a row each) before the bounds
    if len(groups):                                      # each flat group bounded as a whole
        bound[groups] = pose_bounds(part, tip, axis, cutting, stream.pieces, reach=stream.reach, near=stream.reach,
                                    spread=spread)[0]
    bound[:, stream.unchecked] = np.inf
    # safe: no pose, no motion of the group comes too close
    safe: BoolArray = np.asarray((bound >= clearance_min).all(axis=1), dtype=np.bool_)
    n = len(program)
    for lo, hi in _runs(~safe, n):                       # the others in order: poses, then the motion between
        for at in range(lo, hi, REPLAY_ROWS):
            row, tip, axis = _replay_rows(machine, program, at, min(hi, at + REPLAY_ROWS))
            if not stream.add(row, setup.points_to_part(tip), setup.axes_to_part(axis), carried=at > 0):
                return None
    for b in np.flatnonzero(~stream.unchecked).tolist():  # the safe groups' share of the minima, closest first
        order = np.flatnonzero(safe & (bound[:, b] < stream.reach))
        order = order[np.argsort(bound[order, b], kind="stable")]
        k = 0
        while k < len(order) and bound[order[k], b] < min(stream.reach, stream.best[b] - 0.5 * RESOLUTION_MM):
            chosen: BoolArray = np.zeros(len(safe), dtype=np.bool_)
            chosen[order[k:k + _GROUPS_AT_ONCE]] = True
            for lo, hi in _runs(chosen, n):
                row, tip, axis = _replay_rows(machine, program, lo, hi)
                stream.measure(row, setup.points_to_part(tip), setup.axes_to_part(axis))
            k += _GROUPS_AT_ONCE
    return stream.result()


#: Groups the minima of the safe ones replay at a time (closest bound first).
_GROUPS_AT_ONCE = 8


def _runs(groups: BoolArray, n: int) -> list[tuple[int, int]]:
    """The row ranges [lo, hi) of the runs of consecutive True groups (GROUP_ROWS rows each, ``n`` rows)."""
    keep = np.repeat(groups, collision_scan.GROUP_ROWS)[:n]
    edges = np.flatnonzero(np.diff(np.concatenate([[False], keep, [False]]).astype(np.int8)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def _replay_rows(machine: Machine, program: JointProgram, lo: int, hi: int) -> tuple[IntArray, FloatArray, FloatArray]:
    """verify's samples of rows ``lo`` .. ``hi`` replayed from the row before (its end is where row
    ``lo``'s move starts, and the first sample): each sample's row, tip and axis (machine frame)."""
    start = max(lo - 1, 0)
    columns = {name: getattr(program, name)[start:hi] for name in ("kind", "stage", "strokes", "inverse_time",
                                                                  "source")}
    rep = replay(machine, program_from_columns(columns), tolerance=DEFAULT_TOLERANCE)
    return rep.row + start, rep.tip, rep.axis


class _Stream:
    """The check of a program's samples, a piece at a time (:func:`_streamed`): what carries from one
    piece to the next is each body's smallest clearance so far (``best``, to RESOLUTION_MM; the
    smallest measured, ``found``).

    Each piece starts with the end of the row before it (the previous piece's last sample, or the
    last row of a group bounded as a whole): the motion from there is checked (stage 3), and it is
    never a pose where a body is looked for inside the part (the motion to it was checked). In each
    piece the poses are bounded and those under ``clearance_min`` measured as :func:`clearance` does;
    then, per body, the poses under the horizon in order of their bound while the bound is under the
    smallest clearance found (less half the resolution: a pose left out cannot round lower), so the
    minimum does not depend on the pieces' sizes.
    """

    def __init__(self, part: Part, face: Face | None, region: Region, cylinders: FloatArray,
                 clearance_min: float):
        self.part, self.face, self.region, self.cylinders = part, face, region, cylinders
        self.clearance_min = clearance_min
        self.reach = clearance_min + REACH_MM
        self.pieces = body_pieces(cylinders)
        self.unchecked = cylinders[:, 2] <= cylinders[:, 1]
        self.found = np.full(3, np.inf)
        self.best = np.full(3, np.inf)
        self.row = np.full(3, -1, dtype=np.int64)         # the row and body point of each ``best``
        self.point = np.zeros((3, 3))

    def add(self, row: IntArray, tip: FloatArray, axis: FloatArray, *, carried: bool) -> bool:
        """Check a piece's samples (part frame; the first one the end of the row before if ``carried``);
        False: a body is closer than ``clearance_min``."""
        ok: BoolArray = np.asarray(np.isfinite(tip).all(axis=1) & np.isfinite(axis).all(axis=1), dtype=np.bool_)
        linked: BoolArray = ok & np.concatenate([[False], ok[:-1]])
        starts = ~linked
        if carried and len(starts):
            starts[0] = False
        poses = ClearancePoses(self.part, self.face, self.region, self.cylinders, self.clearance_min)
        poses.found = self.found.copy()
        samples = poses.add(tip[ok], axis[ok], row[ok], starts=starts[ok])
        if (poses.found >= self.clearance_min).all():
            check_between(poses, self.cylinders, np.flatnonzero(linked[ok]))
        self.found = poses.found
        if (poses.found < self.clearance_min).any():
            return False
        self.minima(poses, samples)
        return True

    def measure(self, row: IntArray, tip: FloatArray, axis: FloatArray) -> None:
        """Lower ``best`` by the samples of groups whose every pose is ``clearance_min`` clear (their
        bounds say so: nothing is measured under it, the motion is not checked further)."""
        ok = np.isfinite(tip).all(axis=1) & np.isfinite(axis).all(axis=1)
        poses = ClearancePoses(self.part, self.face, self.region, self.cylinders, self.clearance_min)
        self.minima(poses, poses.add(tip[ok], axis[ok], row[ok], starts=np.zeros(int(ok.sum()), dtype=bool)))

    def minima(self, poses: ClearancePoses, samples: IntArray, block: int = MEASURE_BLOCK) -> None:
        """Lower ``best`` by the ``samples`` of ``poses`` (not the midpoints the motion check added):
        measure, body by body, in order of the bound (module docstring of :class:`_Stream`)."""
        half = 0.5 * RESOLUTION_MM
        for b in range(3):
            if self.unchecked[b]:
                continue
            value, exact = poses.value[:, b], poses.exact[:, b]
            self._lower(b, poses, samples[exact[samples] & (value[samples] < self.reach)])
            order = samples[~exact[samples] & (value[samples] < self.reach)]
            order = order[np.argsort(value[order], kind="stable")]
            for k in range(0, len(order), block):
                rows = order[k:k + block]
                if value[rows[0]] >= min(self.reach, self.best[b] - half):
                    break
                poses.measure(rows, b, block, reach=self.reach)
                self._lower(b, poses, rows[poses.exact[rows, b]])

    def _lower(self, b: int, poses: ClearancePoses, measured: IntArray) -> None:
        """Lower ``best`` of body ``b`` by the poses ``measured`` (their values exact), keeping the row and
        the body's point of the minimum: the earliest row of those that round to it."""
        if not len(measured):
            return
        rounded = np.round(poses.value[measured, b] / RESOLUTION_MM) * RESOLUTION_MM
        low = float(rounded.min())
        at = measured[rounded == low]
        k = int(at[np.argmin(poses.origin[at])])
        row = int(poses.origin[k])
        if low < self.best[b] or (low == self.best[b] and (self.row[b] < 0 or row < self.row[b])):
            self.best[b], self.row[b], self.point[b] = low, row, poses.point[k, b]

    def result(self) -> ProgramClearance:
        exact = np.isfinite(self.best) & ~self.unchecked
        return ProgramClearance(distance=np.where(exact, self.best, self.reach), exact=exact,
                                row=np.where(exact, self.row, -1), point=np.where(exact[:, None], self.point, 0.0))


#: Program rows replayed at a time by :func:`check_program` (the replay's limit tables are what
#: costs memory; the check keeps only the samples' tips and axes).
REPLAY_ROWS = 65536


def _replayed(machine: Machine, program: JointProgram) -> tuple[IntArray, FloatArray, FloatArray, FloatArray]:
    """verify's FK samples of ``program`` (machine frame), REPLAY_ROWS program rows at a time, each piece
    from the previous one's last row (its end is where the piece's first move starts: the samples are
    those of one replay): the row, tip and axis of each sample, and the end tips of the FEED rows."""
    out_row, out_tip, out_axis, out_feed = [], [], [], []
    n, rows = len(program), REPLAY_ROWS
    for lo in range(0, max(n, 1), rows):
        start, hi = max(lo - 1, 0), min(n, lo + rows)
        columns = {name: getattr(program, name)[start:hi] for name in ("kind", "stage", "strokes", "inverse_time",
                                                                      "source")}
        rep = replay(machine, program_from_columns(columns), tolerance=DEFAULT_TOLERANCE)
        mine = rep.row >= lo - start                     # not the previous piece's last row again
        out_row.append(rep.row[mine] + start)
        out_tip.append(rep.tip[mine])
        out_axis.append(rep.axis[mine])
        feed = np.flatnonzero(program.kind[lo:hi] == MoveKind.FEED) + (lo - start)
        out_feed.append(rep.tip[rep.end[feed]])
    return (np.concatenate(out_row), np.concatenate(out_tip), np.concatenate(out_axis),
            np.concatenate(out_feed).reshape(-1, 3))
