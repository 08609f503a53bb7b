"""What an operation is: its kind and its parameters, as one tagged union (:data:`Work`).

    HoleJob(HoleParams)                       holes at each position
    ProfileJob(SquareShape | RoundShape, ProfileParams)   one profile

Used by the main job's :class:`~prs3_post.app.job.JobSpec` and by the program header that records it.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from prs3_post.toolpaths.holes import HoleParams
from prs3_post.toolpaths.profiles import ProfileParams, RoundShape, SquareShape


class Operation(enum.Enum):
    """What the machine cuts on the face."""

    HOLE = "hole"
    """Drill holes normal to the face, optionally pecking, at each --at point."""
    SQUARE = "square"
    """A square groove or wall (rounded corners allowed) in depth passes."""
    ROUND = "round"
    """A round groove or wall in depth passes."""


@dataclass(frozen=True, slots=True)
class HoleJob:
    """A hole operation: drill at each position.

    Attributes
    ----------
    params : HoleParams
    """

    params: HoleParams

    @property
    def operation(self) -> Operation:
        """Always :attr:`Operation.HOLE`."""
        return Operation.HOLE


@dataclass(frozen=True, slots=True)
class ProfileJob:
    """A square or round profile at one position.

    Attributes
    ----------
    shape : SquareShape | RoundShape — which outline (and so which operation)
    params : ProfileParams
    """

    shape: SquareShape | RoundShape
    params: ProfileParams

    @property
    def operation(self) -> Operation:
        """:attr:`Operation.SQUARE` or :attr:`Operation.ROUND`, from the shape."""
        return Operation.SQUARE if isinstance(self.shape, SquareShape) else Operation.ROUND


#: An operation and its parameters.
Work = HoleJob | ProfileJob
