"""Forward kinematics of a general 3-PRS head: strokes (and stage X, Y) → platform pose, tool tip and axis.

Frames and symbols as in :mod:`prs3_post.kinematics.prs3_general.legs` and DESIGN.md ("The machine
as built"). Leg i's revolute joint is at C_i = P_i + (T_i + o_i)·d_i; its spherical joint at

    S_i = C_i + U_i·(cos θ_i·u_i + sin θ_i·v_i)                                          (1)

so that |S_i − C_i| = U_i and (S_i − C_i)·r_i = 0 hold for any θ_i. Unknowns: the three θ_i. The
platform is rigid: its joints keep their distances L_ij = |s_i − s_j|,

    D_ij = |S_i − S_j|² − L_ij² = 0   for (i, j) = (1, 2), (2, 3), (3, 1).

With W = C_i − C_j (fixed by the strokes), D_ij expands into terms in cos θ_i, sin θ_i, cos θ_j,
sin θ_j whose coefficients are computed once per pose:

    D_ij = |W|² + U_i² + U_j² − L_ij² + 2U_i W·(c_i u_i + s_i v_i) − 2U_j W·(c_j u_j + s_j v_j)
           − 2U_i U_j (c_i u_i + s_i v_i)·(c_j u_j + s_j v_j).

Each D_ij depends on θ_i and θ_j only, so the Newton Jacobian is cyclic, [[a1, b1, 0], [0, a2, b2],
[b3, 0, a3]], solved in closed form as in :mod:`prs3_post.kinematics.prs3.forward`. The three joints
then fix the platform: the frame of the triangle S_1 S_2 S_3 against that of s_1 s_2 s_3 gives the
rotation R, the centroids the platform origin M = mean S − R·mean s; tip = M + R·c, axis = R·w,
plus the stage (X, Y, 0).

Start and branch: Newton starts from the angle of the untilted platform, cos θ_i = (|P_i,xy| −
|s_i,xy|)/U_i (on the ideal head: (K − r_p)/U, where the ideal forward kinematics start), and so
follows the working assembly mode (θ in (0°, 90°), a_z > 0). A pose is ``converged`` when the worst
side-length error is below ``tol`` and it is in the working mode; otherwise (strokes the head
cannot assemble to, a singular Jacobian, the iteration limit) it is not, with NaN pose values.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.kinematics.prs3.blocks import run_blocks
from prs3_post.kinematics.prs3.forward import FKResult
from prs3_post.kinematics.prs3_general.legs import NEXT, LegArrays, leg_arrays
from prs3_post.machine.model import GeneralGeometry

__all__ = ["GeneralFKResult", "forward_general", "platform_frame"]


@dataclass(frozen=True, slots=True)
class GeneralFKResult:
    """Forward kinematics of N actuator settings of a general head.

    Attributes
    ----------
    tip : (N, 3) float — mm, tool tip, machine frame, stage included (part-relative tip)
    axis : (N, 3) float — unit, tip → spindle
    centre : (N, 3) float — mm, the platform frame's origin, machine frame (stage not included)
    rotation : (N, 3, 3) float — the platform frame's axes in the machine frame:
        x_machine = centre + rotation @ x_platform
    link_angle : (N, 3) float — rad, θ1..θ3 (from the plane normal to each rail)
    joints : (N, 3, 3) float — mm, spherical-joint centres S1..S3 (machine frame, no stage)
    converged : (N,) bool
    iterations : (N,) int — Newton steps used
    residual : (N,) float — mm, worst platform side-length error
    """

    tip: FloatArray
    axis: FloatArray
    centre: FloatArray
    rotation: FloatArray
    link_angle: FloatArray
    joints: FloatArray
    converged: BoolArray
    iterations: IntArray
    residual: FloatArray

    def fk_result(self) -> FKResult:
        """The fields the :class:`~prs3_post.kinematics.protocol.Kinematics` protocol's FK returns."""
        return FKResult(tip=self.tip, axis=self.axis, link_angle=self.link_angle, joints=self.joints,
                        converged=self.converged, iterations=self.iterations, residual=self.residual)


