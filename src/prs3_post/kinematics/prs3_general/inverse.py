"""Inverse kinematics of a general 3-PRS head: tool tip and axis → strokes and stage X, Y, vectorized.

Frames and symbols as in :mod:`prs3_post.kinematics.prs3_general.forward`. The head has three
degrees of freedom and the XY stage two: together they reach a tip and an axis (five). As on the
ideal head (:mod:`prs3_post.kinematics.prs3.exact`), the head sets the tool axis and the tip's
height, its platform drifts sideways as it tilts (the parasitic motion) and the stage supplies
the rest of the tip position.

Unknowns. The rotation R must take the platform's tool axis w to the target axis a; what is left of
it is a turn ψ about a:

    R = Rmin(z → a)·Rz(ψ)·Rmin(w → z)

(Rmin: the smallest rotation; on the ideal head w = z and ψ = 0, the tilt-and-torsion form with zero
torsion). The platform origin M: its z follows from the tip's height, M_z = tip_z − (R·c)_z; M_x and
M_y are free (the stage takes the tip's x, y). So x = (M_x, M_y, ψ), three unknowns.

Equations. With S_i = M + R·s_i and q_i = S_i − P_i, leg i's revolute joint sits at P_i + τ_i·d_i
(τ_i = T_i + o_i) where the link length holds, |q_i − τ_i d_i| = U_i:

    τ_i = q_i·d_i − sqrt((q_i·d_i)² − |q_i|² + U_i²)

(the root with the spherical joint beyond the revolute joint along the rail, the working mode), and
the link must lie in the joint's plane:

    g_i(x) = (q_i − τ_i d_i)·r_i = q_i·r_i − β_i τ_i = 0,   β_i = d_i·r_i.

Newton on g(x) = 0 with the analytic Jacobian: ∂g_i/∂S_i = n_i = r_i − β_i m_i, m_i = ∂τ_i/∂S_i =
ℓ_i/(ℓ_i·d_i) (ℓ_i = q_i − τ_i d_i, the link); ∂S_i/∂M_x = x̂, ∂S_i/∂M_y = ŷ, ∂S_i/∂ψ = a × (R s_i) −
ẑ (a × R c)_z. The 3 × 3 step is solved by Cramer's rule for all active poses at once. It starts
from the ideal closed form: ψ = 0 and (M_x, M_y) of eq. (2) of :mod:`prs3_post.kinematics.prs3.exact`
(for the ideal head that is the answer: no step is taken). Then T_i = τ_i − o_i, the stage
(X, Y) = tip_xy − (M + R·c)_xy and the link angle θ_i = atan2(ℓ_i·v_i, ℓ_i·u_i).

Condition number: of ∂T/∂(M_z, r_p a_x, r_p a_y) along the head's motions, as the ideal IK
reports it (:func:`prs3_post.kinematics.prs3.exact.axis_block`): for a small twist of the platform
(δM, δφ), δS_i = δM + δφ × (S_i − M), the legs allow n_i·δS_i = 0 and move δT_i = m_i·δS_i. With
δφ = a × δa + ω a, the three constraints give (δM_x, δM_y, ω) from (δM_z, δa) and so the 3 × 3
Jacobian J = A_p − A_x·C_x⁻¹·C_p (C: the constraint rows, A: the actuation rows; x: the columns of
δM_x, δM_y, ω; p: those of δM_z, r_p δa_x, r_p δa_y); r_p is the mean |s_i|.

Refusals: a pose where a link cannot reach (the square root's argument < 0), a singular Newton
step, or no convergence within ``max_iter`` comes back ``reachable = False`` with NaN values, never
a guess; so does a_z ≤ 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.kinematics.prs3.blocks import BLOCK_ROWS, run_blocks
from prs3_post.kinematics.prs3.exact import IKResult, condition_from_gram
from prs3_post.kinematics.prs3_general.legs import LegArrays, leg_arrays
from prs3_post.machine.model import GeneralGeometry

__all__ = ["GeneralIKResult", "inverse_general"]


@dataclass(frozen=True, slots=True)
class GeneralIKResult:
    """Inverse kinematics of N poses of a general head.

    Attributes
    ----------
    stage : (N, 2) float — mm, stage X, Y that put the head's tip on the target
    strokes : (N, 3) float — mm, commanded actuator strokes T1, T2, T3
    link_angle : (N, 3) float — rad, θ1..θ3 (from the plane normal to each rail)
    condition : (N,) float — 2-norm condition number of ∂T/∂(M_z, r_p a_x, r_p a_y)
    reachable : (N,) bool — the pose assembles and Newton converged
    centre : (N, 3) float — mm, the platform frame's origin (machine frame, stage not included)
    torsion : (N,) float — rad, ψ: the platform's turn about the tool axis beyond the smallest rotation
    iterations : (N,) int — Newton steps used
    residual : (N,) float — mm, worst distance of a link from its revolute joint's plane
    """

    stage: FloatArray
    strokes: FloatArray
    link_angle: FloatArray
    condition: FloatArray
    reachable: BoolArray
    centre: FloatArray
    torsion: FloatArray
    iterations: IntArray
    residual: FloatArray

    def ik_result(self) -> IKResult:
        """The fields the :class:`~prs3_post.kinematics.protocol.Kinematics` protocol's IK returns."""
        return IKResult(stage=self.stage, strokes=self.strokes, link_angle=self.link_angle,
                        condition=self.condition, reachable=self.reachable)


