"""The default tolerances, defined once (library defaults, the CLI's option defaults, the header's).

A tolerance a user gives overrides these; a program header records the one used.
"""

from __future__ import annotations

import math

__all__ = ["DEFAULT_ANGLE_TOLERANCE", "DEFAULT_ANGLE_TOLERANCE_DEG", "DEFAULT_TOLERANCE"]

DEFAULT_TOLERANCE = 0.002
"""mm: chordal error of expanded arcs, tip deviation of subdivided axis-changing moves, replay tolerance."""

DEFAULT_ANGLE_TOLERANCE_DEG = 0.01
"""deg: how far the tool axis of a subdivided axis-changing move may stray from its great circle."""

DEFAULT_ANGLE_TOLERANCE = math.radians(DEFAULT_ANGLE_TOLERANCE_DEG)
"""rad: :data:`DEFAULT_ANGLE_TOLERANCE_DEG` in code units."""
