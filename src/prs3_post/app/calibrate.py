"""The calibration use cases: plan the poses to measure (``calibrate plan``), identify the head from
measured poses (``calibrate``), and the calibrated machine it gives.

The maths is in :mod:`prs3_post.kinematics.calibration`; this module checks the rows against the
machine's limits, refuses what cannot be calibrated (with the file's line, or the numbers), and puts
the results together (:mod:`prs3_post.app.calibration_report` words and writes them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from prs3_post.core.errors import InputError, ReachError
from prs3_post.core.numbers import fixed
from prs3_post.core.types import FloatArray
from prs3_post.kinematics.calibration.identify import Fit, Residuals, cross_validate, identify, residuals_of
from prs3_post.kinematics.calibration.parameters import ErrorModel, Observations, error_model
from prs3_post.kinematics.calibration.plan import Plan, plan_poses
from prs3_post.kinematics.prs3_general.kinematics import GENERAL_KINEMATICS
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.loading import load_machine
from prs3_post.machine.model import Calibration, Machine
from prs3_post.post.limits import LimitReport, check_limits
from prs3_post.readers.measurements import Measurements, read_measurements

__all__ = ["CalibrationPlan", "CalibrationResult", "calibrate_file", "calibrate_machine", "limit_report",
           "observations_of",
           "plan_calibration"]

#: Candidate poses inside every limit the plan chooses from.
CANDIDATE_POSES = 3000
#: Random stroke settings tried per round when looking for candidates, and the rounds at most.
CANDIDATE_BATCH, CANDIDATE_ROUNDS = 4000, 8
#: Folds of the hold-out validation.
FOLDS = 5
#: mm: measured tips this far (RMS) from where the nominal head puts them are not this machine's, or
#: not in its frame (``--fit-frame`` identifies the frame).
MISMATCH_BEFORE_MM = 25.0
#: mm: what a calibration leaves (RMS) when the file and the machine belong together: the noise and
#: what no geometry explains (a bent link, backlash) are far below.
MISMATCH_AFTER_MM = 0.5


@dataclass(frozen=True, slots=True)
class CalibrationPlan:
    """The poses ``calibrate plan`` chose, and what measuring them will determine.

    Attributes
    ----------
    machine : Machine
    strokes : (n, 3) float — mm; stage : (n, 2) float — mm; tool_length : (n,) float — mm, "TL"
    model : ErrorModel
    plan : Plan — the choice and the expected standard deviations
    noise : float — mm, the measurement noise assumed
    axes : bool — the tool axis will be measured
    tool_lengths : bool — the rows use more than one tool (the CSV gets ``tool_length_mm``)
    candidates : int — how many poses inside every limit it chose from
    """

    machine: Machine
    strokes: FloatArray
    stage: FloatArray
    tool_length: FloatArray
    model: ErrorModel
    plan: Plan
    noise: float
    axes: bool
    tool_lengths: bool
    candidates: int


@dataclass(frozen=True, slots=True)
class CalibrationResult:
    """A calibration: the fit, its validation and the calibrated machine.

    Attributes
    ----------
    machine : Machine — the nominal machine
    measurements : Measurements
    fit : Fit
    holdout : (Residuals, Residuals) | None — k-fold hold-out, per row: nominal and calibrated head
        (None: too few rows for it)
    validation : (Measurements, Residuals, Residuals) | None — another file's rows: nominal and calibrated
    calibrated : Machine — the identified machine (kinematics ``3-prs-general``, ``calibration`` set)
    noise : float — mm, the noise assumed to choose the parameters
    """

    machine: Machine
    measurements: Measurements
    fit: Fit
    holdout: tuple[Residuals, Residuals] | None
    validation: tuple[Measurements, Residuals, Residuals] | None
    calibrated: Machine
    noise: float


def limit_report(machine: Machine, strokes: FloatArray, stage: FloatArray,
                 tool_length: FloatArray | None = None) -> tuple[LimitReport, np.ndarray]:
    """Every limit of ``machine`` at commanded strokes (N, 3) and stage (N, 2), and which rows assemble.

    Returns
    -------
    (LimitReport, (N,) bool) — the report (NaN values where the head does not assemble) and the mask of
    rows forward kinematics placed
    """
    kinematics = kinematics_of(machine)
    fk = kinematics.forward(strokes, stage)
    tip = np.where(fk.converged[:, None], fk.tip, 0.0)
    axis = np.where(fk.converged[:, None], fk.axis, np.array([0.0, 0.0, 1.0]))
    ik = kinematics.inverse(tip, axis)
    ik = replace(ik, stage=np.asarray(stage, dtype=np.float64), strokes=np.asarray(strokes, dtype=np.float64),
                 condition=np.where(fk.converged, ik.condition, np.nan))
    return check_limits(machine, ik, axis), fk.converged


def _stage_home(machine: Machine) -> tuple[float, float]:
    """mm, the stage position the plan measures at: 0, 0, or the travel's middle where 0 is outside it."""
    if not machine.stage.present:
        return 0.0, 0.0
    return tuple(0.0 if low <= 0.0 <= high else (low + high) / 2.0   # type: ignore[return-value]
                 for low, high in (machine.stage.travel_x, machine.stage.travel_y))