def _smallest_rotation(axis: FloatArray) -> FloatArray:
    """Rmin(z → a) of unit vectors (3,) with a_z > −1: the rotation about z × a (3, 3)."""
    ax, ay, az = axis
    k = 1.0 / (1.0 + az)
    return np.array([[1.0 - k * ax * ax, -k * ax * ay, ax],
                     [-k * ax * ay, 1.0 - k * ay * ay, ay],
                     [-ax, -ay, az]])


@dataclass(frozen=True, slots=True)
class _Platform:
    """The platform's points turned so that its tool axis is z (Rmin(w → z)·s_i, ·c), the mean |s_i|
    (r_p) and the ideal closed form's leg-layout constants cos 3α_1, sin 3α_1."""

    joints: FloatArray       # (3 legs, 3)
    tip: FloatArray          # (3,)
    radius: float
    c3: float
    s3: float


def _platform(legs: LegArrays) -> _Platform:
    turn = _smallest_rotation(legs.tool_axis).T       # Rmin(z → w)ᵀ = Rmin(w → z)
    joints = legs.platform_joint @ turn.T
    alpha1 = math.atan2(joints[0, 1], joints[0, 0])
    return _Platform(joints=joints, tip=turn @ legs.tool_tip,
                     radius=float(np.mean(np.sqrt((legs.platform_joint ** 2).sum(axis=1)))),
                     c3=math.cos(3.0 * alpha1), s3=math.sin(3.0 * alpha1))


class _State:
    """Everything one evaluation of g at x = (M_x, M_y, ψ) makes, for n poses (vectors (3, n), per
    leg (3 legs, 3, n))."""

    def __init__(self, legs: LegArrays, plat: _Platform, tip: FloatArray, axis: FloatArray,
                 ex: FloatArray, ey: FloatArray, mx: FloatArray, my: FloatArray, psi: FloatArray):
        cos_p, sin_p = np.cos(psi), np.sin(psi)
        ex_t = cos_p * ex + sin_p * ey                # R x̂' and R ŷ' (the turned platform's x, y)
        ey_t = cos_p * ey - sin_p * ex
        j = plat.joints
        self.rho = (j[:, 0, None, None] * ex_t + j[:, 1, None, None] * ey_t
                    + j[:, 2, None, None] * axis)     # R s_i (3 legs, 3, n)
        c = plat.tip
        self.tool = c[0] * ex_t + c[1] * ey_t + c[2] * axis                # R c (3, n)
        self.centre = np.stack([mx, my, tip[2] - self.tool[2]])             # M (3, n)
        q = self.centre + self.rho - legs.rail_point[:, :, None]          # (3 legs, 3, n)
        d = legs.rail_direction[:, :, None]
        qd = q[:, 0] * d[:, 0] + q[:, 1] * d[:, 1] + q[:, 2] * d[:, 2]
        qq = q[:, 0] * q[:, 0] + q[:, 1] * q[:, 1] + q[:, 2] * q[:, 2]
        self.root = np.sqrt(qd * qd - qq + (legs.link_length ** 2)[:, None])   # ℓ·d; NaN: cannot reach
        self.travel = qd - self.root                                        # τ_i (3, n)
        r = legs.revolute_axis[:, :, None]
        self.g = q[:, 0] * r[:, 0] + q[:, 1] * r[:, 1] + q[:, 2] * r[:, 2] - legs.rail_tilt[:, None] * self.travel
        self.q = q

    def take(self, rows: BoolArray) -> _State:
        """This state of the poses ``rows`` (n,) only."""
        part = object.__new__(_State)
        part.rho, part.q = self.rho[:, :, rows], self.q[:, :, rows]
        part.tool, part.centre = self.tool[:, rows], self.centre[:, rows]
        part.root, part.travel, part.g = self.root[:, rows], self.travel[:, rows], self.g[:, rows]
        return part

    def link(self, legs: LegArrays) -> FloatArray:
        """ℓ_i = q_i − τ_i d_i, each leg's link (3 legs, 3, n)."""
        return self.q - self.travel[:, None] * legs.rail_direction[:, :, None]


