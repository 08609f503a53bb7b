"""The Kinematics protocol: what the stages above ask of a machine's kinematics.

A machine file names its kinematics (``kinematics = "3-prs"``) and
:func:`prs3_post.kinematics.registry.kinematics_of` gives the object for a loaded machine. The
emitter, the program reader, verify, limits, dynamics, collision, placement and the ``ik``/``fk``
tables take the joints' names, letters and count from it; none of them names a joint itself.

A program row is the stage X, Y (mm) and one value per joint (mm: the joints are linear axes),
in the order of :attr:`Kinematics.joint_names`; ``IKResult.strokes`` and the ``joints`` given to
:meth:`Kinematics.forward` are (N, J). Where a common shift s of every joint moves the whole head by
s along one direction and changes nothing else (:attr:`Kinematics.shift_direction`: −z on a head
whose joints slide on parallel vertical guides), the replay computes FK once per distinct pose up to
such a shift (:mod:`prs3_post.kinematics.replay`); where it does not (None: a head as built, whose
rails are not quite parallel), once per distinct joint row.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from prs3_post.core.rowwise import same_rows
from prs3_post.core.types import FloatArray
from prs3_post.kinematics import AxisMemo, FKResult, IKModel, IKResult
from prs3_post.machine.dialect import AxisLetters
from prs3_post.machine.model import Limits

__all__ = ["Kinematics", "LimitColumns", "joint_letters", "tilt_of"]

#: Limits of the joints, grouped by the bounds they share: (names, unit, low, high, values (N, one
#: column per name)); units ``mm``, ``deg`` (values in rad) or ``""``.
LimitColumns = list[tuple[tuple[str, ...], str, float, float, FloatArray]]


class Kinematics(Protocol):
    """A machine's kinematics: its joints, inverse and forward kinematics, the limits of its joints.

    Attributes
    ----------
    name : str — the name machine files use (``3-prs``)
    joint_names : (J,) str — each joint's name in messages, tables and the header (``T1``)
    default_letters : (J,) str — each joint's word letter unless the dialect names one (``U``)
    link_length : float — mm, the length an angle of ``link_angle`` counts as in the replay's
        curvature (a link end moves that far per radian)
    shift_direction : (3,) tuple | None — unit: the head moves by s along it when every joint grows
        by s, and nothing else changes ((0, 0, −1) on parallel vertical guides); None: no such direction
    """

    @property
    def name(self) -> str: ...

    @property
    def joint_names(self) -> tuple[str, ...]: ...

    @property
    def default_letters(self) -> tuple[str, ...]: ...

    @property
    def link_length(self) -> float: ...

    @property
    def shift_direction(self) -> tuple[float, float, float] | None: ...

    def inverse(self, tip: FloatArray, axis: FloatArray, *, model: IKModel = IKModel.EXACT,
                memo: AxisMemo | None = None) -> IKResult:
        """Tips (N, 3) mm and unit axes (N, 3) → stage (N, 2), joints ``strokes`` (N, J), link angles,
        condition numbers (N,) and the ``reachable`` mask (N,)."""
        ...

    def forward(self, joints: FloatArray, stage: FloatArray | None = None) -> FKResult:
        """Joints (N, J) mm and stage (N, 2) mm → tip (N, 3), axis (N, 3), converged, iterations, residual."""
        ...

    def condition(self, tip: FloatArray, axis: FloatArray) -> FloatArray:
        """(N,) the Jacobian's condition number at tips and unit axes (N, 3) (NaN where no pose)."""
        ...

    def limit_columns(self, limits: Limits, ik: IKResult, axis: FloatArray) -> LimitColumns:
        """The limit columns of N IK results and their unit axes (N, 3), in the order reports list
        them (the stage's travel follows them: it is the machine's)."""
        ...


def joint_letters(names: tuple[str, ...], defaults: tuple[str, ...], axes: AxisLetters) -> tuple[str, ...]:
    """The word letter of each joint: the dialect's letter for it (``[axes]`` keys are the joint
    names in lower case: ``t1 = "U"``), else the kinematics' default (``names`` and ``defaults``:
    :attr:`Kinematics.joint_names` and :attr:`Kinematics.default_letters`).

    Raises
    ------
    ValueError
        Two axes (stage X, Y and the joints) would be written with one letter.
    """
    letters = tuple(getattr(axes, name.lower(), default) for name, default in zip(names, defaults, strict=True))
    every = (axes.x, axes.y, *letters)
    if len(set(every)) != len(every):
        raise ValueError(f"axis letters must be distinct: stage X Y and {' '.join(names)} "
                         f"would be {' '.join(every)}")
    return letters


def tilt_of(axis: FloatArray) -> FloatArray:
    """(N,) float — rad, the angle of each unit tool axis (N, 3) from the machine's vertical.

    Rows that all have the bits of the first (a 3+2 chunk) take its angle, computed once.
    """
    axis = np.asarray(axis, dtype=np.float64).reshape(-1, 3)
    if len(axis) > 1 and same_rows(axis):
        return np.full(len(axis), tilt_of(axis[:1])[0])
    return np.arccos(np.clip(axis[:, 2], -1.0, 1.0))   # clip: rounding
