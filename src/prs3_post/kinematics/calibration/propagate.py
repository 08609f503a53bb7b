"""First-order accuracy of the tool: how the actuators' resolution and the head's parameter
uncertainty map to the tip's position and the tool axis's direction.

At commanded strokes T the measured quantities are h(T, p) (tip, axis). With the parameters'
covariance Σ (scaled units) and each actuator set to within a resolution step q (a uniform error,
variance q²/12), the tip's covariance is

    C_tip = J_p Σ J_pᵀ + (q²/12)·J_T J_Tᵀ

with J_p the Jacobian in the parameters (:func:`~prs3_post.kinematics.calibration.residuals.jacobian`)
and J_T the one in the strokes (central differences of forward kinematics); likewise the axis's.
A pose's tip uncertainty is √trace C_tip (mm, the RMS length of its 3D error, one standard
deviation), its axis uncertainty √trace C_axis (rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prs3_post.core.types import FloatArray
from prs3_post.kinematics.calibration.parameters import ErrorModel, Observations
from prs3_post.kinematics.calibration.residuals import AXIS_LEVER_MM, jacobian, predict
from prs3_post.machine.model import Calibration

__all__ = ["PoseUncertainty", "covariance_of", "pose_uncertainty"]

#: mm: the central-difference step in the strokes.
STROKE_STEP = 1e-4


@dataclass(frozen=True, slots=True)
class PoseUncertainty:
    """The tool's first-order uncertainty at N poses (one standard deviation).

    Attributes
    ----------
    tip : (N,) float — mm, √trace of the tip's covariance (parameters and resolution)
    axis : (N,) float — rad, √trace of the axis's covariance
    tip_parameters : (N,) float — mm, the parameters' share alone
    tip_resolution : (N,) float — mm, the actuators' resolution's share alone
    """

    tip: FloatArray
    axis: FloatArray
    tip_parameters: FloatArray
    tip_resolution: FloatArray


def covariance_of(model: ErrorModel, calibration: Calibration) -> FloatArray:
    """(P, P) scaled units²: the parameters' covariance a machine file's ``[calibration]`` table gives
    (parameters it does not name: 0, as known exactly — they were held at nominal).

    Raises
    ------
    ValueError
        A parameter name the model does not have.
    """
    names = model.names
    unknown = [name for name in calibration.parameters if name not in names]
    if unknown:
        raise ValueError(f"calibration.parameters: unknown parameter {unknown[0]!r} (known: {', '.join(names)})")
    index = [names.index(name) for name in calibration.parameters]
    scaled_std = np.array([
        (math.radians(s) if model.parameters[i].unit == "deg" else s) / model.parameters[i].scale
        for s, i in zip(calibration.std, index, strict=True)])
    correlation = np.array(calibration.correlation, dtype=np.float64).reshape(len(index), len(index))
    covariance = np.zeros((len(names), len(names)))
    covariance[np.ix_(index, index)] = correlation * np.outer(scaled_std, scaled_std)
    return covariance


def pose_uncertainty(model: ErrorModel, strokes: FloatArray, tool_length: FloatArray, covariance: FloatArray, *,
                     resolution: float) -> PoseUncertainty:
    """The tool's uncertainty at commanded ``strokes`` (N, 3) with tools ``tool_length`` (N,) mm.

    Parameters
    ----------
    model : ErrorModel — the head (its nominal is the machine's geometry)
    strokes : (N, 3) float — mm
    tool_length : (N,) float — mm, "TL"
    covariance : (P, P) float — scaled units², the parameters' covariance (zeros: known exactly)
    resolution : float — mm, the actuators' resolution step (0: exact)

    Returns
    -------
    PoseUncertainty — NaN where forward kinematics cannot place the head
    """
    n = len(strokes)
    obs = Observations(strokes=np.asarray(strokes, dtype=np.float64), stage=np.zeros((n, 2)),
                       tool_length=np.asarray(tool_length, dtype=np.float64), tip=np.zeros((n, 3)),
                       axis=np.zeros((n, 3)), has_axis=True)
    zero = np.zeros(len(model.parameters))
    jac = jacobian(model, zero, obs)                                        # (6N, P): tips, then axes × lever
    tip_p = jac[:3 * n].reshape(n, 3, -1)
    axis_p = jac[3 * n:].reshape(n, 3, -1) / AXIS_LEVER_MM
    tip_cov_p = np.einsum("nip,pq,njq->nij", tip_p, covariance, tip_p)
    axis_cov = np.einsum("nip,pq,njq->nij", axis_p, covariance, axis_p)
    tip_t, axis_t = np.zeros((n, 3, 3)), np.zeros((n, 3, 3))
    for j in range(3):                                                      # d(tip, axis)/d(stroke j)
        sides = []
        for sign in (1.0, -1.0):
            moved = obs.strokes.copy()
            moved[:, j] += sign * STROKE_STEP
            prediction = predict(model, zero, Observations(strokes=moved, stage=obs.stage, tool_length=obs.tool_length,
                                                           tip=obs.tip, axis=obs.axis, has_axis=True))
            sides.append((prediction.tip, prediction.axis))
        tip_t[:, :, j] = (sides[0][0] - sides[1][0]) / (2.0 * STROKE_STEP)
        axis_t[:, :, j] = (sides[0][1] - sides[1][1]) / (2.0 * STROKE_STEP)
    variance = resolution**2 / 12.0                                         # a uniform error of one step
    tip_cov_t = variance * np.einsum("nij,nkj->nik", tip_t, tip_t)
    axis_cov = axis_cov + variance * np.einsum("nij,nkj->nik", axis_t, axis_t)

    def root_trace(cov: FloatArray) -> FloatArray:
        return np.sqrt(np.maximum(np.trace(cov, axis1=1, axis2=2), 0.0))

    placed = predict(model, zero, obs).converged
    out = [np.where(placed, root_trace(cov), np.nan) for cov in (tip_cov_p + tip_cov_t, axis_cov, tip_cov_p, tip_cov_t)]
    return PoseUncertainty(tip=out[0], axis=out[1], tip_parameters=out[2], tip_resolution=out[3])