def _rows_of(legs: LegArrays, st: _State) -> tuple[FloatArray, FloatArray]:
    """The constraint rows n_i = r_i − β_i m_i and actuation rows m_i = ℓ_i/(ℓ_i·d_i), each (3 legs, 3, n)."""
    actuation = st.link(legs) / st.root[:, None]
    if not legs.rail_tilt.any():                      # every rail in its link's plane (the ideal head): n_i = r_i
        return np.broadcast_to(legs.revolute_axis[:, :, None], actuation.shape), actuation
    return legs.revolute_axis[:, :, None] - legs.rail_tilt[:, None, None] * actuation, actuation


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """a × b over axis −2 of broadcastable (…, 3, n) arrays (written into one output: np.stack of the
    three components measured 10× slower here)."""
    out = np.zeros(np.broadcast_shapes(a.shape, b.shape))
    a0, a1, a2, b0, b1, b2 = a[..., 0, :], a[..., 1, :], a[..., 2, :], b[..., 0, :], b[..., 1, :], b[..., 2, :]
    np.subtract(a1 * b2, a2 * b1, out=out[..., 0, :])
    np.subtract(a2 * b0, a0 * b2, out=out[..., 1, :])
    np.subtract(a0 * b1, a1 * b0, out=out[..., 2, :])
    return out


def _dot(a: FloatArray, b: FloatArray) -> FloatArray:
    """a·b over axis −2 of broadcastable (…, 3, n) arrays."""
    return a[..., 0, :] * b[..., 0, :] + a[..., 1, :] * b[..., 1, :] + a[..., 2, :] * b[..., 2, :]


