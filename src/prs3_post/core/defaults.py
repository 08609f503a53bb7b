"""The default tolerances, defined once (library defaults, the CLI's option defaults, the header's), and
the range of feeds any input may ask for.

A tolerance a user gives overrides these; a program header records the one used.
"""

from __future__ import annotations

import math

__all__ = [
    "DEFAULT_ANGLE_TOLERANCE", "DEFAULT_ANGLE_TOLERANCE_DEG", "DEFAULT_TOLERANCE", "FEED_RANGE_MM_MIN",
    "MAX_SPINDLE_RPM",
]

DEFAULT_TOLERANCE = 0.002
"""mm: chordal error of expanded arcs, tip deviation of subdivided axis-changing moves, replay tolerance."""

DEFAULT_ANGLE_TOLERANCE_DEG = 0.01
"""deg: how far the tool axis of a subdivided axis-changing move may stray from its great circle."""

DEFAULT_ANGLE_TOLERANCE = math.radians(DEFAULT_ANGLE_TOLERANCE_DEG)
"""rad: :data:`DEFAULT_ANGLE_TOLERANCE_DEG` in code units."""

FEED_RANGE_MM_MIN = (0.1, 1e6)
"""mm/min, the tip feeds an option, a job file, a CAM file (FEDRAT/, CYCLE/, G-code F) may ask for: from 6 mm an
hour (slower is a typo or a unit error, and a long move's inverse-time F would print as 0) to a kilometre a
minute (faster is a typo; the controller could not follow)."""

MAX_SPINDLE_RPM = 1e6
"""rpm, the spindle speed an option, a job file, a CAM file (SPINDL/, G-code S) may ask for at most: spindles reach
some 100,000 rpm; more is a typo (a CAM file's ``SPINDL/RPM,1e30`` was written as a 32-digit S word)."""
