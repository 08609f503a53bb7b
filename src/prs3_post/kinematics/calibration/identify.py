"""Identification: which parameters the measurements determine, their values and uncertainties.

Identifiability (:func:`select_parameters`), from the scaled Jacobian J (mm per expected error) at
the nominal head, in two steps. First the parameters no measurement of this kind can separate: the
columns are taken in the model's order of preference, and one is *held* at its nominal value when
it adds no rank (its singular value below :data:`RANK_RTOL` of the largest); the report names the
fitted parameters it moves the tool like (its column's least-squares fit by theirs): a rail point
along its own rail is an encoder zero, the platform joints and the tool share the platform frame,
an unmeasured tool axis is seen by nothing. Then the combinations of the fitted parameters (the
right singular vectors of their columns) that are seen too weakly: a combination whose singular
value is below :data:`MIN_INFORMATION` times the noise (the measurements would know it to worse
than a third of its expected size) is held at nominal too, and named. Nothing held is fitted to noise.

Fit (:func:`identify`). scipy's ``least_squares`` (Levenberg-Marquardt, MINPACK) in the fitted
directions of the scaled parameters, from the nominal head, with the Jacobian of
:func:`~prs3_post.kinematics.calibration.residuals.jacobian`. The noise is estimated from the
residuals (σ² = SSR / (M − R), R the directions fitted), and the parameters' covariance is
σ²·B(BᵀJᵀJB)⁻¹Bᵀ at the solution (B the directions).

Hold-out (:func:`cross_validate`): k-fold; each fold's rows are predicted by the head fitted to the others.
An axis residual counts as the tip error of its turn a lever away from the tip
(:data:`~prs3_post.kinematics.calibration.residuals.AXIS_LEVER_MM`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from prs3_post.core.types import FloatArray, IntArray
from prs3_post.kinematics.calibration.parameters import ErrorModel, Observations
from prs3_post.kinematics.calibration.residuals import jacobian, predict, residual_vector, rigid_fit
from prs3_post.machine.model import Geometry

__all__ = ["MIN_INFORMATION", "Fit", "Identifiability", "Residuals", "cross_validate", "identify", "residuals_of",
           "select_parameters"]

#: How many times the noise the smallest singular value of the fitted parameters' scaled Jacobian
#: must be: every combination of them is then known to 1/3 of its expected error size or better.
MIN_INFORMATION = 3.0
#: Relative to the largest singular value: below this a combination is not seen at all (a
#: structural degeneracy, whatever the noise).
RANK_RTOL = 1e-7


@dataclass(frozen=True, slots=True)
class Identifiability:
    """Which parameters are fitted and which held, and why.

    Attributes
    ----------
    fitted : (K,) int — indices of the fitted parameters, in the model's order
    held : (H,) int — indices of the parameters held at nominal
    combinations : (H,) tuple of str — for each held parameter, the fitted ones it moves the tool
        like (``leg1.stroke_offset +1 mm/mm``), or ``not seen by these measurements``
    held_std : (H,) float — code units, the standard deviation a held parameter would get if it
        were fitted too (inf: not seen at all)
    smallest_singular : float — mm per expected error: the smallest singular value of the scaled
        Jacobian in the directions fitted
    basis : (K, R) float — the directions fitted in the fitted parameters' scaled space (orthonormal
        columns; R < K when some combinations are too weakly seen)
    weak : (W,) tuple of str — the combinations of fitted parameters held at nominal because the
        measurements see them too weakly, in words
    """

    fitted: IntArray
    held: IntArray
    combinations: tuple[str, ...]
    held_std: FloatArray
    smallest_singular: float
    basis: FloatArray
    weak: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class Residuals:
    """How far a head's predictions are from the measured rows.

    Attributes
    ----------
    tip : (N,) float — mm, each row's tip error |predicted − measured|
    axis : (N,) float — rad, each row's axis error (NaN where not measured)
    """

    tip: FloatArray
    axis: FloatArray

    @property
    def tip_rms(self) -> float:
        """mm, the RMS of the tip errors."""
        return float(np.sqrt(np.mean(self.tip**2))) if len(self.tip) else 0.0

    @property
    def worst_row(self) -> int:
        """The row of the largest tip error."""
        return int(np.argmax(self.tip))

    @property
    def axis_rms(self) -> float:
        """rad, the RMS of the axis errors (NaN when not measured)."""
        return float(np.sqrt(np.mean(self.axis**2))) if len(self.axis) else math.nan


@dataclass(frozen=True, slots=True)
class Fit:
    """The result of identifying a head from measurements.

    Attributes
    ----------
    model : ErrorModel — the model fitted (with the measurement frame's first estimate)
    scaled : (P,) float — the scaled parameters found (0 for held ones)
    std : (P,) float — code units, each fitted parameter's standard deviation (NaN for held ones)
    covariance : (P, P) float — scaled units², the fitted parameters' covariance (0 rows and columns
        for held ones)
    identifiability : Identifiability
    before, after : Residuals — the nominal and the fitted head's
    noise : float — mm, the noise estimated from the fitted residuals
    evaluations : int — model evaluations the solver used
    """

    model: ErrorModel
    scaled: FloatArray
    std: FloatArray
    covariance: FloatArray
    identifiability: Identifiability
    before: Residuals
    after: Residuals
    noise: float
    evaluations: int

    @property
    def head(self) -> Geometry:
        """The identified head."""
        return self.model.head(self.scaled)

    @property
    def values(self) -> FloatArray:
        """(P,) code units, each parameter's deviation from nominal."""
        return self.scaled * self.model.scales


