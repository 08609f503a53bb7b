"""The machine types: head geometry, limits, stage (frozen; loaded from TOML by :mod:`prs3_post.machine.loading`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

__all__ = ["DEFAULT_KINEMATICS", "GENERAL_KINEMATICS", "KINEMATICS_NAMES", "Calibration", "Dynamics", "GeneralGeometry",
           "Geometry", "Holder", "LegGeometry", "Limits", "Machine", "Stage", "general_from_ideal"]

Vector = tuple[float, float, float]

#: The kinematics of a machine file without a ``kinematics`` key (the files written before it).
DEFAULT_KINEMATICS = "3-prs"
#: The kinematics of a head whose legs each have their own geometry (a machine file's ``[[legs]]``).
GENERAL_KINEMATICS = "3-prs-general"
#: The kinematics a machine file may name: :func:`prs3_post.kinematics.registry.register` adds
#: each one it registers (this layer cannot import that registry).
KINEMATICS_NAMES: set[str] = {DEFAULT_KINEMATICS, GENERAL_KINEMATICS}


@dataclass(frozen=True, slots=True)
class Geometry:
    """The head's dimensions (mm, rad). Symbols from the paper in quotes.

    Attributes
    ----------
    leg_azimuth : (3,) tuple — rad, azimuth α of legs 1, 2, 3, 120° apart, counter-clockwise
    guide_radius : float — mm, "K": horizontal distance from the base centre to each revolute axis
    link_length : float — mm, "U": revolute-to-spherical link length
    platform_radius : float — mm, "r_p = q/√3": circumradius of the spherical-joint triangle
    tool_length : float — mm, "TL": platform centre to tool tip along the tool axis (with the tool
        the machine file assumes; :meth:`with_tool` gives the geometry with another tool)
    gauge_offset : float — mm, platform centre to the spindle's gauge line along the tool axis
        (0 < gauge_offset < tool_length): a tool of length L (gauge line to tip) makes TL = gauge_offset + L
    general : GeneralGeometry | None — the head as built, leg by leg (a machine file's ``[[legs]]``),
        with its tool tip at ``tool_length``; None: the ideal head these numbers describe. The numbers
        above stay the head's nominal ones (the general kinematics start from their closed form).
    """

    leg_azimuth: tuple[float, float, float]
    guide_radius: float
    link_length: float
    platform_radius: float
    tool_length: float
    gauge_offset: float
    general: GeneralGeometry | None = None

    def __post_init__(self) -> None:
        for name in ("guide_radius", "link_length", "platform_radius", "tool_length", "gauge_offset"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0")

    def with_tool(self, length: float) -> Geometry:
        """This head with a tool ``length`` mm long from the gauge line to its tip (TL = gauge_offset + length)."""
        return self.with_tool_length(self.gauge_offset + length)

    def with_tool_length(self, length: float) -> Geometry:
        """This head with the tool length "TL" ``length`` mm (a general head's tool tip moves along its
        tool axis by the difference)."""
        if self.general is None:
            return replace(self, tool_length=length)
        return replace(self, tool_length=length, general=self.general.with_tool_shift(length - self.tool_length))

    @property
    def layout_offset(self) -> float:
        """rad, how far the leg layout is turned from the reference 210°/330°/90° (legs 1, 2, 3)."""
        return self.leg_azimuth[0] - math.radians(210.0)

    def general_geometry(self) -> GeneralGeometry:
        """The head as built: :attr:`general` when the machine file describes its legs, else the
        ideal head's (:func:`general_from_ideal`)."""
        return self.general if self.general is not None else general_from_ideal(self)


@dataclass(frozen=True, slots=True)
class LegGeometry:
    """One leg of a general 3-PRS head (DESIGN.md, "The machine as built"), machine frame unless said.

    Attributes
    ----------
    rail_point : (3,) tuple — mm, "P_i": the revolute joint's centre at commanded stroke 0 with
        ``stroke_offset`` 0 (ideal: K·e_i)
    rail_direction : (3,) tuple — unit, "d_i": the direction the revolute joint moves as the
        stroke grows (ideal: (0, 0, −1))
    revolute_axis : (3,) tuple — unit, "r_i": the revolute joint's axis; the link stays in the plane
        through the joint's centre normal to it (ideal: t_i)
    link_length : float — mm, "U_i": revolute joint centre to spherical joint centre
    platform_joint : (3,) tuple — mm, "s_i": the spherical joint's centre in the platform frame
        (ideal: r_p·e_i)
    stroke_offset : float — mm, "o_i": the encoder zero; physical stroke = commanded stroke + offset,
        so the revolute joint is at P_i + (T_i + o_i)·d_i (ideal: 0)
    """

    rail_point: Vector
    rail_direction: Vector
    revolute_axis: Vector
    link_length: float
    platform_joint: Vector
    stroke_offset: float = 0.0

    def __post_init__(self) -> None:
        values = (*self.rail_point, *self.rail_direction, *self.revolute_axis, self.link_length,
                  *self.platform_joint, self.stroke_offset)
        if not all(math.isfinite(v) for v in values):
            raise ValueError("leg values must be finite")
        for name in ("rail_direction", "revolute_axis"):
            if abs(math.hypot(*getattr(self, name)) - 1.0) > 1e-12:
                raise ValueError(f"{name} must be a unit vector")
        if not self.link_length > 0:
            raise ValueError("link_length must be > 0")


@dataclass(frozen=True, slots=True)
class GeneralGeometry:
    """A 3-PRS head whose legs each have their own geometry, and its tool in the platform frame.

    The platform frame is the frame the platform joints and the tool are given in; the ideal head's
    has its origin at the platform centre and z along the platform normal (DESIGN.md).

    Attributes
    ----------
    legs : (3,) tuple of LegGeometry — legs 1, 2, 3
    tool_tip : (3,) tuple — mm, "c": the tool tip in the platform frame, with the tool of the
        :class:`Geometry` that holds this (its ``tool_length``; ideal: (0, 0, −TL))
    tool_axis : (3,) tuple — unit, "w": the tool axis in the platform frame, from the tip toward the
        spindle (ideal: (0, 0, 1))
    """

    legs: tuple[LegGeometry, LegGeometry, LegGeometry]
    tool_tip: Vector
    tool_axis: Vector

    def __post_init__(self) -> None:
        if len(self.legs) != 3:
            raise ValueError("a 3-PRS head has 3 legs")
        if not all(math.isfinite(v) for v in (*self.tool_tip, *self.tool_axis)):
            raise ValueError("tool values must be finite")
        if abs(math.hypot(*self.tool_axis) - 1.0) > 1e-12:
            raise ValueError("tool_axis must be a unit vector")

    def with_tool_shift(self, longer: float) -> GeneralGeometry:
        """This head with a tool ``longer`` mm longer: its tip moved by −longer along the tool axis."""
        tip = tuple(c - longer * w for c, w in zip(self.tool_tip, self.tool_axis, strict=True))
        return replace(self, tool_tip=(tip[0], tip[1], tip[2]))


def general_from_ideal(geometry: Geometry) -> GeneralGeometry:
    """The ideal head of ``geometry`` as a :class:`GeneralGeometry` (DESIGN.md: P_i = K·e_i, d_i = −z,
    r_i = t_i, U_i = U, s_i = r_p·e_i, o_i = 0, c = (0, 0, −TL), w = z).

    >>> from prs3_post.machine.loading import load_machine
    >>> g = general_from_ideal(load_machine("patel2020").geometry)
    >>> [round(v, 4) + 0.0 for v in g.legs[2].rail_point], g.legs[2].rail_direction, g.tool_tip
    ([0.0, 392.013, 0.0], (0.0, 0.0, -1.0), (0.0, 0.0, -175.0))
    """
    legs = []
    for alpha in geometry.leg_azimuth:
        cos_a, sin_a = math.cos(alpha), math.sin(alpha)
        legs.append(LegGeometry(
            rail_point=(geometry.guide_radius * cos_a, geometry.guide_radius * sin_a, 0.0),
            rail_direction=(0.0, 0.0, -1.0),
            revolute_axis=(-sin_a, cos_a, 0.0),
            link_length=geometry.link_length,
            platform_joint=(geometry.platform_radius * cos_a, geometry.platform_radius * sin_a, 0.0),
            stroke_offset=0.0,
        ))
    return GeneralGeometry(legs=(legs[0], legs[1], legs[2]), tool_tip=(0.0, 0.0, -geometry.tool_length),
                           tool_axis=(0.0, 0.0, 1.0))


@dataclass(frozen=True, slots=True)
class Limits:
    """Per-point limits, checked on every emitted point (mm, rad).

    Attributes
    ----------
    stroke : (min, max) mm — each actuator stroke T_i
    link_angle : (min, max) rad — each link's angle θ_i from horizontal
    max_tilt : float — rad, tool-axis angle from vertical
    max_condition : float — actuator-Jacobian 2-norm condition number (distance to singularity)
    """

    stroke: tuple[float, float]
    link_angle: tuple[float, float]
    max_tilt: float
    max_condition: float


@dataclass(frozen=True, slots=True)
class Stage:
    """The XY stage under the part (absent on a pure head).

    Attributes
    ----------
    present : bool — the machine has an XY stage
    travel_x, travel_y : (min, max) mm — stage travel (only when present)
    """

    present: bool
    travel_x: tuple[float, float] = (0.0, 0.0)
    travel_y: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True, slots=True)
