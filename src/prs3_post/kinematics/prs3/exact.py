"""Exact inverse kinematics of the 3-PRS head: a rigid platform, vectorized over poses.

Frames (DESIGN.md): machine frame with its origin at the base centre, z up; the head hangs down.
Leg i has azimuth α_i, radial unit e_i = (cos α_i, sin α_i, 0) and tangential t_i = (−sin α_i,
cos α_i, 0). Its revolute joint sits at K·e_i − T_i·z (T_i = stroke, downward), its link of length U
makes the angle θ_i with the horizontal, so the spherical joint is

    S_i = (K − U cos θ_i)·e_i − (T_i + U sin θ_i)·z.                                  (1)

The platform carries the S_i on a circle of radius r_p around its centre M; the tool axis a is the
platform normal (from the tip toward the spindle) and the tool tip is M − TL·a.

Derivation (legs 120° apart). The revolute axis t_i keeps S_i in leg i's vertical plane:
S_i·t_i = 0. Write the platform rotation in tilt-and-torsion form R = Rz(φ)·Ry(θ)·Rz(−φ) (zero
torsion), which is the smallest rotation taking z to a = (a_x, a_y, a_z):

    R = I + [v]× + [v]×²/(1 + a_z),  v = z × a,   S_i = M + r_p·R·e_i.

With c = 1/(1 + a_z) and g_i = a·e_i, the constraint reads M·t_i = −r_p·c·(½ sin 2α_i (a_x² − a_y²)
− cos 2α_i a_x a_y). For three legs α_i = α_1 + k·120° one M solves all three (the zero-torsion
property; 3α_i is the same angle mod 360° for every leg), with (C3, S3) = (cos 3α_1, sin 3α_1):

    M_x = −(r_p c/2)·[C3 (a_x² − a_y²) + 2 S3 a_x a_y]
    M_y = −(r_p c/2)·[S3 (a_x² − a_y²) − 2 C3 a_x a_y]                                 (2)

(for legs at 210/330/90°: M_x = r_p a_x a_y/(1 + a_z), M_y = r_p (a_x² − a_y²)/(2(1 + a_z))).
This sideways drift of the platform centre is the parasitic motion: the head alone sets tilt and
height, and the XY stage supplies the rest of the tip position. M_z = tip_z + TL·a_z. Then the
radial distance and height of S_i,

    r_i = S_i·e_i = M·e_i + r_p·(1 − c g_i²),   S_iz = M_z − r_p g_i,

give cos θ_i = (K − r_i)/U from (1) and T_i = −S_iz − U sin θ_i.

Branch choice: θ_i ∈ [0, π] from arccos, i.e. the revolute joint lies radially outside S_i (the
machine's assembly mode). A pose assembles when |(K − r_i)/U| ≤ 1 for every leg and a_z > 0.

Singularities: a_z → 0 (c blows up) is far outside any tilt limit. The actuator singularity, where
the Jacobian ∂T/∂(M_z, r_p a_x, r_p a_y) loses rank, is first reached at 49.82° tilt leaning toward
φ = 30°, 150°, 270° (away from a leg) for the paper's head; its 2-norm condition number is √2
untilted, 2.8 at 35° and 7.2 at 45° (worst azimuth), and is returned for every pose.

Preconditions: ``axis`` rows are unit vectors (use :func:`prs3_post.kinematics.poses.unit_axes`);
rows that are not finite or point down come back ``reachable = False`` with NaN values.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from prs3_post.core.rowwise import same_rows
from prs3_post.core.types import BoolArray, FloatArray
from prs3_post.kinematics.prs3.blocks import BLOCK_ROWS, run_blocks
from prs3_post.machine.model import Geometry


@dataclass(frozen=True, slots=True)
class IKResult:
    """Inverse kinematics of N poses.

    Attributes
    ----------
    stage : (N, 2) float — mm, stage X, Y that put the head's tip on the target
        (model ``head``: the offset it would need, which must be 0; model ``paper``: 0)
    strokes : (N, 3) float — mm, actuator strokes T1, T2, T3
    link_angle : (N, 3) float — rad, link angles θ1, θ2, θ3 from horizontal
    condition : (N,) float — 2-norm condition number of ∂T/∂(M_z, r_p a_x, r_p a_y)
    reachable : (N,) bool — the pose assembles (and, model ``head``, needs no stage)
    """

    stage: FloatArray
    strokes: FloatArray
    link_angle: FloatArray
    condition: FloatArray
    reachable: BoolArray


def _leg_constants(geometry: Geometry) -> tuple[FloatArray, FloatArray, float, float]:
    """cos α_i, sin α_i (3,), and cos 3α_1, sin 3α_1 of the leg layout."""
    alpha = np.asarray(geometry.leg_azimuth)
    return np.cos(alpha), np.sin(alpha), math.cos(3 * alpha[0]), math.sin(3 * alpha[0])


def platform_centre_xy(geometry: Geometry, axis: FloatArray) -> FloatArray:
    """Parasitic platform-centre position (M_x, M_y) forced by the tool axis, eq. (2).

    Parameters
    ----------
    geometry : Geometry
    axis : (N, 3) float — unit tool axes, a_z > 0

    Returns
    -------
    (N, 2) float — mm, machine frame

    >>> from prs3_post.machine.loading import load_machine
    >>> g = load_machine("patel2020").geometry
    >>> (np.round(platform_centre_xy(g, np.array([[0.447214, 0.0, 0.894427]])), 4) + 0.0).tolist()
    [[0.0, 9.1429]]
    """
    axis = np.asarray(axis, dtype=np.float64).reshape(-1, 3)
    _, _, c3, s3 = _leg_constants(geometry)
    ax, ay, az = axis[:, 0], axis[:, 1], axis[:, 2]
    half = -0.5 * geometry.platform_radius / (1.0 + az)
    diff, cross = ax * ax - ay * ay, 2.0 * ax * ay
    return np.column_stack([half * (c3 * diff + s3 * cross), half * (s3 * diff - c3 * cross)])


def spherical_joints(geometry: Geometry, tip: FloatArray, axis: FloatArray) -> FloatArray:
    """Spherical-joint centres S_i = M + r_p·R·e_i of the rigid platform for head tips and axes.

    Parameters
    ----------
    tip : (N, 3) float — mm, the head's tool tip (machine frame, stage not included)
    axis : (N, 3) float — unit tool axes

    Returns
    -------
    (N, 3, 3) float — mm, ``[:, i]`` is S_{i+1}
    """
    tip = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
    axis = np.asarray(axis, dtype=np.float64).reshape(-1, 3)
    centre = tip + geometry.tool_length * axis
    ax, ay, az = axis[:, 0:1], axis[:, 1:2], axis[:, 2:3]
    c = 1.0 / (1.0 + az)
    # R = I + [v]x + [v]x^2 c with v = (-a_y, a_x, 0): its columns written out
    rot = np.stack(
        [
            np.concatenate([1 - ax * ax * c, -ax * ay * c, -ax], axis=1),
            np.concatenate([-ax * ay * c, 1 - ay * ay * c, -ay], axis=1),
            np.concatenate([ax, ay, az], axis=1),
        ],
        axis=2,
    )                                                   # (N, 3, 3), rot[n] @ x = R x
    alpha = np.asarray(geometry.leg_azimuth)
    radial = np.column_stack([np.cos(alpha), np.sin(alpha), np.zeros(3)])   # (3 legs, 3)
    return centre[:, None, :] + geometry.platform_radius * np.einsum("nij,kj->nki", rot, radial)


def _inverse_block(geometry: Geometry, tip: FloatArray, axis: FloatArray, out: dict[str, FloatArray],
                   memo: AxisMemo | None = None) -> None:
    """Exact IK of one block, written into the ``out`` views (see :func:`inverse`).

    A block whose rows all have one tool axis (a 3+2 program: one per work plane) takes the terms of
    the axis alone (:class:`_OneAxis`) once, for its first row, or from ``memo`` when an earlier block
    had that axis, and broadcasts them where the tip comes in: the same operations on the same
    operands as row by row, so the same bits.
    """
    axis = block_axes(axis)
    if len(axis) == 1:
        part = memo.terms(geometry, axis) if memo is not None else _one_axis(geometry, axis)
        centre_z = tip[:, 2] + part.lift
        out["stage"][:, 0] = tip[:, 0] - part.offset_x
        out["stage"][:, 1] = tip[:, 1] - part.offset_y
        for leg, leg_terms in enumerate(part.legs):
            _write_leg(out, leg, centre_z, leg_terms)
        out["condition"][:], out["reachable"][:] = part.condition, part.reachable
        return
    terms = axis_terms(axis)
    lift, offset_x, offset_y = _platform_offsets(geometry, axis, terms)
    centre_z = tip[:, 2] + lift
    out["stage"][:, 0] = tip[:, 0] - offset_x
    out["stage"][:, 1] = tip[:, 1] - offset_y

    def each_leg(leg: int, g: FloatArray, w: FloatArray, sin_t: FloatArray) -> None:
        _write_leg(out, leg, centre_z, _leg_terms(geometry, g, w, sin_t))

    out["condition"][:], out["reachable"][:] = axis_block(geometry, axis, terms, each_leg)


def _platform_offsets(geometry: Geometry, axis: FloatArray, terms: tuple[FloatArray, FloatArray, FloatArray]
                      ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """What the axes (n, 3) put between the tip and the platform: TL·a_z (the centre's height over the
    tip) and M_x − TL·a_x, M_y − TL·a_y (eq. (2): the stage is the target tip minus these), each (n,)."""
    tool, rp = geometry.tool_length, geometry.platform_radius
    _, _, c3, s3 = _leg_constants(geometry)
    c, diff, cross = terms
    half = -0.5 * rp * c
    mx = half * (c3 * diff + 2.0 * s3 * cross)
    my = half * (s3 * diff - 2.0 * c3 * cross)
    return tool * axis[:, 2], mx - tool * axis[:, 0], my - tool * axis[:, 1]


#: One leg's terms of the axis alone: r_p·(a·e_i), U·sin θ_i and θ_i, each (n,).
LegTerms = tuple[FloatArray, FloatArray, FloatArray]


def _leg_terms(geometry: Geometry, g: FloatArray, w: FloatArray, sin_t: FloatArray) -> LegTerms:
    """A leg's :data:`LegTerms` from a·e_i, cos θ_i and sin θ_i (each (n,))."""
    angle = np.arccos(np.clip(w, -1.0, 1.0))         # clip: |w| > 1 rows are unreachable
    return geometry.platform_radius * g, geometry.link_length * sin_t, angle