def residuals_of(model: ErrorModel, scaled: FloatArray, obs: Observations) -> Residuals:
    """The tip and axis errors of the head ``model.head(scaled)`` on ``obs``."""
    prediction = predict(model, scaled, obs)
    tip = np.sqrt(np.sum((prediction.tip - obs.tip) ** 2, axis=1))
    if obs.has_axis:
        axis = 2.0 * np.arcsin(np.clip(np.sqrt(np.sum((prediction.axis - obs.axis) ** 2, axis=1)) / 2.0, 0.0, 1.0))
    else:
        axis = np.full(len(obs), math.nan)
    return Residuals(tip=np.where(prediction.converged, tip, np.inf), axis=axis)


def _smallest_singular(gram: FloatArray, columns: list[int]) -> float:
    """The smallest singular value of the Jacobian's ``columns``, from its Gram matrix JᵀJ (P, P)."""
    if not columns:
        return math.inf
    return math.sqrt(max(float(np.linalg.eigvalsh(gram[np.ix_(columns, columns)])[0]), 0.0))


def select_parameters(model: ErrorModel, jac: FloatArray, *, noise: float,
                      order: list[int] | None = None) -> Identifiability:
    """The parameters and combinations the scaled Jacobian ``jac`` (M, P) can determine with measurement
    noise ``noise`` mm (see the module's docstring), parameters taken in ``order`` (default: the
    model's preference)."""
    order = model.preference() if order is None else order
    gram = jac.T @ jac
    largest = math.sqrt(max(float(np.linalg.eigvalsh(gram)[-1]), 0.0)) if gram.size else 0.0
    structural = RANK_RTOL * max(largest, 1e-300)
    fitted: list[int] = []
    for column in order:
        if _smallest_singular(gram, [*fitted, column]) >= structural:
            fitted.append(column)
    fitted.sort()
    held = [i for i in range(jac.shape[1]) if i not in fitted]
    combinations, held_std = [], []
    inverse = np.linalg.inv(gram[np.ix_(fitted, fitted)]) if fitted else np.zeros((0, 0))
    for h in held:
        coefficients = inverse @ gram[fitted, h]                   # the column's least-squares fit by the fitted
        column_norm = math.sqrt(gram[h, h])
        rest = math.sqrt(max(gram[h, h] - float(gram[fitted, h] @ coefficients), 0.0))
        both = [*fitted, h]
        if _smallest_singular(gram, both) <= structural:
            held_std.append(math.inf)
        else:
            held_std.append(float(noise * math.sqrt(abs(np.linalg.inv(gram[np.ix_(both, both)])[-1, -1]))
                                  * model.scales[h]))
        combinations.append(_combination(model, fitted, h, coefficients, rest, column_norm))
    # the fitted parameters' combinations: kept where seen to a third of their expected size or better
    values, vectors = np.linalg.eigh(gram[np.ix_(fitted, fitted)]) if fitted else (np.zeros(0), np.zeros((0, 0)))
    singular = np.sqrt(np.maximum(values, 0.0))
    keep = singular >= MIN_INFORMATION * noise
    weak = tuple(_weak_combination(model, fitted, vectors[:, k], noise / max(singular[k], 1e-300))
                 for k in np.flatnonzero(~keep))
    return Identifiability(
        fitted=np.array(fitted, dtype=np.int64), held=np.array(held, dtype=np.int64),
        combinations=tuple(combinations), held_std=np.array(held_std),
        smallest_singular=float(singular[keep].min()) if keep.any() else math.inf,
        basis=vectors[:, keep], weak=weak,
    )


def _weak_combination(model: ErrorModel, fitted: list[int], vector: FloatArray, std: float) -> str:
    """Words for a combination of fitted parameters (a unit vector in their scaled space) held at nominal."""
    terms = []
    for k in np.argsort(-np.abs(vector))[:4]:
        if abs(vector[k]) < 0.1:
            break
        terms.append(f"{vector[k]:+.2f} {model.parameters[fitted[k]].name}")
    return (f"{' '.join(terms)} (in units of their expected errors): the measurements would know it to "
            f"±{std:.2g} of its expected size")


