"""Clearance of the tool, the holder and the spindle nose from the part, at sampled poses.

The bodies are cylinders on the tool axis (:class:`~prs3_post.machine.Holder`): from the tip up
the tool (the operation's diameter, up to the holder), the holder (to the spindle's gauge line:
the tool's length is the machine's, or the tool table's), the spindle nose. Each
is represented by points on its surface: rings every ``RING_SPACING_MM`` along it (and at both
ends), ``AZIMUTHS`` points per ring, and rings on its end discs. The clearance of a pose is the
smallest signed distance of those points to the part's triangles (exact point–triangle distance,
negative inside the part: ray parity along a fixed direction), so a penetration is reported by
its depth. The sampling makes a cylinder facing a plane at most ``r (1 − cos(π / AZIMUTHS))``
(0.19 mm for the holder) closer than the points say.

Only the tool may be in the part, and only where it cuts: while the tip is within the feature's
swept region (the tool radius around the feed moves' tips, in the face's plane), its points below
the worked face are not checked and the others are measured from the part without that face (the
tool touches it where it enters). Everything else must stay ``clearance_min`` clear.

Cost: every pose is first bounded cheaply: points on each body's axis every ``AXIS_STEP_MM``, each
the centre of a sphere holding the cylinder's slice around it, give a lower bound of its clearance.
The poses are then sampled on the surface in order of their bound, until the next bound is no
lower than the smallest distance found (the minimum over all poses), or, once every pose whose
bound is under ``clearance_min`` has been, after ``refine_max`` more (the minimum is then stated
as at least the next bound).

No library beyond numpy: trimesh's proximity queries need rtree (not installed), python-fcl would be
a compiled dependency for what is, here, a few thousand exact point–triangle distances.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prs3_post.face import Face
from prs3_post.machine import Holder, Machine
from prs3_post.setup import Setup
from prs3_post.toolpath import JointProgram
from prs3_post.types import BoolArray, FloatArray, IntArray

__all__ = ["BODY_NAMES", "Clearance", "body_cylinders", "check_program", "clearance"]

#: The bodies, bottom up.
BODY_NAMES = ("tool", "holder", "spindle nose")
AZIMUTHS = 24
RING_SPACING_MM = 2.0
AXIS_STEP_MM = 2.0
#: Poses beyond which the main job does not run the check (it says so in the header).
MAX_POSES = 20000
_RAY = np.array([0.5773502691896258, 0.4082482904638631, 0.7071067811865476])   # no axis-aligned edges hit


def body_cylinders(tool_diameter: float, tool_length: float, holder: Holder) -> FloatArray:
    """(3, 3) mm: radius, start and end along the axis from the tip, of the tool, holder and nose.

    ``tool_length``: mm from the gauge line to the tip; the holder ends at the gauge line."""
    gauge = tool_length
    z1 = gauge - holder.holder_length
    return np.array([[tool_diameter / 2, 0.0, z1], [holder.holder_diameter / 2, z1, gauge],
                     [holder.nose_diameter / 2, gauge, gauge + holder.nose_length]])


def _surface_points(cylinders: FloatArray) -> tuple[FloatArray, IntArray]:
    """Points on the cylinders' surfaces in the tool frame (z along the axis from the tip): (P, 3), body (P,)."""
    points, body = [], []
    angle = 2 * np.pi * np.arange(AZIMUTHS) / AZIMUTHS
    ring = np.column_stack([np.cos(angle), np.sin(angle)])
    for b, (radius, z0, z1) in enumerate(cylinders):
        stations = np.linspace(z0, z1, max(2, math.ceil((z1 - z0) / RING_SPACING_MM) + 1))
        side = np.concatenate([np.column_stack([radius * ring, np.full(AZIMUTHS, z)]) for z in stations])
        discs = [np.array([[0.0, 0.0, z]]) for z in (z0, z1)]
        for fraction in np.arange(1, math.ceil(radius / RING_SPACING_MM)) / math.ceil(radius / RING_SPACING_MM):
            discs += [np.column_stack([fraction * radius * ring, np.full(AZIMUTHS, z)]) for z in (z0, z1)]
        pts = np.concatenate([side, *discs])
        points.append(pts)
        body.append(np.full(len(pts), b))
    return np.concatenate(points), np.concatenate(body)


