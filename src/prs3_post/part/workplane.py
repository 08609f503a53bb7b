"""A work plane: the coordinate system a CAM G-code program is written in, placed in the part frame.

A plain 3-axis program knows nothing of the part: its X, Y, Z are put on a face of the part by a
:class:`WorkPlane` (program X, Y, Z = the face frame u, v, w of :mod:`prs3_post.part.face`, so the
program's +Z, the tool axis, is the face's outward normal), or by numbers (origin, normal,
optional x direction). A 3+2 program's ``G68.2`` defines a tilted plane *inside* the current one;
:meth:`WorkPlane.compose` nests the two.

    p_part = origin + rotation @ p_program          (mm; rotation columns = the plane's x, y, z)

The plane's z axis (``normal``) is the tool axis of every move in it: unit, tool tip → spindle.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from prs3_post.core.errors import Prs3Error
from prs3_post.core.numbers import short_text, short_tuple
from prs3_post.core.types import FloatArray
from prs3_post.part.face import Face, frame_from_normal

__all__ = ["PERPENDICULAR_TOLERANCE", "WorkPlane", "WorkPlaneError", "euler_zxz_deg", "rotate_rows"]

#: |cos| of the angle between a given x direction and the normal, above which they are not
#: perpendicular (1e-3: 0.06°, the rounding of vectors written with 4 decimals).
PERPENDICULAR_TOLERANCE = 1e-3
#: Largest |origin| component, mm (as the setup's part origin).
MAX_ORIGIN_MM = 1e5


class WorkPlaneError(Prs3Error):
    """Numbers that do not make a work plane (zero normal, x along the normal, not finite): bad input."""

    exit_code = 2


def rotate_rows(rows: FloatArray, rotation: FloatArray) -> FloatArray:
    """``rows @ rotation.T`` for (N, 3) rows, element by element: a row's result does not depend on how many
    rows come with it (a matrix product sums in different orders for different shapes), so that a
    file read in chunks of any size gives the same bits.

    >>> rotate_rows(np.array([[1.0, 2.0, 3.0]]), np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])).tolist()
    [[-2.0, 1.0, 3.0]]
    """
    rows = np.asarray(rows, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(rotation, dtype=np.float64)
    return (rows[:, :1] * r[:, 0] + rows[:, 1:2] * r[:, 1]) + rows[:, 2:] * r[:, 2]


def euler_zxz_deg(i_deg: float, j_deg: float, k_deg: float) -> FloatArray:
    """The rotation of Euler angles Z-X'-Z'' (degrees), as ``G68.2 I J K`` gives them.

    ``R = Rz(I) · Rx(J) · Rz(K)``: turn the frame about its z axis by I, then about its new x axis
    by J, then about its new z axis by K (intrinsic rotations; FANUC Series 30i Descriptions
    B-63942EN/02 §5.44 "Tilted working plane command", the same convention as Heidenhain's
    ``PLANE EULER`` EULPR/EULNU/EULROT and Siemens' Euler frames). Columns are the tilted plane's x,
    y, z in the outer frame; the plane's normal is ``R[:, 2] = (sin I·sin J, −cos I·sin J, cos J)``.

    >>> euler_zxz_deg(0.0, 30.0, 0.0)[:, 2].round(6).tolist()   # tilted 30° about X
    [0.0, -0.5, 0.866025]
    """
    def rz(deg: float) -> FloatArray:
        c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    c, s = math.cos(math.radians(j_deg)), math.sin(math.radians(j_deg))
    rx = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    return rz(i_deg) @ rx @ rz(k_deg)


@dataclass(frozen=True, slots=True, eq=False)      # arrays: equal means the same object
class WorkPlane:
    """A right-handed frame in the part: where a program's X, Y, Z are.

    Attributes
    ----------
    origin : (3,) float — mm, part coordinates of the program's X0 Y0 Z0
    rotation : (3, 3) float — columns: the program's x, y, z axes in part coordinates (orthonormal, det +1)
    name : str — where the plane comes from, for headers and messages (``face 2 of wedge.stl``)

    >>> plane = WorkPlane.from_values([0, 0, 10, 0, 0, 1])
    >>> plane.to_part(np.array([[1.0, 2.0, 3.0]])).tolist(), plane.normal.tolist()
    ([[1.0, 2.0, 13.0]], [0.0, 0.0, 1.0])
    """

    origin: FloatArray
    rotation: FloatArray
    name: str = ""

    def __post_init__(self) -> None:
        origin = np.array(self.origin, dtype=np.float64).reshape(3)
        rotation = np.array(self.rotation, dtype=np.float64).reshape(3, 3)
        if not (np.isfinite(origin).all() and np.isfinite(rotation).all()):
            raise WorkPlaneError("work plane: origin and axes must be finite numbers")
        if not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-9) or np.linalg.det(rotation) < 0:
            raise ValueError(f"WorkPlane.rotation must be a rotation matrix, got {rotation.tolist()}")
        origin.flags.writeable = False
        rotation.flags.writeable = False
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "rotation", rotation)

    @property
    def normal(self) -> FloatArray:
        """(3,) float — the plane's z axis in part coordinates: the tool axis (tip → spindle) in it."""
        return self.rotation[:, 2]

    def to_part(self, local: FloatArray) -> FloatArray:
        """(N, 3) program points (mm) → (N, 3) part points (mm) (:func:`rotate_rows`, then the origin)."""
        return rotate_rows(local, self.rotation) + self.origin

    def to_local(self, part: FloatArray) -> FloatArray:
        """(N, 3) part points (mm) → (N, 3) program points (mm): the inverse of :meth:`to_part`."""
        return (np.asarray(part, dtype=np.float64).reshape(-1, 3) - self.origin) @ self.rotation

    def compose(self, inner: WorkPlane, name: str = "") -> WorkPlane:
        """The plane ``inner`` (given in this plane's coordinates) in part coordinates."""
        return WorkPlane(self.origin + self.rotation @ inner.origin, self.rotation @ inner.rotation,
                         name or inner.name)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def identity(cls) -> WorkPlane:
        """The part frame itself (program X, Y, Z = part x, y, z)."""
        return cls(np.zeros(3), np.eye(3), "part frame")

    @classmethod
    def from_face(cls, face: Face, name: str = "") -> WorkPlane:
        """The face frame of the main job: program X, Y, Z = the face's u, v, w (origin at its centroid)."""
        return cls(face.origin, face.rotation, name or f"face {face.index}")

    @classmethod
    def from_vectors(cls, origin: Sequence[float] | FloatArray, normal: Sequence[float] | FloatArray,
                     x_direction: Sequence[float] | FloatArray | None = None, *, name: str = "") -> WorkPlane:
        """A plane through ``origin`` (mm) with z = ``normal``; x = ``x_direction``, or when not given the
        face frame's u for that normal (down-slope; the part's +x for a horizontal plane).

        Raises
        ------
        WorkPlaneError
            A zero or non-finite normal, an origin beyond ±1e5 mm, an x direction that is zero or
            not perpendicular to the normal (within :data:`PERPENDICULAR_TOLERANCE`).
        """
        origin_ = np.asarray(origin, dtype=np.float64).reshape(3)
        normal_ = np.asarray(normal, dtype=np.float64).reshape(3)
        if not np.isfinite(origin_).all() or np.abs(origin_).max() > MAX_ORIGIN_MM:
            raise WorkPlaneError(f"work plane: the origin must be finite numbers within ±{MAX_ORIGIN_MM:g} mm, got "
                                 f"{short_tuple(origin_)}")
        length = math.hypot(*normal_.tolist())         # hypot: no overflow for components near 1e308
        if not (math.isfinite(length) and length > 0.0):
            raise WorkPlaneError(f"work plane: the normal {short_tuple(normal_)} is not a direction (it must be a "
                                 "non-zero vector, the tool axis from the tip toward the spindle)")
        z = normal_ / length
        if x_direction is None:
            x, _ = frame_from_normal(z)
        else:
            x_ = np.asarray(x_direction, dtype=np.float64).reshape(3)
            x_length = math.hypot(*x_.tolist())
            if not (math.isfinite(x_length) and x_length > 0.0):
                raise WorkPlaneError(f"work plane: the x direction {short_tuple(x_)} is not a direction (it must be a "
                                     "non-zero vector)")
            x_unit = x_ / x_length
            cosine = float(x_unit @ z)
            if abs(cosine) > PERPENDICULAR_TOLERANCE:
                angle = math.degrees(math.acos(max(-1.0, min(1.0, cosine))))   # clip: rounding past ±1
                raise WorkPlaneError(f"work plane: the x direction {short_tuple(x_)} is at {angle:.3f}° to the normal "
                                     f"{short_tuple(normal_)}; it must be perpendicular to it (90° within "
                                     f"{math.degrees(math.asin(PERPENDICULAR_TOLERANCE)):.2f}°)")
            x = x_unit - cosine * z                 # made exactly perpendicular
            x /= np.linalg.norm(x)
        y = np.cross(z, x)
        return cls(origin_, np.column_stack([x, y, z]), name)

    @classmethod
    def from_values(cls, values: Sequence[float], *, name: str = "") -> WorkPlane:
        """``OX, OY, OZ, NX, NY, NZ[, XX, XY, XZ]``: origin (mm), normal, optional x direction.

        Raises
        ------
        WorkPlaneError
            Not 6 or 9 values, or as :meth:`from_vectors`.
        """
        values = [float(v) for v in values]
        if len(values) not in (6, 9):
            raise WorkPlaneError(f"work plane: expected 6 numbers (origin x,y,z and normal x,y,z) or 9 (and the "
                                 f"x direction), got {len(values)}")
        return cls.from_vectors(values[:3], values[3:6], values[6:] or None,
                                name=name or f"work plane {','.join(short_text(v) for v in values)}")
