"""The machine types: head geometry, limits, stage (frozen; loaded from TOML by :mod:`prs3_post.machine.loading`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

__all__ = ["DEFAULT_KINEMATICS", "KINEMATICS_NAMES", "Dynamics", "Geometry", "Holder", "Limits", "Machine", "Stage"]

#: The kinematics of a machine file without a ``kinematics`` key (the files written before it).
DEFAULT_KINEMATICS = "3-prs"
#: The kinematics a machine file may name: :func:`prs3_post.kinematics.registry.register` adds
#: each one it registers (this layer cannot import that registry).
KINEMATICS_NAMES: set[str] = {DEFAULT_KINEMATICS}


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
    """

    leg_azimuth: tuple[float, float, float]
    guide_radius: float
    link_length: float
    platform_radius: float
    tool_length: float
    gauge_offset: float

    def __post_init__(self) -> None:
        for name in ("guide_radius", "link_length", "platform_radius", "tool_length", "gauge_offset"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0")

    def with_tool(self, length: float) -> Geometry:
        """This head with a tool ``length`` mm long from the gauge line to its tip (TL = gauge_offset + length)."""
        return replace(self, tool_length=self.gauge_offset + length)

    @property
    def layout_offset(self) -> float:
        """rad, how far the leg layout is turned from the reference 210°/330°/90° (legs 1, 2, 3)."""
        return self.leg_azimuth[0] - math.radians(210.0)


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

    def with_tool_length(self, length: float) -> Machine:
        """This machine with the tool length "TL" ``length`` mm (platform centre to tool tip); itself when it
        is already the machine's. The one place a machine with another tool is made (a job's operations,
        a conversion's ``--tool-length``, a converted program's recorded length, placement)."""
        if length == self.geometry.tool_length:
            return self
        return replace(self, geometry=replace(self.geometry, tool_length=length))
