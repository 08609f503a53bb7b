"""The accuracy use case (``prs3-post accuracy``) and the main job's header line: what the tool's
position is worth on a machine, to first order (:mod:`prs3_post.kinematics.calibration.propagate`).

The parameters' uncertainty comes from, in this order: a planned calibration with the noise the
user gives (``--noise-mm``: what calibrating would give), the machine file's ``[calibration]``
table (a calibrated machine), or each parameter's expected error (the nominal model of a machine
nobody calibrated).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from prs3_post.core.errors import ConfigError, ReachError
from prs3_post.core.numbers import fixed
from prs3_post.core.toolpath import JointProgram
from prs3_post.core.types import FloatArray
from prs3_post.kinematics.calibration.parameters import error_model
from prs3_post.kinematics.calibration.propagate import covariance_of, pose_uncertainty
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.model import Machine
from prs3_post.post.limits import check_limits

__all__ = ["PLANNED_POSES", "AccuracyMap", "accuracy_json", "accuracy_map", "accuracy_text", "header_accuracy"]

#: Poses of the planned calibration ``accuracy --noise-mm`` assumes.
PLANNED_POSES = 60
#: Degrees: the steps of the map's tilts and azimuths.
TILT_STEP_DEG, AZIMUTH_STEP_DEG = 5.0, 15.0
#: Program rows the header's accuracy line is computed on at most (evenly spaced).
HEADER_SAMPLES = 200


@dataclass(frozen=True, slots=True)
class AccuracyMap:
    """The tool's uncertainty over tilts and azimuths of the tool axis at one tip position.

    Attributes
    ----------
    machine : Machine
    where : (3,) float — mm, the tip's position (machine frame)
    tilt_deg : (T,) float; azimuth_deg : (A,) float — the grid (azimuth counter-clockwise from +x)
    tip, axis : (T, A) float — mm and rad, one standard deviation (NaN: outside a limit)
    tip_parameters, tip_resolution : (T, A) float — mm, the parameters' and the resolution's shares
    source : str — where the parameters' uncertainty comes from, in words
    resolution : float — mm, the actuators' resolution assumed
    """

    machine: Machine
    where: FloatArray
    tilt_deg: FloatArray
    azimuth_deg: FloatArray
    tip: FloatArray
    axis: FloatArray
    tip_parameters: FloatArray
    tip_resolution: FloatArray
    source: str
    resolution: float


def _covariance(machine: Machine, noise: float | None) -> tuple[FloatArray, str]:
    """The parameters' covariance (scaled units²) and where it comes from, in words."""
    model = error_model(machine.geometry)
    if noise is not None:
        from prs3_post.app.calibrate import plan_calibration  # planning: only when asked for

        plan = plan_calibration(machine, PLANNED_POSES, noise=noise)
        return plan.plan.covariance, f"a planned {PLANNED_POSES}-pose calibration measured with {fixed(noise)} mm noise"
    if machine.calibration is not None:
        try:
            return covariance_of(model, machine.calibration), "the machine file's calibration"
        except ValueError as exc:
            raise ConfigError(str(exc), path=machine.source) from exc
    return np.eye(len(model.parameters)), "each parameter's expected error (the machine is not calibrated)"


def accuracy_map(machine: Machine, *, resolution: float, noise: float | None = None,
                 where: tuple[float, float, float] | None = None) -> AccuracyMap:
    """The tool's uncertainty at ``where`` (default: :func:`_middle`) for every tilt
    (every :data:`TILT_STEP_DEG` up to the machine's limit) and azimuth (every :data:`AZIMUTH_STEP_DEG`).

    Raises
    ------
    ReachError
        No pose of the grid is inside every limit there.
    """
    position = np.array(_middle(machine) if where is None else where, dtype=np.float64)
    tilts = np.arange(0.0, math.degrees(machine.limits.max_tilt) + 1e-9, TILT_STEP_DEG)
    azimuths = np.arange(0.0, 360.0, AZIMUTH_STEP_DEG)
    tilt, azimuth = (np.radians(v) for v in np.meshgrid(tilts, azimuths, indexing="ij"))
    axis = np.stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)],
                    axis=-1).reshape(-1, 3)
    tip = np.tile(position, (len(axis), 1))
    ik = kinematics_of(machine).inverse(tip, axis)
    ok = ik.reachable & check_limits(machine, ik, axis).ok
    if not ok.any():
        raise ReachError(f"no tool pose at machine {', '.join(fixed(v, 3) for v in position)} mm is inside every "
                         f"limit of {machine.name}: give a position the tool reaches (--at X,Y,Z)")
    covariance, source = _covariance(machine, noise)
    model = error_model(machine.geometry)
    found = pose_uncertainty(model, ik.strokes[ok], np.full(int(ok.sum()), machine.geometry.tool_length), covariance,
                             resolution=resolution)
    shape = tilt.shape

    def grid(values: FloatArray) -> FloatArray:
        out = np.full(len(axis), np.nan)
        out[ok] = values
        return out.reshape(shape)

    return AccuracyMap(machine=machine, where=position, tilt_deg=tilts, azimuth_deg=azimuths, tip=grid(found.tip),
                       axis=grid(found.axis), tip_parameters=grid(found.tip_parameters),
                       tip_resolution=grid(found.tip_resolution), source=source, resolution=resolution)