class _Cramer:
    """3 × 3 systems with the columns (3, n) given, for any right-hand side (3, n), by Cramer's rule;
    singular ones give NaN, never a step."""

    def __init__(self, col0: FloatArray, col1: FloatArray, col2: FloatArray):
        self.c12, self.c20, self.c01 = _cross(col1, col2), _cross(col2, col0), _cross(col0, col1)
        det = _dot(col0, self.c12)
        self.inv = 1.0 / np.where(np.abs(det) > 1e-300, det, np.nan)

    def solve(self, rhs: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        return _dot(rhs, self.c12) * self.inv, _dot(rhs, self.c20) * self.inv, _dot(rhs, self.c01) * self.inv


def _ik_block(legs: LegArrays, plat: _Platform, tip: FloatArray, axis: FloatArray, tol: float,
              max_iter: int, out: dict[str, np.ndarray]) -> None:
    """General IK of one block into the ``out`` views (keys as :class:`GeneralIKResult` fields)."""
    n = len(tip)
    for key in ("stage", "strokes", "link_angle", "condition", "centre", "torsion", "residual"):
        out[key][:] = np.nan                          # rows that never converge keep NaN
    tip_t, axis_t = np.ascontiguousarray(tip.T), np.ascontiguousarray(axis.T)     # (3, n)
    ax, ay, az = axis_t
    k = 1.0 / (1.0 + az)
    ex = np.stack([1.0 - k * ax * ax, -k * ax * ay, -ax])             # Rmin(z → a) x̂, ŷ
    ey = np.stack([-k * ax * ay, 1.0 - k * ay * ay, -ay])
    half = -0.5 * plat.radius * k                                      # eq. (2): the ideal closed form
    diff, cross = ax * ax - ay * ay, 2.0 * ax * ay
    mx = half * (plat.c3 * diff + plat.s3 * cross)
    my = half * (plat.s3 * diff - plat.c3 * cross)
    psi = np.zeros(n)
    active = np.flatnonzero(az > 0.0)
    if len(active) < n:
        t_a, a_a, ex_a, ey_a = tip_t[:, active], axis_t[:, active], ex[:, active], ey[:, active]
        mx, my, psi = mx[active], my[active], psi[active]
    else:
        t_a, a_a, ex_a, ey_a = tip_t, axis_t, ex, ey
    for step in range(max_iter + 1):
        if not len(active):
            break
        st = _State(legs, plat, t_a, a_a, ex_a, ey_a, mx, my, psi)
        res = np.max(np.abs(st.g), axis=0)
        good = res < tol
        done = good | ~np.isfinite(res) | (step == max_iter)
        if done.any():
            every = bool(done.all())
            rows = active if every else active[done]
            out["iterations"][rows] = step
            if good.any():
                ok = good if every else good[done]
                part = st if every else st.take(done)
                part = part if ok.all() else part.take(ok)
                pick = done & good
                _write(legs, plat, t_a[:, pick], a_a[:, pick], part, psi[pick], rows[ok], out)
            if every:
                break
            keep = ~done
            active = active[keep]
            t_a, a_a, ex_a, ey_a = t_a[:, keep], a_a[:, keep], ex_a[:, keep], ey_a[:, keep]
            mx, my, psi = mx[keep], my[keep], psi[keep]
            st = st.take(keep)
        normal, _ = _rows_of(legs, st)
        swing = _cross(a_a, st.rho)                                  # a × R s_i: ∂S_i/∂ψ without the lift
        lift = -_cross(a_a, st.tool)[2]                               # ∂M_z/∂ψ
        col2 = _dot(normal, swing) + normal[:, 2] * lift
        d0, d1, d2 = _Cramer(normal[:, 0], normal[:, 1], col2).solve(-st.g)
        mx, my, psi = mx + d0, my + d1, psi + d2
    out["reachable"][:] = np.isfinite(out["condition"])


def _write(legs: LegArrays, plat: _Platform, tip: FloatArray, axis: FloatArray, st: _State, psi: FloatArray,
           rows: IntArray, out: dict[str, np.ndarray]) -> None:
    """The outputs of converged states into ``out``'s ``rows`` (tips and axes (3, m))."""
    link = st.link(legs)
    out["residual"][rows] = np.max(np.abs(st.g), axis=0)
    out["strokes"][rows] = (st.travel - legs.stroke_offset[:, None]).T
    out["stage"][rows] = (tip[:2] - st.centre[:2] - st.tool[:2]).T
    out["centre"][rows] = st.centre.T
    out["torsion"][rows] = psi
    u, v = legs.in_plane_u[:, :, None], legs.in_plane_v[:, :, None]
    out["link_angle"][rows] = np.arctan2(_dot(link, v), _dot(link, u)).T
    out["condition"][rows] = _condition(legs, plat, axis, st, link)


def _condition(legs: LegArrays, plat: _Platform, axis: FloatArray, st: _State, link: FloatArray) -> FloatArray:
    """(n,) the condition number of ∂T/∂(M_z, r_p a_x, r_p a_y) (module docstring): NaN where it is
    not finite (a singular pose)."""
    actuation = link / st.root[:, None]
    normal = (legs.revolute_axis[:, :, None] - legs.rail_tilt[:, None, None] * actuation
              if legs.rail_tilt.any() else np.broadcast_to(legs.revolute_axis[:, :, None], actuation.shape))
    ax, ay, az = axis
    scale = 1.0 / plat.radius
    slope_x, slope_y = ax / az, ay / az                  # δa per r_p δa_x: (1, 0, −a_x/a_z)/r_p; δa_y alike
    rho = st.rho
    swing = _cross(axis, rho)                            # δS_i per ω
    along = _dot(axis, rho)                              # a·ρ_i (3 legs, n)
    tilt_x_rho = (rho[:, 0] - rho[:, 2] * slope_x) * scale
    tilt_y_rho = (rho[:, 1] - rho[:, 2] * slope_y) * scale

    def columns(rows: FloatArray) -> tuple[FloatArray, ...]:
        # δS = (a × δa) × ρ = δa (a·ρ) − a (δa·ρ) for the two tilts
        along_rows = _dot(rows, axis)
        tx = (rows[:, 0] - rows[:, 2] * slope_x) * scale * along - along_rows * tilt_x_rho
        ty = (rows[:, 1] - rows[:, 2] * slope_y) * scale * along - along_rows * tilt_y_rho
        return rows[:, 0], rows[:, 1], _dot(rows, swing), rows[:, 2], tx, ty

    cx0, cx1, cx2, cp0, cp1, cp2 = columns(normal)
    ax0, ax1, ax2, ap0, ap1, ap2 = columns(actuation)
    system = _Cramer(cx0, cx1, cx2)
    jac = []
    for cp, ap in ((cp0, ap0), (cp1, ap1), (cp2, ap2)):
        x0, x1, x2 = system.solve(cp)
        jac.append(ap - (ax0 * x0 + ax1 * x1 + ax2 * x2))            # (3 legs, n): one column of J
    j0, j1, j2 = jac
    gram = np.stack([_dot(j0, j0), _dot(j0, j1), _dot(j0, j2), _dot(j1, j1), _dot(j1, j2), _dot(j2, j2)], axis=1)
    condition = condition_from_gram(gram, _dot(j0, _cross(j1, j2)))
    return np.where(np.isfinite(condition), condition, np.nan)


def inverse_general(
    general: GeneralGeometry,
    tip: FloatArray,
    axis: FloatArray,
    *,
    tol: float = 1e-11,
    max_iter: int = 20,
    block_rows: int = BLOCK_ROWS,
    workers: int | None = None,
) -> GeneralIKResult:
    """General IK: target tips and unit axes → stage X, Y, commanded strokes, link angles, condition numbers.

    Parameters
    ----------
    general : GeneralGeometry
    tip : (N, 3) float — mm, target tool tip in the machine frame (part-relative tip with the stage)
    axis : (N, 3) float — unit tool axes (tip → spindle), a_z > 0
    tol : float — mm, converged when every link is within it of its revolute joint's plane
    max_iter : int — Newton step limit
    block_rows, workers : int — rows per block and threads (no effect on the result)

    Returns
    -------
    GeneralIKResult — ``reachable`` False (and NaN values) where the pose does not assemble or
    Newton did not converge

    >>> from prs3_post.machine.loading import load_machine
    >>> from prs3_post.machine.model import general_from_ideal
    >>> g = general_from_ideal(load_machine("patel2020").geometry)
    >>> a = np.array([[1.0, 0.0, 2.0]]) / np.sqrt(5.0)
    >>> r = inverse_general(g, np.array([[-81.0264, 21.2132, -679.4865]]), a)
    >>> np.round(r.stage, 4).tolist(), np.round(r.strokes, 4).tolist()
    ([[-2.764, 12.0703]], [[36.2244, 170.3885, 88.9519]])
    """
    legs = leg_arrays(general)
    plat = _platform(legs)
    tip = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
    axis = np.asarray(axis, dtype=np.float64).reshape(-1, 3)
    n = len(tip)
    out = {
        "stage": np.zeros((n, 2)),
        "strokes": np.zeros((n, 3)),
        "link_angle": np.zeros((n, 3)),
        "condition": np.zeros(n),
        "reachable": np.zeros(n, dtype=bool),
        "centre": np.zeros((n, 3)),
        "torsion": np.zeros(n),
        "iterations": np.zeros(n, dtype=np.int64),
        "residual": np.zeros(n),
    }

    def kernel(rows: slice) -> None:
        _ik_block(legs, plat, tip[rows], axis[rows], tol, max_iter, {k: v[rows] for k, v in out.items()})

    run_blocks(kernel, n, block_rows=block_rows, workers=workers)
    return GeneralIKResult(**out)
