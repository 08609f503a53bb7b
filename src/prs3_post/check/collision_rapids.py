"""The tool's clearance from the part in a CAM program's rapids (``convert --part``; verify of a
converted program): a feed cuts what the CAM program removes, a rapid must not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from prs3_post.check.collision_bodies import BODY_NAMES, CollisionError, body_cylinders
from prs3_post.check.collision_distance import REACH_MM, clearance
from prs3_post.core.defaults import DEFAULT_TOLERANCE
from prs3_post.core.numbers import fixed
from prs3_post.core.toolpath import JointProgram, MoveKind, program_from_columns
from prs3_post.core.types import FloatArray
from prs3_post.kinematics.replay import replay
from prs3_post.machine.model import Machine
from prs3_post.part.setup_transform import Setup

__all__ = ["RAPID_TOUCH_MM", "RETRACT_SIDEWAYS_MM", "RapidClearance", "check_rapids", "rapid_tool_clearance",
           "tool_words"]

#: mm: how far a rapid's tool may reach into the part's triangles unrefused. A CAM program's rapid
#: may start or end where a cut left the tool touching the finished part (retracting past the wall
#: it cut, or with its tip on the floor), and an STL's facets lie off the true surface by their
#: chord; what a rapid must not do is cut. The tool is checked eroded by twice this (its radius and
#: its tip end), held this far from the part: touching passes with a margin, a penetration of more
#: than this is refused.
RAPID_TOUCH_MM = 0.05
#: mm: a rapid that moves the tip along the tool axis, away from the part, sideways by at most this
#: (the tip's offset plus the axis's turn times the tool's length) retracts the tool through where
#: it and the holder already were: its tool is not checked (the holder is, at every pose).
RETRACT_SIDEWAYS_MM = 0.5 * RAPID_TOUCH_MM


@dataclass(frozen=True, slots=True)
class RapidClearance:
    """The tool's closest approach to the part in a CAM program's rapids (:func:`rapid_tool_clearance`).

    Attributes
    ----------
    diameter : float — mm, the tool's diameter checked (0: unknown, its axis segment)
    distance : float — mm, the tool's smallest clearance in the rapids (negative: depth in the part);
        inf: no rapid checked
    exact : bool — measured on the tool's surface (False: a lower bound, stated as ``over``)
    row : int — the program row (the rapid) of that minimum (-1: none)
    fraction : float — the fraction along that row's move (0: its start)
    point : (3,) float — mm, part frame: the tool's point of that minimum
    rapids : int — rapid rows checked (retracts along the tool axis are not: RETRACT_SIDEWAYS_MM)
    """

    diameter: float
    distance: float
    exact: bool
    row: int
    fraction: float
    point: FloatArray
    rapids: int

    def entry(self) -> str:
        """The header's words on the tool in the rapids: ``tool in rapids 2.345 mm (6.000 mm diameter)``
        (``none to check``: no rapid but retracts along the tool axis)."""
        if self.rapids == 0:
            shown = "none to check"
        else:
            shown = f"{'' if self.exact else 'over '}{fixed(self.distance, 3)} mm"
        return f"tool in rapids {shown} ({tool_words(self.diameter)})"

    def message(self, program: JointProgram) -> str:
        """The refusal: ``part.cls:12: the tool hits the part in a rapid, 4.950 mm deep (...)``."""
        d = self.distance
        what = f"hits the part in a rapid, {-d:.3f} mm deep" if d < 0 else f"comes within {d:.3f} mm of the part"
        return (f"{program.describe(self.row)}: the tool {what} (a rapid may touch the part, not cut it: "
                f"{RAPID_TOUCH_MM:.3f} mm at most; {tool_words(self.diameter)})")


def tool_words(diameter: float) -> str:
    """What the rapid check took the tool to be: ``6.000 mm diameter``, or its axis where none is known."""
    return (f"{diameter:.3f} mm diameter" if diameter > 0
            else "diameter unknown: its axis, 0 mm radius")


def rapid_tool_clearance(machine: Machine, program: JointProgram, setup: Setup, triangles: FloatArray,
                         tool_diameter: float) -> RapidClearance:
    """The tool's clearance from the part in the rapids of a CAM program (``convert --part``; verify
    of a converted program), at verify's samples of each rapid and along the motion between them.

    A feed cuts what the CAM program removes; a rapid must not. Each run of rapids is checked from
    where the row before it left the tool (that pose is the motion's start: the tool may touch the
    part there, as a cut leaves it); a rapid that only retracts the tool along its axis
    (:data:`RETRACT_SIDEWAYS_MM`) is not checked, so a run starts after it. The tool is the
    cylinder of ``tool_diameter`` (0: unknown, its axis segment) from the tip to the holder,
    eroded by 2 × :data:`RAPID_TOUCH_MM` and held that far from the part (:data:`RAPID_TOUCH_MM`):
    the clearance stated is the eroded tool's less the erosion (exact where the part faces the
    tool's side or end).

    Raises
    ------
    ValueError
        The machine has no ``[holder]`` (the tool ends where it begins).
    """
    if machine.holder is None:
        raise ValueError(f"machine {machine.name} has no [holder]")
    erosion = 2.0 * RAPID_TOUCH_MM
    length = machine.geometry.tool_length - machine.geometry.gauge_offset
    cylinders = body_cylinders(tool_diameter, length, machine.holder)
    cylinders[0] = [max(cylinders[0, 0] - erosion, 0.0), erosion, cylinders[0, 2]]
    cylinders[1:, 2] = cylinders[1:, 1]                         # the holder and nose: check_program's
    none = RapidClearance(diameter=tool_diameter, distance=math.inf, exact=True, row=-1, fraction=0.0,
                          point=np.zeros(3), rapids=0)
    rapid = np.flatnonzero(program.kind == MoveKind.RAPID)
    rapid = rapid[rapid > 0]                                    # row 0: a start, not a move
    if not len(rapid) or cylinders[0, 2] <= cylinders[0, 1]:
        return none
    keep = np.zeros(len(program), dtype=bool)
    keep[rapid] = keep[rapid - 1] = True
    rows = np.flatnonzero(keep)                                 # the rapids and the rows they start from
    is_rapid = np.zeros(len(rows), dtype=bool)
    is_rapid[np.searchsorted(rows, rapid)] = True
    columns = {name: getattr(program, name)[rows] for name in ("kind", "stage", "strokes", "inverse_time", "source")}
    rep = replay(machine, program_from_columns(columns), tolerance=DEFAULT_TOLERANCE)
    tip, axis = setup.points_to_part(rep.tip), setup.axes_to_part(rep.axis)
    # a retract: the axis kept, the tip moved along it (up, away from the part), barely sideways
    end_tip, end_axis = tip[rep.end], axis[rep.end]
    step = np.diff(end_tip, axis=0)
    along = (step * end_axis[:-1]).sum(axis=1)
    sideways = np.linalg.norm(step - along[:, None] * end_axis[:-1], axis=1) + \
        np.linalg.norm(np.diff(end_axis, axis=0), axis=1) * cylinders[0, 2]
    retract = np.concatenate([[False], (along > 0) & (sideways <= RETRACT_SIDEWAYS_MM)])
    checked = is_rapid & ~retract                               # sub-row 0 is never a rapid (its row before is kept)
    if not checked.any():
        return none
    # the samples of the checked rapids, each run's start: the end sample of the row before it
    sampled = checked[rep.row]
    starts = np.zeros(len(rep.row), dtype=bool)
    starts[rep.end[np.flatnonzero(checked[1:] & ~checked[:-1])]] = True   # the end of the row before a run
    mine = np.flatnonzero(sampled | starts)
    ok = np.isfinite(tip[mine]).all(axis=1) & np.isfinite(axis[mine]).all(axis=1)
    mine = mine[ok]
    connected = np.concatenate([[False], sampled[mine[1:]] & (np.diff(mine) == 1)])
    found = clearance(triangles, tip[mine], axis[mine], cylinders, None, np.zeros((0, 3)),
                      clearance_min=RAPID_TOUCH_MM, refine_max=_RAPID_REFINE, connected=connected,
                      near=RAPID_TOUCH_MM + REACH_MM)
    if not np.isfinite(found.distance[0]):
        return replace(none, rapids=int(checked.sum()))
    k = int(mine[found.sample[0]])
    sub_row = int(rep.row[k])
    fraction = float(rep.fraction[k])
    if not checked[sub_row]:                                    # a run's start: named as the rapid it starts
        sub_row, fraction = sub_row + 1, 0.0
    return RapidClearance(diameter=tool_diameter, distance=float(found.distance[0]) - erosion,
                          exact=bool(found.exact[0]), row=int(rows[sub_row]), fraction=fraction,
                          point=found.point[0].copy(), rapids=int(checked.sum()))


#: Poses of the rapids measured beyond those the check needs, nearest first, to sharpen the minimum.
_RAPID_REFINE = 32


def check_rapids(machine: Machine, program: JointProgram, setup: Setup, triangles: FloatArray,
                 tool_diameter: float) -> RapidClearance:
    """:func:`rapid_tool_clearance`, refused when the tool cuts in a rapid.

    Raises
    ------
    LimitError
        ``part.cls:12: the tool hits the part in a rapid, 4.950 mm deep (a rapid may touch the part,
        not cut it: 0.050 mm at most; 6.000 mm diameter)``.
    """
    found = rapid_tool_clearance(machine, program, setup, triangles, tool_diameter)
    if found.distance < -RAPID_TOUCH_MM:
        raise CollisionError(found.message(program), body=BODY_NAMES[0])
    return found