def _rotate(cos_t: FloatArray, sin_t: FloatArray, delta: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(cos, sin) of θ + δ for |δ| ≤ 0.3 rad by Taylor polynomials, put back on the unit circle (as
    :func:`prs3_post.kinematics.prs3.forward._rotate`: no trigonometric calls in the loop)."""
    d2 = delta * delta
    cos_d = 1.0 - d2 * (0.5 - d2 * (1.0 / 24.0 - d2 * (1.0 / 720.0)))
    sin_d = delta * (1.0 - d2 * (1.0 / 6.0 - d2 * (1.0 / 120.0 - d2 * (1.0 / 5040.0))))
    new_cos = cos_t * cos_d - sin_t * sin_d
    new_sin = sin_t * cos_d + cos_t * sin_d
    scale = 1.0 / np.sqrt(new_cos * new_cos + new_sin * new_sin)
    return new_cos * scale, new_sin * scale


def _dot(a: FloatArray, b: FloatArray) -> FloatArray:
    """Row-wise dot products over axis 1 of (3 legs, 3, n) arrays (or their broadcasts) → (3, n)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def revolute_centres(legs: LegArrays, strokes: FloatArray) -> FloatArray:
    """C_i = P_i + (T_i + o_i)·d_i of N stroke rows (N, 3) → (3 legs, 3, N) mm."""
    travel = strokes.T + legs.stroke_offset[:, None]                          # (3, n)
    return legs.rail_point[:, :, None] + travel[:, None, :] * legs.rail_direction[:, :, None]


def _solve_block(legs: LegArrays, strokes: FloatArray, tol: float, max_iter: int
                 ) -> tuple[FloatArray, FloatArray, FloatArray, IntArray, FloatArray]:
    """Newton on the link angles of one block: C (3, 3, n), cos θ, sin θ (3, n), iterations (n,), residual (n,) mm."""
    n = len(strokes)
    centres = revolute_centres(legs, strokes)
    u, v, link = legs.in_plane_u, legs.in_plane_v, legs.link_length
    link_j = link[NEXT]
    # the coefficients of D_ij (module docstring), pair k = (i, j) = (k, NEXT[k]); per pose (3, n)
    w = centres - centres[NEXT]
    w0 = _dot(w, w) + (link * link + link_j * link_j - legs.side * legs.side)[:, None]
    p_i = (2.0 * link)[:, None] * _dot(w, u[:, :, None])
    q_i = (2.0 * link)[:, None] * _dot(w, v[:, :, None])
    p_j = (-2.0 * link_j)[:, None] * _dot(w, u[NEXT][:, :, None])
    q_j = (-2.0 * link_j)[:, None] * _dot(w, v[NEXT][:, :, None])
    # and per head (3, 1): −2 U_i U_j times u_i·u_j, u_i·v_j, v_i·u_j, v_i·v_j
    both = -2.0 * link * link_j
    m11 = (both * np.einsum("ij,ij->i", u, u[NEXT]))[:, None]
    m12 = (both * np.einsum("ij,ij->i", u, v[NEXT]))[:, None]
    m21 = (both * np.einsum("ij,ij->i", v, u[NEXT]))[:, None]
    m22 = (both * np.einsum("ij,ij->i", v, v[NEXT]))[:, None]
    two_side = (2.0 * legs.side)[:, None]

    start = legs.start_cos[:, None]
    out_cos = np.zeros((3, n)) + start
    out_sin = np.zeros((3, n)) + np.sqrt(1.0 - start * start)
    iterations = np.zeros(n, dtype=np.int64)
    residual = np.full(n, np.inf)
    active = np.arange(n)
    cos_t, sin_t = out_cos.copy(), out_sin.copy()
    for step in range(max_iter + 1):
        cos_j, sin_j = cos_t[NEXT], sin_t[NEXT]
        x = m11 * cos_j + m12 * sin_j
        y = m21 * cos_j + m22 * sin_j
        err = w0 + (p_i + x) * cos_t + (q_i + y) * sin_t + p_j * cos_j + q_j * sin_j   # (3, n): D12 D23 D31
        res = np.max(np.abs(err) / two_side, axis=0)                                   # mm, first order
        done = res < tol
        if step == max_iter:
            done[:] = True
        if done.any():
            idx = active[done]
            out_cos[:, idx], out_sin[:, idx] = cos_t[:, done], sin_t[:, done]
            iterations[idx], residual[idx] = step, res[done]
            keep = ~done
            if not keep.any():
                break
            active, cos_t, sin_t = active[keep], cos_t[:, keep], sin_t[:, keep]
            cos_j, sin_j = cos_j[:, keep], sin_j[:, keep]
            w0, p_i, q_i, p_j, q_j = w0[:, keep], p_i[:, keep], q_i[:, keep], p_j[:, keep], q_j[:, keep]
            x, y, err = x[:, keep], y[:, keep], err[:, keep]
        a = (q_i + y) * cos_t - (p_i + x) * sin_t                           # ∂D_ij/∂θ_i
        b = (q_j + cos_t * m12 + sin_t * m22) * cos_j - (p_j + cos_t * m11 + sin_t * m21) * sin_j   # ∂D_ij/∂θ_j
        det = a[0] * a[1] * a[2] + b[0] * b[1] * b[2]
        regular = np.abs(det) > 1e-300
        inv = -1.0 / np.where(regular, det, 1.0)      # f = -err folded into the sign
        delta = np.zeros_like(err)
        delta[0] = (a[1] * a[2] * err[0] - b[0] * a[2] * err[1] + b[0] * b[1] * err[2]) * inv
        delta[1] = (a[2] * a[0] * err[1] - b[1] * a[0] * err[2] + b[1] * b[2] * err[0]) * inv
        delta[2] = (a[0] * a[1] * err[2] - b[2] * a[1] * err[0] + b[2] * b[0] * err[1]) * inv
        delta[:, ~regular] = 0.0                      # singular rows: zero step, they stay unconverged
        np.clip(delta, -0.3, 0.3, out=delta)          # damp wild first steps far from the solution
        cos_t, sin_t = _rotate(cos_t, sin_t, delta)
    return centres, out_cos, out_sin, iterations, residual


def platform_frame(points: FloatArray) -> FloatArray:
    """The orthonormal frame of triangles: columns x = (p2 − p1)/|p2 − p1|, z = the unit normal of
    (p2 − p1) × (p3 − p1), y = z × x.

    Parameters
    ----------
    points : (N, 3, 3) float — ``[:, i]`` is point i + 1

    Returns
    -------
    (N, 3, 3) float — ``[:, :, k]`` is axis k
    """
    edge1, edge2 = points[:, 1] - points[:, 0], points[:, 2] - points[:, 0]
    x = edge1 / np.sqrt(np.sum(edge1 * edge1, axis=1, keepdims=True))
    z = np.cross(edge1, edge2)
    z /= np.sqrt(np.sum(z * z, axis=1, keepdims=True))
    return np.stack([x, np.cross(z, x), z], axis=2)


def _pose_block(legs: LegArrays, strokes: FloatArray, stage: FloatArray, tol: float, max_iter: int,
                out: dict[str, np.ndarray]) -> None:
    """FK of one block into the ``out`` views (keys as :class:`GeneralFKResult` fields)."""
    centres, cos_t, sin_t, out["iterations"][:], out["residual"][:] = _solve_block(legs, strokes, tol, max_iter)
    link = legs.link_length[:, None, None]
    joints_lcn = centres + link * (cos_t[:, None, :] * legs.in_plane_u[:, :, None]
                                   + sin_t[:, None, :] * legs.in_plane_v[:, :, None])   # (3 legs, 3, n)
    joints = np.ascontiguousarray(joints_lcn.transpose(2, 0, 1))                       # (n, 3 legs, 3)
    platform = legs.platform_joint
    frame_p = platform_frame(platform[None])[0]                      # (3, 3) platform frame's triangle axes
    rotation = platform_frame(joints) @ frame_p.T                    # (n, 3, 3)
    centre = joints.mean(axis=1) - rotation @ platform.mean(axis=0)
    tip = centre + rotation @ legs.tool_tip
    axis = rotation @ legs.tool_axis
    tip[:, :2] += stage
    theta = np.arctan2(sin_t, cos_t).T
    converged = (
        (out["residual"] < tol)
        & (axis[:, 2] > 0.0)
        & np.all((theta > 0.0) & (theta < np.pi / 2), axis=1)
        & np.isfinite(tip).all(axis=1)                # strokes of 1e308 overflow to inf, not a pose
    )
    for values in (tip, axis, centre, rotation, theta, joints):
        values[~converged] = np.nan
    out["tip"][:], out["axis"][:], out["centre"][:], out["rotation"][:] = tip, axis, centre, rotation
    out["link_angle"][:], out["joints"][:], out["converged"][:] = theta, joints, converged


def forward_general(
    general: GeneralGeometry,
    strokes: FloatArray,
    stage: FloatArray | None = None,
    *,
    tol: float = 1e-11,
    max_iter: int = 30,
    block_rows: int = 16384,
    workers: int | None = None,
) -> GeneralFKResult:
    """Forward kinematics of a general head: commanded strokes T1..T3 (and stage X, Y) → platform pose, tip, axis.

    Parameters
    ----------
    general : GeneralGeometry
    strokes : (N, 3) float — mm, commanded actuator strokes (the program's words; the encoder zeros
        ``stroke_offset`` are added here)
    stage : (N, 2) float, optional — mm, stage X, Y (default zeros: the head's own tip)
    tol : float — mm, converged when the worst platform side-length error is below it
    max_iter : int — Newton step limit
    block_rows, workers : int — block size and threads (no effect on the result)

    Returns
    -------
    GeneralFKResult — NaN pose values where not converged

    >>> from prs3_post.machine.loading import load_machine
    >>> from prs3_post.machine.model import general_from_ideal
    >>> g = general_from_ideal(load_machine("patel2020").geometry)
    >>> r = forward_general(g, np.array([[36.2243753, 170.3884539, 88.9518701]]), np.array([[-2.7640208, 12.0703266]]))
    >>> np.round(r.tip, 4).tolist(), np.round(r.axis, 6).tolist(), bool(r.converged[0])
    ([[-81.0264, 21.2132, -679.4865]], [[0.447214, 0.0, 0.894427]], True)
    """
    legs = leg_arrays(general)
    strokes = np.asarray(strokes, dtype=np.float64).reshape(-1, 3)
    n = len(strokes)
    stage = np.zeros((n, 2)) if stage is None else np.asarray(stage, dtype=np.float64).reshape(-1, 2)
    out = {
        "tip": np.zeros((n, 3)),
        "axis": np.zeros((n, 3)),
        "centre": np.zeros((n, 3)),
        "rotation": np.zeros((n, 3, 3)),
        "link_angle": np.zeros((n, 3)),
        "joints": np.zeros((n, 3, 3)),
        "converged": np.zeros(n, dtype=bool),
        "iterations": np.zeros(n, dtype=np.int64),
        "residual": np.zeros(n),
    }

    def kernel(rows: slice) -> None:
        _pose_block(legs, strokes[rows], stage[rows], tol, max_iter, {k: v[rows] for k, v in out.items()})

    run_blocks(kernel, n, block_rows=block_rows, workers=workers)
    return GeneralFKResult(**out)
