"""Machining operations: a :class:`~prs3_post.part.face.Face` plus options → a part-frame Toolpath.

* :func:`plan_holes` — drilling normal to the face, with pecking and dwell;
* :func:`plan_profile` — square and round profiles (on / inside / outside the outline), in depth
  passes, entered by plunging or ramping.

Both keep the tool axis on the face normal and take the tool and its cutting data as a
:class:`Cutting`.
"""

from prs3_post.toolpaths.common import Coolant, Cutting, check_fits
from prs3_post.toolpaths.holes import HoleParams, plan_holes
from prs3_post.toolpaths.profiles import (
    Direction,
    Entry,
    ProfileParams,
    RoundShape,
    Shape,
    Side,
    SquareShape,
    plan_profile,
    tool_center_contour,
)

__all__ = [
    "Coolant",
    "Cutting",
    "Direction",
    "Entry",
    "HoleParams",
    "ProfileParams",
    "RoundShape",
    "Shape",
    "Side",
    "SquareShape",
    "check_fits",
    "plan_holes",
    "plan_profile",
    "tool_center_contour",
]