def _write_leg(out: dict[str, FloatArray], leg: int, centre_z: FloatArray, terms: LegTerms) -> None:
    """Leg ``leg``'s link angle and stroke T_i = −(M_z − r_p a·e_i) − U sin θ_i into ``out``."""
    drop, reach, angle = terms
    out["link_angle"][:, leg] = angle
    out["strokes"][:, leg] = -(centre_z - drop) - reach


@dataclass(frozen=True, slots=True)
class _OneAxis:
    """Everything the IK of a block takes from its one tool axis, each (1,): TL·a_z, the stage offsets
    (:func:`_platform_offsets`), each leg's :data:`LegTerms`, the condition number and reachability."""

    lift: FloatArray
    offset_x: FloatArray
    offset_y: FloatArray
    legs: tuple[LegTerms, ...]
    condition: FloatArray
    reachable: BoolArray


def _one_axis(geometry: Geometry, axis: FloatArray) -> _OneAxis:
    """The :class:`_OneAxis` of one unit axis (1, 3)."""
    terms = axis_terms(axis)
    legs: list[LegTerms] = []

    def each_leg(leg: int, g: FloatArray, w: FloatArray, sin_t: FloatArray) -> None:
        legs.append(_leg_terms(geometry, g, w, sin_t))

    condition, reachable = axis_block(geometry, axis, terms, each_leg)
    return _OneAxis(*_platform_offsets(geometry, axis, terms), legs=tuple(legs), condition=condition,
                    reachable=reachable)


