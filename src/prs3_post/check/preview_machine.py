"""The machine in the preview: the 3-PRS head at one pose over the table, with the part at its setup.

    joints, stage of one sample ──► machine_pose (the project's own FK) ──► draw_machine (a 3D axes)

Frame: the machine frame, the base still (DESIGN.md: base centre at the origin, z up, the head
hanging below it). The stage moves the table: the part (its setup, part → machine) and the tool
path are drawn shifted by ``(−X, −Y, 0)`` of the drawn pose's stage, so the tool tip touches the
path where that pose is on it. Bodies: the base (the triangle through the rails' upper ends), the
three rails, their sliders at the pose's strokes, the links to the spherical joints, the platform
(their triangle), and the spindle nose, holder and tool as cylinders on the tool axis
(:class:`~prs3_post.check.machine_pose.MachinePose`; no second drawing of the legs). The table is
a rectangle under the part (or the path, without a part), 10 mm below it.

matplotlib's 3D toolkit is passed in by the caller (:mod:`prs3_post.check.preview` imports it lazily).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from prs3_post.check.machine_pose import BODY_NAMES, MachinePose
from prs3_post.core.types import FloatArray

__all__ = ["BODY_COLOURS", "cylinder_quads", "draw_machine", "table_corners"]

#: Colours of the tool, the holder and the spindle nose (:data:`BODY_NAMES` order).
BODY_COLOURS = ("#d4a017", "#5f6b7a", "#3b4450")
_RAIL, _LINK, _PLATFORM, _BASE, _TABLE, _PART = "#7f7f7f", "#1f4e9a", "#6baed6", "#bdbdbd", "#d9c9a3", "#c7c7c7"


def cylinder_quads(bottom: FloatArray, top: FloatArray, radius: float, *, sides: int = 16) -> FloatArray:
    """The side of a cylinder from ``bottom`` to ``top`` ((3,) mm) as ``sides`` quads, (sides, 4, 3) mm."""
    axis = top - bottom
    length = float(np.linalg.norm(axis))
    w = axis / length if length > 0 else np.array([0.0, 0.0, 1.0])
    helper = np.array([1.0, 0.0, 0.0]) if abs(w[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(w, helper)
    u /= np.linalg.norm(u)
    v = np.cross(w, u)
    angle = np.linspace(0.0, 2.0 * math.pi, sides + 1)
    ring = radius * (np.cos(angle)[:, None] * u + np.sin(angle)[:, None] * v)        # (sides + 1, 3)
    low, high = bottom + ring, top + ring
    return np.stack([low[:-1], low[1:], high[1:], high[:-1]], axis=1)


def table_corners(points: FloatArray, *, margin: float = 15.0, below: float = 10.0) -> FloatArray:
    """The table drawn under ``points`` ((P, 3) mm, finite rows): their x, y extent plus ``margin``,
    ``below`` mm under the lowest; (4, 3) mm."""
    finite = points[np.isfinite(points).all(axis=1)]
    if not len(finite):
        return np.zeros((0, 3))
    low, high = finite.min(axis=0), finite.max(axis=0)
    z = low[2] - below
    x0, x1, y0, y1 = low[0] - margin, high[0] + margin, low[1] - margin, high[1] + margin
    return np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]])


def draw_machine(ax: Any, poly_cls: Any, pose: MachinePose, *, part: FloatArray | None,
                 path: FloatArray, path_colour: str = "#1f5fbf") -> FloatArray:
    """Draw the machine at ``pose``'s one row (module docstring) on the 3D axes ``ax``.

    Parameters
    ----------
    poly_cls : matplotlib's ``Poly3DCollection``
    pose : MachinePose — one row (N = 1), head frame
    part : (K, 3, 3) float, optional — mm, the part's triangles in the machine frame at the setup
        (without the stage: this shifts them)
    path : (P, 3) float — mm, the tool path in the machine frame (part-relative, NaN rows break it)

    Returns
    -------
    (Q, 3) float — mm, every point drawn (to frame the view)
    """
    shift = np.zeros(3)
    shift[:2] = -pose.stage[0]
    drawn = [pose.rails.reshape(-1, 3), pose.sliders[0], pose.spherical[0], pose.body_segments()[0].reshape(-1, 3)]
    base = pose.rails[:, 1 if pose.rails[0, 1, 2] > pose.rails[0, 0, 2] else 0]      # each rail's upper end
    ax.add_collection3d(poly_cls([base], facecolor=_BASE, edgecolor="#555555", alpha=0.35, linewidth=0.8,
                                 label="base", gid="base"))
    for leg in range(len(pose.rails)):
        rail = pose.rails[leg]
        ax.plot(rail[:, 0], rail[:, 1], rail[:, 2], color=_RAIL, linewidth=3.0, solid_capstyle="round",
                label="rails" if leg == 0 else "_nolegend_", gid=f"rail {leg}")
        link = np.stack([pose.sliders[0, leg], pose.spherical[0, leg]])
        ax.plot(link[:, 0], link[:, 1], link[:, 2], color=_LINK, linewidth=2.2,
                label="links" if leg == 0 else "_nolegend_", gid=f"link {leg}")
    sliders, spherical = pose.sliders[0], pose.spherical[0]
    ax.scatter(sliders[:, 0], sliders[:, 1], sliders[:, 2], color="black", marker="s", s=22, depthshade=False,
               label="sliders", gid="sliders")
    ax.add_collection3d(poly_cls([spherical], facecolor=_PLATFORM, edgecolor=_LINK, alpha=0.6, linewidth=1.0,
                                 label="platform", gid="platform"))
    segments = pose.body_segments()[0]
    for b in range(len(BODY_NAMES) - 1, -1, -1):       # the nose first: the tool stays on top
        quads = cylinder_quads(segments[b, 0], segments[b, 1], float(pose.bodies[b, 0]))
        ax.add_collection3d(poly_cls(quads, facecolor=BODY_COLOURS[b], edgecolor="none", alpha=0.85,
                                     label=BODY_NAMES[b], gid=BODY_NAMES[b]))
    on_table = path + shift
    if part is not None and len(part):
        moved = part + shift
        ax.add_collection3d(poly_cls(moved, facecolor=_PART, edgecolor="none", alpha=0.55, label="part (at the setup)",
                                     gid="part"))
        table = table_corners(moved.reshape(-1, 3))
        drawn.append(moved.reshape(-1, 3))
    else:
        table = table_corners(on_table)
    if len(table):
        ax.add_collection3d(poly_cls([table], facecolor=_TABLE, edgecolor="#8c7b57", alpha=0.35, label="table",
                                     gid="table"))
        drawn.append(table)
    ax.plot(on_table[:, 0], on_table[:, 1], on_table[:, 2], color=path_colour, linewidth=0.8, label="tool path",
            gid="tool path")
    drawn.append(on_table)
    points = np.concatenate(drawn)
    return points[np.isfinite(points).all(axis=1)]
