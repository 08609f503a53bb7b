"""The setup: where and how the part sits on the machine (a rigid part → machine transform).

    p_machine = Rz(θ) · p_part + origin

θ is the part's rotation about the machine's +z axis (counter-clockwise seen from above), origin
the machine coordinates of the part origin (DESIGN.md, "Part → machine"). Tool axes are
directions: they turn with Rz(θ) and do not shift. One :class:`Setup` is resolved once (the
machine file's default, overridden by what the user gives) and passed to the pipeline, `verify`,
`preview` and the program header.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prs3_post.core.errors import Prs3Error
from prs3_post.core.numbers import fixed as _fixed
from prs3_post.core.numbers import short_text
from prs3_post.core.types import FloatArray
from prs3_post.machine.model import Machine

#: The setup value (an option's or a job file's) that asks :func:`prs3_post.check.placement.place` to choose
#: the part origin or rotation.
AUTO = "auto"
#: Largest |origin| component accepted, mm (100 m: no machine of this kind is larger).
MAX_ORIGIN_MM = 1e5
#: Largest |rotation| accepted, degrees (a few turns at most is a typo, not a setup).
MAX_ROTATION_DEG = 3600.0

UP_ROTATION: dict[str, tuple[str, tuple[tuple[int, int, int], ...]]] = {
    "z": ("unchanged", ((1, 0, 0), (0, 1, 0), (0, 0, 1))),
    "y": ("+90° about x", ((1, 0, 0), (0, 0, -1), (0, 1, 0))),
    "-y": ("−90° about x", ((1, 0, 0), (0, 0, 1), (0, -1, 0))),
    "x": ("−90° about y", ((0, 0, -1), (0, 1, 0), (1, 0, 0))),
    "-x": ("+90° about y", ((0, 0, 1), (0, 1, 0), (-1, 0, 0))),
    "-z": ("180° about x", ((1, 0, 0), (0, -1, 0), (0, 0, -1))),
}
"""For each accepted ``up`` (the STL's up axis, which :func:`prs3_post.part.stl.load_part` turns to +z before
the part is set up): the rotation in words and its matrix (rows; part = matrix @ file), which turns that
file axis into +z."""


class SetupError(Prs3Error):
    """A setup value that is not physically meaningful (not finite, or absurdly large): bad input.

    The message names the value (``part origin``, ``part rotation``) and what is valid, without
    naming any command-line flag; ``field`` says which value (``origin`` or ``rotation``).
    """

    exit_code = 2

    def __init__(self, message: str, *, field: str):
        super().__init__(message)
        self.field = field


@dataclass(frozen=True, slots=True)
class Setup:
    """Part → machine rigid transform.

    Attributes
    ----------
    origin : (3,) tuple — mm, machine coordinates of the part origin
    rotation_deg : float — degrees, part rotation about the machine +z axis (counter-clockwise seen from above)

    >>> s = Setup((10.0, 0.0, -5.0), 90.0)
    >>> s.points_to_machine(np.array([[1.0, 0.0, 0.0]])).round(12).tolist()
    [[10.0, 1.0, -5.0]]
    """

    origin: tuple[float, float, float]
    rotation_deg: float = 0.0

    def __post_init__(self) -> None:
        origin = tuple(float(v) for v in self.origin)
        if len(origin) != 3:
            raise SetupError(f"part origin: expected 3 numbers x, y, z in mm, got {len(origin)}", field="origin")
        if not all(math.isfinite(v) and abs(v) <= MAX_ORIGIN_MM for v in origin):
            shown = ", ".join(short_text(v) for v in origin)
            raise SetupError(f"part origin: each of x, y, z must be a finite number within ±{MAX_ORIGIN_MM:g} mm, "
                             f"got [{shown}]", field="origin")
        rotation = float(self.rotation_deg)
        if not (math.isfinite(rotation) and abs(rotation) <= MAX_ROTATION_DEG):
            raise SetupError(f"part rotation: must be a finite number within ±{MAX_ROTATION_DEG:g} degrees, "
                             f"got {short_text(rotation)}", field="rotation")
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "rotation_deg", rotation)

    @classmethod
    def resolve(cls, machine: Machine, origin: tuple[float, ...] | FloatArray | None = None,
                rotation_deg: float | None = None) -> Setup:
        """The setup a job uses: the machine file's default part origin (rotation 0), overridden by
        the given ``origin`` / ``rotation_deg`` where they are not None.

        Raises
        ------
        SetupError
            A value out of range (see the class).
        """
        chosen = machine.part_origin if origin is None else origin
        return cls(tuple(float(v) for v in chosen), 0.0 if rotation_deg is None else float(rotation_deg))  # type: ignore[arg-type]

    @property
    def rotation(self) -> FloatArray:
        """(3, 3) Rz(θ), part axes → machine axes."""
        theta = math.radians(self.rotation_deg)
        c, s = math.cos(theta), math.sin(theta)
        if self.rotation_deg % 90.0 == 0.0:           # exact quarter turns: no 6e-17 residue in the programs
            c, s = round(c), round(s)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    @property
    def shift(self) -> FloatArray:
        """(3,) float — mm, the origin as an array."""
        return np.array(self.origin, dtype=np.float64)

    def part_to_machine(self) -> FloatArray:
        """(4, 4) homogeneous transform, part → machine.

        >>> Setup((-100.0, -200.0, -970.0)).part_to_machine()[:3, 3].tolist()
        [-100.0, -200.0, -970.0]
        """
        transform = np.eye(4)
        transform[:3, :3] = self.rotation
        transform[:3, 3] = self.shift
        return transform

    def machine_to_part(self) -> FloatArray:
        """(4, 4) homogeneous transform, machine → part (the inverse of :meth:`part_to_machine`)."""
        transform = np.eye(4)
        transform[:3, :3] = self.rotation.T
        transform[:3, 3] = -self.rotation.T @ self.shift
        return transform

    def points_to_machine(self, points: FloatArray) -> FloatArray:
        """(N, 3) mm part coordinates → (N, 3) mm machine coordinates.

        Without a turn (a rotation of whole turns: R is I exactly) the product is skipped for finite
        points: x·1 + y·0 + z·0 is x, but for the sign of a zero, which adding an origin coordinate
        that is not −0.0 makes +0.0 either way; so the same bits as with the product.
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if (self.rotation_deg % 360.0 == 0.0 and not any(v == 0.0 and math.copysign(1.0, v) < 0.0 for v in self.origin)
                and np.isfinite(points).all()):
            out = np.zeros_like(points)
            for column, shift in enumerate(self.origin):
                np.add(points[:, column], shift, out=out[:, column])
            return out
        out = points @ self.rotation.T
        for column, shift in enumerate(self.origin):     # a column at a time: a (3,) row broadcast over
            out[:, column] += shift                      # (N, 3) adds three values at a time, ~3x slower
        return out

    def points_to_part(self, points: FloatArray) -> FloatArray:
        """(N, 3) mm machine coordinates → (N, 3) mm part coordinates."""
        return (np.asarray(points, dtype=np.float64).reshape(-1, 3) - self.shift) @ self.rotation

    def axes_to_machine(self, axes: FloatArray) -> FloatArray:
        """(N, 3) directions in the part frame → (N, 3) in the machine frame (rotated, not shifted)."""
        return np.asarray(axes, dtype=np.float64).reshape(-1, 3) @ self.rotation.T

    def axes_to_part(self, axes: FloatArray) -> FloatArray:
        """(N, 3) directions in the machine frame → (N, 3) in the part frame."""
        return np.asarray(axes, dtype=np.float64).reshape(-1, 3) @ self.rotation

    def with_origin(self, origin: tuple[float, ...] | FloatArray) -> Setup:
        """The same rotation with another origin."""
        return Setup(tuple(float(v) for v in origin), self.rotation_deg)  # type: ignore[arg-type]

    def describe(self) -> str:
        """``part origin at machine [x, y, z] mm, rotation θ deg about z`` (the header's form)."""
        return (f"part origin at machine [{', '.join(_fixed(v, 4) for v in self.origin)}] mm, "
                f"rotation {_fixed(self.rotation_deg, 4)} deg about z")
