"""Forward kinematics of the 3-PRS head: strokes (and stage X, Y) → platform pose and tool tip.

Frames and eq. (1) as in :mod:`prs3_post.kinematics.prs3.exact`. Unknowns: the three link angles θ_i.
With ρ_i = K − U cos θ_i (radius of S_i) and z_i = −T_i − U sin θ_i (its height), and legs 120°
apart (e_i·e_j = −½), the rigid platform triangle of side q = r_p√3 requires

    D_ij = ρ_i² + ρ_j² + ρ_i ρ_j + (z_i − z_j)² − q² = 0   for (i, j) = (1, 2), (2, 3), (3, 1).

Each D_ij depends on θ_i and θ_j only, so the Newton Jacobian is cyclic,
[[a1, b1, 0], [0, a2, b2], [b3, 0, a3]], with det = a1 a2 a3 + b1 b2 b3, solved in closed form for
all active points at once. The three points fix the rigid platform: M = their centroid, the tool
axis a = normalized (S2 − S1) × (S3 − S1) (legs counter-clockwise, so a_z > 0 in the working
assembly mode), tip = M − TL·a, plus the stage (X, Y, 0).

Start and branch: Newton starts from the untilted pose's link angle cos θ0 = (K − r_p)/U for all
legs and so follows the working assembly mode (θ in (0°, 90°), platform below the base, a_z > 0).
A point is ``converged`` when the worst side-length error |S_i − S_j| − q is below ``tol`` and that
pose is in the working mode; otherwise (strokes the head cannot assemble to, a singular Jacobian,
or the iteration limit) it is reported not converged, with NaN pose values, never garbage.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.kinematics.prs3.blocks import run_blocks
from prs3_post.machine.model import Geometry


@dataclass(frozen=True, slots=True)
class FKResult:
    """Forward kinematics of N actuator settings.

    Attributes
    ----------
    tip : (N, 3) float — mm, tool tip, machine frame, stage included (part-relative tip)
    axis : (N, 3) float — unit, tip → spindle
    link_angle : (N, 3) float — rad, θ1..θ3
    joints : (N, 3, 3) float — mm, spherical-joint centres S1..S3 (head frame, no stage)
    converged : (N,) bool
    iterations : (N,) int — Newton steps used
    residual : (N,) float — mm, worst platform side-length error
    """

    tip: FloatArray
    axis: FloatArray
    link_angle: FloatArray
    joints: FloatArray
    converged: BoolArray
    iterations: IntArray
    residual: FloatArray


def _rotate(cos_t: FloatArray, sin_t: FloatArray, delta: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(cos, sin) of θ + δ for |δ| ≤ 0.3 rad, without trigonometric calls.

    np.cos costs about 40 multiplications here, and Newton needs cos and sin of every angle at every
    step, so the angles are carried as (cos, sin) pairs and turned by δ with Taylor polynomials
    (error < 2e-9 at |δ| = 0.3, far smaller near convergence), then put back on the unit circle. The
    residual is always evaluated exactly from the pair, so the polynomial only shapes the step.
    """
    d2 = delta * delta
    cos_d = 1.0 - d2 * (0.5 - d2 * (1.0 / 24.0 - d2 * (1.0 / 720.0)))
    sin_d = delta * (1.0 - d2 * (1.0 / 6.0 - d2 * (1.0 / 120.0 - d2 * (1.0 / 5040.0))))
    new_cos = cos_t * cos_d - sin_t * sin_d
    new_sin = sin_t * cos_d + cos_t * sin_d
    scale = 1.0 / np.sqrt(new_cos * new_cos + new_sin * new_sin)
    return new_cos * scale, new_sin * scale


def _solve_block(
    geometry: Geometry, strokes: FloatArray, tol: float, max_iter: int
) -> tuple[FloatArray, FloatArray, IntArray, FloatArray]:
    """Newton on the link angles of one block: cos θ, sin θ (3, n), iterations (n,), residual (n,) mm.

    Arrays are leg-major, (3, n), so that every per-leg row is contiguous.
    """
    n = len(strokes)
    big_k, link = geometry.guide_radius, geometry.link_length
    side_sq = 3.0 * geometry.platform_radius**2
    two_side = 2.0 * math.sqrt(side_sq)
    cos0 = min(max((big_k - geometry.platform_radius) / link, -1.0), 1.0)
    out_cos, out_sin = np.full((3, n), cos0), np.full((3, n), math.sqrt(1.0 - cos0 * cos0))
    iterations = np.zeros(n, dtype=np.int64)
    residual = np.full(n, np.inf)
    active = np.arange(n)
    cos_t, sin_t, height = out_cos.copy(), out_sin.copy(), -np.ascontiguousarray(strokes.T)
    nxt = [1, 2, 0]
    for step in range(max_iter + 1):
        rho = big_k - link * cos_t                    # radius of S_i
        z = height - link * sin_t                     # height of S_i
        rho_j, z_j = rho[nxt], z[nxt]
        dzij = z - z_j
        err = rho * (rho + rho_j) + rho_j * rho_j + dzij * dzij - side_sq   # (3, n): D12 D23 D31
        res = np.max(np.abs(err), axis=0) / two_side                        # mm, first order
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
            active, cos_t, sin_t, height = active[keep], cos_t[:, keep], sin_t[:, keep], height[:, keep]
            rho, rho_j, dzij, err = rho[:, keep], rho_j[:, keep], dzij[:, keep], err[:, keep]
        drho, dz = link * sin_t, -link * cos_t        # d(rho)/dθ, dz/dθ
        # dD_ij/dθ_i = a_i, dD_ij/dθ_j = b_i
        a = (2.0 * rho + rho_j) * drho + 2.0 * dzij * dz
        b = (2.0 * rho_j + rho) * drho[nxt] - 2.0 * dzij * dz[nxt]
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
    return out_cos, out_sin, iterations, residual


