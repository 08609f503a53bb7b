"""Array type aliases shared by every stage."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]

Progress = Callable[[float, float], None]
"""A long loop's progress, ``progress(done, total)`` in one unit (bytes read, rows replayed), called as it goes
by the library's read and replay loops; the front end draws it (or not)."""