class Dynamics:
    """How fast the machine's axes move (the ``[dynamics]`` table).

    Attributes
    ----------
    stroke_speed : float — mm/min, top speed of each actuator
    stroke_accel : float — mm/s², acceleration (and deceleration) of each actuator
    stage_speed : float — mm/min, top speed of each stage axis (unused without a stage)
    stage_accel : float — mm/s², acceleration of each stage axis
    """

    stroke_speed: float
    stroke_accel: float
    stage_speed: float
    stage_accel: float

    def __post_init__(self) -> None:
        for name in ("stroke_speed", "stroke_accel", "stage_speed", "stage_accel"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0")

    def speeds(self, joints: int = 3) -> tuple[float, ...]:
        """mm/min, the top speed of the program's axes in column order: stage X, Y, then ``joints``
        actuator strokes (T1, T2, T3 on a 3-PRS head)."""
        return (self.stage_speed,) * 2 + (self.stroke_speed,) * joints

    def accels(self, joints: int = 3) -> tuple[float, ...]:
        """mm/min², the acceleration of stage X, Y and the ``joints`` strokes (the config's mm/s² × 3600)."""
        return (self.stage_accel * 3600.0,) * 2 + (self.stroke_accel * 3600.0,) * joints


@dataclass(frozen=True, slots=True)
class Holder:
    """What holds the tool: the tool holder below the spindle's gauge line and the spindle nose above
    it, as cylinders on the tool axis (the ``[holder]`` table), for the collision check with the part.

    From the tip up: the tool (the operation's diameter), from the tip to ``holder_length`` below
    the gauge line; the holder, from there to the gauge line; the spindle nose, ``nose_length`` above it.

    Attributes
    ----------
    holder_diameter, holder_length : float — mm
    nose_diameter, nose_length : float — mm
    """

    holder_diameter: float
    holder_length: float
    nose_diameter: float
    nose_length: float

    def __post_init__(self) -> None:
        for name in ("holder_diameter", "holder_length", "nose_diameter", "nose_length"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0")


@dataclass(frozen=True, slots=True)
class Calibration:
    """How well a calibration determined the head (a calibrated machine file's ``[calibration]`` table):
    the identified parameters' standard deviations and correlations, for the accuracy they give the tool.

    Attributes
    ----------
    parameters : (K,) tuple of str — the identified parameters' names (``leg1.link_length``: see
        :mod:`prs3_post.kinematics.calibration.parameters`)
    std : (K,) tuple of float — each one's standard deviation in its unit (mm for lengths, degrees
        for angles)
    correlation : (K, K) tuple of tuples — their correlation coefficients (1 on the diagonal)
    noise : float — mm, the measurement noise the calibration found
    """

    parameters: tuple[str, ...]
    std: tuple[float, ...]
    correlation: tuple[tuple[float, ...], ...]
    noise: float

    def __post_init__(self) -> None:
        count = len(self.parameters)
        if len(self.std) != count or len(self.correlation) != count or any(len(r) != count for r in self.correlation):
            raise ValueError(f"calibration: expected {count} standard deviations and a {count}×{count} correlation")
        if not all(math.isfinite(s) and s >= 0 for s in self.std) or not self.noise >= 0:
            raise ValueError("calibration: standard deviations and the noise must be ≥ 0")


@dataclass(frozen=True, slots=True)
class Machine:
    """A whole machine file: head geometry, limits, stage and default setup.

    Attributes
    ----------
    name : str — the file's stem (``patel2020``)
    description : str — one line for ``prs3-post machines``
    source : str — where it was loaded from, as shown in messages
    geometry, limits, stage : see their classes
    part_origin : (3,) tuple — mm, machine coordinates of the part origin in the default setup
    dynamics : Dynamics | None — axis speeds and accelerations (None: an older file without
        ``[dynamics]``: no feed clamping, no cycle time)
    holder : Holder | None — holder and spindle nose (None: no ``[holder]``: no collision check)
    kinematics : str — the kinematics' registered name (:mod:`prs3_post.kinematics.registry`)
    calibration : Calibration | None — the uncertainties of a calibrated head (None: not calibrated)
    """

    name: str
    description: str
    source: str
    geometry: Geometry
    limits: Limits
    stage: Stage
    part_origin: tuple[float, float, float]
    dynamics: Dynamics | None = None
    holder: Holder | None = None
    kinematics: str = DEFAULT_KINEMATICS
    calibration: Calibration | None = None

    def with_tool_length(self, length: float) -> Machine:
        """This machine with the tool length "TL" ``length`` mm (platform centre to tool tip); itself when it
        is already the machine's. The one place a machine with another tool is made (a job's operations,
        a conversion's ``--tool-length``, a converted program's recorded length, placement)."""
        if length == self.geometry.tool_length:
            return self
        return replace(self, geometry=self.geometry.with_tool_length(length))
