"""What LinuxCNC's vismach model of a 3-PRS machine draws at one joint setting: cylinders, spheres,
boxes and the platform's triangle, in the model's frame.

    joints (3,), stage (2,) ──► machine_pose (our FK) ──► Scene (primitives) ──► the model's OpenGL calls

The model's frame is the machine's (DESIGN.md): the base centre at the origin, z up, the head
still; the XY stage moves the table (and the part on it) by (−X, −Y), since program X, Y are the
tool's displacement relative to the part. The head's bodies are :func:`machine_pose`'s (rails,
sliders, links, spherical joints, platform, tool, holder, spindle nose), placed by our own forward
kinematics; nothing here solves a leg. What it adds is the machine's frame around them, sized from
the head: the base plate above the rails, a spindle housing from the nose to the platform, and the
stage: a fixed bed, the saddle (moves in Y) and the table (X and Y) whose top is at the default
setup's part origin height (``[setup] part_origin_mm``).

Pure numpy, no OpenGL: it imports under the system Python LinuxCNC's vismach runs in, and a test
compares it with :func:`machine_pose` without a display.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prs3_post.check.machine_pose import machine_pose
from prs3_post.core.types import FloatArray
from prs3_post.machine.model import Machine

__all__ = ["Scene", "vismach_scene"]

#: Sizes of the drawn parts as fractions of the guide radius "K" (392 mm on the paper's machine).
RAIL_RADIUS = 0.03
SLIDER_RADIUS = 0.06
SLIDER_LENGTH = 0.16
LINK_RADIUS = 0.02
JOINT_RADIUS = 0.035
PLATFORM_EDGE = 0.025
BASE_MARGIN = 0.2          # the base plate's radius beyond the rails
BASE_THICKNESS = 0.08
TABLE_THICKNESS = 0.1
#: The table's half-size in x and y, the saddle's, and the bed's beyond the stage travel, per K.
TABLE_HALF = (0.9, 0.7)
SADDLE_HALF = (0.7, 0.9)
BED_MARGIN = 0.3


@dataclass(frozen=True, slots=True)
class Scene:
    """The model's primitives at one pose, model frame (mm).

    Attributes
    ----------
    cylinders : (C, 2, 3) float — each cylinder's axis, from one end to the other
    radii : (C,) float — each cylinder's radius
    kinds : (C,) tuple of str — what each cylinder is: ``rail``, ``slider``, ``link``, ``platform``,
        ``spindle``, ``tool``, ``holder``, ``spindle nose``, ``base``
    spheres : (S, 4) float — the spherical joints: centre x, y, z and radius
    platform : (3, 3) float — the platform's corners (the spherical joints)
    boxes : (B, 2, 3) float — axis-aligned boxes, lowest and highest corner
    box_kinds : (B,) tuple of str — ``bed``, ``saddle``, ``table``
    tip : (3,) float — the tool tip
    work : (3,) float — the table top's centre (moves with the stage)
    converged : bool — False where the joints give no pose (the head is then not drawn)
    """

    cylinders: FloatArray
    radii: FloatArray
    kinds: tuple[str, ...]
    spheres: FloatArray
    platform: FloatArray
    boxes: FloatArray
    box_kinds: tuple[str, ...]
    tip: FloatArray
    work: FloatArray
    converged: bool

    def as_dict(self) -> dict[str, object]:
        """The scene as JSON-ready lists (the model's ``--pose`` prints it)."""
        return {"cylinders": self.cylinders.tolist(), "radii": self.radii.tolist(), "kinds": list(self.kinds),
                "spheres": self.spheres.tolist(), "platform": self.platform.tolist(), "boxes": self.boxes.tolist(),
                "box_kinds": list(self.box_kinds), "tip": self.tip.tolist(), "work": self.work.tolist(),
                "converged": self.converged}


def vismach_scene(machine: Machine, joints: FloatArray, stage: FloatArray | None = None, *,
                  tool_diameter: float = 6.0) -> Scene:
    """The model at joints ``joints`` (3,) mm and stage ``stage`` (2,) mm (None: 0, 0).

    ``machine`` carries the tool in the spindle (:meth:`Machine.with_tool_length`); ``tool_diameter``
    is the drawn tool's, mm.

    >>> from prs3_post.machine.loading import load_machine
    >>> scene = vismach_scene(load_machine("patel2020"), np.array([300.0, 300.0, 300.0]), np.array([10.0, 0.0]))
    >>> (scene.tip.round(3) + 0.0).tolist(), (scene.work.round(3) + 0.0).tolist()
    ([0.0, 0.0, -904.473], [-10.0, 0.0, -970.0])
    """
    joints = np.asarray(joints, dtype=np.float64).reshape(1, 3)
    stage = np.zeros((1, 2)) if stage is None else np.asarray(stage, dtype=np.float64).reshape(1, 2)
    pose = machine_pose(machine, joints, stage, tool_diameter=tool_diameter)
    size = machine.geometry.guide_radius
    cylinders: list[FloatArray] = []
    radii: list[float] = []
    kinds: list[str] = []

    def add(ends: FloatArray, radius: float, kind: str) -> None:
        cylinders.append(np.asarray(ends, dtype=np.float64).reshape(2, 3))
        radii.append(radius)
        kinds.append(kind)

    rails = pose.rails                                                       # (3, 2, 3)
    top = float(rails[:, :, 2].max())
    add(np.array([[0.0, 0.0, top], [0.0, 0.0, top + BASE_THICKNESS * size]]),
        float(np.hypot(rails[:, :, 0], rails[:, :, 1]).max()) + BASE_MARGIN * size, "base")
    for rail in rails:
        add(rail, RAIL_RADIUS * size, "rail")
    converged = bool(pose.converged[0])
    spheres = np.zeros((0, 4))
    platform = np.full((3, 3), np.nan)
    if converged:
        sliders, spherical = pose.sliders[0], pose.spherical[0]
        for leg in range(len(rails)):
            direction = rails[leg, 1] - rails[leg, 0]
            direction = direction / np.linalg.norm(direction)
            half = 0.5 * SLIDER_LENGTH * size * direction
            add(np.array([sliders[leg] - half, sliders[leg] + half]), SLIDER_RADIUS * size, "slider")
            add(np.array([sliders[leg], spherical[leg]]), LINK_RADIUS * size, "link")
        for leg in range(len(rails)):
            add(np.array([spherical[leg], spherical[(leg + 1) % len(rails)]]), PLATFORM_EDGE * size, "platform")
        segments = pose.body_segments()[0]                                   # (B, 2, 3)
        for (radius, _, _), segment, kind in zip(pose.bodies, segments, ("tool", "holder", "spindle nose"),
                                                 strict=True):
            add(segment, float(radius), kind)
        # the spindle's housing: from the nose up to the platform's centre
        add(np.array([segments[-1, 1], pose.centre[0]]), float(pose.bodies[-1, 0]), "spindle")
        spheres = np.column_stack([spherical, np.full(len(spherical), JOINT_RADIUS * size)])
        platform = spherical.copy()
    boxes, box_kinds, work = _stage(machine, stage[0], size)
    return Scene(cylinders=np.array(cylinders), radii=np.array(radii), kinds=tuple(kinds), spheres=spheres,
                 platform=platform, boxes=boxes, box_kinds=box_kinds, tip=pose.tip[0].copy(), work=work,
                 converged=converged)


def _stage(machine: Machine, stage: FloatArray, size: float) -> tuple[FloatArray, tuple[str, ...], FloatArray]:
    """The bed (fixed), the saddle (moved by −Y) and the table (−X, −Y) as boxes, and the table top's centre."""
    top = machine.part_origin[2]
    x, y = (float(stage[0]), float(stage[1])) if machine.stage.present else (0.0, 0.0)
    thick = TABLE_THICKNESS * size
    table = np.array([[-TABLE_HALF[0] * size - x, -TABLE_HALF[1] * size - y, top - thick],
                      [TABLE_HALF[0] * size - x, TABLE_HALF[1] * size - y, top]])
    saddle = np.array([[-SADDLE_HALF[0] * size, -SADDLE_HALF[1] * size - y, top - 2 * thick],
                       [SADDLE_HALF[0] * size, SADDLE_HALF[1] * size - y, top - thick]])
    travel_x = machine.stage.travel_x if machine.stage.present else (0.0, 0.0)
    travel_y = machine.stage.travel_y if machine.stage.present else (0.0, 0.0)
    reach = max(abs(v) for v in (*travel_x, *travel_y)) + (max(*TABLE_HALF, *SADDLE_HALF) + BED_MARGIN) * size
    bed = np.array([[-reach, -reach, top - 3 * thick], [reach, reach, top - 2 * thick]])
    if not machine.stage.present:                                  # a plain table under the head
        return np.array([bed]), ("bed",), np.array([0.0, 0.0, top - 2 * thick])
    return np.array([bed, saddle, table]), ("bed", "saddle", "table"), np.array([-x, -y, top])