class AxisMemo:
    """The terms of the tool axis alone of the last few one-axis blocks, for a caller that makes many
    blocks of one axis (the chunks of a 3+2 program, one axis per work plane: a
    :class:`~prs3_post.post.pipeline.PostStream`), so that they are made once per axis, not once per chunk.

    The kinematics keep no state: the caller owns the memo. An axis is looked up by its bits; a
    geometry other than the memo's is computed and not kept. Safe on the IK's two threads (at worst
    both make the same terms).
    """

    #: Axes kept (then the memo starts again: a 3+2 program has a few work planes).
    SIZE = 16

    def __init__(self, geometry: Geometry):
        self.geometry = geometry
        self._terms: dict[bytes, _OneAxis] = {}

    def terms(self, geometry: Geometry, axis: FloatArray) -> _OneAxis:
        """The :class:`_OneAxis` of ``axis`` (1, 3)."""
        if geometry is not self.geometry:
            return _one_axis(geometry, axis)
        key = axis.tobytes()
        found = self._terms.get(key)
        if found is None:
            found = _one_axis(geometry, axis)
            if len(self._terms) >= self.SIZE:
                self._terms.clear()
            self._terms[key] = found
        return found


def block_axes(axis: FloatArray) -> FloatArray:
    """A block's axes (n, 3), or its first row alone (1, 3) when every row has that axis (the axis
    terms are then computed once and broadcast: :func:`_inverse_block`)."""
    if len(axis) > 1 and same_rows(axis):            # the same bits on every row: the same results
        return axis[:1]
    return axis


