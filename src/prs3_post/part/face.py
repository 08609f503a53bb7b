"""A planar face of a part, with its own frame (u, v, w).

Face frame: origin at the face centroid, ``w`` = outward normal, ``u`` = the down-slope direction
within the face (for a horizontal face, the part's +x), ``v = w × u``. Face coordinates (u, v, w)
are mm along those unit vectors; w > 0 is outside the material, w < 0 is depth into it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from prs3_post.core.types import FloatArray, IntArray

if TYPE_CHECKING:                      # shapely costs 60 ms to import: only the commands that plan load it
    import shapely


def frame_from_normal(normal: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The face frame's (u, v) for outward unit normals ``w``, one or many.

    ``u`` is the steepest descent within the plane (−z projected onto it); for a horizontal face
    (either way up) there is none and ``u`` is the part's +x projected onto the plane.

    Parameters
    ----------
    normal : (3,) or (G, 3) float — unit outward normals w

    Returns
    -------
    u, v : same shape as ``normal`` — unit vectors, ``v = w × u``

    >>> u, v = frame_from_normal(np.array([0.6, 0.0, 0.8]))
    >>> (np.round(u, 6) + 0.0).tolist(), (np.round(v, 6) + 0.0).tolist()   # + 0.0: no -0.0
    ([0.8, 0.0, -0.6], [0.0, 1.0, 0.0])
    """
    w = np.asarray(normal, dtype=np.float64)
    rows = w.reshape(-1, 3)
    down = np.array([0.0, 0.0, -1.0]) - rows * (-rows[:, 2:3])    # -z minus its component along w
    flat = np.linalg.norm(down, axis=1) < 1e-9                      # horizontal face: no slope, use +x
    down[flat] = np.array([1.0, 0.0, 0.0]) - rows[flat] * rows[flat, 0:1]
    u = down / np.linalg.norm(down, axis=1, keepdims=True)
    v = np.cross(rows, u)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return u.reshape(w.shape), v.reshape(w.shape)


@dataclass(frozen=True, slots=True)
class Face:
    """One planar face of a part (part coordinates, mm).

    Attributes
    ----------
    index : int — position in the part's face table (largest area first)
    area : float — mm²
    normal : (3,) float — outward unit normal, the frame's w
    origin : (3,) float — mm, area centroid of the face, the frame's origin
    u, v : (3,) float — in-plane unit vectors (u down-slope, v = w × u)
    inclination : float — rad, angle between the normal and the part's +z
    boundary : shapely.Polygon — outline (with holes) in face (u, v) coordinates, mm
    triangles : (K,) int — indices of the mesh triangles that make the face
    width : float — mm, diameter of the largest circle inside ``boundary`` (to 0.1 % of the face's size):
        the widest tool that fits
    curved : bool — True when the face is one strip of a tessellated curved surface (neighbours at small
        angles share most of its outline; see ``geometry.find_faces``), not a planar face of the design
    """

    index: int
    area: float
    normal: FloatArray
    origin: FloatArray
    u: FloatArray
    v: FloatArray
    inclination: float
    boundary: shapely.Polygon
    triangles: IntArray
    width: float
    curved: bool

    @property
    def rotation(self) -> FloatArray:
        """(3, 3) float — columns u, v, w: face coordinates → part directions."""
        return np.column_stack([self.u, self.v, self.normal])

    def to_part(self, uvw: FloatArray) -> FloatArray:
        """Face coordinates (N, 3) [or (N, 2), w = 0] in mm → part coordinates (N, 3) mm."""
        uvw = np.asarray(uvw, dtype=np.float64).reshape(-1, np.shape(uvw)[-1] if np.ndim(uvw) else 3)
        if uvw.shape[1] == 2:
            uvw = np.column_stack([uvw, np.zeros(len(uvw))])
        return self.origin + uvw @ self.rotation.T

    def from_part(self, xyz: FloatArray) -> FloatArray:
        """Part coordinates (N, 3) mm → face coordinates (u, v, w) (N, 3) mm."""
        xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
        return (xyz - self.origin) @ self.rotation
