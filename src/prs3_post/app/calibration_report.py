"""The calibration's words and files: the plan's CSV and summary, the calibration's summary and JSON
report, and the calibrated machine file (:mod:`prs3_post.app.calibrate` computes them)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from prs3_post.app.calibrate import CalibrationPlan, CalibrationResult
from prs3_post.core.numbers import fixed
from prs3_post.kinematics.calibration.identify import MIN_INFORMATION, Identifiability, Residuals
from prs3_post.kinematics.calibration.parameters import ErrorModel
from prs3_post.kinematics.calibration.residuals import AXIS_LEVER_MM
from prs3_post.machine.writing import machine_toml
from prs3_post.readers.measurements import MEASUREMENT_COLUMNS, Measurements

__all__ = ["CRITERION", "calibrated_toml", "calibration_json", "calibration_text", "plan_csv", "plan_json",
           "plan_text"]

#: The plan's criterion, as reports state it.
CRITERION = ("D-optimal: the chosen poses maximise det(I + JᵀJ/σ²) of the scaled identification Jacobian J "
             "(parameters in units of their expected errors, σ the measurement noise)")
#: How the fitted parameters are chosen, as reports state it.
IDENTIFIABILITY = (f"a parameter is fitted when the smallest singular value of the fitted parameters' scaled Jacobian "
                   f"stays ≥ {MIN_INFORMATION:g}× the noise (each combination known to a third of its expected error); "
                   f"the others are held at nominal")


# ----------------------------------------------------------------------------- plan


def plan_csv(plan: CalibrationPlan) -> str:
    """The plan as a measurement CSV with the measured cells empty, ready to be filled in."""
    columns = [c for c in MEASUREMENT_COLUMNS if (plan.axes or c not in ("ax", "ay", "az"))
               and (plan.tool_lengths or c != "tool_length_mm")]
    lines = [",".join(columns)]
    for row in range(len(plan.strokes)):
        values = {"t1": plan.strokes[row, 0], "t2": plan.strokes[row, 1], "t3": plan.strokes[row, 2],
                  "x": plan.stage[row, 0], "y": plan.stage[row, 1], "tool_length_mm": plan.tool_length[row]}
        lines.append(",".join(fixed(float(values[c])) if c in values else "" for c in columns))
    return "\n".join(lines) + "\n"


def _parameter_rows(model: ErrorModel, std: np.ndarray, values: np.ndarray | None = None) -> list[dict[str, Any]]:
    """The fitted parameters (finite ``std``): name, unit, expected error, the deviation found (``values``), std."""
    return [{"name": p.name, "unit": p.unit, "expected_error": _round(p.shown(p.scale))}
            | ({} if values is None else {"value": _round(p.shown(values[i]))}) | {"std": _round(p.shown(std[i]))}
            for i, p in enumerate(model.parameters) if math.isfinite(std[i])]


def _held_rows(model: ErrorModel, found: Identifiability) -> list[dict[str, Any]]:
    return [{"name": model.parameters[h].name, "unit": model.parameters[h].unit,
             "std_if_fitted": _round(model.parameters[h].shown(s)) if math.isfinite(s) else None, "why": why}
            for h, why, s in zip(found.held, found.combinations, found.held_std, strict=True)]


def _round(value: float, digits: int = 6) -> float:
    """A report's number: six decimals (mm: a nanometre)."""
    return round(float(value), digits)


def plan_json(plan: CalibrationPlan) -> dict[str, Any]:
    """The plan's report (``calibrate plan --report``)."""
    found = plan.plan.identifiability
    return {
        "machine": plan.machine.name, "poses": len(plan.strokes), "candidates": plan.candidates,
        "criterion": CRITERION, "log_det": _round(plan.plan.log_det, 3), "noise_mm": plan.noise,
        "axes_measured": plan.axes, "tool_lengths_mm": sorted({float(v) for v in plan.tool_length}),
        "smallest_singular_value_mm": _round(found.smallest_singular),
        "identifiability": IDENTIFIABILITY,
        "expected_std": _parameter_rows(plan.model, plan.plan.std),
        "held": _held_rows(plan.model, found), "weak_combinations": list(found.weak),
    }