def plan_calibration(machine: Machine, poses: int, *, noise: float, axes: bool = True,
                     tool_lengths: tuple[float, ...] = (), fit_frame: bool = False, seed: int = 0) -> CalibrationPlan:
    """Choose ``poses`` measurement poses inside every limit of ``machine`` (D-optimal:
    :mod:`prs3_post.kinematics.calibration.plan`).

    Parameters
    ----------
    machine : Machine
    poses : int — how many
    noise : float — mm, the measurement noise expected
    axes : bool — the tool axis will be measured too
    tool_lengths : tuple of float — mm, tool lengths "TL" to measure with (empty: the machine's)
    fit_frame : bool — the measurement frame will be identified too
    seed : int — the random candidates' seed (the same seed, the same plan)

    Raises
    ------
    ReachError
        Fewer candidate poses inside the limits than asked for.
    """
    rng = np.random.default_rng(seed)
    low, high = machine.limits.stroke
    home = _stage_home(machine)
    found: list[FloatArray] = []
    total = 0
    for _ in range(CANDIDATE_ROUNDS):
        strokes = rng.uniform(low, high, (CANDIDATE_BATCH, 3))
        stage = np.tile(home, (CANDIDATE_BATCH, 1))
        report, placed = limit_report(machine, strokes, stage)
        keep = strokes[report.ok & placed]
        found.append(keep)
        total += len(keep)
        if total >= CANDIDATE_POSES:
            break
    strokes = np.concatenate(found)[:CANDIDATE_POSES]
    lengths = tool_lengths or (machine.geometry.tool_length,)
    count = len(strokes)
    if count * len(lengths) < poses:
        raise ReachError(f"only {count * len(lengths)} candidate poses inside every limit of {machine.name} were "
                         f"found for {poses} poses: ask for fewer")
    candidates = Observations(
        strokes=np.tile(strokes, (len(lengths), 1)), stage=np.tile(home, (count * len(lengths), 1)),
        tool_length=np.repeat(np.array(lengths, dtype=np.float64), count),
        tip=np.full((count * len(lengths), 3), math.nan), axis=np.full((count * len(lengths), 3), math.nan),
        has_axis=axes)
    model = error_model(machine.geometry, fit_frame=fit_frame)
    plan = plan_poses(model, candidates, poses, noise=noise)
    chosen = candidates.rows(plan.index)
    order = np.lexsort((chosen.strokes[:, 2], chosen.strokes[:, 1], chosen.strokes[:, 0], chosen.tool_length))
    return CalibrationPlan(machine=machine, strokes=chosen.strokes[order], stage=chosen.stage[order],
                           tool_length=chosen.tool_length[order], model=model, plan=plan, noise=noise, axes=axes,
                           tool_lengths=len(lengths) > 1, candidates=count * len(lengths))


