"""Inverse and forward kinematics on arrays for a machine given by name (the ``ik`` and ``fk`` use cases).

:func:`inverse_kinematics` and :func:`forward_kinematics` are the library's batch entry points (N poses
at once, no limits checked); :func:`pose_record` and :func:`setting_record` are one pose checked
against every limit of the machine, as the ``ik`` and ``fk`` commands print it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from prs3_post.core.errors import ReachError
from prs3_post.kinematics import FKResult, IKModel, IKResult, unit_axes
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.loading import DEFAULT_MACHINE, Machine, load_machine
from prs3_post.machine.model import GENERAL_KINEMATICS
from prs3_post.post.limits import check_limits

#: The inverse kinematics models ``ik --model`` offers.
IK_MODELS = tuple(model.value for model in IKModel)

__all__ = ["IK_MODELS", "IKModel", "forward_kinematics", "inverse_kinematics", "machine_of", "pose_record",
           "setting_record"]


#: What else stops a head as built (general kinematics) from reaching a pose.
_NEWTON = ", or its Newton iterations from the ideal head's pose did not converge"


def machine_of(machine: Machine | str) -> Machine:
    """``machine`` itself, or the machine a shipped name or a TOML path names (:func:`load_machine`)."""
    return load_machine(machine) if isinstance(machine, str) else machine


def inverse_kinematics(tip: npt.ArrayLike, axis: npt.ArrayLike, *, machine: Machine | str = DEFAULT_MACHINE,
                       model: IKModel | str = IKModel.EXACT) -> IKResult:
    """Stage X, Y and actuator strokes for N tool poses (no limit is checked).

    Parameters
    ----------
    tip : (N, 3) float — mm, tool tip in the machine frame (part-relative, stage included)
    axis : (N, 3) float — tool axes from the tip toward the spindle, any length > 0 (normalized here)
    machine : Machine | str — a loaded machine, a shipped machine's name or a machine TOML path
    model : IKModel | str — ``exact`` (rigid platform and XY stage), ``head`` (no stage) or ``paper``

    Returns
    -------
    IKResult — ``stage`` (N, 2) mm, ``strokes`` (N, 3) mm, ``link_angle`` (N, 3) rad, ``condition`` (N,),
    ``reachable`` (N,) bool

    Raises
    ------
    PoseError
        A tip or axis that is not finite, or an axis of length 0 or pointing down.
    """
    tips = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
    axes = unit_axes(tips, np.asarray(axis, dtype=np.float64).reshape(-1, 3))
    return kinematics_of(machine_of(machine)).inverse(tips, axes, model=IKModel(model))


def forward_kinematics(strokes: npt.ArrayLike, stage: npt.ArrayLike | None = None, *,
                       machine: Machine | str = DEFAULT_MACHINE) -> FKResult:
    """Tool tip and axis for N actuator settings (no limit is checked).

    Parameters
    ----------
    strokes : (N, 3) float — mm, actuator strokes T1..T3 (downward from the base)
    stage : (N, 2) float, optional — mm, stage X, Y (None: zeros, the head's own tip)
    machine : Machine | str — a loaded machine, a shipped machine's name or a machine TOML path

    Returns
    -------
    FKResult — ``tip`` (N, 3) mm, ``axis`` (N, 3) unit, ``converged`` (N,) bool, ``iterations``, ``residual``
    """
    settings = np.asarray(strokes, dtype=np.float64).reshape(-1, 3)
    xy = None if stage is None else np.asarray(stage, dtype=np.float64).reshape(-1, 2)
    return kinematics_of(machine_of(machine)).forward(settings, xy)


def pose_record(machine: Machine, tip: tuple[float, ...], axis: tuple[float, ...], *,
                model: IKModel) -> dict[str, Any]:
    """One pose's IK checked against every limit (the record ``ik`` prints: IK columns, ``ok``, violations).

    Raises
    ------
    PoseError
        A bad tip or axis.
    ReachError
        The head does not assemble there, or (``head``) misses the tip by the parasitic shift.
    """
    from prs3_post.app.pose_tables import ik_records  # the tables: only `ik` and `fk` need them

    tips = np.array([tip])
    axes = unit_axes(tips, np.array([axis]), row_name="pose")
    result = kinematics_of(machine).inverse(tips, axes, model=model)
    if model is IKModel.HEAD and not result.reachable[0] and np.isfinite(result.stage[0]).all():
        dx, dy = result.stage[0]
        raise ReachError(
            f"machine {machine.name} has no stage and its head alone misses this tip by "
            f"{np.hypot(dx, dy):.4f} mm (x {dx:.4f}, y {dy:.4f}): the tilt's parasitic shift must be "
            "matched by the part setup, or use a machine with an XY stage"
        )
    if not result.reachable[0]:
        raise ReachError("this pose cannot be reached: the head does not assemble there (a link cannot reach"
                         f"{_NEWTON if machine.kinematics == GENERAL_KINEMATICS else ''})")
    return ik_records(tips, axes, result, check_limits(machine, result, axes))[0]


def setting_record(machine: Machine, strokes: tuple[float, ...], xy: tuple[float, ...]) -> dict[str, Any]:
    """One actuator setting's FK, checked against every limit as :func:`pose_record` checks a pose.

    Raises
    ------
    ReachError
        Strokes that do not assemble the head.
    """
    from prs3_post.app.pose_tables import fk_records

    kinematics = kinematics_of(machine)
    result = kinematics.forward(np.array([strokes]), np.array([xy]))
    if not result.converged[0]:
        raise ReachError(
            f"strokes {', '.join(f'{s:g}' for s in strokes)} mm do not assemble the head of {machine.name} "
            f"(no rigid platform pose after {result.iterations[0]} Newton steps; "
            f"side-length error {result.residual[0]:.3g} mm)"
        )
    model = IKModel.EXACT if machine.stage.present else IKModel.HEAD
    pose = kinematics.inverse(result.tip, result.axis, model=model)     # the same strokes, checked
    return fk_records(result, check_limits(machine, pose, result.axis))[0]