def plan_text(plan: CalibrationPlan) -> str:
    """The plan's summary for people: what it chose, the expected uncertainty of each parameter."""
    found = plan.plan.identifiability
    tools = ", ".join(fixed(v, 1) for v in sorted(set(plan.tool_length)))
    out = [f"{len(plan.strokes)} poses chosen from {plan.candidates} inside every limit of {plan.machine.name} "
           f"(D-optimal; log det {fixed(plan.plan.log_det, 1)}), measuring the tip"
           f"{' and the axis' if plan.axes else ''}"
           f"{' with tools ' + tools + ' mm' if plan.tool_lengths else ''}.",
           f"Expected standard deviations with {fixed(plan.noise)} mm measurement noise "
           f"({len(found.fitted)} parameters identifiable; smallest singular value "
           f"{fixed(found.smallest_singular, 3)} mm):"]
    out += _parameter_table(plan.model, plan.plan.std)
    out += _held_text(plan.model, found)
    return "\n".join(out) + "\n"


def _parameter_table(model: ErrorModel, std: np.ndarray, values: np.ndarray | None = None) -> list[str]:
    out = []
    for i, p in enumerate(model.parameters):
        if not math.isfinite(std[i]):
            continue
        value = "" if values is None else f"{fixed(p.shown(values[i]), 4):>10} "
        out.append(f"  {p.name:30s} {value}± {fixed(p.shown(std[i]), 4)} {p.unit}")
    return out


def _held_text(model: ErrorModel, found: Identifiability) -> list[str]:
    out = []
    if len(found.held):
        out.append("Held at nominal (no measurement of this kind separates them):")
        out += [f"  {model.parameters[h].name}: {why}" for h, why in zip(found.held, found.combinations, strict=True)]
    if found.weak:
        out.append("Combinations held at nominal (seen too weakly by these poses):")
        out += [f"  {text}" for text in found.weak]
    return out


# ----------------------------------------------------------------------------- calibration


def _residual_json(res: Residuals, measurements: Measurements) -> dict[str, Any]:
    out: dict[str, Any] = {"tip_rms_mm": _round(res.tip_rms), "tip_worst_mm": _round(float(np.max(res.tip))),
                           "tip_worst_line": int(measurements.line[res.worst_row])}
    if measurements.has_axis:
        out["axis_rms_deg"] = _round(math.degrees(res.axis_rms))
        out["axis_worst_deg"] = _round(math.degrees(float(np.nanmax(res.axis))))
    return out


def calibration_json(result: CalibrationResult) -> dict[str, Any]:
    """The calibration's report (``calibrate --report``)."""
    fit, m = result.fit, result.measurements
    found = fit.identifiability
    out: dict[str, Any] = {
        "machine": result.machine.name, "measurements": m.path, "rows": len(m.line), "axes_measured": m.has_axis,
        "axis_residual_lever_mm": AXIS_LEVER_MM, "fit_frame": fit.model.fit_frame,
        "noise_mm": {"assumed": result.noise, "estimated": _round(fit.noise)},
        "before": _residual_json(fit.before, m), "after": _residual_json(fit.after, m),
        "identifiability": IDENTIFIABILITY,
        "smallest_singular_value_mm": _round(found.smallest_singular),
        "parameters": _parameter_rows(fit.model, fit.std, fit.values),
        "held": _held_rows(fit.model, found), "weak_combinations": list(found.weak),
        "holdout": None, "validation": None, "frame": None, "evaluations": fit.evaluations,
    }
    if result.holdout is not None:
        out["holdout"] = {"method": "5-fold", "before": _residual_json(result.holdout[0], m),
                          "after": _residual_json(result.holdout[1], m)}
    if result.validation is not None:
        other, nominal, calibrated = result.validation
        out["validation"] = {"measurements": other.path, "rows": len(other.line),
                             "before": _residual_json(nominal, other), "after": _residual_json(calibrated, other)}
    if fit.model.fit_frame:
        rotation, translation = fit.model.frame(fit.scaled)
        out["frame"] = {"rotation": [[_round(v, 9) for v in row] for row in rotation],
                        "translation_mm": [_round(v) for v in translation]}
    return out