def _pose_block(
    geometry: Geometry, strokes: FloatArray, stage: FloatArray, tol: float, max_iter: int, out: dict[str, np.ndarray]
) -> None:
    """FK of one block into the ``out`` views (keys as :class:`FKResult` fields)."""
    cos_t, sin_t, out["iterations"][:], out["residual"][:] = _solve_block(geometry, strokes, tol, max_iter)
    alpha = np.asarray(geometry.leg_azimuth)
    joints = out["joints"]
    rho = geometry.guide_radius - geometry.link_length * cos_t                 # (3, n)
    joints[:, :, 0] = (rho * np.cos(alpha)[:, None]).T
    joints[:, :, 1] = (rho * np.sin(alpha)[:, None]).T
    joints[:, :, 2] = (-strokes.T - geometry.link_length * sin_t).T
    edge1, edge2 = joints[:, 1] - joints[:, 0], joints[:, 2] - joints[:, 0]
    normal = np.cross(edge1, edge2)
    axis = normal / np.sqrt(np.sum(normal * normal, axis=1, keepdims=True))
    tip = joints.sum(axis=1) * (1.0 / 3.0) - geometry.tool_length * axis
    tip[:, :2] += stage
    theta = np.arctan2(sin_t, cos_t).T
    converged = (
        (out["residual"] < tol)
        & (axis[:, 2] > 0.0)
        & np.all((theta > 0.0) & (theta < np.pi / 2), axis=1)
        & np.isfinite(tip).all(axis=1)                # strokes of 1e308 overflow to inf, not a pose
    )
    for values in (tip, axis, theta, joints):
        values[~converged] = np.nan
    out["tip"][:], out["axis"][:], out["link_angle"][:], out["converged"][:] = tip, axis, theta, converged


def forward(
    geometry: Geometry,
    strokes: FloatArray,
    stage: FloatArray | None = None,
    *,
    tol: float = 1e-11,
    max_iter: int = 30,
    block_rows: int = 16384,
    workers: int | None = None,
) -> FKResult:
    """Forward kinematics: strokes T1..T3 (and stage X, Y) → tool tip, axis and platform pose.

    Parameters
    ----------
    geometry : Geometry
    strokes : (N, 3) float — mm, actuator strokes
    stage : (N, 2) float, optional — mm, stage X, Y (default zeros: the head's own tip)
    tol : float — mm, converged when the worst platform side-length error is below it
    max_iter : int — Newton step limit
    block_rows, workers : int — block size and threads (no effect on the result)

    Returns
    -------
    FKResult — NaN tip/axis/joints where not converged

    >>> from prs3_post.machine.loading import load_machine
    >>> g = load_machine("patel2020").geometry
    >>> r = forward(g, np.array([[36.2243753, 170.3884539, 88.9518701]]), np.array([[-2.7640208, 12.0703266]]))
    >>> np.round(r.tip, 4).tolist(), np.round(r.axis, 6).tolist(), bool(r.converged[0])
    ([[-81.0264, 21.2132, -679.4865]], [[0.447214, 0.0, 0.894427]], True)
    """
    strokes = np.asarray(strokes, dtype=np.float64).reshape(-1, 3)
    n = len(strokes)
    stage = np.zeros((n, 2)) if stage is None else np.asarray(stage, dtype=np.float64).reshape(-1, 2)
    out = {
        "tip": np.zeros((n, 3)),
        "axis": np.zeros((n, 3)),
        "link_angle": np.zeros((n, 3)),
        "joints": np.zeros((n, 3, 3)),
        "converged": np.zeros(n, dtype=bool),
        "iterations": np.zeros(n, dtype=np.int64),
        "residual": np.zeros(n),
    }

    def kernel(rows: slice) -> None:
        _pose_block(geometry, strokes[rows], stage[rows], tol, max_iter, {k: v[rows] for k, v in out.items()})

    run_blocks(kernel, n, block_rows=block_rows, workers=workers)
    return FKResult(**out)