def axis_terms(axis: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """c = 1/(1 + a_z), a_x² − a_y² and a_x·a_y of unit axes (n, 3), each (n,)."""
    ax, ay, az = axis[:, 0], axis[:, 1], axis[:, 2]
    return 1.0 / (1.0 + az), ax * ax - ay * ay, ax * ay


def axis_block(geometry: Geometry, axis: FloatArray, terms: tuple[FloatArray, FloatArray, FloatArray],
               each_leg: Callable[[int, FloatArray, FloatArray, FloatArray], None] | None = None
               ) -> tuple[FloatArray, BoolArray]:
    """What the tool axis alone decides, for one block of unit axes (n, 3) and their
    :func:`axis_terms`: the condition number (n,) and whether the pose assembles (n,): a_z > 0,
    |cos θ_i| ≤ 1 for every leg and a finite condition number. ``each_leg(i, a·e_i, cos θ_i,
    sin θ_i)`` (each (n,)) is called as each leg's terms are made (while they are in the cache:
    :func:`_inverse_block` finishes the leg there). The tip only moves the platform up and down
    (the strokes) and the stage, so the paper model's reachability takes this part alone
    (:func:`~prs3_post.kinematics.prs3.paper.inverse_paper`)."""
    cos_a, sin_a, c3, s3 = _leg_constants(geometry)
    rp, big_k, link = geometry.platform_radius, geometry.guide_radius, geometry.link_length
    ax, ay, az = axis[:, 0], axis[:, 1], axis[:, 2]
    c, diff, cross = terms
    gram = np.zeros((len(axis), 6))                   # J^T J upper triangle: 00 01 02 11 12 22
    gram[:, 0] = 3.0
    jac_x = np.zeros((3, len(axis)))
    jac_y = np.zeros((3, len(axis)))
    c2_over_az = c * c / az
    reach = az > 0.0
    for leg in range(3):
        ca, sa = cos_a[leg], sin_a[leg]
        # leg constants of M·e_i: cos(3α_1 − α_i), sin(3α_1 − α_i)
        a_leg, b_leg = c3 * ca + s3 * sa, s3 * ca - c3 * sa
        g = ax * ca + ay * sa                          # a·e_i
        h = 0.5 * a_leg * diff + b_leg * cross + g * g  # r_i = r_p (1 - c h)
        w = (big_k - rp * (1.0 - c * h)) / link        # cos θ_i
        reach &= np.abs(w) <= 1.0
        sin_t = np.sqrt(np.clip(1.0 - w * w, 0.0, None))   # clip: |w| > 1 rows are flagged above
        if each_leg is not None:
            each_leg(leg, g, w, sin_t)
        # Jacobian row: dT/dM_z = -1; dT/d(r_p a) = e_i + cot θ_i (c dh/da + h c² a/a_z)
        cot = w / sin_t
        jx = ca + cot * (c * (a_leg * ax + b_leg * ay + 2.0 * g * ca) + h * c2_over_az * ax)
        jy = sa + cot * (c * (b_leg * ax - a_leg * ay + 2.0 * g * sa) + h * c2_over_az * ay)
        jac_x[leg], jac_y[leg] = jx, jy
        gram[:, 1] -= jx
        gram[:, 2] -= jy
        gram[:, 3] += jx * jx
        gram[:, 4] += jx * jy
        gram[:, 5] += jy * jy
    det_j = (                                          # det J, first column all -1
        -(jac_x[1] * jac_y[2] - jac_x[2] * jac_y[1])
        + (jac_x[0] * jac_y[2] - jac_x[2] * jac_y[0])
        - (jac_x[0] * jac_y[1] - jac_x[1] * jac_y[0])
    )
    condition = condition_from_gram(gram, det_j)
    return condition, reach & np.isfinite(condition)


def condition_from_gram(gram: FloatArray, det_j: FloatArray) -> FloatArray:
    """2-norm condition numbers sqrt(λmax/λmin) of J from G = JᵀJ (N, 6 upper) and det J (N,).

    λmax by the closed form for symmetric 3×3 matrices (Smith 1961); the two others from their sum
    (trace − λmax) and product (det G / λmax = det J² / λmax), the smaller one as product / larger
    root so that it keeps its relative accuracy near a singularity.
    """
    g00, g01, g02, g11, g12, g22 = gram.T
    q = (g00 + g11 + g22) / 3.0
    off = g01 * g01 + g02 * g02 + g12 * g12
    b00, b11, b22 = g00 - q, g11 - q, g22 - q
    p = np.sqrt((b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * off) / 6.0)
    det_b = b00 * (b11 * b22 - g12 * g12) - g01 * (g01 * b22 - g12 * g02) + g02 * (g01 * g12 - b11 * g02)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(p > 0.0, det_b / (2.0 * p * p * p), 0.0)
        phi = np.arccos(np.clip(r, -1.0, 1.0)) / 3.0   # clip: rounding can push |r| past 1
        lam_max = q + 2.0 * p * np.cos(phi)
        rest_sum = 3.0 * q - lam_max
        rest_prod = det_j * det_j / lam_max
        lam_mid = 0.5 * (rest_sum + np.sqrt(np.clip(rest_sum * rest_sum - 4.0 * rest_prod, 0.0, None)))
        lam_min = rest_prod / lam_mid
        return np.where(lam_min > 0.0, np.sqrt(lam_max / lam_min), np.inf)


def inverse_exact(
    geometry: Geometry,
    tip: FloatArray,
    axis: FloatArray,
    *,
    block_rows: int = BLOCK_ROWS,
    workers: int | None = None,
    memo: AxisMemo | None = None,
) -> IKResult:
    """Exact IK: target tips and unit axes → stage X, Y, strokes, link angles, condition numbers.

    Parameters
    ----------
    geometry : Geometry
    tip : (N, 3) float — mm, target tool tip in the machine frame (part-relative tip with the stage)
    axis : (N, 3) float — unit tool axes (tip → spindle), a_z > 0
    block_rows, workers : int — rows per cache-sized block and threads (no effect on the result)
    memo : AxisMemo, optional — the terms of axes seen before, kept by the caller (no effect on the result)

    Returns
    -------
    IKResult — with ``reachable`` False (and NaN values) where the pose does not assemble

    >>> from prs3_post.machine.loading import load_machine
    >>> g = load_machine("patel2020").geometry
    >>> a = np.array([[1.0, 0.0, 2.0]]) / np.sqrt(5.0)
    >>> r = inverse_exact(g, np.array([[-81.0264, 21.2132, -679.4865]]), a)
    >>> np.round(r.stage, 4).tolist(), np.round(r.strokes, 4).tolist()
    ([[-2.764, 12.0703]], [[36.2244, 170.3885, 88.9519]])
    """
    tip = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
    axis = np.asarray(axis, dtype=np.float64).reshape(-1, 3)
    n = len(tip)
    out = {
        "stage": np.zeros((n, 2)),
        "strokes": np.zeros((n, 3)),
        "link_angle": np.zeros((n, 3)),
        "condition": np.zeros(n),
        "reachable": np.zeros(n, dtype=bool),
    }

    def kernel(rows: slice) -> None:
        _inverse_block(geometry, tip[rows], axis[rows], {k: v[rows] for k, v in out.items()}, memo)

    run_blocks(kernel, n, block_rows=block_rows, workers=workers)
    bad = ~out["reachable"]
    if bad.any():
        for key in ("stage", "strokes", "link_angle", "condition"):
            out[key][bad] = np.nan                     # never hand out values of a pose that can't exist
    return IKResult(**out)