def observations_of(machine: Machine, measurements: Measurements) -> Observations:
    """The measured rows as the identification takes them (a row without a tool length: the machine's)."""
    length = np.where(np.isnan(measurements.tool_length), machine.geometry.tool_length, measurements.tool_length)
    return Observations(strokes=measurements.strokes, stage=measurements.stage, tool_length=length,
                        tip=measurements.tip, axis=measurements.axis, has_axis=measurements.has_axis)


def check_rows(machine: Machine, measurements: Measurements) -> None:
    """Refuse the first row that does not assemble the head or is outside a limit (or moves a stage the
    machine does not have), naming its line.

    Raises
    ------
    InputError
    """
    if not machine.stage.present:
        moved = np.flatnonzero(np.any(measurements.stage != 0.0, axis=1))
        if len(moved):
            row = int(moved[0])
            x, y = (fixed(float(v)) for v in measurements.stage[row])
            raise InputError(f"stage x, y = {x}, {y} mm, but {machine.name} has no stage (stage.present = false): "
                             "leave x, y at 0 or out", path=measurements.path, line=int(measurements.line[row]))
    report, placed = limit_report(machine, measurements.strokes, measurements.stage)
    bad = np.flatnonzero(~placed | ~report.ok)
    if not len(bad):
        return
    row = int(bad[0])
    others = f" ({len(bad)} rows in all)" if len(bad) > 1 else ""
    where = dict(path=measurements.path, line=int(measurements.line[row]))
    if not placed[row]:
        raise InputError(f"strokes {', '.join(fixed(v) for v in measurements.strokes[row])} mm do not assemble the "
                         f"head of {machine.name}{others}: not a pose of this machine", **where)  # type: ignore[arg-type]
    column = int(np.flatnonzero(~(report.margin[row] >= 0.0))[0])
    raise InputError(f"outside the limits of {machine.name}: {report.describe(row, column)}{others}",
                     **where)  # type: ignore[arg-type]


def _rows_needed(model: ErrorModel, has_axis: bool) -> int:
    """How many parameters measurements of this kind can determine at best: the model's, less the
    combinations no pose separates (each rail point along its rail, the platform frame's six, the tool
    axis without axes)."""
    unseen = 3 + 6 + (0 if has_axis else 2)
    return len(model.parameters) - unseen - (6 if model.fit_frame else 0)


def calibrate_machine(machine: Machine, measurements: Measurements, *, noise: float, fit_frame: bool = False,
                      validate: Measurements | None = None, folds: int = FOLDS) -> CalibrationResult:
    """Identify ``machine``'s head from ``measurements`` (see :mod:`prs3_post.kinematics.calibration.identify`).

    Parameters
    ----------
    machine : Machine — the nominal machine (ideal or general)
    measurements : Measurements
    noise : float — mm, the measurement noise assumed when choosing what can be fitted
    fit_frame : bool — the measurements are in an unknown frame: identify it too
    validate : Measurements, optional — other rows to check the calibrated head on
    folds : int — folds of the hold-out validation

    Raises
    ------
    InputError
        A row outside the limits (its line), fewer rows than the parameters to identify, a fit that says
        the file and the machine do not belong together (with the numbers).
    """
    check_rows(machine, measurements)
    if validate is not None:
        check_rows(machine, validate)
    model = error_model(machine.geometry, fit_frame=fit_frame)
    obs = observations_of(machine, measurements)
    needed = _rows_needed(model, obs.has_axis)
    if len(obs) < needed:
        raise InputError(f"{len(obs)} measured poses are fewer than the {needed} parameters that "
                         f"{'tips and axes' if obs.has_axis else 'tips'} can identify: measure at least {needed} poses "
                         f"(prs3-post calibrate plan --poses N makes a plan)", path=measurements.path)
    fit = identify(model, obs, noise=noise)
    _check_belongs(machine, measurements, fit)
    holdout = None
    if len(obs) * (folds - 1) // folds >= needed:
        holdout = cross_validate(model, obs, fit.identifiability, folds=folds, noise=noise)
    validation = None
    if validate is not None:
        other = observations_of(machine, validate)
        validation = (validate, residuals_of(fit.model, np.zeros(len(model.parameters)), other),
                      residuals_of(fit.model, fit.scaled, other))
    return CalibrationResult(machine=machine, measurements=measurements, fit=fit, holdout=holdout,
                             validation=validation, calibrated=calibrated_machine(machine, fit), noise=noise)


