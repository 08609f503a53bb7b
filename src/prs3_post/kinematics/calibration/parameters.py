"""The error model: the parameters of a general 3-PRS head that calibration identifies, and how
each is scaled.

Every parameter is a small deviation from a nominal head (the machine file's), measured along a
direction fixed at the nominal, in code units (mm, rad). Identification works on *scaled*
deviations: a deviation divided by the size its error is expected to have (:data:`ERROR_SIZES`:
rail points ±0.5 mm, directions and axes ±0.1°, link lengths ±0.2 mm, platform joints ±0.3 mm,
encoder zeros ±0.5 mm), so that one unit means as much for a length as for an angle.

Per leg i (``leg1`` … ``leg3``), with the nominal rail direction d, revolute axis r,
q = r made normal to d ("tangential") and p = d × q ("radial": outward on the ideal head):

- ``rail_point.radial``, ``.tangential``, ``.along_rail`` — mm, P_i moved along p, q, d;
- ``rail_direction.radial``, ``.tangential`` — rad, d_i tilted toward p, q;
- ``revolute_axis.tilt``, ``.turn`` — rad, r_i tilted toward the rail direction (made normal to r),
  and turned about it (toward r × that);
- ``link_length`` — mm; ``platform_joint.x``, ``.y``, ``.z`` — mm, s_i in the platform frame;
- ``stroke_offset`` — mm, the encoder zero o_i;

and for the tool: ``tool_tip.x``, ``.y``, ``.z`` (mm, platform frame) and ``tool_axis.x``, ``.y``
(rad, w tilted toward the platform frame's x and y made normal to w). With ``fit_frame``, the
measurement frame too: ``frame.rx``, ``.ry``, ``.rz`` (rad, a rotation vector) and ``frame.tx``,
``.ty``, ``.tz`` (mm): a measured point is R·p + t with R, t a first estimate (fitted to the
nominal head's points) refined by these.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from prs3_post.core.types import FloatArray, IntArray
from prs3_post.machine.model import GeneralGeometry, Geometry, LegGeometry

__all__ = ["ERROR_SIZES", "ErrorModel", "Observations", "Parameter", "error_model", "rotation"]

#: Code units (mm, rad): the size each kind of parameter's error is expected to have; a scaled
#: parameter is its deviation divided by this.
ERROR_SIZES: dict[str, float] = {
    "rail_point": 0.5,
    "rail_direction": math.radians(0.1),
    "revolute_axis": math.radians(0.1),
    "link_length": 0.2,
    "platform_joint": 0.3,
    "stroke_offset": 0.5,
    "tool_tip": 0.3,
    "tool_axis": math.radians(0.1),
    "frame_rotation": math.radians(0.1),
    "frame_translation": 1.0,
}

#: The order in which parameters are preferred for fitting when the measurements cannot tell some
#: apart (the later of two that move the tool alike is held at its nominal value): the measurement
#: frame, the encoder zeros and link lengths, the rails, the revolute axes, the tool, the platform
#: joints (whose frame the tool also fixes), and last each rail point along its own rail (the
#: encoder zero does the same).
_PREFERENCE = ("frame", "stroke_offset", "link_length", "rail_point.radial", "rail_point.tangential",
               "rail_direction", "revolute_axis", "tool_tip", "tool_axis", "platform_joint", "rail_point.along_rail")


@dataclass(frozen=True, slots=True)
class Parameter:
    """One identified parameter.

    Attributes
    ----------
    name : str — ``leg1.rail_point.radial``
    kind : str — its key in :data:`ERROR_SIZES`
    unit : str — ``mm`` or ``deg`` (code units: mm, rad)
    scale : float — mm or rad, the expected size of its error (one scaled unit)
    """

    name: str
    kind: str
    unit: str
    scale: float

    def shown(self, value: float) -> float:
        """A value of this parameter in code units (mm, rad) in its display unit (mm, deg)."""
        return math.degrees(value) if self.unit == "deg" else value


@dataclass(frozen=True, slots=True)
class Observations:
    """Commanded poses and, where measured, the tool's tip and axis.

    Attributes
    ----------
    strokes : (N, 3) float — mm, commanded strokes
    stage : (N, 2) float — mm, stage X, Y (the stage is ideal: added to the head's tip)
    tool_length : (N,) float — mm, the tool length "TL" of each row
    tip : (N, 3) float — mm, measured tips (stage applied, measurement frame); NaN: not measured
    axis : (N, 3) float — unit, measured axes; NaN where not measured
    has_axis : bool — the axes are measured (and enter the residuals)
    """

    strokes: FloatArray
    stage: FloatArray
    tool_length: FloatArray
    tip: FloatArray
    axis: FloatArray
    has_axis: bool

    def rows(self, index: IntArray) -> Observations:
        """The rows ``index`` (indices or a mask)."""
        return replace(self, strokes=self.strokes[index], stage=self.stage[index], tool_length=self.tool_length[index],
                       tip=self.tip[index], axis=self.axis[index])

    def __len__(self) -> int:
        return len(self.strokes)


def rotation(vector: FloatArray) -> FloatArray:
    """(3, 3) the rotation by the rotation vector ``vector`` (3,) rad (Rodrigues)."""
    angle = float(np.linalg.norm(vector))
    if angle < 1e-300:
        return np.eye(3)
    k = np.asarray(vector, dtype=np.float64) / angle
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * cross + (1.0 - math.cos(angle)) * (cross @ cross)


def _unit(v: FloatArray) -> FloatArray:
    return v / np.linalg.norm(v)


def _normal_part(v: FloatArray, n: FloatArray) -> FloatArray:
    """The unit vector of ``v`` made normal to the unit ``n``."""
    return _unit(v - float(v @ n) * n)


def _exact_unit(v: FloatArray) -> tuple[float, float, float]:
    """A unit vector as a tuple whose length is 1 to the last bit the model's checks allow."""
    u = _unit(np.asarray(v, dtype=np.float64))
    return float(u[0]), float(u[1]), float(u[2])


@dataclass(frozen=True, slots=True)
class ErrorModel:
    """The parameters of a nominal head (and, with ``fit_frame``, of the measurement frame).

    Attributes
    ----------
    nominal : Geometry — the machine's geometry (its ``general`` head, or the ideal one)
    parameters : (P,) tuple of Parameter
    bases : (3, 6, 3) float — per leg, the fixed directions p, q, d (rail point and direction) and
        the revolute axis's tilt and turn directions and r itself
    tool_bases : (3, 3) float — the tool axis's two tilt directions and w
    frame_rotation : (3, 3) float — the first estimate of the measurement frame's rotation (identity
        without ``fit_frame``)
    frame_translation : (3,) float — mm, its translation
    fit_frame : bool
    """

    nominal: Geometry
    parameters: tuple[Parameter, ...]
    bases: FloatArray
    tool_bases: FloatArray
    frame_rotation: FloatArray
    frame_translation: FloatArray
    fit_frame: bool

    @property
    def names(self) -> tuple[str, ...]:
        """(P,) the parameters' names."""
        return tuple(p.name for p in self.parameters)

    @property
    def scales(self) -> FloatArray:
        """(P,) mm or rad, each parameter's expected error size."""
        return np.array([p.scale for p in self.parameters])

    def preference(self) -> list[int]:
        """The parameters' indices in the order they are preferred for fitting (see :data:`_PREFERENCE`)."""
        order: list[int] = []
        for prefix in _PREFERENCE:
            order += [i for i, p in enumerate(self.parameters) if i not in order and _matches(p.name, prefix)]
        return order + [i for i in range(len(self.parameters)) if i not in order]

    def head(self, scaled: FloatArray) -> Geometry:
        """The nominal geometry with the head's parameters moved by ``scaled`` (P,) (frame parameters ignored)."""
        general = self.nominal.general_geometry()
        delta = np.asarray(scaled, dtype=np.float64)[:_HEAD_COUNT] * self.scales[:_HEAD_COUNT]
        legs = []
        for i, leg in enumerate(general.legs):
            d = delta[i * _LEG_COUNT:(i + 1) * _LEG_COUNT]
            p, q, rail, tilt, turn, _ = self.bases[i]
            point = np.array(leg.rail_point) + d[0] * p + d[1] * q + d[2] * rail
            legs.append(LegGeometry(
                rail_point=(float(point[0]), float(point[1]), float(point[2])),
                rail_direction=_exact_unit(np.array(leg.rail_direction) + d[3] * p + d[4] * q),
                revolute_axis=_exact_unit(np.array(leg.revolute_axis) + d[5] * tilt + d[6] * turn),
                link_length=leg.link_length + float(d[7]),
                platform_joint=tuple(float(v) for v in np.array(leg.platform_joint) + d[8:11]),  # type: ignore[arg-type]
                stroke_offset=leg.stroke_offset + float(d[11]),
            ))
        t = delta[3 * _LEG_COUNT:]
        tip = np.array(general.tool_tip) + t[0:3]
        axis = np.array(general.tool_axis) + t[3] * self.tool_bases[0] + t[4] * self.tool_bases[1]
        head = GeneralGeometry(legs=(legs[0], legs[1], legs[2]),
                               tool_tip=(float(tip[0]), float(tip[1]), float(tip[2])),
                               tool_axis=_exact_unit(axis))
        return replace(self.nominal, general=head)

    def frame(self, scaled: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The measurement frame's rotation (3, 3) and translation (3,) mm for ``scaled`` (P,):
        a point p of the machine frame is measured at R·p + t."""
        if not self.fit_frame:
            return self.frame_rotation, self.frame_translation
        f = np.asarray(scaled, dtype=np.float64)[_HEAD_COUNT:] * self.scales[_HEAD_COUNT:]
        return rotation(f[:3]) @ self.frame_rotation, self.frame_translation + f[3:]

    def with_frame(self, rotation_: FloatArray, translation: FloatArray) -> ErrorModel:
        """This model with another first estimate of the measurement frame."""
        return replace(self, frame_rotation=np.asarray(rotation_, dtype=np.float64),
                       frame_translation=np.asarray(translation, dtype=np.float64))


def _matches(name: str, prefix: str) -> bool:
    """``leg1.rail_point.radial`` matches ``rail_point.radial`` and ``rail_point``; ``frame.rx`` matches ``frame``."""
    bare = name.split(".", 1)[1] if name.startswith("leg") else name
    return bare == prefix or bare.startswith(prefix + ".")


_LEG_NAMES = (("rail_point.radial", "rail_point", "mm"), ("rail_point.tangential", "rail_point", "mm"),
              ("rail_point.along_rail", "rail_point", "mm"), ("rail_direction.radial", "rail_direction", "deg"),
              ("rail_direction.tangential", "rail_direction", "deg"), ("revolute_axis.tilt", "revolute_axis", "deg"),
              ("revolute_axis.turn", "revolute_axis", "deg"), ("link_length", "link_length", "mm"),
              ("platform_joint.x", "platform_joint", "mm"), ("platform_joint.y", "platform_joint", "mm"),
              ("platform_joint.z", "platform_joint", "mm"), ("stroke_offset", "stroke_offset", "mm"))
_TOOL_NAMES = (("tool_tip.x", "tool_tip", "mm"), ("tool_tip.y", "tool_tip", "mm"), ("tool_tip.z", "tool_tip", "mm"),
               ("tool_axis.x", "tool_axis", "deg"), ("tool_axis.y", "tool_axis", "deg"))
_FRAME_NAMES = (("frame.rx", "frame_rotation", "deg"), ("frame.ry", "frame_rotation", "deg"),
                ("frame.rz", "frame_rotation", "deg"), ("frame.tx", "frame_translation", "mm"),
                ("frame.ty", "frame_translation", "mm"), ("frame.tz", "frame_translation", "mm"))
_LEG_COUNT = len(_LEG_NAMES)
_HEAD_COUNT = 3 * _LEG_COUNT + len(_TOOL_NAMES)


def parameter_names(*, fit_frame: bool = False) -> tuple[str, ...]:
    """Every parameter's name, in the model's order.

    >>> parameter_names()[:2], len(parameter_names()), len(parameter_names(fit_frame=True))
    (('leg1.rail_point.radial', 'leg1.rail_point.tangential'), 41, 47)
    """
    legs = tuple(f"leg{i + 1}.{name}" for i in range(3) for name, _, _ in _LEG_NAMES)
    return legs + tuple(name for name, _, _ in _TOOL_NAMES) + (
        tuple(name for name, _, _ in _FRAME_NAMES) if fit_frame else ())


def error_model(nominal: Geometry, *, fit_frame: bool = False) -> ErrorModel:
    """The error model of the head ``nominal`` (its legs as built when it has them, else the ideal ones).

    Raises
    ------
    ValueError
        A revolute axis along its rail, or a tool axis with no direction normal to it (not a head).
    """
    general = nominal.general_geometry()
    bases = np.zeros((3, 6, 3))
    for i, leg in enumerate(general.legs):
        d, r = np.array(leg.rail_direction), np.array(leg.revolute_axis)
        q = _normal_part(r, d)
        p = np.cross(d, q)
        tilt = _normal_part(d, r)
        bases[i] = (p, q, d, tilt, np.cross(r, tilt), r)
    w = np.array(general.tool_axis)
    reference = np.array([1.0, 0.0, 0.0]) if abs(w[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    first = _normal_part(reference, w)
    tool_bases = np.array([first, np.cross(w, first), w])
    parameters = [Parameter(f"leg{i + 1}.{name}", kind, unit, ERROR_SIZES[kind])
                  for i in range(3) for name, kind, unit in _LEG_NAMES]
    parameters += [Parameter(name, kind, unit, ERROR_SIZES[kind]) for name, kind, unit in _TOOL_NAMES]
    if fit_frame:
        parameters += [Parameter(name, kind, unit, ERROR_SIZES[kind]) for name, kind, unit in _FRAME_NAMES]
    return ErrorModel(nominal=nominal, parameters=tuple(parameters), bases=bases, tool_bases=tool_bases,
                      frame_rotation=np.eye(3), frame_translation=np.zeros(3), fit_frame=fit_frame)
