"""The general 3-PRS head (each leg with its own geometry) as a
:class:`~prs3_post.kinematics.protocol.Kinematics`: strokes T1, T2, T3 (letters U, V, W), as the ideal head's.

Machine files name it ``kinematics = "3-prs-general"``; their ``[[legs]]`` tables describe the head
as built (:class:`~prs3_post.machine.model.GeneralGeometry`); without them it is the ideal head of
``[geometry]``, solved by the general kinematics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from prs3_post.core.errors import PoseError
from prs3_post.core.types import FloatArray
from prs3_post.kinematics import HEAD_XY_TOL, AxisMemo, FKResult, IKModel, IKResult
from prs3_post.kinematics.protocol import LimitColumns, tilt_of
from prs3_post.kinematics.prs3_general.forward import forward_general
from prs3_post.kinematics.prs3_general.inverse import inverse_general
from prs3_post.machine.model import GENERAL_KINEMATICS, GeneralGeometry, Geometry, Limits

__all__ = ["GENERAL_KINEMATICS", "Prs3GeneralKinematics"]


@dataclass(frozen=True, slots=True)
class Prs3GeneralKinematics:
    """The general 3-PRS head of :mod:`prs3_post.kinematics.prs3_general` (Newton IK and FK from the
    ideal closed form); the IK models ``exact`` and ``head`` (``paper`` is the ideal head's alone)."""

    geometry: Geometry
    name: ClassVar[str] = GENERAL_KINEMATICS
    joint_names: ClassVar[tuple[str, ...]] = ("T1", "T2", "T3")
    default_letters: ClassVar[tuple[str, ...]] = ("U", "V", "W")

    @property
    def general(self) -> GeneralGeometry:
        """The head as built (the ideal head's legs when the machine file gives none)."""
        return self.geometry.general_geometry()

    @property
    def shift_direction(self) -> tuple[float, float, float] | None:
        """The rails' direction when all three are parallel (adding s to every stroke moves every revolute
        joint, so the whole head, by s along it); None when they are not (a common shift then tilts the head)."""
        first, *others = (leg.rail_direction for leg in self.general.legs)
        return first if all(other == first for other in others) else None

    @property
    def link_length(self) -> float:
        """mm, the mean of the three link lengths."""
        return sum(leg.link_length for leg in self.general.legs) / 3.0

    def inverse(self, tip: FloatArray, axis: FloatArray, *, model: IKModel = IKModel.EXACT,
                memo: AxisMemo | None = None) -> IKResult:
        """:func:`~prs3_post.kinematics.prs3_general.inverse.inverse_general` (``memo``: no effect).

        Raises
        ------
        PoseError
            ``model`` is ``paper``: the paper's per-leg method exists for the ideal head only.
        """
        if model is IKModel.PAPER:
            raise PoseError(f"the paper's IK model exists for the ideal head only (kinematics = \"3-prs\"), "
                            f"not for {GENERAL_KINEMATICS} (use the model exact or head)")
        result = inverse_general(self.general, tip, axis).ik_result()
        if model is IKModel.HEAD:
            with np.errstate(invalid="ignore"):
                on_target = np.hypot(result.stage[:, 0], result.stage[:, 1]) <= HEAD_XY_TOL
            return IKResult(stage=result.stage, strokes=result.strokes, link_angle=result.link_angle,
                            condition=result.condition, reachable=result.reachable & on_target)
        return result

    def forward(self, joints: FloatArray, stage: FloatArray | None = None) -> FKResult:
        """:func:`~prs3_post.kinematics.prs3_general.forward.forward_general`."""
        return forward_general(self.general, joints, stage).fk_result()

    def condition(self, tip: FloatArray, axis: FloatArray) -> FloatArray:
        """The actuator Jacobian's condition number (general IK)."""
        return inverse_general(self.general, tip, axis).condition

    def limit_columns(self, limits: Limits, ik: IKResult, axis: FloatArray) -> LimitColumns:
        """Each stroke and each link angle (one bound for all three legs), the tilt, the condition number."""
        return [
            (tuple(f"{name} stroke" for name in self.joint_names), "mm", *limits.stroke, ik.strokes),
            (tuple(f"θ{leg + 1} link angle" for leg in range(3)), "deg", *limits.link_angle, ik.link_angle),
            (("tilt",), "deg", -math.inf, limits.max_tilt, tilt_of(axis)[:, None]),
            (("condition number",), "", -math.inf, limits.max_condition, ik.condition[:, None]),
        ]
