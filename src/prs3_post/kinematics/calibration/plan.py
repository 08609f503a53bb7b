"""Choosing the poses to measure: a D-optimal design over candidate poses the caller checked against
every limit.

Criterion: maximise det(I + Σ JₖᵀJₖ/σ²) over the chosen poses k, where Jₖ is pose k's scaled
Jacobian in the parameters the whole candidate set can determine (:func:`select_parameters` with
the noise σ) and I is the prior information of parameters known to their expected error sizes:
the volume of the parameters' confidence ellipsoid is made as small as it can be. Poses are added
greedily, each the one that increases the determinant most (the increase of a pose is
det(I + Jₖ A⁻¹ Jₖᵀ/σ²) for the information A so far, computed for all candidates at once), then the
chosen set is improved by exchanges (Fedorov) while one raises the determinant.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prs3_post.core.types import FloatArray, IntArray
from prs3_post.kinematics.calibration.identify import Identifiability, select_parameters
from prs3_post.kinematics.calibration.parameters import ErrorModel, Observations
from prs3_post.kinematics.calibration.residuals import jacobian

__all__ = ["Plan", "plan_poses"]

#: Exchange passes over the chosen poses after the greedy choice.
EXCHANGE_PASSES = 2


@dataclass(frozen=True, slots=True)
class Plan:
    """A chosen set of measurement poses and what measuring them would determine.

    Attributes
    ----------
    index : (n,) int — the chosen candidates, in the candidates' order
    identifiability : Identifiability — what the chosen poses determine (fitted and held parameters)
    std : (P,) float — code units, each fitted parameter's expected standard deviation (NaN: held)
    covariance : (P, P) float — scaled units², the parameters' expected covariance (0 for held ones)
    log_det : float — the criterion: log det(I + JᵀJ/σ²) on the fitted parameters
    """

    index: IntArray
    identifiability: Identifiability
    std: FloatArray
    covariance: FloatArray
    log_det: float


def plan_poses(model: ErrorModel, candidates: Observations, count: int, *, noise: float) -> Plan:
    """Choose ``count`` of the ``candidates`` to measure (see the module's docstring).

    Parameters
    ----------
    model : ErrorModel — the nominal head (``fit_frame`` adds the measurement frame's parameters)
    candidates : Observations — poses inside every limit (their ``tip`` is not used; ``has_axis``:
        the axes will be measured)
    count : int — poses to choose (≤ the number of candidates)
    noise : float — mm, the measurement noise σ

    Returns
    -------
    Plan
    """
    zero = np.zeros(len(model.parameters))
    if model.fit_frame:                                  # the frame's first estimate: the identity
        model = model.with_frame(np.eye(3), np.zeros(3))
    jac = jacobian(model, zero, candidates)                              # (m·C, P) in blocks of coordinates
    per_row = 3 * (1 + candidates.has_axis)
    c = len(candidates)
    blocks = jac.reshape(per_row // 3, c, 3, -1).transpose(1, 0, 2, 3).reshape(c, per_row, -1)   # (C, m, P)
    pool = select_parameters(model, jac, noise=noise)
    columns = [int(i) for i in pool.fitted]
    g = blocks[:, :, columns] / noise                                    # (C, m, K)
    k = len(columns)
    information = np.eye(k)
    chosen: list[int] = []
    available = np.ones(c, dtype=bool)
    for _ in range(count):
        best = _best_addition(g, information, available)
        chosen.append(best)
        available[best] = False
        information += g[best].T @ g[best]
    for _ in range(EXCHANGE_PASSES):
        improved = False
        for slot in range(len(chosen)):
            out = chosen[slot]
            without = information - g[out].T @ g[out]
            best = _best_addition(g, without, available)
            if _gain(g[best], without) > _gain(g[out], without) + 1e-9:
                chosen[slot] = best
                available[out], available[best] = True, False
                information = without + g[best].T @ g[best]
                improved = True
        if not improved:
            break
    index = np.sort(np.array(chosen, dtype=np.int64))
    rows = np.concatenate([np.arange(3 * block * c, 3 * (block + 1) * c).reshape(c, 3)[index].ravel()
                           for block in range(per_row // 3)])
    final = select_parameters(model, jac[rows], noise=noise)
    fitted = [int(i) for i in final.fitted]
    basis = final.basis
    gram = basis.T @ (jac[rows][:, fitted].T @ jac[rows][:, fitted]) @ basis / noise**2
    std = np.full(len(model.parameters), math.nan)
    covariance = np.zeros((len(model.parameters),) * 2)
    if basis.shape[1]:
        covariance[np.ix_(fitted, fitted)] = basis @ np.linalg.inv(gram) @ basis.T
        std[fitted] = np.sqrt(np.diag(covariance)[fitted]) * model.scales[fitted]
    sign, log_det = np.linalg.slogdet(np.eye(k) + sum(g[i].T @ g[i] for i in index))
    return Plan(index=index, identifiability=final, std=std, covariance=covariance,
                log_det=float(log_det) if sign > 0 else -math.inf)


def _gain(block: FloatArray, information: FloatArray) -> float:
    """log det(I + G A⁻¹ Gᵀ): how much adding the pose's block G (m, K) raises log det A."""
    inner = np.eye(len(block)) + block @ np.linalg.solve(information, block.T)
    return float(np.linalg.slogdet(inner)[1])


def _best_addition(g: FloatArray, information: FloatArray, available: np.ndarray) -> int:
    """The available candidate whose block raises log det of ``information`` most (all at once)."""
    inverse = np.linalg.inv(information)
    inner = np.eye(g.shape[1])[None] + g @ inverse @ g.transpose(0, 2, 1)   # (C, m, m)
    _, gain = np.linalg.slogdet(inner)
    gain[~available] = -np.inf
    return int(np.argmax(gain))