def _middle(machine: Machine) -> tuple[float, float, float]:
    """mm: the part origin's x, y at the height of the untilted tool with every stroke at the middle of its
    range (the part origin itself is the part's bottom, where the tool seldom is)."""
    middle = sum(machine.limits.stroke) / 2.0
    fk = kinematics_of(machine).forward(np.full((1, 3), middle))
    z = float(fk.tip[0, 2]) if fk.converged[0] else machine.part_origin[2]
    return machine.part_origin[0], machine.part_origin[1], z


def _stats(values: FloatArray) -> tuple[float, float]:
    finite = values[np.isfinite(values)]
    return (float(np.sqrt(np.mean(finite**2))), float(finite.max())) if len(finite) else (math.nan, math.nan)


def accuracy_text(found: AccuracyMap) -> str:
    """The map as a table: per tilt, the tip's and the axis's uncertainty (RMS and worst over the azimuths)."""
    out = [f"Tool accuracy of {found.machine.name} at machine {', '.join(fixed(v, 3) for v in found.where)} mm "
           f"(1 sigma, first order): parameters from {found.source}; actuators set to "
           f"{fixed(found.resolution)} mm.",
           f"{'tilt deg':>8} {'tip RMS mm':>11} {'tip worst mm':>13} {'params mm':>10} {'resolution mm':>14} "
           f"{'axis RMS deg':>13} {'axis worst deg':>15} {'poses':>6}"]
    for k, tilt in enumerate(found.tilt_deg):
        row = found.tip[k]
        if not np.isfinite(row).any():
            out.append(f"{fixed(tilt, 1):>8} {'outside the limits':>11}")
            continue
        tip_rms, tip_worst = _stats(row)
        axis_rms, axis_worst = _stats(np.degrees(found.axis[k]))
        out.append(f"{fixed(tilt, 1):>8} {fixed(tip_rms):>11} {fixed(tip_worst):>13} "
                   f"{fixed(_stats(found.tip_parameters[k])[0]):>10} {fixed(_stats(found.tip_resolution[k])[0]):>14} "
                   f"{fixed(axis_rms):>13} {fixed(axis_worst):>15} {int(np.isfinite(row).sum()):>6}")
    return "\n".join(out) + "\n"


def accuracy_json(found: AccuracyMap) -> dict[str, Any]:
    """The map as JSON (``accuracy --json``): one record per tilt, and every pose's values."""
    def number(v: float) -> float | None:
        return round(float(v), 6) if math.isfinite(v) else None

    return {
        "machine": found.machine.name, "at_mm": [number(v) for v in found.where], "source": found.source,
        "resolution_mm": found.resolution, "tilt_deg": [number(v) for v in found.tilt_deg],
        "azimuth_deg": [number(v) for v in found.azimuth_deg],
        "tip_mm": [[number(v) for v in row] for row in found.tip],
        "axis_deg": [[number(math.degrees(v)) for v in row] for row in found.axis],
    }


def accuracy_picture(found: AccuracyMap, fmt: str) -> bytes:
    """The map as a polar picture (tilt outward, azimuth around), PNG or SVG bytes."""
    from prs3_post.check.calibration_pictures import accuracy_figure  # matplotlib: only for a picture

    return accuracy_figure(found.tilt_deg, found.azimuth_deg, found.tip, fmt=fmt,
                           title=f"{found.machine.name}: tip uncertainty (1σ, mm) at the part origin")


def header_accuracy(machine: Machine, program: JointProgram, *, resolution: float) -> str | None:
    """The main job's ``accuracy`` header entry, when the machine file carries calibration uncertainties
    (None otherwise): the tip's uncertainty over the program's points (at most :data:`HEADER_SAMPLES`
    of them, evenly spaced)."""
    if machine.calibration is None or not len(program):
        return None
    rows = np.unique(np.linspace(0, len(program) - 1, min(HEADER_SAMPLES, len(program))).round().astype(np.int64))
    strokes = np.asarray(program.strokes, dtype=np.float64)[rows]
    model = error_model(machine.geometry)
    try:
        covariance = covariance_of(model, machine.calibration)
    except ValueError as exc:
        raise ConfigError(str(exc), path=machine.source) from exc
    found = pose_uncertainty(model, strokes, np.full(len(rows), machine.geometry.tool_length), covariance,
                             resolution=resolution)
    rms, worst = _stats(found.tip)
    return (f"expected tip uncertainty {fixed(rms)} mm RMS, {fixed(worst)} mm at most (1 sigma, from the machine "
            f"file's calibration and {fixed(resolution)} mm actuator resolution)")
