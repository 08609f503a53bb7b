"""Every default and constant of the library, defined once: the tolerances (the CLI's option defaults, the
header's), the clearance a collision check keeps, the nominal rapid rate, the inch, and the range of feeds any
input may ask for. What is a machine's own (its limits, speeds, holder) is in its machine file instead.

A value a user gives overrides these; a program header records the one used. The stages take them as
required keyword arguments (the post pipeline and linearization, the profiles, placement, the replay and
verify_program, the verify report and the move times, the collision check, the preview, the CAM readers),
so a value someone forgets to pass is an error, not
silently the default: the edges (the command line, a job file, a request's fields, a conversion's settings)
fill them in from this module.
tests/test_defaults.py fails on a new copy of these numbers elsewhere in the package.
"""

from __future__ import annotations

import math

__all__ = [
    "DEFAULT_ACTUATOR_RESOLUTION_MM", "DEFAULT_ANGLE_TOLERANCE", "DEFAULT_ANGLE_TOLERANCE_DEG",
    "DEFAULT_CIRCLE_TOLERANCE", "DEFAULT_CLEARANCE_MIN", "DEFAULT_MEASUREMENT_NOISE_MM", "DEFAULT_TOLERANCE",
    "FEED_RANGE_MM_MIN", "LIMIT_TOLERANCE", "MAX_SPINDLE_RPM", "MIN_SPINDLE_RPM", "MM_PER_INCH", "NOMINAL_ACCEL",
    "NOMINAL_RAPID_RATE",
]

DEFAULT_TOLERANCE = 0.002
"""mm: chordal error of expanded arcs, tip deviation of subdivided axis-changing moves, replay tolerance."""

DEFAULT_ANGLE_TOLERANCE_DEG = 0.01
"""deg: how far the tool axis of a subdivided axis-changing move may stray from its great circle."""

DEFAULT_ANGLE_TOLERANCE = math.radians(DEFAULT_ANGLE_TOLERANCE_DEG)
"""rad: :data:`DEFAULT_ANGLE_TOLERANCE_DEG` in code units."""

DEFAULT_CIRCLE_TOLERANCE = 0.01
"""mm: how far a CAM arc's start and end may be from its circle (radially, and in height for a helix)."""

DEFAULT_CLEARANCE_MIN = 1.0
"""mm: the least distance the tool, holder and spindle nose must keep from the part (``--clearance-min``)."""

NOMINAL_RAPID_RATE = 5000.0
"""mm/min: the joint-space rate a G0 move is timed at where the machine file has no ``[dynamics]``
(``verify --rapid-rate``)."""

NOMINAL_ACCEL = 500.0
"""mm/s²: the acceleration a LinuxCNC configuration gives each axis where the machine file has no
``[dynamics]`` (``prs3-post linuxcnc-config``; the speed is :data:`NOMINAL_RAPID_RATE`)."""

MM_PER_INCH = 25.4
"""mm in an inch (G20 programs, ``UNITS/INCHES`` CL files, STL parts in inches)."""

FEED_RANGE_MM_MIN = (0.1, 1e6)
"""mm/min, the tip feeds an option, a job file, a CAM file (FEDRAT/, CYCLE/, G-code F) may ask for: from 6 mm an
hour (slower is a typo or a unit error, and a long move's inverse-time F would print as 0) to a kilometre a
minute (faster is a typo; the controller could not follow)."""

MAX_SPINDLE_RPM = 1e6
"""rpm, the spindle speed an option, a job file, a CAM file (SPINDL/, G-code S) may ask for at most: spindles reach
some 100,000 rpm; more is a typo (a CAM file's ``SPINDL/RPM,1e30`` was written as a 32-digit S word)."""

MIN_SPINDLE_RPM = 1.0
"""rpm, the spindle speed an option, a job file, a CAM file (SPINDL/, a G-code S other than S0) may ask for at
least: slower is a typo or a unit error, and printed with no decimals (a dialect's ``decimals.spindle = 0``) it
would be an S0 that does not turn the spindle."""

LIMIT_TOLERANCE = 1e-9
"""mm, deg (or a plain number: the condition number): how far a value may pass a machine limit and still be at
it, not beyond: the float noise of a round trip (a stroke of 400 mm comes back as 400.00000000000006), far below
the 0.0001 mm and deg printed. Every limit check (post.limits, the placement search) compares with it."""

DEFAULT_MEASUREMENT_NOISE_MM = 0.01
"""mm: the noise of a calibration's measured tool tips (one coordinate, one standard deviation) unless the user
gives it (``calibrate --noise-mm``): a laser tracker at a couple of metres, or a touch probe on a reference artefact."""

DEFAULT_ACTUATOR_RESOLUTION_MM = 0.001
"""mm: the step an actuator is set to within unless the user gives it (``accuracy --resolution-mm``): a lead screw's
encoder, and the 4 decimals of a U V W word at most."""