def _combination(model: ErrorModel, fitted: list[int], held: int, coefficients: FloatArray, rest: float,
                 column_norm: float) -> str:
    """Words for what a held parameter moves the tool like: the fitted parameters whose combination
    fits its Jacobian column (the largest four, per unit of it), or that nothing seen moves it."""
    if column_norm <= 1e-9 or rest > 0.5 * column_norm:
        return "not seen by these measurements" if column_norm <= 1e-9 else "too weakly seen by these measurements"
    parameter = model.parameters[held]
    terms = []
    for k in np.argsort(-np.abs(coefficients))[:4]:
        if abs(coefficients[k]) < 0.05:
            break
        other = model.parameters[fitted[k]]
        ratio = coefficients[k] * other.shown(other.scale) / parameter.shown(parameter.scale)
        terms.append(f"{other.name} {ratio:+.3g} {other.unit}/{parameter.unit}")
    return "moves the tool like " + ", ".join(terms)


def initial_frame(model: ErrorModel, obs: Observations) -> ErrorModel:
    """``model`` with the measurement frame that best carries the nominal head's tips onto the measured
    ones (a rigid fit), when it fits the frame; else ``model``."""
    if not model.fit_frame:
        return model
    nominal = predict(model.with_frame(np.eye(3), np.zeros(3)), np.zeros(len(model.parameters)), obs)
    ok = nominal.converged
    rotation, translation = rigid_fit(nominal.tip[ok], obs.tip[ok])
    return model.with_frame(rotation, translation)


def identify(model: ErrorModel, obs: Observations, *, noise: float,
             identifiability: Identifiability | None = None) -> Fit:
    """Identify the head (and with ``model.fit_frame`` the measurement frame) from ``obs``.

    Parameters
    ----------
    model : ErrorModel — the nominal head's
    obs : Observations — measured rows (their tips, and axes when ``obs.has_axis``)
    noise : float — mm, the measurement noise assumed when choosing what can be fitted
    identifiability : Identifiability, optional — the parameters to fit (default: chosen here)

    Returns
    -------
    Fit
    """
    model = initial_frame(model, obs)
    count = len(model.parameters)
    start = np.zeros(count)
    before = residuals_of(model, start, obs)
    if identifiability is None:
        identifiability = select_parameters(model, jacobian(model, start, obs), noise=noise)
    fitted = [int(i) for i in identifiability.fitted]
    basis = identifiability.basis                                  # (K, R): the directions fitted

    def full(x: FloatArray) -> FloatArray:
        out = np.zeros(count)
        out[fitted] = basis @ x
        return out

    def fun(x: FloatArray) -> FloatArray:
        return residual_vector(predict(model, full(x), obs), obs)

    def jac(x: FloatArray) -> FloatArray:
        return jacobian(model, full(x), obs, fitted) @ basis

    rank = basis.shape[1]
    if rank:
        solution = least_squares(fun, np.zeros(rank), jac=jac, method="lm", x_scale=1.0, ftol=1e-12,
                                 xtol=1e-10, gtol=1e-12, max_nfev=60)
        scaled, evaluations = full(solution.x), int(solution.nfev)
        final_jac = jac(solution.x)
        residual = fun(solution.x)
    else:
        scaled, evaluations = start, 0
        final_jac = np.zeros((3 * len(obs), 0))
        residual = fun(np.zeros(0))
    dof = max(len(residual) - rank, 1)
    noise_estimate = float(np.sqrt(residual @ residual / dof))
    covariance = np.zeros((count, count))
    std = np.full(count, math.nan)
    if rank:
        inverse = basis @ np.linalg.inv(final_jac.T @ final_jac) @ basis.T      # (K, K) in the fitted directions
        covariance[np.ix_(fitted, fitted)] = noise_estimate**2 * inverse
        std[fitted] = np.sqrt(np.abs(np.diag(inverse))) * noise_estimate * model.scales[fitted]
    return Fit(model=model, scaled=scaled, std=std, covariance=covariance, identifiability=identifiability,
               before=before, after=residuals_of(model, scaled, obs), noise=noise_estimate, evaluations=evaluations)


def cross_validate(model: ErrorModel, obs: Observations, identifiability: Identifiability, *, folds: int = 5,
                   noise: float, seed: int = 0) -> tuple[Residuals, Residuals]:
    """k-fold hold-out: each row predicted by the nominal head and by the head fitted to the other folds.

    Returns
    -------
    (nominal, fitted) : Residuals — (N,) per row of ``obs``
    """
    n = len(obs)
    fold = np.random.default_rng(seed).permutation(n) % folds
    tip_nominal, tip_fitted = np.zeros(n), np.zeros(n)
    axis_nominal, axis_fitted = np.full(n, math.nan), np.full(n, math.nan)
    for k in range(folds):
        test, train = fold == k, fold != k
        fit = identify(model, obs.rows(train), noise=noise, identifiability=identifiability)
        held_out = obs.rows(test)
        nominal = residuals_of(fit.model, np.zeros(len(model.parameters)), held_out)
        fitted = residuals_of(fit.model, fit.scaled, held_out)
        tip_nominal[test], tip_fitted[test] = nominal.tip, fitted.tip
        axis_nominal[test], axis_fitted[test] = nominal.axis, fitted.axis
    return Residuals(tip=tip_nominal, axis=axis_nominal), Residuals(tip=tip_fitted, axis=axis_fitted)