def calibrate_file(machine: Machine | str, path: str, *, noise: float, fit_frame: bool = False,
                   validate_path: str | None = None) -> CalibrationResult:
    """:func:`calibrate_machine` of the measurement CSV ``path`` (and ``validate_path``), for a machine
    or its shipped name or TOML path.

    Raises
    ------
    InputError
        As :func:`~prs3_post.readers.measurements.read_measurements` and :func:`calibrate_machine`.
    ConfigError
        The machine file.
    """
    machine = load_machine(machine) if isinstance(machine, str) else machine
    measurements = read_measurements(path)
    validate = read_measurements(validate_path) if validate_path else None
    return calibrate_machine(machine, measurements, noise=noise, fit_frame=fit_frame, validate=validate)


def _check_belongs(machine: Machine, measurements: Measurements, fit: Fit) -> None:
    """Refuse a fit whose residuals say the file was not measured on this machine (or not in its frame)."""
    before, after = fit.before, fit.after
    worst = int(measurements.line[after.worst_row])
    if not fit.model.fit_frame and before.tip_rms > MISMATCH_BEFORE_MM:
        raise InputError(
            f"the measured tips are {fixed(before.tip_rms, 1)} mm (RMS) from where {machine.name} puts them at these "
            f"strokes (its errors are some millimetres): the file and the machine do not belong together, or the "
            f"tips are not in the machine frame (--fit-frame identifies the measurement frame)", path=measurements.path)
    if after.tip_rms > MISMATCH_AFTER_MM:
        raise InputError(
            f"after identifying the head the tips still miss by {fixed(after.tip_rms, 3)} mm RMS (worst "
            f"{fixed(float(after.tip[after.worst_row]), 3)} mm at line {worst}; "
            f"before: {fixed(before.tip_rms, 3)} mm): "
            f"no geometry of {machine.name} explains these measurements (a calibration leaves the noise, "
            f"well under {fixed(MISMATCH_AFTER_MM, 1)} mm): the file and the machine do not belong together",
            path=measurements.path)


def calibrated_machine(machine: Machine, fit: Fit) -> Machine:
    """``machine`` with the identified head, the general kinematics and the identified parameters' uncertainties."""
    fitted = [int(i) for i in fit.identifiability.fitted]
    parameters = [fit.model.parameters[i] for i in fitted]
    covariance = fit.covariance[np.ix_(fitted, fitted)]
    scaled_std = np.sqrt(np.diag(covariance))
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = covariance / np.outer(scaled_std, scaled_std)
    correlation = np.where(np.isfinite(correlation), correlation, 0.0)
    np.fill_diagonal(correlation, 1.0)
    calibration = Calibration(
        parameters=tuple(p.name for p in parameters),
        std=tuple(float(p.shown(fit.std[i])) for p, i in zip(parameters, fitted, strict=True)),
        correlation=tuple(tuple(float(v) for v in row) for row in correlation),
        noise=fit.noise,
    )
    return replace(machine, geometry=fit.head, kinematics=GENERAL_KINEMATICS, calibration=calibration)


def worst_line(measurements: Measurements, residuals: Residuals) -> int:
    """The file line of the row with the largest tip error."""
    return int(measurements.line[residuals.worst_row])

