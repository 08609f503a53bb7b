"""The paper's inverse kinematics (Patel & Patel 2020), kept for validation only.

The paper places the platform centre at M = tip + TL·a with no stage and computes each spherical
joint S_i on its own: the intersection of leg i's vertical plane {S·t_i = 0} with the circle of
radius r_p around M in the plane normal to a. Nothing ties the three S_i together, so they are not
r_p·√3 apart (288.7 / 307.4 / 303.0 mm in case 2a) and a rigid platform cannot take that pose. The
strokes and link angles then follow from eq. (1) of :mod:`prs3_post.kinematics.prs3.exact`.

Circle ∩ plane. The plane normal to a through M meets {S·t = 0} in a line with direction a × t. Its
point nearest to M is X0 = M − (t·M)·n/|n|², n = t − (t·a)·a (in the platform plane, ⊥ the line),
and S = X0 ± √(r_p² − |X0 − M|²)·(a × t)/|a × t|. Branch choice: the sign that puts S farther out
along e_i (the joint on the leg's own side of the platform). No intersection (|X0 − M| > r_p) or a
link that cannot reach makes the pose unreachable.
"""

from __future__ import annotations

import numpy as np

from prs3_post.core.types import FloatArray
from prs3_post.kinematics.prs3.blocks import BLOCK_ROWS, run_blocks
from prs3_post.kinematics.prs3.exact import IKResult, axis_block, axis_terms, block_axes
from prs3_post.machine.model import Geometry


def _centre(geometry: Geometry, tip: FloatArray, axis: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """M = tip + TL·a as columns (x, y, z), each (N,) mm (the same for every leg)."""
    tool = geometry.tool_length
    return tip[:, 0] + tool * axis[:, 0], tip[:, 1] + tool * axis[:, 1], tip[:, 2] + tool * axis[:, 2]


def _branch(axis: FloatArray) -> FloatArray:
    """(N,) ±1: the sign that puts S_i farther out along e_i (:func:`_joint`; the same for every leg)."""
    return np.where(-axis[:, 2] >= 0.0, 1.0, -1.0)


def _joint(geometry: Geometry, centre: tuple[FloatArray, ...], axis: FloatArray, branch: FloatArray,
           leg: int) -> tuple[FloatArray, ...]:
    """S_i of one leg as columns (x, y, z), each (N,) mm; NaN where the circle misses the leg's plane.
    ``centre``: :func:`_centre`; ``branch``: :func:`_branch`.

    Written out per component (e = (cos α, sin α, 0), t = (−sin α, cos α, 0), g = a·e, τ = a·t):
    n = t − τa has |n|² = 1 − τ², a × t = g·z − a_z·e has the same length, and e·(a × t) = −a_z,
    so the branch sign is −1 for every axis with a_z > 0.
    """
    alpha = geometry.leg_azimuth[leg]
    ca, sa = np.cos(alpha), np.sin(alpha)
    ax, ay, az = axis[:, 0], axis[:, 1], axis[:, 2]
    mx, my, mz = centre
    tau = ay * ca - ax * sa                                   # t·a
    g = ax * ca + ay * sa                                     # a·e
    s2 = 1.0 - tau * tau                                      # |n|² = |a × t|²
    tm = my * ca - mx * sa                                    # t·M
    k = tm / s2                                               # foot X0 = M − k·n
    with np.errstate(invalid="ignore"):
        half_chord = np.sqrt(geometry.platform_radius**2 - tm * k)   # |X0 − M|² = tm²/s2
    step = branch * half_chord / np.sqrt(s2)                  # farther out along e_i
    return (mx + k * (sa + tau * ax) - step * az * ca,
            my - k * (ca - tau * ay) - step * az * sa,
            mz + k * tau * az + step * g)


def paper_joints(geometry: Geometry, tip: FloatArray, axis: FloatArray) -> FloatArray:
    """The paper's spherical-joint centres, each leg on its own.

    Parameters
    ----------
    tip : (N, 3) float — mm, tool tip, machine frame (the paper has no stage)
    axis : (N, 3) float — unit tool axes

    Returns
    -------
    (N, 3, 3) float — mm, ``[:, i]`` is S_{i+1}; NaN where the circle misses leg i's plane
    """
    tip = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
    axis = np.asarray(axis, dtype=np.float64).reshape(-1, 3)
    centre, branch = _centre(geometry, tip, axis), _branch(axis)
    return np.stack([np.column_stack(_joint(geometry, centre, axis, branch, leg)) for leg in range(3)], axis=1)


def _paper_block(geometry: Geometry, tip: FloatArray, axis: FloatArray, out: dict[str, FloatArray]) -> None:
    """Strokes, link angles, condition and reachability of one block (see :func:`inverse_paper`)."""
    reach = np.ones(len(tip), dtype=bool)
    centre, branch = _centre(geometry, tip, axis), _branch(axis)
    for leg in range(3):
        sx, sy, sz = _joint(geometry, centre, axis, branch, leg)
        alpha = geometry.leg_azimuth[leg]
        radial = sx * np.cos(alpha) + sy * np.sin(alpha)
        with np.errstate(invalid="ignore"):
            cos_t = (geometry.guide_radius - radial) / geometry.link_length
            reach &= np.abs(cos_t) <= 1.0                 # False for NaN too
            cos_t = np.clip(cos_t, -1.0, 1.0)              # clip: flagged above
        out["link_angle"][:, leg] = np.arccos(cos_t)
        out["strokes"][:, leg] = -sz - geometry.link_length * np.sqrt(1.0 - cos_t * cos_t)
    # the exact model's condition and reachability: its axis part alone (the tip does not change them)
    axes = block_axes(axis)
    condition, exact_reach = axis_block(geometry, axes, axis_terms(axes))
    out["condition"][:] = np.where(exact_reach, condition, np.nan)
    out["reachable"][:] = reach & exact_reach


def inverse_paper(geometry: Geometry, tip: FloatArray, axis: FloatArray, *, block_rows: int = BLOCK_ROWS,
                  workers: int | None = None) -> IKResult:
    """The paper's IK: strokes and link angles from independently placed joints; stage X, Y = 0.

    ``condition`` is the exact model's at the same tip and axis (the paper's pose is not rigid), and
    a pose is reachable only where the exact model's is too: both come from the exact model's part
    that depends on the axis alone (its strokes, link angles and stage are not computed). Cache-sized
    blocks on up to two threads, as :func:`~prs3_post.kinematics.prs3.exact.inverse_exact`.

    Parameters
    ----------
    tip : (N, 3) float — mm, tool tip, machine frame
    axis : (N, 3) float — unit tool axes
    block_rows, workers : int — rows per block and threads (no effect on the result)

    Returns
    -------
    IKResult
    """
    tip = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
    axis = np.asarray(axis, dtype=np.float64).reshape(-1, 3)
    n = len(tip)
    out = {"strokes": np.zeros((n, 3)), "link_angle": np.zeros((n, 3)), "condition": np.zeros(n),
           "reachable": np.zeros(n, dtype=bool)}

    def kernel(rows: slice) -> None:
        _paper_block(geometry, tip[rows], axis[rows], {k: v[rows] for k, v in out.items()})

    run_blocks(kernel, n, block_rows=block_rows, workers=workers)
    reachable = out["reachable"]
    stage = np.zeros((n, 2))
    for values in (stage, out["strokes"], out["link_angle"]):
        values[~reachable] = np.nan
    return IKResult(stage=stage, strokes=out["strokes"], link_angle=out["link_angle"], condition=out["condition"],
                    reachable=reachable)