def _residual_line(name: str, res: Residuals, measurements: Measurements) -> str:
    text = (f"  {name:9s} tip RMS {fixed(res.tip_rms)} mm, worst {fixed(float(np.max(res.tip)))} mm "
            f"(line {int(measurements.line[res.worst_row])})")
    if measurements.has_axis:
        text += f"; axis RMS {fixed(math.degrees(res.axis_rms))} deg"
    return text


def calibration_text(result: CalibrationResult) -> str:
    """The calibration's summary for people."""
    fit, m = result.fit, result.measurements
    found = fit.identifiability
    out = [f"Calibrated {result.machine.name} from {len(m.line)} measured poses of {m.path} "
           f"({'tips and axes' if m.has_axis else 'tips only'}"
           f"{', measurement frame identified' if fit.model.fit_frame else ''}):",
           _residual_line("before", fit.before, m), _residual_line("after", fit.after, m)]
    if result.holdout is not None:
        out += ["Hold-out (5-fold: each row predicted by the head fitted to the others):",
                _residual_line("nominal", result.holdout[0], m), _residual_line("calibrated", result.holdout[1], m)]
    else:
        out.append("Hold-out: too few rows for a 5-fold validation (give --validate OTHER.csv)")
    if result.validation is not None:
        other, nominal, calibrated = result.validation
        out += [f"Validation on {len(other.line)} poses of {other.path}:",
                _residual_line("nominal", nominal, other), _residual_line("calibrated", calibrated, other)]
    out.append(f"Noise: estimated {fixed(fit.noise)} mm (assumed {fixed(result.noise)} mm to choose the parameters).")
    out.append(f"{len(found.fitted)} parameters identified (deviation from nominal ± standard deviation):")
    out += _parameter_table(fit.model, fit.std, fit.values)
    out += _held_text(fit.model, found)
    return "\n".join(out) + "\n"


def calibrated_toml(result: CalibrationResult, *, date: str) -> str:
    """The calibrated machine file: ``result.calibrated`` with a comment block saying where it comes from.

    Parameters
    ----------
    result : CalibrationResult
    date : str — when it was identified (``2026-12-06``)
    """
    fit, m = result.fit, result.measurements
    machine = replace(result.calibrated, description=f"{result.machine.description} (calibrated from "
                                                     f"{Path(m.path).name}, {date})")
    held = ", ".join(fit.model.parameters[h].name for h in fit.identifiability.held) or "none"
    weak = len(fit.identifiability.weak)
    axis = (f"; axis RMS {fixed(math.degrees(fit.before.axis_rms))} → {fixed(math.degrees(fit.after.axis_rms))} deg"
            if m.has_axis else "")
    comment = [
        f"Machine {result.machine.name} as calibrated by prs3-post calibrate (machine file: {result.machine.source}).",
        f"Identified from {m.path} ({len(m.line)} measured poses, {'tips and axes' if m.has_axis else 'tips only'}) "
        f"on {date}.",
        f"Tip residuals: RMS {fixed(fit.before.tip_rms)} mm before, {fixed(fit.after.tip_rms)} mm after; worst "
        f"{fixed(float(np.max(fit.before.tip)))} mm before, {fixed(float(np.max(fit.after.tip)))} mm after{axis}.",
        f"Noise estimate: {fixed(fit.noise)} mm (one coordinate, one standard deviation).",
    ]
    if result.holdout is not None:
        comment.append(f"Hold-out (5-fold) tip RMS: {fixed(result.holdout[1].tip_rms)} mm "
                       f"(nominal head: {fixed(result.holdout[0].tip_rms)} mm).")
    comment += [f"{len(fit.identifiability.fitted)} parameters identified; held at nominal: {held}"
                f"{f'; and {weak} weakly seen combinations' if weak else ''}.",
                "Limits, stage, setup, dynamics and holder are the machine file's."]
    return machine_toml(machine, comment=comment)


def residual_picture(result: CalibrationResult, fmt: str) -> bytes:
    """``calibrate --preview``: each row's tip error before and after (and held out), as PNG or SVG bytes."""
    from prs3_post.check.calibration_pictures import residual_figure  # matplotlib: only for a picture

    m, fit = result.measurements, result.fit
    return residual_figure(m.line, fit.before.tip, fit.after.tip,
                           None if result.holdout is None else result.holdout[1].tip,
                           title=f"{result.machine.name} calibrated from {Path(m.path).name}: tip errors", fmt=fmt)