def _frames(axis: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(S, 3) unit x and y vectors perpendicular to each unit axis."""
    helper = np.where(np.abs(axis[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    x = np.cross(axis, helper)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    return x, np.cross(axis, x)


def point_triangle_distance(points: FloatArray, triangles: FloatArray) -> FloatArray:
    """(P, T) mm: exact distance from each point (P, 3) to each triangle (T, 3, 3) (Ericson's regions)."""
    p = points[:, None, :]
    a, b, c = (triangles[None, :, k, :] for k in range(3))
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp = p - b
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    cp = p - c
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v = vb / denom
        w = vc / denom
        closest = a + ab * v[..., None] + ac * w[..., None]                  # inside the face
        t_ab = np.clip(d1 / (d1 - d3), 0, 1)
        t_ac = np.clip(d2 / (d2 - d6), 0, 1)
        t_bc = np.clip((d4 - d3) / ((d4 - d3) + (d5 - d6)), 0, 1)
    on_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    on_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    on_bc = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
    closest = np.where(on_bc[..., None], b + (c - b) * t_bc[..., None], closest)
    closest = np.where(on_ac[..., None], a + ac * t_ac[..., None], closest)
    closest = np.where(on_ab[..., None], a + ab * t_ab[..., None], closest)
    closest = np.where(((d6 >= 0) & (d5 <= d6))[..., None], c, closest)
    closest = np.where(((d3 >= 0) & (d4 <= d3))[..., None], b, closest)
    closest = np.where(((d1 <= 0) & (d2 <= 0))[..., None], a, closest)
    return np.linalg.norm(p - closest, axis=-1)


def inside(points: FloatArray, triangles: FloatArray) -> BoolArray:
    """(P,) bool: the point is inside the closed mesh (crossings of a ray in a fixed direction, odd)."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]        # Möller–Trumbore, all pairs
    e1, e2 = b - a, c - a
    h = np.cross(_RAY, e2)
    det = (e1 * h).sum(-1)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = points[:, None, :] - a[None]
    u = (s * h).sum(-1) * inv
    q = np.cross(s, e1[None])
    v = (q @ _RAY) * inv
    t = (q * e2[None]).sum(-1) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return (hit.sum(axis=1) % 2) == 1


@dataclass(frozen=True, slots=True)
class Clearance:
    """The closest approach of each body to the part over the poses checked.

    Attributes
    ----------
    distance : (3,) float — mm, per body (tool, holder, nose): smallest signed distance (negative:
        penetration depth); inf: no pose (or the tool always below the face it cuts)
    sample : (3,) int — the pose of that minimum (-1: none)
    point : (3, 3) float — mm, part frame, the body point of that minimum
    exact : (3,) bool — the minimum over the surface points of every pose (False: a lower bound,
        which happens only above ``clearance_min``: the poses that could be closer were all sampled)
    """

    distance: FloatArray
    sample: IntArray
    point: FloatArray
    exact: BoolArray

    def worst(self) -> int:
        """The body with the smallest clearance."""
        return int(np.argmin(self.distance))


def _signed(points: FloatArray, triangles: FloatArray, others: BoolArray, face: Face,
            cutting: BoolArray | None) -> FloatArray:
    """(P,) mm: signed distance of points to the part (negative inside); where ``cutting`` (the tool
    in its swept region) a point below the worked face is not counted (inf) and the others are
    measured from the part without that face."""
    every = point_triangle_distance(points, triangles)
    inner = inside(points, triangles)
    dist = np.where(inner, -1.0, 1.0) * every.min(axis=1)
    if cutting is not None and cutting.any():
        height = (points - face.origin) @ face.normal
        off_face = every[:, others].min(axis=1, initial=np.inf)
        dist = np.where(cutting, np.where(height < 0.0, np.inf, np.where(inner, -off_face, off_face)), dist)
    return dist


def _signed_min(tip: FloatArray, axis: FloatArray, stations: FloatArray, triangles: FloatArray, others: BoolArray,
                face: Face, swept: BoolArray | None, block: int, *, radius: float, slack: float,
                near_mm: float, group: int = 128) -> FloatArray:
    """(S,) mm: a lower bound of the smallest :func:`_signed` distance of the axis points ``stations``
    (mm from the tip) at each pose.

    Consecutive poses are taken ``group`` at a time first: the stations of the group's first pose,
    less how far any pose of the group moves any station from there, bound the whole group; only
    the groups whose bound is under ``near_mm`` are measured pose by pose.
    """
    n = len(tip)
    out = np.zeros(n)
    if not n:
        return out
    first = np.arange(0, n, group)
    owner = np.arange(n) // group
    reach = float(np.abs(stations).max())
    spread = (np.linalg.norm(tip - tip[first][owner], axis=1)
              + reach * np.linalg.norm(axis - axis[first][owner], axis=1))
    spread = np.maximum.reduceat(spread, first)                                  # (G,) mm
    cutting = None
    if swept is not None:
        cutting = np.logical_and.reduceat(swept, first)                          # every pose of the group cuts
    coarse = _station_min(tip[first], axis[first], stations, triangles, others, face, cutting, block,
                          radius=radius, slack=slack) - spread
    out[:] = coarse[owner]
    near = np.flatnonzero(coarse[owner] < near_mm)
    if len(near):
        out[near] = _station_min(tip[near], axis[near], stations, triangles, others, face,
                                 None if swept is None else swept[near], block, radius=radius, slack=slack)
    return out


def _station_min(tip: FloatArray, axis: FloatArray, stations: FloatArray, triangles: FloatArray, others: BoolArray,
                 face: Face, swept: BoolArray | None, block: int, *, radius: float = 0.0,
                 slack: float = 0.0) -> FloatArray:
    """(S,) mm: a lower bound of each pose's cylinder distance to the part (-inf: an axis point inside it).

    Per triangle, the larger of two bounds: the axis points' distances less ``slack`` (the radius of
    the spheres round them that hold the cylinder), and the gap between the cylinder and the
    triangle's plane when the cylinder is all on one side of it (what keeps a wide holder's bound
    tight over the face below it). Where ``swept`` (the tool cutting): axis points below the worked
    face do not count, nor do the face's own triangles.
    """
    out = np.zeros(len(tip))
    normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    offset = (normal * triangles[:, 0]).sum(axis=1)                             # (T,)
    rows_per = max(1, block * 8)
    for start in range(0, len(tip), rows_per):
        rows = slice(start, start + rows_per)
        t, a = tip[rows], axis[rows]
        n = len(t)
        world = t[:, None] + stations[None, :, None] * a[:, None]                # (n, k, 3)
        flat = world.reshape(-1, 3)
        every = point_triangle_distance(flat, triangles).reshape(n, len(stations), -1)   # (n, k, T)
        if swept is not None and swept[rows].any():
            height = ((world - face.origin) @ face.normal)                       # (n, k)
            below = swept[rows][:, None] & (height < 0.0)
            every = np.where(below[..., None], np.inf, every)
            every = np.where(swept[rows][:, None, None] & ~others[None, None, :], np.inf, every)
        spheres = every.min(axis=1) - slack                                      # (n, T)
        ends = (t @ normal.T)[:, None, :] + stations[[0, -1]][None, :, None] * (a @ normal.T)[:, None, :]
        ends = ends - offset                                                     # (n, 2, T) signed heights
        bulge = radius * np.sqrt(np.clip(1.0 - (a @ normal.T) ** 2, 0.0, 1.0))   # (n, T)
        gap = np.maximum(np.maximum(ends.min(axis=1) - bulge, -ends.max(axis=1) - bulge), 0.0)
        if swept is not None:
            gap = np.where(swept[rows][:, None] & ~others[None, :], np.inf, gap)
        bound = np.maximum(spheres, gap).min(axis=1)
        inner = inside(flat, triangles).reshape(n, -1)
        if swept is not None and swept[rows].any():
            inner &= ~below
        out[rows] = np.where(inner.any(axis=1), -np.inf, bound)
    return out


def _swept(tip_uv: FloatArray, feed_uv: FloatArray, radius: float, *, cell: float = 0.25) -> BoolArray:
    """(S,) bool: the tip (in face u, v) is within about ``radius`` of the polyline of the feed tips (M, 2).

    The polyline is drawn on a grid of ``cell`` mm (points every half cell along each segment),
    widened by ``radius`` plus a cell, and each tip looks up its cell: a region a cell or two wider
    than the exact one, at a cost linear in the rows.
    """
    if len(feed_uv) == 0 or len(tip_uv) == 0:
        return np.zeros(len(tip_uv), dtype=bool)
    low = feed_uv.min(axis=0) - radius - 2 * cell
    size = np.ceil((feed_uv.max(axis=0) + radius + 2 * cell - low) / cell).astype(np.int64) + 1
    if size.prod() > 4e7:                               # a region too large to draw: no exemption
        return np.zeros(len(tip_uv), dtype=bool)
    grid = np.zeros(tuple(size), dtype=bool)
    ends = feed_uv[:-1], feed_uv[1:]
    length = np.linalg.norm(ends[1] - ends[0], axis=1) if len(feed_uv) > 1 else np.zeros(0)
    steps = np.maximum(1, np.ceil(length / (0.5 * cell)).astype(np.int64))
    seg = np.repeat(np.arange(len(steps)), steps + 1)
    t = (np.arange(len(seg)) - np.repeat(np.cumsum(steps + 1) - (steps + 1), steps + 1)) / np.repeat(steps, steps + 1)
    points = np.concatenate([feed_uv[:1], ends[0][seg] + t[:, None] * (ends[1][seg] - ends[0][seg])])
    index = np.floor((points - low) / cell).astype(np.int64)
    grid[index[:, 0], index[:, 1]] = True
    reach = math.ceil(radius / cell) + 1
    wide = np.zeros_like(grid)
    for du in range(-reach, reach + 1):
        for dv in range(-reach, reach + 1):
            if (abs(du) - 1) ** 2 + (abs(dv) - 1) ** 2 > (radius / cell) ** 2 and (du or dv):
                continue
            wide[max(du, 0):size[0] + min(du, 0), max(dv, 0):size[1] + min(dv, 0)] |= \
                grid[max(-du, 0):size[0] + min(-du, 0), max(-dv, 0):size[1] + min(-dv, 0)]
    cells = np.floor((tip_uv - low) / cell).astype(np.int64)
    ok = (cells >= 0).all(axis=1) & (cells < size).all(axis=1)
    out = np.zeros(len(tip_uv), dtype=bool)
    out[ok] = wide[cells[ok, 0], cells[ok, 1]]
    return out


def clearance(triangles: FloatArray, tip: FloatArray, axis: FloatArray, cylinders: FloatArray, face: Face,
              feed_tips: FloatArray, *, clearance_min: float = 1.0, block: int = 64,
              refine_max: int = 0) -> Clearance:
    """The clearance of the bodies from the part at every pose (part frame).

    Parameters
    ----------
    triangles : (T, 3, 3) float — mm, the part
    tip, axis : (S, 3) float — mm, unit: the poses (samples of the program's moves)
    cylinders : (3, 3) float — :func:`body_cylinders`
    face : Face — the worked face (its plane bounds the tool's exempt part)
    feed_tips : (M, 3) float — mm, the tips of the feed moves in order (the swept region)
    clearance_min : float — mm
    block : int — poses sampled at a time
    refine_max : int — poses sampled beyond those whose bound is under ``clearance_min``, to sharpen
        the reported minimum (where it stays a bound, ``exact`` says so)
    """
    tip = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
    axis = np.asarray(axis, dtype=np.float64).reshape(-1, 3)
    triangles = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    local, body = _surface_points(cylinders)
    to_uv = np.stack([face.u, face.v], axis=1)
    swept = _swept((tip - face.origin) @ to_uv, (np.asarray(feed_tips).reshape(-1, 3) - face.origin) @ to_uv,
                   float(cylinders[0, 0]) + 1e-6)
    best = np.full(3, np.inf)
    where = np.full(3, -1, dtype=np.int64)
    point = np.zeros((3, 3))
    exact = np.ones(3, dtype=bool)
    x, y = _frames(axis)
    others = np.ones(len(triangles), dtype=bool)
    others[np.asarray(face.triangles, dtype=np.int64)] = False
    for b in range(3):
        radius, z0, z1 = cylinders[b]
        if not len(tip):
            break
        # a lower bound at every pose: points on the axis every AXIS_STEP_MM, each a sphere that holds
        # the cylinder's slice around it
        stations = np.linspace(z0, z1, max(2, math.ceil((z1 - z0) / AXIS_STEP_MM) + 1))
        slack = math.hypot(radius, 0.5 * (stations[1] - stations[0]))
        bound = _signed_min(tip, axis, stations, triangles, others, face, swept if b == 0 else None, block,
                            radius=float(radius), slack=slack, near_mm=clearance_min)
        # the surface points, poses in order of their bound, until no bound is below the best found:
        # the minimum over the surface points of every pose, without sampling most of them
        order = np.argsort(bound, kind="stable")
        mine = local[body == b]
        must = int(np.searchsorted(bound[order], clearance_min))      # poses that may be too close: all
        start = 0
        for start in range(0, len(order), block):
            rows = order[start:start + block]
            if bound[rows[0]] >= best[b] or (start >= must + refine_max and bound[rows[0]] >= clearance_min):
                break
            world = (tip[rows, None] + mine[None, :, :1] * x[rows, None] + mine[None, :, 1:2] * y[rows, None]
                     + mine[None, :, 2:] * axis[rows, None])                    # (s, p, 3)
            dist = _signed(world.reshape(-1, 3), triangles, others, face,
                           np.repeat(swept[rows], len(mine)) if b == 0 else None).reshape(len(rows), -1)
            k = int(np.argmin(dist))
            s_, p_ = divmod(k, dist.shape[1])
            if dist[s_, p_] < best[b]:
                best[b], where[b], point[b] = dist[s_, p_], rows[s_], world[s_, p_]
        else:
            start = len(order)
        if start < len(order) and bound[order[start]] < best[b]:      # stopped early: a lower bound
            i = int(order[start])
            best[b], where[b], point[b], exact[b] = bound[i], i, tip[i] + axis[i] * 0.5 * (z0 + z1), False
    return Clearance(distance=best, sample=where, point=point, exact=exact)


def check_program(machine: Machine, program: JointProgram, setup: Setup, triangles: FloatArray, face: Face,
                  tool_diameter: float, *, clearance_min: float = 1.0, max_poses: int = MAX_POSES) -> str:
    """Replay ``program`` (verify's FK samples) and check the bodies' clearance from the part.

    Returns
    -------
    str — the header's ``collision`` entry (the clearance of each body)

    Raises
    ------
    LimitError
        ``hole 1, peck 1: the holder hits the part, 2.498 mm deep (clearance min 1.000 mm)`` or
        ``...: the tool comes within 0.400 mm of the part (clearance min 1.000 mm)``.
    """
    from prs3_post.errors import LimitError
    from prs3_post.toolpath import MoveKind
    from prs3_post.verify import replay

    if machine.holder is None:
        return "not checked: no [holder] in the machine file"
    length = machine.geometry.tool_length - machine.geometry.gauge_offset     # gauge line to tip
    if length <= machine.holder.holder_length:
        raise LimitError(f"the tool sticks out {length:.3f} mm below the gauge line, not more than the holder's "
                         f"length {machine.holder.holder_length:.3f} mm: the holder would cut (a longer tool, or "
                         "a shorter holder in the machine file)")
    rep = replay(machine, program)
    if len(rep.row) > max_poses:
        return (f"not checked: {len(rep.row)} poses, more than the check's limit of {max_poses} (it costs about "
                "60 us a pose: a long program would take minutes)")
    tip, axis = setup.points_to_part(rep.tip), setup.axes_to_part(rep.axis)
    ok = np.isfinite(tip).all(axis=1)
    feed_rows = np.flatnonzero(program.kind == MoveKind.FEED)
    result = clearance(triangles, tip[ok], axis[ok], body_cylinders(tool_diameter, length, machine.holder), face,
                       tip[rep.end[feed_rows]], clearance_min=clearance_min)
    b = result.worst()
    if result.distance[b] < clearance_min:
        row = int(rep.row[np.flatnonzero(ok)[result.sample[b]]])
        d = float(result.distance[b])
        what = (f"hits the part, {-d:.3f} mm deep" if d < 0 else f"comes within {d:.3f} mm of the part")
        raise LimitError(f"{program.describe(row)}: the {BODY_NAMES[b]} {what} (clearance min {clearance_min:.3f} mm)")
    shown = ", ".join(f"{name} {'over ' if not exact else ''}{d:.3f} mm" for name, d, exact in zip(
        BODY_NAMES, result.distance.tolist(), result.exact.tolist(), strict=True))
    return f"clear of the part by at least {clearance_min:.3f} mm: {shown}"
